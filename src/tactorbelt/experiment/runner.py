"""The session runner: a loop over an injected clock that runs a study's schedule.

:func:`run_session` plays each scheduled trial's stimulus through a
:class:`tactorbelt.player.Player`, samples the cursor at the study's rate (100 Hz) on
absolute deadlines (onset + k * 10 ms), drives the trial state machine, stores each
trial (with its samples) in one transaction, and keeps the inter-trial interval and
the breaks. On a :class:`~tactorbelt.clock.SimClock` nothing sleeps, so a whole paper
session runs in well under a second of CPU; on the wall clock it paces a real
participant.

Every exit path turns the motors off: normal end, a pause or abort from the
observer, Ctrl-C (KeyboardInterrupt), a belt that fails (DeviceError) and any other
exception. An interrupted trial is stored as ``aborted`` and the session is left
``interrupted`` (resumable with ``resume=True``).

The experiment window plugs in as a :class:`SessionObserver`; cursor sources
(joystick, mouse, scripted, model participant) as a
:class:`~tactorbelt.inputs.base.CursorSource`.

I/O edge: imports the pure experiment modules, the store, tactorbelt.stimuli and (in
:func:`run_session`) tactorbelt.player; never the window or a concrete device.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from .._errors import ConfigError, DeviceError, StoreError, TactorbeltError
from ..clock import Clock
from ..inputs.base import CursorSample, CursorSource, TrialCue
from .schedule import ScheduledTrial, block_order, make_schedule
from .store import Store
from .study import Study
from .trial import ResponseRule, TrialMachine, TrialResult, TrialState

if TYPE_CHECKING:
    from ..devices.base import Belt
    from ..stimuli import Stimulus

__all__ = [
    "Command",
    "NullObserver",
    "SessionInfo",
    "SessionObserver",
    "SessionResult",
    "run_session",
]

#: Test hook: seconds of real time each trial takes (after its row is stored).
SLOW_TRIAL_ENV = "TACTORBELT_TEST_SLOW_TRIAL_S"
#: On a simulated clock, a cursor that stays out of the home zone this long is an error.
SIM_HOME_LIMIT_NS = 600_000_000_000
#: SessionResult.results keeps the cursor samples of this many most recent trials; older
#: results drop theirs (they are in the store), so a long session's memory stays flat.
RESULT_SAMPLES_KEPT = 1000


class Command(StrEnum):
    """What the window (observer) can ask of the runner."""

    PAUSE = "pause"
    RESUME = "resume"
    ABORT = "abort"


@dataclass(frozen=True)
class SessionInfo:
    """What an observer learns when a session starts.

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


class SessionObserver(Protocol):
    """Hooks for the experiment window (every one optional through :class:`NullObserver`)."""

    def on_session_start(self, info: SessionInfo, schedule: list[ScheduledTrial]) -> None: ...
    def on_block_start(self, block: str, condition: str) -> None: ...
    def on_trial_state(self, trial: ScheduledTrial, state: TrialState, now_ns: int) -> None: ...
    def on_sample(self, sample: CursorSample) -> None: ...
    def on_trial_done(self, result: TrialResult) -> None: ...
    def on_break(self, n_done: int, n_total: int) -> None:
        """A break: return when the participant is ready to go on."""
        ...
    def on_session_end(self, status: str) -> None: ...
    def poll(self, now_ns: int) -> Command | None:
        """Called at every sampling step: PAUSE (motors off at once), RESUME or ABORT."""
        ...


class NullObserver:
    """An observer that does nothing; subclass it and override what you need."""

    def on_session_start(self, info: SessionInfo, schedule: list[ScheduledTrial]) -> None:
        pass

    def on_block_start(self, block: str, condition: str) -> None:
        pass

    def on_trial_state(self, trial: ScheduledTrial, state: TrialState, now_ns: int) -> None:
        pass

    def on_sample(self, sample: CursorSample) -> None:
        pass

    def on_trial_done(self, result: TrialResult) -> None:
        pass

    def on_break(self, n_done: int, n_total: int) -> None:
        pass

    def on_session_end(self, status: str) -> None:
        pass

    def poll(self, now_ns: int) -> Command | None:
        return None


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
        done = [r for r in self.results if r.trial.block == "test" and r.status == "done"]
        test = [r for r in self.results if r.trial.block == "test" and r.status != "aborted"]
        if not test:
            return None
        return sum(1 for r in done if r.correct) / len(test)


