"""A toy input kind for the contract suite: a cursor that answers every trial with the
target the training shows, else straight ahead (0 deg). It touches nothing but this
module and one registry line (tests/test_input_contract.py adds the line)."""

from __future__ import annotations

import math

from tactorbelt.inputs.base import CursorSample, CursorSource, TrialCue
from tactorbelt.inputs.kinds import InputContext


class ToyCursor(CursorSource):
    """Home until a stimulus starts, then on the ellipse at the chosen angle."""

    person = False

    def __init__(self) -> None:
        self._at: tuple[float, float] = (0.0, 0.0)

    def read(self, now_ns: int) -> CursorSample:
        return CursorSample(now_ns, *self._at)

    def trial_started(self, cue: TrialCue, onset_ns: int) -> None:
        a = math.radians(cue.shown_target_deg or 0.0)
        self._at = (math.sin(a), math.cos(a))

    def trial_ended(self, now_ns: int) -> None:
        self._at = (0.0, 0.0)


def cursor(ctx: InputContext) -> ToyCursor:
    return ToyCursor()
