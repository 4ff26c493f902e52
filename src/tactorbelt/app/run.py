"""Start one participant's session the way ``tactorbelt run`` does (the library behind it).

:func:`run_study` takes a :class:`~tactorbelt.app.request.RunRequest` (the command line's
options, ``None`` for options not given), applies the rules of :mod:`.request` (the
session policy, the options a resumed run reuses and says it reuses, the clock), and
assembles the session's seam: the input kind from the registry (a cursor made here for a
headless kind, by the window for a display kind), the listeners (the run's stored
options, the background push, the LSL streams, the progress) and the operator (the
experiment window, when there is one). A window needs a display (``DISPLAY`` /
``WAYLAND_DISPLAY``, or an explicit ``SDL_VIDEODRIVER``); without it the run fails at once
instead of drawing into an invisible window. The :class:`RunOutcome`'s
:meth:`~RunOutcome.summary` counts the session's totals (and this run's share).

Multi-site studies (docs/multisite.md): with ``push`` (``--push postgresql://...``, or
``--db postgresql://...``, which keeps the local store next to the study file) every
trial is written to the local SQLite store first and copied to the shared store in the
background (:class:`tactorbelt.experiment.sync.Pusher`); the shared store must be
reachable at the start (it also refuses a participant id taken at another site) unless
``offline``.
"""

from __future__ import annotations

import contextlib
import os
import shlex
import statistics
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .. import devices
from .._errors import ConfigError
from ..clock import SimClock, WallClock
from ..devices.calibration import Calibration
from ..experiment.listeners import NullListener, SessionInfo, SessionListener
from ..experiment.provenance import default_site
from ..experiment.recorder import SessionRecorder
from ..experiment.runner import SessionResult, check_participant, run_session
from ..experiment.schedule import ScheduledTrial
from ..experiment.store import Store, open_store
from ..experiment.store.postgresql import check_url
from ..experiment.study import load_study
from ..experiment.sync import Pusher, check_push
from ..experiment.trial import TrialResult
from ..inputs import kinds, make_cursor
from ..lsl import LslListener, load_pylsl
from .display import check_display
from .request import (
    RunRequest,
    check_options,
    check_session,
    headless_inputs,
    pick_clock,
    resolve,
    resume_command,
    reuse_lines,
)

__all__ = ["RunOutcome", "RunRequest", "resume_command", "run_study", "task_lines"]

#: Seconds of real time added after each trial (to test interrupting a fast run).
SLOW_TRIAL_ENV = "TACTORBELT_TEST_SLOW_TRIAL_S"
#: Seconds a run waits at its end for the background push to catch up.
PUSH_WAIT_S = 15.0


@dataclass
class RunOutcome:
    """What :func:`run_study` did: the runner's result and the session's totals."""

    result: SessionResult
    db: Path
    trials: list[dict[str, Any]]
    resumed: bool
    #: What happened to the background push (stderr lines; empty without --push).
    push_lines: list[str] = field(default_factory=list)
    #: The session's secondary-task events (``Store.task_events``; empty without load).
    task_events: list[dict[str, Any]] = field(default_factory=list)

    def summary(self) -> tuple[list[str], list[str]]:
        """(lines for stdout, lines for stderr) of the end-of-run summary."""
        r = self.result
        out = [f"session {r.session_id}: {r.status}, {r.n_done}/{r.n_total} trials done "
               f"({r.n_run} this run), stored in {self.db}"]
        final = [t for t in self.trials if t["block"] == "test" and t["status"] != "aborted"]
        out += _condition_lines(
            [(t["condition"], bool(t["correct"]), t["rt_s"]) for t in final],
            "  " if not self.resumed else "  session ")
        if self.resumed:
            mine = [(x.trial.condition, bool(x.correct), x.rt_s) for x in r.results
                    if x.trial.block == "test" and x.status != "aborted"]
            out += _condition_lines(mine, "  this run ") or ["  this run: no test trials"]
        out += task_lines(self.task_events)
        err = list(self.push_lines)
        if r.status != "complete":
            err.append(f"  continue with --resume (session {r.session_id})")
        return out, err


