"""The session runner: a loop over an injected clock that runs a study's schedule.

:func:`run_session` (a :class:`SessionRunner`) plays each scheduled trial's stimulus
through a :class:`tactorbelt.player.Player`, samples the cursor at the study's rate
(100 Hz) on absolute deadlines (:class:`tactorbelt.clock.Deadlines`: onset + k * 10 ms,
late samples skipped), drives the trial state machine, stores each
trial (with its samples) in one transaction, and keeps the inter-trial interval and
the breaks. On a :class:`~tactorbelt.clock.SimClock` nothing sleeps, so a whole paper
session runs in well under a second of CPU; on the wall clock it paces a real
participant. When nothing but the samples depends on the ticks (an exact simulated
clock, nobody watching, no task running, a device-rendered stimulus) a cursor source that
reads in runs (the model participant) is sampled a run of ticks at a time
(:meth:`SessionRunner._present_runs`), with the same stored results.

Every exit path turns the motors off: normal end, a pause or abort from the
operator, Ctrl-C (KeyboardInterrupt), SIGTERM / SIGHUP
(:class:`~tactorbelt.interrupts.Terminated`), a belt that fails (DeviceError) and any
other exception. An interrupted trial is stored as ``aborted`` and the session is left
``interrupted`` (resumable with ``resume=True``).

Cognitive load (``[tasks.NAME]``, docs/study.md): before the first test block with a
load, a practice run of the task alone and then its single-task baseline; during each
test block with the load a :class:`~tactorbelt.tasks.session.TaskSession` on its own
clock, stepped on every sampling tick (items announced
:data:`~tactorbelt.tasks.TASK_LEAD_NS` ahead to the window and the cursor source,
presses collected from both); its events are written when the block ends, and also at
a pause, a break, an abort or an error (nothing lost). With ``[questionnaire] tlx``
the raw NASA-TLX follows every test block (the cursor source answers first: the model
participant; else the window asks a person).

Events go to a list of listeners and queries to one operator
(:mod:`~tactorbelt.experiment.listeners`; the experiment window is both, a
:class:`SessionObserver`); cursor sources
(joystick, mouse, scripted, model participant) as a
:class:`~tactorbelt.inputs.base.CursorSource`.

I/O edge: imports the pure experiment modules, the store, tactorbelt.stimuli and (in
:func:`run_session`) tactorbelt.player; never the window or a concrete device.
"""

from __future__ import annotations

import contextlib
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING, Any

from .._errors import ConfigError, DeviceError, TactorbeltError
from ..clock import Clock, Deadlines, SimClock
from ..geometry import Layout
from ..inputs.base import CursorSample, CursorSource, TrialCue
from ..interrupts import Terminated
from ..tasks import TASK_LEAD_NS, TLX_SCALE, WorkloadInfo, check_tlx
from ..tasks.schedule import derive_seed
from ..tasks.session import TaskSession
from . import provenance
from .listeners import (
    Command,
    Listeners,
    NullOperator,
    Operator,
    Progress,
    SessionInfo,
    SessionListener,
    SessionObserver,
)
from .recorder import SessionRecorder
from .schedule import ScheduledTrial
from .store import Store
from .study import StimulusSpec, Study, TaskSpec
from .trial import ResponseRule, TrialMachine, TrialResult, TrialState

if TYPE_CHECKING:
    from ..devices.base import Belt
    from ..devices.calibration import Calibration
    from ..stimuli import Stimulus

__all__ = [
    "SessionResult",
    "SessionRunner",
    "check_participant",
    "run_session",
    "skin_latency",
    "starting_tactors",
]

#: Participant ids that name files without being mangled (see :func:`check_participant`).
PARTICIPANT_RE = re.compile(r"[A-Za-z0-9][A-Za-z0-9_-]{0,63}")
#: On a simulated clock, a cursor that stays out of the home zone this long is an error.
SIM_HOME_LIMIT_NS = 600_000_000_000
#: SessionResult.results keeps the cursor samples of this many most recent trials; older
#: results drop theirs (they are in the store), so a long session's memory stays flat.
RESULT_SAMPLES_KEPT = 1000
#: A simulated session nobody watches reads the model participant's cursor in runs of
#: up to this many sampling ticks (:meth:`SessionRunner._present_runs`).
RUN_TICKS = 256


@dataclass
class SessionResult:
    """What :func:`run_session` did.

    Attributes:
        session_id: the store's id of the session.
        status: ``complete``, ``interrupted`` (limit reached, resumable) or ``aborted``.
        n_total: trials in the schedule.
        n_done: trials with a final outcome (done or timeout), this run and before.
        n_run: trials run by this call (final outcomes only).
        results: this call's trial results, aborted ones included, in order. Only the
            last :data:`RESULT_SAMPLES_KEPT` (1000) keep their cursor samples in memory;
            older ones have released them (``n_samples`` still counts them; the store
            holds them all).
    """

    session_id: int
    status: str
    n_total: int
    n_done: int
    n_run: int
    results: list[TrialResult] = field(default_factory=list)

    @property
    def accuracy(self) -> float | None:
        """Share of correct answers among this call's finished test trials."""
        test = [r for r in self.results if r.trial.block == "test" and r.status != "aborted"]
        return sum(1 for r in test if r.correct) / len(test) if test else None


