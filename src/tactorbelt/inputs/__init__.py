"""Cursor sources, and :func:`make_cursor`, the one way to make one by name.

Sources: ``joystick`` (:mod:`.joystick`), ``mouse`` (:mod:`.mouse`), ``scripted``
(:mod:`.scripted`, the right answer of every trial) and ``model`` (:mod:`.model`, the
model participant). Every module is imported only when its source is made.

Seed policy (the model participant; the other sources use no randomness): the model's
own seed is ``cursor_seed`` when given (``tactorbelt demo`` draws one per participant),
else :func:`participant_seed` of the session's seed (``seed``, default the study's
``session.seed``) and the participant id. So one participant gives the same model
run for the same session seed, whichever command or window starts it, and two
participants of one study differ.
"""

from __future__ import annotations

import hashlib
from typing import TYPE_CHECKING, Any

from .._errors import ConfigError

if TYPE_CHECKING:
    from ..clock import Clock
    from ..devices.base import Belt
    from ..experiment.schedule import ScheduledTrial
    from ..experiment.study import Study
    from ..participant.params import ModelParams
    from .base import CursorSource
    from .joystick import JoystickConfig

__all__ = ["INPUTS", "make_cursor", "participant_seed"]

#: The names ``--input`` takes.
INPUTS = ("joystick", "mouse", "model", "scripted")


def participant_seed(seed: int, participant: str) -> int:
    """The model participant's seed for ``participant`` in a session seeded ``seed``:
    the first 4 bytes (little-endian) of SHA-256 of ``"<seed>:<participant>"``."""
    h = hashlib.sha256(f"{seed}:{participant}".encode()).digest()
    return int.from_bytes(h[:4], "little")


def make_cursor(
    kind: str,
    *,
    study: Study,
    belt: Belt | None = None,
    clock: Clock | None = None,
    participant: str = "",
    seed: int | None = None,
    cursor_seed: int | None = None,
    params: ModelParams | None = None,
    schedule: list[ScheduledTrial] | None = None,
    geometry: Any = None,
    joystick: JoystickConfig | int | str | None = None,
) -> CursorSource:
    """The cursor source for ``--input KIND``.

    Args:
        kind: ``joystick``, ``mouse``, ``scripted`` or ``model``.
        study: the study.
        belt: the belt (``model``: the participant feels its vibration).
        clock: the runner's clock (``model``).
        participant: the participant id (``model`` seed, ``scripted`` schedule).
        seed: the session's seed (default: the study's ``session.seed``).
        cursor_seed: the model participant's own seed, instead of
            :func:`participant_seed` of ``seed`` and ``participant``.
        params: the model observer (default: the typical observer timed for the
            study's dynamic period).
        schedule: the session's schedule (``scripted``: its answers, required: the one
            ``seed`` makes for ``participant``, or the stored one on resume).
        geometry: the window's ellipse geometry (``mouse``).
        joystick: which stick (index or name substring) or a full JoystickConfig.

    Raises:
        ConfigError: an unknown kind, or a model participant without belt or clock.
    """
    session_seed = study.session.seed if seed is None else int(seed)
    if kind == "scripted":
        from .scripted import ScriptedCursor

        if schedule is None:  # the experiment layer makes it (inputs sit below it)
            raise ConfigError("a scripted cursor needs the session's schedule (its answers): "
                              "pass schedule=make_schedule(study, participant, seed)")
        return ScriptedCursor(answers={t.trial_index: t.target_deg for t in schedule})
    if kind == "model":
        if belt is None or clock is None:
            raise ConfigError("the model participant (--input model) needs the belt and the "
                              "clock")
        from ..participant.params import ModelParams
        from .model import make_model_cursor

        own = participant_seed(session_seed, participant) if cursor_seed is None \
            else int(cursor_seed)
        if params is None:
            params = ModelParams().for_period(study.stimulus.period_s)
        return make_model_cursor(belt, clock, own, params=params)
    if kind == "mouse":
        from .mouse import MouseCursor

        return MouseCursor(geometry)
    if kind == "joystick":
        from .joystick import JoystickConfig, JoystickCursor

        if isinstance(joystick, JoystickConfig):
            cfg = joystick
        else:
            cfg = JoystickConfig(device=JoystickConfig.parse_device(joystick)
                                 if isinstance(joystick, str) else joystick)
        return JoystickCursor(cfg)
    raise ConfigError(f"unknown input {kind!r}; allowed: {', '.join(INPUTS)}")