def _condition_lines(rows: list[tuple[str, bool, float | None]], prefix: str) -> list[str]:
    lines = []
    for cond in ("static", "dynamic"):
        rs = [x for x in rows if x[0] == cond]
        if rs:
            acc = sum(1 for x in rs if x[1]) / len(rs)
            rts = [x[2] for x in rs if x[2] is not None]
            med = f"{statistics.median(rts):.2f} s" if rts else "n/a (no response)"
            lines.append(f"{prefix}{cond:<8s} {len(rs):4d} test trials, accuracy {acc:.1%}, "
                         f"median RT {med}")
    return lines


def task_lines(events: list[dict[str, Any]], prefix: str = "  ") -> list[str]:
    """One summary line per secondary task and phase (practice, baseline, dual): go
    items pressed, false alarms among the no-go items, extra presses, median RT."""
    lines = []
    keys = sorted({(e["task"], e["phase"]) for e in events},
                  key=lambda k: (k[0], ("practice", "baseline", "dual").index(k[1])))
    for task, phase in keys:
        rows = [e for e in events if (e["task"], e["phase"]) == (task, phase)]
        items = [e for e in rows if e["item_index"] >= 0]
        go = [e for e in items if e["target"]]
        nogo = [e for e in items if not e["target"]]
        hits = sum(1 for e in go if e["response"])
        fas = sum(1 for e in nogo if e["response"])
        extra = len(rows) - len(items)
        rts = [e["rt_s"] for e in go if e["rt_s"] is not None]
        med = f"{statistics.median(rts):.2f} s" if rts else "n/a"
        lines.append(f"{prefix}{task} {phase:<8s} {len(items):4d} items, {hits}/{len(go)} go "
                     f"items pressed, {fas}/{len(nogo)} false alarms"
                     + (f", {extra} extra presses" if extra else "")
                     + f", median RT {med}")
    return lines


def run_study(req: RunRequest, *, progress: Callable[[int, int], None] | None = None,
              note: Callable[[str], None] | None = None) -> RunOutcome:
    """Run ``tactorbelt run``'s session (see the module's docstring).

    Args:
        req: the options.
        progress: ``progress(n_done, n_total)`` after each trial of a headless run.
        note: called with a line of information for the experimenter.

    Raises:
        ConfigError: a participant id that is not allowed, options that exclude each
            other, no display for the window.
        StoreError, StudyFileError, DeviceError: as the store, the study file, the belt.
        KeyboardInterrupt, Terminated: the run was stopped; the trial in flight is stored
            ``aborted`` and the session can be resumed (:func:`resume_command`).
    """
    check_display(not req.resume and not req.headless)  # before the study and the store
    req.participant = pid = check_participant(req.participant)
    if req.resume and req.new_session:
        raise ConfigError("--resume and --new-session exclude each other")
    text = req.study_file.read_text(encoding="utf-8") if req.study_file.is_file() else None
    study = load_study(req.study_file)
    if req.push is not None:  # before anything is written: no password in the URL; unless
        check_url(req.push)  # offline, the shared store is reachable, this login writes
        if not req.offline:  # the site, and the participant id is free there
            check_push(req.push, pid, req.site or default_site())
    check_options(req, given=True)  # what the request gives: before a store file is created
    if req.lsl:
        load_pylsl()  # no liblsl: an error now, before a store file is created
    push_lines: list[str] = []
    with open_store(req.db) as store:
        stored = check_session(store, req)
        r = resolve(req, stored)
        check_options(r)  # with the stored options of a resumed session
        # a bad calibration file is an error before the session starts
        calibration = None if r.calibration_file is None else Calibration.load(
            r.calibration_file)
        window = None if r.headless else _window_factory(str(r.input_kind), note)
        check_display(window is not None)
        r.headless = window is None
        r.clock, kind = pick_clock(req, r)
        clock = SimClock() if kind == "sim" else WallClock()
        schedule = None
        seed = study.session.seed if r.seed is None else r.seed
        if req.resume:
            row = store.find_resumable(pid)
            assert row is not None
            schedule, seed = store.schedule(int(row["session_id"]), study), int(row["seed"])
            if note is not None:
                done = len(store.finished_indices(int(row["session_id"])))
                for line in reuse_lines(req, r, stored, row, done, kind):
                    note(line)
        input_kind = kinds.input_kind(str(r.input_kind))
        slow_s = float(os.environ.get(SLOW_TRIAL_ENV, "0") or 0)
        with _pushing(req, push_lines) as pusher, \
                devices.open_belt(str(r.belt_url), clock=clock, layout=study.layout_obj(),
                                  **({} if calibration is None else {"calibration": calibration})
                                  ) as belt, contextlib.ExitStack() as stack:
            listeners: list[SessionListener] = [*([pusher] if pusher else []),
                                                _RunListener(store, r.stored(), slow_s)]
            lsl = None if not req.lsl else stack.enter_context(LslListener(
                clock, belt, wait_s=req.lsl_wait, wait_all=req.lsl_wait_all, report=note))
            listeners += [lsl] if lsl is not None else []
            cursor = None
            if not input_kind.display:  # the window makes its own kinds' cursors
                if schedule is None:  # the schedule the session will have (its answers)
                    schedule = SessionRecorder.schedule_for(study, pid, seed)[0]
                cursor = make_cursor(input_kind.name, study=study, belt=belt, clock=clock,
                                     participant=pid, seed=seed, schedule=schedule)
                stack.callback(cursor.close)
            kwargs: dict[str, Any] = dict(seed=seed, resume=req.resume, limit=req.limit,
                                          study_toml=text, input_name=input_kind.name,
                                          site=req.site)
            if window is None:
                assert cursor is not None
                result = run_session(study, pid, belt, cursor, store, clock,
                                     progress=progress, listeners=listeners, **kwargs)
            else:
                win = stack.enter_context(window(
                    study, input=input_kind.name, participant=pid, clock=clock, belt=belt,
                    fullscreen=r.fullscreen, screenshot_dir=r.screenshot_dir,
                    joystick=r.joystick()))
                src = cursor if cursor is not None else win.cursor
                if src is None:
                    raise ConfigError(f"the window gave no cursor for --input {input_kind.name}")
                if lsl is not None:
                    lsl.operator = win.observer
                result = win.run(lambda: run_session(
                    study, pid, belt, src, store, clock, listeners=listeners,
                    observer=win.observer, **kwargs))
        trials = store.trials(result.session_id)
        events = store.task_events(result.session_id) if study.tasks else []
    return RunOutcome(result, Path(req.db), trials, req.resume, push_lines, events)


