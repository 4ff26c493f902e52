"""The registry of input kinds: one module per kind, one line here.

``tactorbelt run --input`` and ``tactorbelt calibrate perceptual --input`` name a kind.
Each line declares what the kind needs (the experiment window and so a display, a
person on live hardware in real time, or simulated time) and what the window says for
it; the kind's module makes its cursor source (``cursor(ctx)``, for a session) and its
respondent (``respondent(ctx)``, for the perceptual calibration), each from one
:class:`InputContext`. Nothing outside the kinds' modules branches on a kind's name.

Adding a kind (docs/architecture.md, "Adding things"): a module with ``cursor`` and/or
``respondent``, and one line in :data:`INPUT_KINDS`.

Pure: the standard library, the error tree and the registry helper; a kind's module is imported when
its cursor or respondent is made.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from .._errors import ConfigError
from .._registry import Registry, check_option, resolve

if TYPE_CHECKING:
    from ..calibration.perceptual import Respondent
    from ..clock import Clock
    from ..devices.base import Belt
    from ..participant.params import ModelParams
    from .base import CursorSource

__all__ = ["INPUT_KINDS", "InputContext", "InputKind", "JoystickConfig", "ScheduledAnswer",
           "StudyFacts", "calibration_inputs", "input_kind", "session_inputs"]


class _SessionFacts(Protocol):
    @property
    def seed(self) -> int: ...


class _StimulusFacts(Protocol):
    @property
    def period_s(self) -> float: ...


class StudyFacts(Protocol):
    """What an input kind reads of a study (a :class:`~tactorbelt.experiment.study.Study`
    is one): the session's seed and the stimulus period (the model participant's)."""

    @property
    def session(self) -> _SessionFacts: ...

    @property
    def stimulus(self) -> _StimulusFacts: ...


class ScheduledAnswer(Protocol):
    """What an input kind reads of a scheduled trial (a
    :class:`~tactorbelt.experiment.schedule.ScheduledTrial` is one): its position and
    its target (the scripted cursor's answer)."""

    @property
    def trial_index(self) -> int: ...

    @property
    def target_deg(self) -> float: ...


@dataclass(frozen=True)
class JoystickConfig:
    """Which stick and how its axes map to the cursor.

    Attributes:
        device: a device index (``0``) or a case-insensitive substring of its name
            (``"warthog joystick"``); None picks the first device whose name does not
            contain ``throttle`` (the Warthog's throttle is a separate USB device).
        axis_x: index of the left/right axis (Warthog stick: 0).
        axis_y: index of the front/back axis (Warthog stick: 1).
        dead_zone: radial dead zone in [0, 1).
        invert_x, invert_y: mirror an axis.
    """

    device: int | str | None = None
    axis_x: int = 0
    axis_y: int = 1
    dead_zone: float = 0.05
    invert_x: bool = False
    invert_y: bool = False

    def __post_init__(self) -> None:
        if not 0.0 <= self.dead_zone < 1.0:
            raise ConfigError(f"joystick dead zone must be in [0, 1), got {self.dead_zone!r}")
        for name in ("axis_x", "axis_y"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 0:
                raise ConfigError(f"joystick {name} must be an axis index >= 0, got {v!r}")
        if self.axis_x == self.axis_y:
            raise ConfigError(f"joystick axis_x and axis_y are both {self.axis_x}")

    @classmethod
    def parse_device(cls, text: str | None) -> int | str | None:
        """``"0"`` -> 0, ``"warthog"`` -> ``"warthog"``, ``None``/``""`` -> None."""
        if text is None or not str(text).strip():
            return None
        t = str(text).strip()
        return int(t) if t.isdigit() else t



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

    study: StudyFacts | None = None
    belt: Belt | None = None
    clock: Clock | None = None
    participant: str = ""
    seed: int | None = None
    cursor_seed: int | None = None
    params: ModelParams | None = None
    schedule: Sequence[ScheduledAnswer] | None = None
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
