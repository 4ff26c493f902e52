"""Cursor sources, and :func:`make_cursor`, the one way to make one by name.

The input kinds are registered in :mod:`.kinds` (one module per kind, one line there):
``joystick`` (:mod:`.joystick`), ``mouse`` (:mod:`.mouse`), ``scripted``
(:mod:`.scripted`, the right answer of every trial), ``model`` (:mod:`.model`, the
model participant) and ``keyboard`` (:mod:`.keyboard`, the perceptual calibration only).
Every module is imported only when its source is made.

Seed policy (the model participant; the other sources use no randomness): the model's
own seed is ``cursor_seed`` when given (``tactorbelt demo`` draws one per participant),
else :func:`participant_seed` of the session's seed (``seed``, default the study's
``session.seed``) and the participant id. So one participant gives the same model
run for the same session seed, whichever command or window starts it, and two
participants of one study differ.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ..clock import Clock
    from ..devices.base import Belt
    from ..participant.params import ModelParams
    from .base import CursorSource
    from .kinds import JoystickConfig, ScheduledAnswer, StudyFacts

__all__ = ["make_cursor", "participant_seed"]


def participant_seed(seed: int, participant: str) -> int:
    """The model participant's seed for ``participant`` in a session seeded ``seed``:
    the first 4 bytes (little-endian) of SHA-256 of ``"<seed>:<participant>"``."""
    h = hashlib.sha256(f"{seed}:{participant}".encode()).digest()
    return int.from_bytes(h[:4], "little")


def make_cursor(
    kind: str,
    *,
    study: StudyFacts,
    belt: Belt | None = None,
    clock: Clock | None = None,
    participant: str = "",
    seed: int | None = None,
    cursor_seed: int | None = None,
    params: ModelParams | None = None,
    schedule: Sequence[ScheduledAnswer] | None = None,
    geometry: Any = None,
    joystick: JoystickConfig | int | str | None = None,
) -> CursorSource:
    """The cursor source for ``--input KIND``: the kind's module makes it
    (:mod:`.kinds`) from these values.

    Args:
        kind: a session input kind (:func:`~.kinds.session_inputs`).
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
        ConfigError: an unknown kind, or what the kind needs is missing (the model
            participant without belt or clock, a scripted cursor without schedule).
    """
    from .kinds import InputContext, input_kind

    return input_kind(kind).cursor(InputContext(
        study=study, belt=belt, clock=clock, participant=participant, seed=seed,
        cursor_seed=cursor_seed, params=params, schedule=schedule, geometry=geometry,
        joystick=joystick))