@dataclass
class _TaskRun:
    """A secondary task's run in progress: the part since the last (re)start is
    :attr:`session`; a pause or a break ends that part (its events are written) and
    starts another, numbering its items on."""

    name: str
    spec: TaskSpec
    phase: str
    block_index: int
    remaining: int | None
    next_index: int = 0
    session: TaskSession | None = None


class _Aborted(Exception):
    """The observer asked to abort the session."""


class _Paused(Exception):
    """The observer paused the session during a trial (the trial is aborted)."""


def check_participant(participant: object) -> str:
    """The participant id, stripped, or ConfigError when it cannot be used.

    Allowed: 1 to 64 ASCII letters, digits, ``-`` and ``_``, starting with a letter or a
    digit. The id names files (BIDS ``sub-<label>`` keeps its letters and digits;
    ``participants.tsv`` maps the label back to the id), so spaces, slashes and other
    characters are refused rather than mangled.
    """
    pid = participant.strip() if isinstance(participant, str) else ""
    if not pid:
        raise ConfigError("participant id must be a non-empty string")
    if not PARTICIPANT_RE.fullmatch(pid):
        raise ConfigError(
            f"participant id {pid!r} is not allowed: use 1 to 64 letters, digits, '-' or "
            "'_', starting with a letter or digit (e.g. P01); it names the exported files"
        )
    return pid


def starting_tactors(stimulus: Stimulus) -> dict[int, float]:
    """The tactors that start a stimulus, each with its weight in the skin onset.

    A dynamic stimulus (a moving location on a between-tactor target) starts with its
    dwell on the nearer tactor n: ``{n: 1.0}``. Any other stimulus (static, on-tactor):
    every tactor driven above zero at the onset (``amplitudes(0)``, with the wearer
    profile's gains), weighted by its amplitude.
    """
    if stimulus.is_dynamic:
        return {int(stimulus.near_idx): 1.0}
    amps = stimulus.amplitudes(0.0)
    return {k: float(a) for k, a in enumerate(amps.tolist()) if a > 0.0}


def skin_latency(calibration: Calibration, stimulus: Stimulus) -> tuple[float, float] | None:
    """The skin-onset offset of a stimulus on a calibrated belt: ``(ms, sd_ms)``, or None
    when a tactor that starts it (:func:`starting_tactors`) has no measured latency
    (``tactorbelt validate onsets --calibration FILE``, docs/validation.md).

    ``ms`` is the starting tactors' ``latency_ms`` averaged with their weights (one
    tactor: its latency); ``sd_ms`` how far one onset may be from it: the root of the
    weighted mean of their variances (``latency_sd_ms**2``) plus the weighted variance of
    their latencies about ``ms`` (with equal weights, :meth:`Calibration.skin_latency`).
    """
    weights = starting_tactors(stimulus)
    total = sum(weights.values())
    if not weights or total <= 0.0 or calibration.n != stimulus.layout.n:
        return None
    rows = [(calibration.tactors[k], w / total) for k, w in weights.items()]
    if any(t.latency_ms is None for t, _ in rows):
        return None
    mean = sum(w * float(t.latency_ms or 0.0) for t, w in rows)
    var = sum(w * (float(t.latency_sd_ms or 0.0) ** 2
                   + (float(t.latency_ms or 0.0) - mean) ** 2) for t, w in rows)
    return mean, math.sqrt(var)


def check_layout(want: Layout, belt: Belt, hint: str) -> None:
    """ConfigError unless ``belt`` has the study's layout ``want`` (to 1e-6 degree);
    ``hint`` ends the message: what to do."""
    w, got = want.angles_deg, belt.layout.angles_deg
    if tuple(round(a, 6) for a in w) != tuple(round(a, 6) for a in got):
        raise ConfigError(f"the study's layout ({', '.join(f'{a:g}' for a in w)} deg) is not "
                          f"the belt's ({', '.join(f'{a:g}' for a in got)} deg); {hint}")


def _stop_quietly(player: Any, belt: Belt) -> None:
    """Motors off, best effort (a failed belt may raise again)."""
    with contextlib.suppress(Exception):
        if player is not None and player.playing:
            player.stop()
    with contextlib.suppress(Exception):
        belt.stop()


def _abort_reason(exc: BaseException) -> str:
    """Why a trial was aborted, as stored in its ``abort_reason``."""
    if isinstance(exc, KeyboardInterrupt):
        return "interrupted (Ctrl-C)"
    if isinstance(exc, Terminated):
        return f"terminated ({exc.name})"
    if isinstance(exc, _Aborted):
        return "aborted by the experimenter"
    if isinstance(exc, DeviceError):
        return f"device error: {exc}"
    return f"error: {type(exc).__name__}: {exc}"


