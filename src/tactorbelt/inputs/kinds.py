"""The registry of input kinds: one module per kind, one line here.

``tactorbelt run --input`` and ``tactorbelt calibrate perceptual --input`` name a kind.
Each line declares what the kind needs (the experiment window and so a display, a
person on live hardware in real time, or simulated time) and what the window says for
it; the kind's module makes its cursor source (``cursor(ctx)``, for a session) and its
respondent (``respondent(ctx)``, for the perceptual calibration), each from one
:class:`InputContext`. Nothing outside the kinds' modules branches on a kind's name.

Adding a kind (docs/architecture.md, "Adding things"): a module with ``cursor`` and/or
``respondent``, and one line in :data:`INPUT_KINDS`.

Pure: the standard library and the registry helper; a kind's module is imported when
its cursor or respondent is made.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from .._registry import Registry, check_option, resolve

if TYPE_CHECKING:
    from ..calibration.perceptual import Respondent
    from ..clock import Clock
    from ..devices.base import Belt
    from ..experiment.schedule import ScheduledTrial
    from ..experiment.study import Study
    from ..participant.params import ModelParams
    from .base import CursorSource
    from .joystick import JoystickConfig

__all__ = ["INPUT_KINDS", "InputContext", "InputKind", "calibration_inputs", "input_kind",
           "session_inputs"]


@dataclass(frozen=True)
class InputContext:
    """What a kind's module may use to make its cursor source or respondent.

    Attributes:
        study: the study (None for the perceptual calibration).
        belt, clock: the session's (the model participant feels the belt on the clock).
        participant: the participant id.
        seed: the session's seed (default: the study's ``session.seed``; the
            calibration's seed).
        cursor_seed: the model participant's own seed, instead of
            :func:`~tactorbelt.inputs.participant_seed` of ``seed`` and ``participant``.
        params: the model observer (default: the typical observer timed for the study).
        schedule: the session's schedule (the scripted cursor's answers).
        geometry: the window's ellipse geometry (mouse).
        joystick: which stick (index or name substring) or a full JoystickConfig.
        read_key, say: the terminal (the keyboard respondent).
    """

    study: Study | None = None
    belt: Belt | None = None
    clock: Clock | None = None
    participant: str = ""
    seed: int | None = None
    cursor_seed: int | None = None
    params: ModelParams | None = None
    schedule: list[ScheduledTrial] | None = None
    geometry: Any = None
    joystick: JoystickConfig | int | str | None = None
    read_key: Callable[[], str] | None = None
    say: Callable[[str], None] | None = None


@dataclass(frozen=True)
class InputKind:
    """One input kind: what it needs and what the window says for it.

    Attributes:
        name: its ``--input`` name.
        module: the module with its ``cursor(ctx)`` and/or ``respondent(ctx)``.
        help: one line for the docs.
        display: it needs the experiment window (and so a display): the window makes
            and feeds its cursor, and the calibration asks in the window.
        live: a person answers on live hardware in real time (the wall clock; waiting
            screens wait for their key).
        simulated_time: it can run on a simulated clock (headless, as fast as the CPU
            allows).
        session: it gives a cursor for ``tactorbelt run``.
        calibration: it answers ``tactorbelt calibrate perceptual``.
        go_on, move: how the window tells the participant to go on and to answer.
        stick: a stick (the window hides the pointer; the NASA-TLX is set by stick).
        clicks: a mouse click goes on from a waiting screen.
    """

    name: str
    module: str
    help: str
    display: bool = False
    live: bool = False
    simulated_time: bool = False
    session: bool = True
    calibration: bool = True
    go_on: str = "press Space (or wait a moment)"
    move: str = "Move the cursor"
    stick: bool = False
    clicks: bool = False

    def cursor(self, ctx: InputContext) -> CursorSource:
        """The kind's cursor source (its module's ``cursor``)."""
        made: CursorSource = resolve(f"{self.module}:cursor")(ctx)
        return made

    def respondent(self, ctx: InputContext) -> Respondent:
        """The kind's respondent for the perceptual calibration (its module's
        ``respondent``; a display kind's is the window's, made by the caller)."""
        made: Respondent = resolve(f"{self.module}:respondent")(ctx)
        return made


#: Every input kind, by name (a new kind: one line).
INPUT_KINDS: Registry[InputKind] = Registry("input", [
    InputKind("joystick", "tactorbelt.inputs.joystick", "a person pushing a joystick",
              display=True, live=True, stick=True, go_on="press the trigger or Space",
              move="Push the joystick"),
    InputKind("mouse", "tactorbelt.inputs.mouse", "a person moving the mouse",
              display=True, live=True, clicks=True, go_on="click or press Space",
              move="Move the mouse"),
    InputKind("model", "tactorbelt.inputs.model", "the model participant",
              simulated_time=True),
    InputKind("scripted", "tactorbelt.inputs.scripted", "the right answer of every trial",
              simulated_time=True, calibration=False),
    InputKind("keyboard", "tactorbelt.inputs.keyboard", "a person at the terminal's keys",
              live=True, session=False),
])


def session_inputs() -> tuple[str, ...]:
    """The names ``tactorbelt run --input`` takes."""
    return tuple(k.name for k in INPUT_KINDS.values() if k.session)


def calibration_inputs() -> tuple[str, ...]:
    """The names ``tactorbelt calibrate perceptual --input`` takes."""
    return tuple(k.name for k in INPUT_KINDS.values() if k.calibration)


def input_kind(name: str, *, calibration: bool = False) -> InputKind:
    """The kind ``name`` of a session (or of the calibration); ConfigError ``unknown
    input 'x'; allowed: ...`` when there is none."""
    check_option("input", name, calibration_inputs() if calibration else session_inputs())
    return INPUT_KINDS[name]
