"""Cursor sources: where a participant's answer comes from.

A cursor source gives the cursor position, normalised so that the response ellipse
has radius 1 along each axis (x right, y up = front), with buttons and a timestamp.
Joystick, mouse, a scripted list and the model participant are all cursor sources;
the runner never knows which one it has.

The runner tells the source when a trial's stimulus starts and ends, with only what a
participant in the study would know (:class:`TrialCue`): the candidate targets, and
during training the highlighted target. Never the answer in a test trial.

Imports only the standard library and tactorbelt.geometry.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..geometry import Layout

__all__ = ["CursorSample", "CursorSource", "TrialCue"]


@dataclass(frozen=True)
class CursorSample:
    """One cursor reading: time (ns, the runner's clock), x, y in ellipse units, buttons."""

    t_ns: int
    x: float
    y: float
    buttons: int = 0


@dataclass(frozen=True)
class TrialCue:
    """What a participant knows when a trial starts.

    Attributes:
        trial_index: position in the session's schedule.
        block: ``training`` or ``test``.
        condition: ``static`` or ``dynamic``.
        targets_deg: the candidate targets shown on screen.
        layout: the belt's layout (the model participant's body map; hidden on screen).
        shown_target_deg: in training, the highlighted target; None in test trials.
    """

    trial_index: int
    block: str
    condition: str
    targets_deg: tuple[float, ...]
    layout: Layout
    shown_target_deg: float | None = None


class CursorSource:
    """Base class of cursor sources. Subclasses implement :meth:`read`."""

    def read(self, now_ns: int) -> CursorSample:
        """The cursor at ``now_ns`` (the runner's clock)."""
        raise NotImplementedError

    def trial_started(self, cue: TrialCue, onset_ns: int) -> None:
        """The stimulus of a trial started at ``onset_ns``."""

    def trial_ended(self, now_ns: int) -> None:
        """The trial's response was taken (or it timed out or was aborted)."""

    def close(self) -> None:
        """Release the device."""
