"""What a running session tells its listeners, and what it asks its operator.

The runner (:mod:`.runner`) sends every event of a session to a list of
:class:`SessionListener` s, in order, none wrapping another (the run's stored options and
push, the LSL streams, the window, a progress bar); the queries that need an answer
(:meth:`Operator.poll` for a pause or an abort, the secondary task's presses, the
NASA-TLX, the waits at a break and before a secondary task) go to one
:class:`Operator` (the window; :class:`NullOperator` when nobody operates the session).
:class:`SessionListener` and :class:`Operator` implement every hook as nothing;
subclass them and override what you need. :class:`SessionObserver` is both (the window
is); ``NullListener``, ``NullOperator`` and ``NullObserver`` are their other names.

Pure: imports the experiment's types only.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import StrEnum
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ..inputs.base import CursorSample
    from ..tasks import WorkloadInfo
    from ..tasks.schedule import TaskItem
    from .schedule import ScheduledTrial
    from .study import Study, TaskSpec
    from .trial import TrialResult, TrialState

__all__ = ["Command", "Listeners", "NullListener", "NullObserver", "NullOperator", "Operator",
           "Progress", "SessionInfo", "SessionListener", "SessionObserver"]


class Command(StrEnum):
    """What the operator (the window) can ask of the runner."""

    PAUSE = "pause"
    RESUME = "resume"
    ABORT = "abort"


@dataclass(frozen=True)
class SessionInfo:
    """What a listener learns when a session starts.

    Attributes:
        session_id: the store's id of the session.
        participant: the participant id.
        study: the study.
        n_total: trials in the schedule.
        n_done: trials already done (non-zero when resuming).
        resumed: True when this continues an interrupted session.
        condition_order: the test blocks' conditions in running order.
    """

    session_id: int
    participant: str
    study: Study
    n_total: int
    n_done: int
    resumed: bool
    condition_order: tuple[str, ...]


class SessionListener:
    """The events of a session, in the order they happen; every hook does nothing here
    (subclass and override what you need).

    ``watching`` declares that the listener follows the session as it happens (a window,
    a stream, a push): the runner then sends it every cursor sample and tick, and
    commits each trial at once. A listener that only counts (:class:`Progress`) says
    False and leaves a simulated session its fast paths.
    """

    watching = True

    def on_session_start(self, info: SessionInfo, schedule: list[ScheduledTrial]) -> None:
        pass

    def on_block_start(self, block: str, condition: str) -> None:
        pass

    def on_trial_state(self, trial: ScheduledTrial, state: TrialState, now_ns: int) -> None:
        pass

    def on_tick(self, now_ns: int) -> None:
        """A sampling step (or a wait's step) at ``now_ns`` (watching listeners only)."""

    def on_sample(self, sample: CursorSample) -> None:
        """A cursor sample (watching listeners only)."""

    def on_command(self, command: Command, now_ns: int) -> None:
        """The operator paused, resumed or aborted the session."""

    def on_skin_onset(self, trial: ScheduledTrial, skin_onset_ns: int,
                      skin_onset_sd_ns: int) -> None:
        """A trial's onset at the skin is known (its belt's calibration has measured
        latencies): sent just before :meth:`on_trial_done`."""

    def on_trial_done(self, result: TrialResult) -> None:
        pass

    def on_break(self, n_done: int, n_total: int) -> None:
        """A break starts (the operator's :meth:`Operator.wait_break` follows)."""

    def on_break_end(self) -> None:
        pass

    def on_task_phase(self, name: str | None, spec: TaskSpec | None, phase: str | None
                      ) -> None:
        """A secondary task starts (``practice`` or ``baseline`` alone, before the first
        block with its load; ``dual`` with a test block) or ends (None, None, None)."""

    def on_task_item(self, item: TaskItem, onset_ns: int, spec: TaskSpec) -> None:
        """An item will be presented at ``onset_ns`` (at least
        :data:`~tactorbelt.tasks.TASK_LEAD_NS` ahead): schedule its sound or glyph."""

    def on_task_presses(self, presses: list[int]) -> None:
        """The operator's presses of the task's button (ns, runner clock)."""

    def on_workload(self, info: WorkloadInfo, values: dict[str, float]) -> None:
        """The operator's NASA-TLX answers after a test block."""

    def on_session_end(self, status: str) -> None:
        pass


class Operator:
    """The queries of a session that need an answer (the window); each answers
    "nothing" here (subclass and override what you need)."""

    def poll(self, now_ns: int) -> Command | None:
        """Called at every sampling step: PAUSE (motors off at once), RESUME or ABORT."""
        return None

    def task_presses(self, now_ns: int) -> list[int]:
        """Response presses (ns, runner clock) of the task's button since the last call."""
        return []

    def ask_workload(self, info: WorkloadInfo) -> dict[str, float] | None:
        """Ask the NASA-TLX after a test block: item -> 0..100, or None (not asked)."""
        return None

    def wait_break(self, n_done: int, n_total: int) -> None:
        """A break: return when the participant is ready to go on."""

    def wait_task_phase(self, name: str | None, spec: TaskSpec | None,
                        phase: str | None) -> None:
        """After :meth:`SessionListener.on_task_phase`: return when the participant is
        ready (the task's instructions, once per task and phase)."""

    def show_wait(self, title: str | None, lines: list[str]) -> bool:
        """Show why the session waits (None: stop showing it), keep handling the
        operator's keys; True when the operator stopped the session."""
        return False


class SessionObserver(SessionListener, Operator):
    """A listener that is also the operator (the experiment window)."""


#: A listener, an operator and an observer that do nothing (subclass them).
NullListener = SessionListener
NullOperator = Operator
NullObserver = SessionObserver


class Progress(NullListener):
    """The run's progress as a listener: ``callback(n_done, n_total)`` after each trial
    with a final outcome (done or timeout)."""

    watching = False

    def __init__(self, callback: Callable[[int, int], None]) -> None:
        self.callback = callback
        self.n_done = 0
        self.n_total = 0

    def on_session_start(self, info: SessionInfo, schedule: list[ScheduledTrial]) -> None:
        self.n_done, self.n_total = info.n_done, info.n_total

    def on_trial_done(self, result: TrialResult) -> None:
        if result.status != "aborted":
            self.n_done += 1
            self.callback(self.n_done, self.n_total)


class Listeners(SessionListener):
    """Sends each event to every listener, in order (samples and ticks only to those
    :attr:`~SessionListener.watching`); its hooks are :class:`SessionListener`'s."""

    def __init__(self, listeners: Sequence[SessionListener]) -> None:
        self.all = list(listeners)
        self.watchers = [x for x in self.all if x.watching]
        #: someone follows the session as it happens
        self.watching = bool(self.watchers)


def _send_to_all(hook: str) -> Callable[..., None]:
    """The hook of :class:`Listeners` that calls ``hook`` of each listener in turn."""
    watched = hook in ("on_tick", "on_sample")

    def send(self: Listeners, *args: Any) -> None:
        for x in self.watchers if watched else self.all:
            getattr(x, hook)(*args)

    send.__name__ = send.__qualname__ = hook
    return send


for _hook in [name for name in vars(SessionListener) if name.startswith("on_")]:
    setattr(Listeners, _hook, _send_to_all(_hook))