class SessionRunner:
    """One run of one participant's session; :meth:`run` does it all.

    The parts, in order: :meth:`open_session` (a new session in the store, or the
    resumed one), then for each scheduled trial :meth:`run_trial` (:meth:`wait_home`,
    :meth:`present`), :meth:`inter_trial` and the breaks, with :meth:`pause` whenever
    the observer pauses; :meth:`fail` at the end after an error. Cursor sampling and
    every wait keep time with one :class:`~tactorbelt.clock.Deadlines` per loop.

    Args:
        study: the study.
        participant: the participant id (see :func:`check_participant`).
        belt: an open belt with the study's layout (the caller closes it).
        cursor: where responses come from.
        store: an open, writable store.
        clock: the clock that paces everything (SimClock: no sleeping).
        seed: randomisation seed (None: the study's ``session.seed``); ignored on resume.
        resume: continue the participant's latest unfinished session with the trials
            of its stored schedule that have no final outcome, in order.
        limit: stop after this many test trials (the session stays resumable).
        listeners: where the session's events go, in order
            (:class:`~tactorbelt.experiment.listeners.SessionListener`).
        operator: who answers the session's queries (pause, task presses, NASA-TLX,
            the waits; :class:`~tactorbelt.experiment.listeners.Operator`), or None.
        observer: a listener that is also the operator (the experiment window), or None.
        progress: called as ``progress(n_done, n_total)`` after each trial (a listener,
            :class:`~tactorbelt.experiment.listeners.Progress`, that watches nothing).
        study_toml: the study file's text, stored verbatim (default: ``study.to_toml()``).
        input_name: the cursor source's name, stored with the session.
        site: the lab running the session, stored with it (default
            :func:`~tactorbelt.experiment.provenance.default_site`).

    :meth:`run` returns a :class:`SessionResult`; it (and the constructor) raises
    ConfigError for a participant id that is empty or not allowed, a negative limit, a
    belt whose layout is not the study's; StoreError with nothing to resume, or a study
    changed since the session started; DeviceError when the belt failed (the trial in
    flight is stored ``aborted`` and the session ``interrupted``; KeyboardInterrupt and
    :class:`~tactorbelt.interrupts.Terminated`, SIGTERM or SIGHUP, likewise).
    """

    def __init__(self, study: Study, participant: str, belt: Belt, cursor: CursorSource,
                 store: Store, clock: Clock, *, seed: int | None = None,
                 resume: bool = False, limit: int | None = None,
                 listeners: Sequence[SessionListener] = (), operator: Operator | None = None,
                 observer: SessionObserver | None = None,
                 progress: Callable[[int, int], None] | None = None,
                 study_toml: str | None = None, input_name: str | None = None,
                 site: str | None = None) -> None:
        from ..player import Player

        self.participant = check_participant(participant)
        if limit is not None and limit < 0:
            raise ConfigError(f"limit must be a number of test trials >= 0, got {limit}")
        check_layout(study.layout_obj(), belt, "use a study file for this belt or open the "
                     "belt with the study's layout")
        self.study = study
        self.belt = belt
        self.cursor = cursor
        self.store = store
        self.clock = clock
        self.seed = seed
        self.resume = resume
        self.limit = limit
        every = [*listeners, *([observer] if observer is not None else []),
                 *([Progress(progress)] if progress is not None else [])]
        if operator is None:
            operator = observer
        #: the session's events go to every listener, in order; its queries to the operator
        self.listeners = Listeners(every)
        self.operator: Operator = operator if operator is not None else NullOperator()
        #: Nobody watches and nobody operates: nobody sees the samples or sends commands
        #: (the runner skips those calls in its loops).
        self._headless = not self.listeners.watching and operator is None
        #: ... on an exact simulated clock: a loop may skip ticks at which nothing happens
        self._fast = self._headless and isinstance(clock, SimClock) and clock.exact
        #: How the session's writes are committed (provenance.commit_mode): in batches
        #: only with nothing real involved; recorded in the store (Store.commit_mode).
        self.commits = provenance.commit_mode(
            simulated_clock=bool(clock.simulated), hardware_belt=belt.hardware,
            person=cursor.person, observer=not self._headless)
        self.study_toml = study_toml if study_toml is not None else study.to_toml()
        self.input_name = input_name
        self.site = site
        self.rule = ResponseRule.from_study(study)
        self._rules: dict[float, ResponseRule] = {}
        self.rate_hz = float(study.session.sample_rate_hz)
        self.sim = bool(clock.simulated)
        self.player = Player(belt, clock)
        self._stimuli: dict[tuple[Any, ...], Stimulus] = {}
        #: the skin-onset offset (ms, sd_ms) of each stimulus made (by id), None without a
        #: measured latency; nothing is computed when the calibration has no timing
        self._skin: dict[int, tuple[float, float] | None] = {}
        self._has_latency = belt.calibration.has_timing
        self._block_stimuli: dict[str, StimulusSpec] = {}
        self.profile: Any = None  # the wearer profile ([calibration] perceptual), by open_session
        #: the session in the store (the store seam: its id, seed, schedule and block
        #: order), by open_session
        self.recorder: SessionRecorder = None  # type: ignore[assignment]
        self.n_done = 0
        self.n_run = 0
        self.n_test_run = 0
        self.results: list[TrialResult] = []
        # secondary tasks (set by open_session)
        self._task: _TaskRun | None = None
        self._phases_done: set[tuple[str, str]] = set()
        self._rated: set[int] = set()
        self._block_last: dict[int, int] = {}

    # -- setup -----------------------------------------------------------------------------
    def open_session(self) -> list[ScheduledTrial]:
        """Create the session (or reopen the resumed one) through its
        :class:`~tactorbelt.experiment.recorder.SessionRecorder`; return the trials to run."""
        from ..calibration.perceptual import (
            profile_for_session,  # before training (and the session)
        )

        study, store = self.study, self.store
        study.check_belt(self.belt)  # a pattern the belt cannot show, before anything starts
        if study.stimulus.drive is not None:  # the study's drive, for the whole session
            self.belt.set_drive(study.stimulus.drive)
        self.profile = profile_for_session(
            study, store, self.belt, self.clock, self.participant,
            self.cursor.calibration_respondent(int(study.session.seed if self.seed is None
                                                   else self.seed)), resume=self.resume)
        rec = self.recorder = SessionRecorder.open(
            store, study, self.participant, input_kind=self.input_name, seed=self.seed,
            resume=self.resume, study_toml=self.study_toml, belt_url=self.belt.session_url,
            firmware_version=self.belt.firmware_version,
            calibration=self.belt.calibration.to_list(), clock="sim" if self.sim else "wall",
            site=self.site)
        if self.profile is not None:  # the wearer profile is part of the session's provenance
            rec.set_profile(self.profile.to_toml())
        todo = rec.todo()
        self.n_done = len(rec.schedule) - len(todo)
        for t in rec.schedule:
            self._block_last[t.block_index] = t.trial_index
        if self.resume and (study.tasks or study.questionnaire.tlx):
            self._phases_done = {(e["task"], e["phase"]) for e in rec.task_events()
                                 if e["phase"] != "dual"}
            self._rated = {int(r["block_index"]) for r in rec.ratings()
                           if r["scale"] == TLX_SCALE}
        return todo

    def trial_stimulus(self, t: ScheduledTrial) -> StimulusSpec:
        """The ``[stimulus]`` settings of a trial's block (``Study.trial_stimulus``, made
        once per block)."""
        spec = self._block_stimuli.get(t.block_name)
        if spec is None:
            spec = self._block_stimuli[t.block_name] = self.study.trial_stimulus(t.block_name)
        return spec

    def stimulus_for(self, t: ScheduledTrial) -> Stimulus:
        """The stimulus of a trial (one per target, condition and block stimulus, made
        once): its block's ``[stimulus]`` with the block's overrides."""
        sp = self.trial_stimulus(t)
        key = (t.target_deg, t.condition, sp.law, sp.falloff_deg, sp.period_s, sp.transit_s,
               sp.pattern)
        if key not in self._stimuli:
            # (a pattern was checked against the belt once, when the session opened)
            self._stimuli[key] = self.study.make_stimulus(
                sp, self.belt.layout, t.target_deg, t.condition, profile=self.profile)
        return self._stimuli[key]

    def rule_for(self, t: ScheduledTrial) -> ResponseRule:
        """The response rule of a trial: the study's, with its block's longest presentation."""
        max_s = self.trial_stimulus(t).max_presentation_s
        if max_s not in self._rules:
            self._rules[max_s] = replace(self.rule, max_presentation_ns=round(max_s * 1e9))
        return self._rules[max_s]

    # -- waiting and commands --------------------------------------------------------------
    def _ticks(self, onset_ns: int | None = None, first: int = 1) -> Deadlines:
        """The sampling deadlines of one loop: frame 0 at ``onset_ns`` (default now); the
        first :meth:`_tick` waits for frame ``first``."""
        ticks = Deadlines(self.clock, self.rate_hz, onset_ns)
        ticks.next_index = first
        return ticks

    def _tick(self, ticks: Deadlines) -> int:
        """Wait for the next sampling deadline; pump a simulated player; step a running
        secondary task; return now."""
        _, now = ticks.wait()
        if self.sim:
            self.player.pump(now)
        if self._task is not None:
            self._step_task(now)
        return now

    # -- secondary tasks -------------------------------------------------------------------
    def _step_task(self, now: int) -> None:
        """Announce the items due within the lead time; collect the presses."""
        run = self._task
        assert run is not None and run.session is not None
        ts = run.session
        for item, onset in ts.announce(now, TASK_LEAD_NS):
            self.listeners.on_task_item(item, onset, run.spec)
            self.cursor.task_item(item, onset)
        for p in self._operator_presses(now):
            ts.press(p)
        for p in self.cursor.task_presses(now):
            ts.press(p)

    def _start_task(self, run: _TaskRun) -> None:
        """Start (or go on with) a task run: tell the window and the cursor source, drop
        the presses made while no task ran, then put item ``run.next_index`` at now +
        the lead time."""
        if run.remaining is not None and run.remaining <= 0:
            self._task = None
            return
        self._task_phase(run.name, run.spec, run.phase)
        self.cursor.task_phase(run.spec, run.phase)
        now = self.clock.now_ns()
        self._operator_presses(now)  # pressed while no task ran: not part of this run
        self.cursor.task_presses(now)
        seed = derive_seed(self.recorder.seed, self.participant, run.name, run.phase,
                           run.block_index, run.next_index)
        run.session = TaskSession(run.name, run.spec, run.phase, run.block_index, seed,
                                  now + TASK_LEAD_NS, run.remaining,
                                  first_index=run.next_index)
        self._task = run

    def _stop_task(self) -> _TaskRun | None:
        """End the running part of a task run and write its events (one transaction);
        return the run (to go on with after a pause), or None when none was running."""
        run = self._task
        if run is None:
            return None
        self._task = None
        ts = run.session
        assert ts is not None
        now = self.clock.now_ns()
        events = ts.finish(now)
        shown = sum(1 for _, onset in ts.announced if onset <= now)
        run.next_index += shown
        if run.remaining is not None:
            run.remaining -= shown
        run.session = None
        try:
            self.recorder.write_task_events(events)
        finally:
            with contextlib.suppress(Exception):
                self.cursor.task_phase(None, None)
            self._task_phase(None, None, None)
        return run

    def _stop_task_quietly(self) -> None:
        """Teardown: write what the running task has, best effort."""
        with contextlib.suppress(Exception):
            self._stop_task()
        self._task = None

    def _task_of(self, t: ScheduledTrial) -> tuple[str, TaskSpec] | None:
        """The secondary task of a test trial's block (None without one)."""
        if t.block != "test":
            return None
        spec = self.study.tasks.get(t.load)
        return (t.load, spec) if spec is not None and spec.active else None

    def run_alone(self, name: str, spec: TaskSpec, phase: str, block_index: int) -> None:
        """A practice or baseline run: the task alone (no trial, the cursor idle), its
        ``practice`` or ``baseline`` items; skipped when none or already stored."""
        n = spec.practice if phase == "practice" else spec.baseline
        if n <= 0 or (name, phase) in self._phases_done:
            return
        self._start_task(_TaskRun(name, spec, phase, block_index, n))
        ticks = self._ticks()
        while True:
            now = self._tick(ticks)
            run = self._task
            if run is None or run.session is None or run.session.done(now):
                break
            self.handle(self._poll(now), None)
        self._stop_task()
        self._phases_done.add((name, phase))

    def _start_block_task(self, t: ScheduledTrial) -> None:
        """The dual-task run of a test block, from its first trial to be run (a resumed
        block numbers its items on from those stored)."""
        task = self._task_of(t)
        if task is None:
            return
        name, spec = task
        stored = [e["item_index"] for e in self.recorder.task_events()
                  if e["phase"] == "dual" and e["block_index"] == t.block_index
                  and e["task"] == name] if self.resume else []
        self._start_task(_TaskRun(name, spec, "dual", t.block_index, None,
                                  max(stored, default=-1) + 1))

    def rate_block(self, t: ScheduledTrial) -> None:
        """After a test block (``[questionnaire] tlx``): the NASA-TLX, from the cursor
        source (the model participant) or else the window; stored when answered."""
        if (not self.study.questionnaire.tlx or t.block != "test"
                or t.block_index in self._rated):
            return
        task = self._task_of(t)
        info = WorkloadInfo(t.block_index, t.block_name, t.condition,
                            t.n_targets or self.study.targets.count, t.load,
                            None if task is None else task[1])
        values = self.cursor.rate_workload(info)
        if values is None:
            values = self.operator.ask_workload(info)
            if values is not None:
                self.listeners.on_workload(info, values)
        if values is not None:
            self.recorder.write_ratings(t.block_index, TLX_SCALE, check_tlx(values))
            self._rated.add(t.block_index)

    def _rate_unrated_before(self, todo: list[ScheduledTrial]) -> None:
        """On resume: the block finished just before the interruption, when its
        NASA-TLX was not stored (the session stopped during the questionnaire)."""
        schedule = self.recorder.schedule
        first = todo[0].trial_index if todo else len(schedule)
        before = [t for t in schedule if t.trial_index < first]
        if before and not (todo and todo[0].block_index == before[-1].block_index):
            self.rate_block(before[-1])

    def wait_for(self, duration_ns: int) -> None:
        """Wait ``duration_ns`` in sampling steps (the last one ends at the end), pumping
        the player and polling the observer at each."""
        ticks = self._ticks()
        end = ticks.onset_ns + duration_ns
        now = ticks.onset_ns
        if self._fast and self._task is None and not self.player.playing:
            # nothing would happen at the ticks (nothing plays, nobody polls, no task):
            # the clock ends at ``end`` as it would after them
            self.clock.sleep_until_ns(end)
            return
        while now < end:
            if ticks.deadline(ticks.next_index) < end:
                now = self._tick(ticks)
            else:
                self.clock.sleep_until_ns(end)
                now = self.clock.now_ns()
                if self.sim:
                    self.player.pump(now)
            self.handle(self._poll(now), None)

    def _poll(self, now: int) -> Command | None:
        """A tick for the listeners, then the operator's command (told to the listeners)."""
        self.listeners.on_tick(now)
        cmd = self.operator.poll(now)
        if cmd is not None:
            self.listeners.on_command(cmd, now)
        return cmd

    def _operator_presses(self, now: int) -> list[int]:
        """The operator's task presses since the last call (told to the listeners)."""
        presses = self.operator.task_presses(now)
        if presses:
            self.listeners.on_task_presses(presses)
        return presses

    def _task_phase(self, name: str | None, spec: TaskSpec | None, phase: str | None
                    ) -> None:
        """A task run starts or ends: the listeners, then the operator's wait."""
        self.listeners.on_task_phase(name, spec, phase)
        self.operator.wait_task_phase(name, spec, phase)

    def handle(self, cmd: Command | None, machine: TrialMachine | None) -> None:
        """Act on a command from the observer. A pause aborts the trial in flight."""
        if cmd is None or cmd is Command.RESUME:
            return
        _stop_quietly(self.player, self.belt)
        if cmd is Command.ABORT:
            raise _Aborted
        # PAUSE: a trial whose stimulus has started is aborted (and run again after the
        # pause); otherwise wait here, motors off, until RESUME or ABORT
        if machine is not None and machine.state is TrialState.STIMULUS:
            raise _Paused
        self.pause()

    def pause(self) -> None:
        """Wait, motors off, until the observer resumes (or aborts) the session. A
        running secondary task stops (its events are written) and goes on after."""
        run = self._stop_task()
        ticks = self._ticks()
        while True:
            ticks.wait()
            cmd = self._poll(self.clock.now_ns())
            if cmd is Command.RESUME:
                if run is not None:
                    self._start_task(run)
                return
            if cmd is Command.ABORT:
                raise _Aborted

    # -- a trial ---------------------------------------------------------------------------
    def _sample(self) -> tuple[int, CursorSample]:
        now = self.clock.now_ns()
        s = self.cursor.read(now)
        sample = CursorSample(now, s.x, s.y, s.buttons)
        if not self._headless:
            self.listeners.on_sample(sample)
        return now, sample

    def wait_home(self, t: ScheduledTrial, machine: TrialMachine) -> None:
        """Sample the cursor until it is in the home zone."""
        self.listeners.on_trial_state(t, TrialState.WAIT_HOME, self.clock.now_ns())
        ticks = self._ticks()
        while True:
            now, s = self._sample()
            if machine.at_home(s):
                return
            if self.sim and now - ticks.onset_ns > SIM_HOME_LIMIT_NS:
                raise TactorbeltError(
                    f"trial {t.trial_index}: the cursor never came back to the home zone "
                    f"(within {self.rule.home_radius:g} of the centre)"
                )
            if not self._headless:
                self.handle(self._poll(now), machine)
            self._tick(ticks)

    def present(self, t: ScheduledTrial, machine: TrialMachine) -> TrialState:
        """Play the stimulus and sample the cursor on its deadlines until an outcome."""
        layout = self.belt.layout
        cue = TrialCue(t.trial_index, t.block, t.condition, self.recorder.targets(t).angles_deg,
                       layout, t.target_deg if t.block == "training" else None)
        onset = int(self.player.start(
            self.stimulus_for(t),
            duration_s=self.trial_stimulus(t).max_presentation_s))
        machine.start(onset)
        self.cursor.trial_started(cue, onset)
        self.listeners.on_trial_state(t, TrialState.STIMULUS, onset)
        ticks = self._ticks(onset, first=0)
        if (self._fast and self._task is None and self.cursor.reads_runs
                and not self.player.pumped):
            return self._present_runs(machine, ticks)
        headless = self._headless
        read, feed, tick = self.cursor.read, machine.feed, self._tick
        while True:
            now = tick(ticks)
            s = read(now)
            state = feed(now, s.x, s.y, s.buttons)
            if not headless:
                self.listeners.on_sample(CursorSample(now, s.x, s.y, s.buttons))
            if self._stop_when_due(machine, now):
                return state
            if not headless:
                self.handle(self._poll(now), machine)

    def _present_runs(self, machine: TrialMachine, ticks: Deadlines) -> TrialState:
        """:meth:`present`'s loop when nothing but the samples depends on the ticks: a
        simulated session on an exact clock that nobody watches, no task running, a
        device-rendered stimulus and a cursor that reads in runs (the model
        participant). The cursor is read for runs of up to :data:`RUN_TICKS` ticks
        (:meth:`~tactorbelt.inputs.base.CursorSource.read_run`) and the trial machine
        takes them up to the one that ends the trial; the clock stands at a run's first
        tick when it is read and at its last sample after, and a run ends at the tick
        the stimulus is due off, so every effect (the model's decision reading the
        belt, the stimulus stopping) happens at the time it happens sample by sample,
        and the stored samples are the same."""
        clock, cursor, machine_feed = self.clock, self.cursor, machine.feed_run
        onset = ticks.onset_ns
        off_ns = onset + machine.rule.max_presentation_ns
        while True:
            first = ticks.next_index
            times = ticks.deadlines(first, RUN_TICKS)
            if machine.result.stimulus_off_ns is None and int(times[-1]) >= off_ns:
                times = times[: int(times.searchsorted(off_ns)) + 1]
            clock.sleep_until_ns(int(times[0]))
            n = cursor.read_run(times, machine_feed)
            now = int(times[n - 1])
            clock.sleep_until_ns(now)
            ticks.next_index = first + n
            if self._stop_when_due(machine, now):
                return machine.state

    def _stop_when_due(self, machine: TrialMachine, now: int) -> bool:
        """Stop the stimulus (once) when the trial has its outcome or the stimulus is due
        off at ``now``; whether the trial has its outcome."""
        finished = machine.finished
        if machine.result.stimulus_off_ns is None and (finished
                                                      or machine.stimulus_due_off(now)):
            self.player.stop()
            machine.stimulus_stopped(self.clock.now_ns())
        return finished

    def run_trial(self, t: ScheduledTrial) -> TrialResult:
        """One trial: home, stimulus and response. A pause returns it ``aborted``; any
        other way out stores nothing here, aborts it and re-raises with the result
        attached (``exc.trial_result``)."""
        machine = TrialMachine(t, self.rule_for(t), self.recorder.targets(t))
        try:
            self.wait_home(t, machine)
            state = self.present(t, machine)
            device_onset = self.player.device_onset()  # (host_ns, uncertainty_ns) or None
            if device_onset is not None:
                machine.result.device_onset_ns, machine.result.onset_uncertainty_ns = device_onset
            self.listeners.on_trial_state(t, state, self.clock.now_ns())
            return machine.result
        except _Paused:
            machine.stimulus_stopped(self.clock.now_ns())
            return machine.abort("paused")
        except BaseException as exc:
            _stop_quietly(self.player, self.belt)
            machine.stimulus_stopped(self.clock.now_ns())
            machine.abort(_abort_reason(exc))
            exc.trial_result = machine.result  # type: ignore[attr-defined]
            raise
        finally:
            with contextlib.suppress(Exception):
                self.cursor.trial_ended(self.clock.now_ns())

    def skin_onset(self, result: TrialResult) -> tuple[int, int] | None:
        """When the skin felt a trial's stimulus: ``(skin_onset_ns, skin_onset_sd_ns)``, or
        None (no onset, or no measured latency of the tactors that start it).

        The stored onset (the device-true ``device_onset_ns`` where the belt reports it,
        else the command time ``onset_ns``) plus :func:`skin_latency` of the trial's
        stimulus on the belt's calibration; the spread combines the latency's spread
        with the device onset's uncertainty (root of the sum of squares).
        """
        if not self._has_latency or result.onset_ns is None:
            return None
        stim = self.stimulus_for(result.trial)
        key = id(stim)
        if key not in self._skin:
            self._skin[key] = skin_latency(self.belt.calibration, stim)
        offset = self._skin[key]
        if offset is None:
            return None
        ms, sd_ms = offset
        base, unc = result.onset_ns, 0
        if result.device_onset_ns is not None:
            base, unc = result.device_onset_ns, int(result.onset_uncertainty_ns or 0)
        return base + round(ms * 1e6), round(math.hypot(sd_ms * 1e6, unc))

    def _write(self, result: TrialResult) -> None:
        """Write a trial with its skin onset; tell the listeners the skin onset."""
        skin = self.skin_onset(result)
        self.recorder.record(result, skin)
        if skin is not None:
            self.listeners.on_skin_onset(result.trial, skin[0], skin[1])

    def record(self, result: TrialResult) -> None:
        """Store a trial (one transaction) and keep it in :attr:`results`."""
        self._write(result)
        self.results.append(result)
        if len(self.results) > RESULT_SAMPLES_KEPT:
            self.results[-RESULT_SAMPLES_KEPT - 1].release_samples()
        self.listeners.on_trial_done(result)

    # -- the session -----------------------------------------------------------------------
    def run(self) -> SessionResult:
        """Run the session; see :func:`run_session`."""
        todo = self.open_session()
        with self.recorder.batched(provenance.BATCH_TRIALS
                                   if self.commits == provenance.COMMITS_BATCHED else None):
            return self._run(todo)

    def _run(self, todo: list[ScheduledTrial]) -> SessionResult:
        rec = self.recorder
        n_total = len(rec.schedule)
        info = SessionInfo(rec.session_id, self.participant, self.study, n_total,
                           self.n_done, self.resume, rec.order)
        try:
            # inside the try: Ctrl-C or a window error on the instructions screen leaves
            # the session "interrupted", not "running"
            self.listeners.on_session_start(info, rec.schedule)
            status = self._trials(todo)
        except _Aborted as exc:
            self._stop_task_quietly()
            self._record_failed(exc)
            status = "aborted"
        except BaseException as exc:
            self.fail(exc)
            raise
        finally:
            _stop_quietly(self.player, self.belt)
        self.recorder.end(status)
        self.listeners.on_session_end(status)
        return SessionResult(rec.session_id, status, n_total, self.n_done, self.n_run,
                             self.results)

    def _trials(self, todo: list[ScheduledTrial]) -> str:
        """Run the trials to do, with the inter-trial intervals and breaks; the status."""
        iti_ns = round(self.study.session.iti_s * 1e9)
        break_every = self.study.session.break_every
        n_total = len(self.recorder.schedule)
        prev_block: int | None = None
        if self.resume:
            self._rate_unrated_before(todo)
        i = 0
        while i < len(todo):
            t = todo[i]
            if self.limit is not None and t.block == "test" and self.n_test_run >= self.limit:
                break
            if t.block_index != prev_block:
                self._stop_task()  # a block cut short by the limit or a resume
                task = self._task_of(t)
                if task is not None:
                    self.run_alone(*task, "practice", t.block_index)
                    self.run_alone(*task, "baseline", t.block_index)
                self.listeners.on_block_start(t.block, t.condition)
                self._start_block_task(t)
                prev_block = t.block_index
            result = self.run_trial(t)
            self.record(result)
            if result.status == "aborted":  # paused: wait, then run the same trial again
                self.listeners.on_trial_state(t, TrialState.ABORTED, self.clock.now_ns())
                self.pause()
                continue
            self.n_run += 1
            self.n_done += 1
            if t.block == "test":
                self.n_test_run += 1
            i += 1
            if t.trial_index == self._block_last.get(t.block_index):
                self._stop_task()
                self.rate_block(t)
            if i < len(todo):
                self.listeners.on_trial_state(t, TrialState.ITI, self.clock.now_ns())
                self.wait_for(iti_ns)
                if break_every and (t.trial_index + 1) % break_every == 0:
                    run = self._stop_task()
                    self.listeners.on_break(self.n_done, n_total)
                    self.operator.wait_break(self.n_done, n_total)
                    self.listeners.on_break_end()
                    if run is not None:
                        self._start_task(run)
        self._stop_task()
        return "complete" if self.n_done >= n_total else "interrupted"

    def fail(self, exc: BaseException) -> None:
        """Teardown after an error or an interrupt: motors off, the trial in flight
        stored ``aborted``, the session ``interrupted`` (resumable). A device error is
        re-raised by the caller with what happened to the session."""
        _stop_quietly(self.player, self.belt)
        self._stop_task_quietly()
        self._record_failed(exc)
        with contextlib.suppress(Exception):
            self.recorder.end("interrupted")
        with contextlib.suppress(Exception):
            self.listeners.on_session_end("interrupted")
        if isinstance(exc, DeviceError):
            raise DeviceError(
                f"belt {self.belt.url} failed during the session ({exc}); motors off (a belt "
                "that no longer answers turns them off itself within its heartbeat timeout), "
                "the trial in flight was stored as aborted and session "
                f"{self.recorder.session_id} of {self.participant!r} can be resumed with --resume"
            ) from exc

    def _record_failed(self, exc: BaseException) -> None:
        """Store the aborted trial attached to ``exc`` (best effort)."""
        result = getattr(exc, "trial_result", None)
        if isinstance(result, TrialResult):
            with contextlib.suppress(Exception):
                self._write(result)
                self.results.append(result)


def run_session(study: Study, participant: str, belt: Belt, cursor: CursorSource,
                store: Store, clock: Clock, **options: Any) -> SessionResult:
    """Run (or resume) one participant's session: ``SessionRunner(...).run()`` (the
    arguments, the options and what it raises: :class:`SessionRunner`)."""
    return SessionRunner(study, participant, belt, cursor, store, clock, **options).run()