@contextlib.contextmanager
def _pushing(req: RunRequest, lines: list[str]) -> Iterator[Pusher | None]:
    """The background push of ``req.push`` (None without one, or offline); at the end of
    the run (even an interrupted one) it catches up and ``lines`` say what is left for
    ``tactorbelt sync``."""
    if req.push is None:
        yield None
        return
    url = req.push
    pusher = None if req.offline else Pusher(req.db, url, site=req.site or default_site()
                                              ).start()
    try:
        yield pusher
    finally:
        sync = f"tactorbelt sync {shlex.quote(str(req.db))} {shlex.quote(url)}"
        pending = None if pusher is None else pusher.close(PUSH_WAIT_S)
        if pusher is None:
            lines.append(f"  offline: the trials are in {req.db} only; push them with "
                         f"'{sync}'")
        elif pending == 0 and pusher.error is None:
            lines.append(f"  pushed to {url}")
        else:
            left = "some trials" if pending is None else f"{pending} trial(s)"
            lines.append(f"  {left} not pushed to {url} yet ({pusher.error}); they "
                         f"are safe in {req.db}: push them with '{sync}'")


class _RunListener(NullListener):
    """The run's own listener: stores the run's options when the session starts."""

    def __init__(self, store: Store, opts: dict[str, Any], slow_s: float) -> None:
        self.store, self.opts, self.slow_s = store, opts, slow_s

    def on_session_start(self, info: SessionInfo, schedule: list[ScheduledTrial]) -> None:
        self.store.set_run_options(info.session_id, self.opts)

    def on_trial_done(self, result: TrialResult) -> None:
        if self.slow_s > 0:
            time.sleep(self.slow_s)


def _window_factory(input_kind: str, note: Callable[[str], None] | None) -> Any:
    """``tactorbelt.gui.session_window``, or None (headless) when it is not installed."""
    try:
        from ..gui.window import session_window
    except ImportError:
        if kinds.input_kind(input_kind).display:
            raise ConfigError(
                f"--input {input_kind} needs the experiment window (tactorbelt.gui), which "
                f"is not available in this installation; use --headless with "
                f"{headless_inputs()}") from None
        if note is not None:
            note("note: the experiment window is not available; running headless")
        return None
    return session_window