class _Aborted(Exception):
    """The observer asked to abort the session."""


class _Paused(Exception):
    """The observer paused the session during a trial (the trial is aborted)."""


@lru_cache(maxsize=1)
def _git_commit() -> str | None:
    here = Path(__file__).resolve().parent
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True,
                             text=True, timeout=2, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    commit = out.stdout.strip()
    return commit if out.returncode == 0 and len(commit) == 40 else None


def _package_version() -> str:
    from .. import __version__

    return __version__


def _study_text(study: Study, study_toml: str | None) -> str:
    return study_toml if study_toml is not None else study.to_toml()


def _check_layout(study: Study, belt: Belt) -> None:
    want = study.layout_obj()
    if tuple(round(a, 6) for a in want.angles_deg) != tuple(
        round(a, 6) for a in belt.layout.angles_deg
    ):
        raise ConfigError(
            f"the study's layout ({', '.join(f'{a:g}' for a in want.angles_deg)} deg) is not "
            f"the belt's ({', '.join(f'{a:g}' for a in belt.layout.angles_deg)} deg); "
            "use a study file for this belt or open the belt with the study's layout"
        )


def _stop_quietly(player: Any, belt: Belt) -> None:
    """Motors off, best effort (a failed belt may raise again)."""
    with contextlib.suppress(Exception):
        if player is not None and player.playing:
            player.stop()
    with contextlib.suppress(Exception):
        belt.stop()


