"""Cursor sources: where a participant's answer comes from.

A cursor source gives the cursor position, normalised so that the response ellipse
has radius 1 along each axis (x right, y up = front), with buttons and a timestamp.
Joystick, mouse, a scripted list and the model participant are all cursor sources;
the runner never knows which one it has.

The runner tells the source when a trial's stimulus starts and ends, with only what a
participant in the study would know (:class:`TrialCue`): the candidate targets, and
during training the highlighted target. Never the answer in a test trial.

Under cognitive load (issue 18) the runner also tells the source when a secondary task
runs and which items it presents, and asks it for response presses and workload
ratings: no-ops here, so a person's device answers nothing (the window collects a
person's presses and ratings); the model participant answers them itself.

:class:`LiveCursor` is the base of the sources a window's event loop feeds (the joystick,
the mouse).

Imports only the standard library and tactorbelt.geometry (numpy, the respondent and the
task types for annotations).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..geometry import Layout

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from ..calibration.perceptual import Respondent
    from ..tasks import WorkloadInfo
    from ..tasks.schedule import TaskItem
    from ..tasks.spec import TaskSpec
    from .screen import EllipseGeometry

__all__ = ["CursorSample", "CursorSource", "LiveCursor", "RunTaker", "TrialCue"]

#: ``take(t_ns, x, y) -> m``: what :meth:`CursorSource.read_run` hands a run of samples
#: to (the trial machine's :meth:`~tactorbelt.experiment.trial.TrialMachine.feed_run`).
RunTaker = Callable[[Any, Any, Any], int]


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
    """Base class of cursor sources. Subclasses implement :meth:`read`.

    What a window may use, declared here with defaults (a source sets what it has):

    Attributes:
        geometry: where the response ellipse is on screen (pixels); the window sets it
            when it lays out (the mouse uses it; other sources ignore it).
        name: the device's name for the operator's overlay, or None.
        problem: why the device cannot be used now (shown while paused), or None.
        raw_axes: the device's raw axes for the overlay, or None.
        person: True when a person moves the cursor (every source but the model
            participant); a session without a person may batch its store commits.
        reads_runs: True when the source can be read for a run of sampling times at
            once (:meth:`read_run`; the model participant): a simulated session that
            nobody watches samples it that way, with the same samples.
    """

    person: bool = True
    reads_runs: bool = False
    geometry: EllipseGeometry | None = None
    name: str | None = None
    problem: str | None = None
    raw_axes: tuple[float, float] | None = None

    @property
    def instance_id(self) -> int | None:
        """SDL's instance id of the device (its events carry it), or None."""
        return None

    def live_input(self) -> LiveCursor | None:
        """The part of this source the window's event loop feeds (a joystick's or a
        mouse's state), or None: a source that reads itself (scripted, the model)."""
        return None

    def describe_wanted(self) -> str:
        """What the source waits for while its device is gone, in words."""
        return "the joystick"

    def read(self, now_ns: int) -> CursorSample:
        """The cursor at ``now_ns`` (the runner's clock)."""
        raise NotImplementedError

    def read_run(self, times_ns: NDArray[np.int64], take: RunTaker) -> int:
        """Read the cursor at the first k of ``times_ns`` (increasing sampling times, the
        clock at ``times_ns[0]``) as k calls of :meth:`read` would, hand them to
        ``take(t_ns, x, y)`` (arrays of length k), which returns how many m (1..k) it
        used, and go on as if only those m reads had been made; return m.

        The source chooses k >= 1: a run never goes past a point where reading has an
        effect beyond the run (the model participant's decision, which reads the belt,
        only ever at a run's first time). Buttons are never pressed in a run. Only for
        sources with :attr:`reads_runs`.
        """
        raise NotImplementedError(f"{type(self).__name__} cannot be read in runs")

    def trial_started(self, cue: TrialCue, onset_ns: int) -> None:
        """The stimulus of a trial started at ``onset_ns``."""

    def trial_ended(self, now_ns: int) -> None:
        """The trial's response was taken (or it timed out or was aborted)."""

    def close(self) -> None:
        """Release the device."""

    def calibration_respondent(self, seed: int) -> Respondent | None:
        """Who answers the perceptual calibration's trials when a study requires a wearer
        profile and none is kept (:mod:`tactorbelt.calibration.perceptual`): the model participant
        answers itself; a person's device (None, the default) cannot, so the person is
        calibrated beforehand with ``tactorbelt calibrate perceptual --input keyboard``."""
        return None

    # -- secondary tasks and workload (no-ops unless the source answers them) ---------
    def task_phase(self, spec: TaskSpec | None, phase: str | None) -> None:
        """A secondary task starts (its spec and phase: ``practice``, ``baseline``,
        ``dual``) or ends (None, None)."""

    def task_item(self, item: TaskItem, onset_ns: int) -> None:
        """A task item will be presented at ``onset_ns``. A source that answers the task
        works out whether it is a go item from the stimuli (never ``item.target``)."""

    def task_presses(self, now_ns: int) -> list[int]:
        """The source's response presses (ns, runner clock) due by ``now_ns`` and not
        reported yet; [] by default."""
        return []

    def rate_workload(self, info: WorkloadInfo) -> dict[str, float] | None:
        """The source's NASA-TLX ratings after a block (item -> 0..100), or None when a
        person answers (the window asks)."""
        return None


class LiveCursor(CursorSource):
    """A cursor whose state is set by the window's main loop and read by anyone.

    :meth:`set_state` (main thread) replaces one tuple; :meth:`read` (any thread)
    reads it. Assigning and reading one attribute is atomic in CPython, so no lock.

    When the runner's loop runs in the thread that owns the window (the usual case:
    everything in the main thread), the window registers a refresh function with
    :meth:`attach_refresh`; :meth:`read` then pumps SDL's events and re-reads the
    device first, so each 100 Hz sample holds the stick's state at that moment, not
    at the last frame. From any other thread :meth:`read` never touches SDL.
    """

    def __init__(self) -> None:
        self._state: tuple[float, float, int] = (0.0, 0.0, 0)
        self._refresh: Callable[[], None] | None = None
        self._owner: int | None = None

    def live_input(self) -> LiveCursor:
        return self

    def attach_refresh(self, refresh: Callable[[], None] | None) -> None:
        """Call ``refresh`` (pump and update) in :meth:`read` when read from this thread."""
        self._refresh = refresh
        self._owner = threading.get_ident() if refresh is not None else None

    def set_state(self, x: float, y: float, buttons: int = 0) -> None:
        """Store the latest position (cursor units) and button mask."""
        self._state = (float(x), float(y), int(buttons))

    @property
    def state(self) -> tuple[float, float, int]:
        """The latest ``(x, y, buttons)``."""
        return self._state

    @property
    def connected(self) -> bool:
        """False while the device is gone (the window pauses the session)."""
        return True

    def read(self, now_ns: int) -> CursorSample:
        refresh = self._refresh
        if refresh is not None and threading.get_ident() == self._owner:
            refresh()
        x, y, b = self._state
        return CursorSample(int(now_ns), x, y, b)

    def handle_event(self, event: Any) -> None:
        """Look at one pygame event (main thread). Default: ignore it."""

    def update(self) -> None:
        """Refresh the state from the device after an event pump (main thread)."""
