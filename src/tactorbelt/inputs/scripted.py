"""A scripted cursor: answers given in advance, moved like a hand would, for tests and demos.

Each trial's response is a :class:`ScriptedResponse`: an answer (an angle in degrees,
``"correct"``, ``None`` for no answer, or a callable ``(cue) -> angle``), a reaction
time (the cursor stays at home), a movement time (from home out to ``radius`` along
the answer's direction) and a profile (``min_jerk`` or ``linear``). Between trials the
cursor is at home (the centre), like a sprung joystick.

``"correct"`` needs to know the answer: pass ``answers`` (trial_index -> target
angle, e.g. ``{t.trial_index: t.target_deg for t in schedule}``); in training trials the
highlighted target is used when no answer is given.

Imports only the standard library and tactorbelt.inputs.base.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .._errors import ConfigError
from .base import CursorSample, CursorSource, TrialCue

if TYPE_CHECKING:
    from .kinds import InputContext

__all__ = ["ScriptedCursor", "ScriptedResponse", "min_jerk"]

Answer = float | int | str | None | Callable[[TrialCue], float | None]


def min_jerk(s: float) -> float:
    """The minimum-jerk position profile: 0 at s <= 0, 1 at s >= 1, smooth between."""
    if s <= 0.0:
        return 0.0
    if s >= 1.0:
        return 1.0
    return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


@dataclass(frozen=True)
class ScriptedResponse:
    """How to answer one trial.

    Attributes:
        answer: an angle (degrees), ``"correct"``, ``None`` (stay home: a timeout), or
            a callable taking the :class:`TrialCue` and returning an angle or None.
        reaction_s: time from onset before the cursor starts to move.
        movement_s: time to move from home to ``radius``.
        radius: how far out the cursor goes (cursor units; the ellipse has radius 1).
        profile: ``min_jerk`` or ``linear``.
    """

    answer: Answer = "correct"
    reaction_s: float = 0.3
    movement_s: float = 0.4
    radius: float = 1.0
    profile: str = "min_jerk"

    def __post_init__(self) -> None:
        if self.profile not in ("min_jerk", "linear"):
            raise ConfigError(f"profile must be min_jerk or linear, got {self.profile!r}")
        for name in ("reaction_s", "movement_s"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v >= 0):
                raise ConfigError(f"{name} must be a finite number of seconds >= 0, got {v!r}")
        if not (0 < self.radius <= 2):
            raise ConfigError(f"radius must be in (0, 2], got {self.radius!r}")
        if isinstance(self.answer, str) and self.answer != "correct":
            raise ConfigError(
                f"answer must be an angle, 'correct', None or a callable, got {self.answer!r}"
            )


class ScriptedCursor(CursorSource):
    """A cursor that plays back scripted responses.

    Args:
        responses: one :class:`ScriptedResponse` for every trial, a sequence (the n-th
            trial started gets the n-th; the last one repeats when they run out), or a
            mapping trial_index -> response (missing trials: ``default``).
        answers: trial_index -> target angle, needed for ``"correct"`` in test trials.
        default: the response for trials the mapping does not list.
    """

    def __init__(
        self,
        responses: ScriptedResponse | Sequence[ScriptedResponse] | Mapping[int, ScriptedResponse]
        | None = None,
        answers: Mapping[int, float] | None = None,
        default: ScriptedResponse | None = None,
    ) -> None:
        self._responses = ScriptedResponse() if responses is None else responses
        if isinstance(self._responses, Sequence) and not self._responses:
            raise ConfigError("a scripted cursor needs at least one response")
        self._answers = dict(answers or {})
        self._default = default or ScriptedResponse()
        self._n_started = 0
        self._onset: int | None = None
        self._dir: tuple[float, float] | None = None
        self._current = self._default

    def _response_for(self, cue: TrialCue) -> ScriptedResponse:
        r = self._responses
        if isinstance(r, ScriptedResponse):
            return r
        if isinstance(r, Mapping):
            return r.get(cue.trial_index, self._default)
        return r[min(self._n_started, len(r) - 1)]

    def _angle(self, resp: ScriptedResponse, cue: TrialCue) -> float | None:
        a = resp.answer
        if callable(a):
            return a(cue)
        if a == "correct":
            if cue.trial_index in self._answers:
                return float(self._answers[cue.trial_index])
            if cue.shown_target_deg is not None:
                return float(cue.shown_target_deg)
            raise ConfigError(
                f"scripted answer 'correct' for test trial {cue.trial_index} needs the answers "
                "(pass answers={trial_index: target_deg})"
            )
        return None if a is None else float(a)

    def trial_started(self, cue: TrialCue, onset_ns: int) -> None:
        resp = self._response_for(cue)
        self._n_started += 1
        angle = self._angle(resp, cue)
        self._current = resp
        self._onset = int(onset_ns)
        if angle is None:
            self._dir = None
        else:
            rad = math.radians(angle)
            self._dir = (math.sin(rad), math.cos(rad))

    def trial_ended(self, now_ns: int) -> None:
        self._onset = None
        self._dir = None

    def read(self, now_ns: int) -> CursorSample:
        if self._onset is None or self._dir is None:
            return CursorSample(int(now_ns), 0.0, 0.0, 0)
        resp = self._current
        t = (now_ns - self._onset) / 1e9 - resp.reaction_s
        if t <= 0:
            return CursorSample(int(now_ns), 0.0, 0.0, 0)
        s = 1.0 if resp.movement_s == 0 else t / resp.movement_s
        frac = min_jerk(s) if resp.profile == "min_jerk" else min(max(s, 0.0), 1.0)
        r = resp.radius * frac
        return CursorSample(int(now_ns), r * self._dir[0], r * self._dir[1], 0)


def cursor(ctx: InputContext) -> ScriptedCursor:
    """The ``scripted`` input kind's cursor (:mod:`tactorbelt.inputs.kinds`): the right
    answer of every trial of ``ctx.schedule``."""
    if ctx.schedule is None:  # the experiment layer makes it (inputs sit below it)
        raise ConfigError("a scripted cursor needs the session's schedule (its answers): "
                          "pass schedule=make_schedule(study, participant, seed)")
    return ScriptedCursor(answers={t.trial_index: t.target_deg for t in ctx.schedule})