def run_session(
    study: Study,
    participant: str,
    belt: Belt,
    cursor: CursorSource,
    store: Store,
    clock: Clock,
    *,
    seed: int | None = None,
    resume: bool = False,
    limit: int | None = None,
    observer: SessionObserver | None = None,
    progress: Callable[[int, int], None] | None = None,
    study_toml: str | None = None,
    input_name: str | None = None,
) -> SessionResult:
    """Run (or resume) one participant's session.

    Args:
        study: the study.
        participant: the participant id (non-empty).
        belt: an open belt with the study's layout (the caller closes it).
        cursor: where responses come from.
        store: an open, writable store.
        clock: the clock that paces everything (SimClock: no sleeping).
        seed: randomisation seed (None: the study's ``session.seed``); ignored on resume.
        resume: continue the participant's latest unfinished session with the trials
            of its stored schedule that have no final outcome, in order.
        limit: stop after this many test trials (the session stays resumable).
        observer: the experiment window, or None.
        progress: called as ``progress(n_done, n_total)`` after each trial.
        study_toml: the study file's text, stored verbatim (default: ``study.to_toml()``).
        input_name: the cursor source's name, stored with the session.

    Returns:
        A :class:`SessionResult`.

    Raises:
        ConfigError: an empty participant id, a negative limit, a belt whose layout is
            not the study's.
        StoreError: nothing to resume, or the study changed since the session started.
        DeviceError: the belt failed; the trial in flight is stored ``aborted`` and the
            session ``interrupted``. KeyboardInterrupt likewise.
    """
    from ..player import Player
    from ..stimuli import make_stimulus

    participant = participant.strip() if isinstance(participant, str) else ""
    if not participant:
        raise ConfigError("participant id must be a non-empty string")
    if limit is not None and limit < 0:
        raise ConfigError(f"limit must be a number of test trials >= 0, got {limit}")
    _check_layout(study, belt)
    obs: Any = observer if observer is not None else NullObserver()
    text = _study_text(study, study_toml)
    import hashlib

    sha = hashlib.sha256(text.encode("utf-8")).hexdigest()

    # -- the session: new or resumed -------------------------------------------------
    if resume:
        row = store.find_resumable(participant)
        if row is None:
            raise StoreError(
                f"participant {participant!r} has no unfinished session in {store.url}; "
                "run without --resume to start one"
            )
        if row["study_sha256"] != sha:
            stored = Study.from_toml(row["study_toml"], path=f"{store.url} (session "
                                     f"{row['session_id']})")
            if stored != study:
                raise StoreError(
                    f"the study changed since session {row['session_id']} of {participant!r} "
                    f"started ({row['study_name']}, sha256 {row['study_sha256'][:12]}); resume "
                    "with the same study file"
                )
        session_id = int(row["session_id"])
        schedule = store.schedule(session_id)
        order = tuple(json.loads(row["condition_order"]))
        store.mark_resumed(session_id)
    else:
        seed = study.session.seed if seed is None else int(seed)
        schedule = make_schedule(study, participant, seed)
        order = tuple(study.test[i].condition for i in block_order(study, participant))
        session_id = store.create_session(
            participant=participant, study_name=study.name, study_toml=text,
            study_sha256=sha, seed=seed, condition_order=list(order), schedule=schedule,
            belt=belt.url, firmware_version=belt.firmware_version,
            calibration=belt.calibration.to_list(), package_version=_package_version(),
            git_commit=_git_commit(), host=socket.gethostname(), input=input_name,
            clock="sim" if clock.simulated else "wall",
        )
    finished = store.finished_indices(session_id)
    todo = [t for t in schedule if t.trial_index not in finished]
    n_total = len(schedule)
    n_done = len(finished)

    rule = ResponseRule.from_study(study)
    targets = study.target_set()
    layout = belt.layout
    sp = study.stimulus
    stimuli: dict[tuple[float, str], Stimulus] = {}

    def stimulus_for(t: ScheduledTrial) -> Stimulus:
        key = (t.target_deg, t.condition)
        if key not in stimuli:
            stimuli[key] = make_stimulus(layout, t.target_deg, t.condition, sp.law,
                                         sp.falloff_deg, sp.period_s, sp.transit_s)
        return stimuli[key]

    slow_s = float(os.environ.get(SLOW_TRIAL_ENV, "0") or 0)
    period = rule.sample_period_ns
    iti_ns = round(study.session.iti_s * 1e9)
    break_every = study.session.break_every
    sim = bool(clock.simulated)
    player = Player(belt, clock)
    results: list[TrialResult] = []
    n_run = 0
    n_test_run = 0
    status = "interrupted"
    info = SessionInfo(session_id, participant, study, n_total, n_done, resume, order)

    def wait_until(deadline_ns: int) -> None:
        """Sleep to a deadline in sample-period steps, pumping the player and polling."""
        now = clock.now_ns()
        while now < deadline_ns:
            step = min(deadline_ns, now + period)
            clock.sleep_until_ns(step)
            now = clock.now_ns()
            if sim:
                player.pump(now)
            handle(obs.poll(now), None)

    def handle(cmd: Command | None, machine: TrialMachine | None) -> None:
        """Act on a command from the observer. A pause aborts the trial in flight."""
        if cmd is None or cmd is Command.RESUME:
            return
        _stop_quietly(player, belt)
        if cmd is Command.ABORT:
            raise _Aborted
        # PAUSE: wait (motors off) until RESUME or ABORT; a trial whose stimulus has
        # started is aborted (and run again after the pause)
        if machine is not None and machine.state is TrialState.STIMULUS:
            raise _Paused
        pause_loop()

    def pause_loop() -> None:
        while True:
            now = clock.now_ns()
            clock.sleep_until_ns(now + period)
            cmd = obs.poll(clock.now_ns())
            if cmd is Command.RESUME:
                return
            if cmd is Command.ABORT:
                raise _Aborted

    def run_trial(t: ScheduledTrial) -> TrialResult:
        machine = TrialMachine(t, rule, targets)
        cue = TrialCue(t.trial_index, t.block, t.condition, targets.angles_deg, layout,
                       t.target_deg if t.block == "training" else None)
        stim = stimulus_for(t)
        try:
            # WAIT_HOME
            obs.on_trial_state(t, TrialState.WAIT_HOME, clock.now_ns())
            start = clock.now_ns()
            while True:
                now = clock.now_ns()
                s = cursor.read(now)
                obs.on_sample(CursorSample(now, s.x, s.y, s.buttons))
                if machine.at_home(s):
                    break
                if sim and now - start > SIM_HOME_LIMIT_NS:
                    raise TactorbeltError(
                        f"trial {t.trial_index}: the cursor never came back to the home zone "
                        f"(within {rule.home_radius:g} of the centre)"
                    )
                handle(obs.poll(now), machine)
                clock.sleep_until_ns(now + period)
                if sim:
                    player.pump(clock.now_ns())
            # STIMULUS
            onset = int(player.start(stim, duration_s=sp.max_presentation_s))
            machine.start(onset)
            cursor.trial_started(cue, onset)
            obs.on_trial_state(t, TrialState.STIMULUS, onset)
            k = 0
            playing = True
            while True:
                deadline = onset + k * period
                clock.sleep_until_ns(deadline)
                now = clock.now_ns()
                if now - deadline >= period:  # late (wall clock): skip missed deadlines
                    k = (now - onset) // period
                if sim:
                    player.pump(now)
                s = cursor.read(now)
                state = machine.feed(now, s.x, s.y, s.buttons)
                obs.on_sample(CursorSample(now, s.x, s.y, s.buttons))
                if playing and (machine.finished or machine.stimulus_due_off(now)):
                    player.stop()
                    machine.stimulus_stopped(clock.now_ns())
                    playing = False
                if machine.finished:
                    break
                handle(obs.poll(now), machine)
                k += 1
            obs.on_trial_state(t, state, clock.now_ns())
            return machine.result
        except _Paused:
            machine.stimulus_stopped(clock.now_ns())
            return machine.abort("paused")
        except BaseException as exc:
            _stop_quietly(player, belt)
            machine.stimulus_stopped(clock.now_ns())
            reason = ("interrupted (Ctrl-C)" if isinstance(exc, KeyboardInterrupt)
                      else "aborted by the experimenter" if isinstance(exc, _Aborted)
                      else f"device error: {exc}" if isinstance(exc, DeviceError)
                      else f"error: {type(exc).__name__}: {exc}")
            machine.abort(reason)
            exc.trial_result = machine.result  # type: ignore[attr-defined]
            raise
        finally:
            with contextlib.suppress(Exception):
                cursor.trial_ended(clock.now_ns())

    prev_block: int | None = None
    try:
        # inside the try: Ctrl-C or a window error on the instructions screen leaves
        # the session "interrupted", not "running"
        obs.on_session_start(info, schedule)
        queue = list(todo)
        i = 0
        while i < len(queue):
            t = queue[i]
            if limit is not None and t.block == "test" and n_test_run >= limit:
                break
            if t.block_index != prev_block:
                obs.on_block_start(t.block, t.condition)
                prev_block = t.block_index
            result = run_trial(t)
            if slow_s > 0:
                time.sleep(slow_s / 2)
            store.write_trial(session_id, result)
            results.append(result)
            if len(results) > RESULT_SAMPLES_KEPT:
                results[-RESULT_SAMPLES_KEPT - 1].release_samples()
            obs.on_trial_done(result)
            if result.status == "aborted":  # paused: wait, then run the same trial again
                obs.on_trial_state(t, TrialState.ABORTED, clock.now_ns())
                pause_loop()
                continue
            n_run += 1
            n_done += 1
            if t.block == "test":
                n_test_run += 1
            if progress is not None:
                progress(n_done, n_total)
            if slow_s > 0:
                time.sleep(slow_s / 2)
            i += 1
            last = i >= len(queue)
            if not last:
                obs.on_trial_state(t, TrialState.ITI, clock.now_ns())
                wait_until(clock.now_ns() + iti_ns)
                if break_every and (t.trial_index + 1) % break_every == 0:
                    obs.on_break(n_done, n_total)
        status = "complete" if n_done >= n_total else "interrupted"
    except _Aborted as exc:
        _record_failed(store, session_id, exc, results)
        status = "aborted"
    except BaseException as exc:
        _stop_quietly(player, belt)
        _record_failed(store, session_id, exc, results)
        status = "interrupted"
        with contextlib.suppress(Exception):
            store.set_status(session_id, status)
        with contextlib.suppress(Exception):
            obs.on_session_end(status)
        if isinstance(exc, DeviceError):
            raise DeviceError(
                f"belt {belt.url} failed during the session ({exc}); motors off (a belt that "
                "no longer answers turns them off itself within its heartbeat timeout), the "
                f"trial in flight was stored as aborted and session {session_id} of "
                f"{participant!r} can be resumed with --resume"
            ) from exc
        raise
    finally:
        _stop_quietly(player, belt)
    store.set_status(session_id, status)
    obs.on_session_end(status)
    return SessionResult(session_id, status, n_total, n_done, n_run, results)


def _record_failed(store: Store, session_id: int, exc: BaseException,
                   results: list[TrialResult]) -> None:
    """Store the aborted trial attached to ``exc`` (best effort)."""
    result = getattr(exc, "trial_result", None)
    if isinstance(result, TrialResult):
        with contextlib.suppress(Exception):
            store.write_trial(session_id, result)
            results.append(result)
