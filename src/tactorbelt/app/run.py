"""Start one participant's session the way ``tactorbelt run`` does (the library behind it).

:func:`run_study` takes a :class:`RunRequest` (the command line's options, ``None`` for
options not given) and does everything the command does:

- checks the participant id (:func:`~tactorbelt.experiment.runner.check_participant`);
- the session policy: with ``resume`` the participant's unfinished session, reusing the
  input, belt and window options stored with it unless the request overrides them;
  without, a new session, refused when the participant has an unfinished one (resume
  it) or a complete one (ask for ``new_session``);
- the display: a window needs one (``DISPLAY`` / ``WAYLAND_DISPLAY``, or an explicit
  ``SDL_VIDEODRIVER``); without it the run fails at once instead of drawing into an
  invisible window;
- the clock policy (:func:`clock_kind`, :func:`choose_clock`): ``clock`` ``sim`` (a
  SimClock, as fast as the CPU allows; only for a headless model or scripted run on the
  sim belt) or ``wall`` (real time); not given, ``sim`` where it can be, else ``wall``;
  ``lsl`` runs on the wall clock;
- the cursor (:func:`tactorbelt.inputs.make_cursor`, one seed policy);
- the run, headless or in the experiment window, and a :class:`RunOutcome` whose
  :meth:`~RunOutcome.summary` counts the session's totals (and this run's share).

The run's options are kept in the store's ``meta`` table under
``run_options:<session_id>`` (JSON), so ``--resume`` can reuse them; a resumed run
reports (``note``) each option it reuses and the option that overrides it
(:func:`reuse_lines`).

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
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from .. import devices
from .._errors import ConfigError, StoreError
from ..clock import Clock, SimClock, WallClock
from ..devices import parse_url, runs_on_simulated_time
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
from ..inputs.kinds import JoystickConfig
from ..lsl import LslListener, load_pylsl
from .display import check_display, has_display

__all__ = ["CLOCKS", "RunOutcome", "RunRequest", "choose_clock", "clock_kind", "has_display",
           "resolve_db", "resume_command", "reuse_lines", "run_study"]

#: The values of ``RunRequest.clock`` (``--clock``).
CLOCKS = ("sim", "wall")

#: Seconds of real time added after each trial (to test interrupting a fast run).
SLOW_TRIAL_ENV = "TACTORBELT_TEST_SLOW_TRIAL_S"
#: Seconds a run waits at its end for the background push to catch up.
PUSH_WAIT_S = 15.0


@dataclass
class JoystickOptions:
    """The stick options of ``tactorbelt run`` (None: not given)."""

    device: str | None = None
    axes: str | None = None
    dead_zone: float | None = None
    invert_x: bool | None = None
    invert_y: bool | None = None

    def config(self) -> JoystickConfig:
        """As a JoystickConfig (defaults for what is not given)."""
        axes = self.axes or "0,1"
        try:
            ax, ay = (int(a) for a in axes.split(","))
        except ValueError:
            raise ConfigError(f"--axes: expected two axis indices like 0,1, got {axes!r}") \
                from None
        return JoystickConfig(device=JoystickConfig.parse_device(self.device), axis_x=ax,
                              axis_y=ay, dead_zone=0.05 if self.dead_zone is None
                              else self.dead_zone, invert_x=bool(self.invert_x),
                              invert_y=bool(self.invert_y))


@dataclass
class PushOptions:
    """``--push URL`` (``--offline``): the shared store each trial is copied to."""

    #: ``postgresql://user@host/dbname``
    url: str
    #: run on the local store alone (push later with ``tactorbelt sync``)
    offline: bool = False


@dataclass
class LslOptions:
    """``--lsl``: LSL marker and cursor streams (tactorbelt.lsl; the run is then on the
    wall clock)."""

    #: seconds to wait for a consumer of each stream before the first trial
    wait_s: float = 0.0
    #: with ``wait_s``: wait for a consumer of every stream, not only the markers
    wait_all: bool = False


@dataclass
class RunRequest:
    """What ``tactorbelt run`` was asked. ``None``: not given (a default, or on resume the
    session's stored value)."""

    study_file: Path
    participant: str
    db: Path = Path("study.sqlite")
    belt_url: str | None = None
    #: the belt's calibration file (motor levels; with ``validate onsets``' measured
    #: latencies, each trial's skin onset is stored)
    calibration: str | None = None
    input_kind: str | None = None
    headless: bool | None = None
    resume: bool = False
    new_session: bool = False
    limit: int | None = None
    seed: int | None = None
    #: ``sim`` or ``wall`` (:data:`CLOCKS`); None: sim where it can be, else wall
    clock: str | None = None
    #: the old spelling of ``clock="wall"`` (``--realtime``)
    realtime: bool | None = None
    fullscreen: bool | None = None
    screenshot_dir: Path | None = None
    joystick: JoystickOptions = field(default_factory=JoystickOptions)
    #: the lab running the session (default: provenance.default_site)
    site: str | None = None
    #: copy each trial to a shared store in the background (None: no push)
    push: PushOptions | None = None
    #: LSL marker and cursor streams (None: none)
    lsl: LslOptions | None = None


def resolve_db(db: str, push: str | None, study_file: Path) -> tuple[Path, str | None]:
    """``(local store, shared store URL or None)`` of ``--db`` and ``--push``.

    ``--db postgresql://...`` means: push there, with the local store
    ``<study file without suffix>.sqlite`` next to the study file.
    """
    if db.lower().startswith(("postgresql://", "postgres://")):
        if push is not None and push != db:
            raise ConfigError("--db postgresql://... already pushes there; give --db "
                              "LOCAL.sqlite --push URL to choose the local store")
        return study_file.with_suffix(".sqlite"), db
    if push is not None and not push.lower().startswith(("postgresql://", "postgres://")):
        raise ConfigError(f"--push takes a postgresql://user@host/dbname URL, not {push!r}")
    return Path(db), push


#: What is stored with a session and reused on resume.
_STORED = ("belt_url", "calibration", "input_kind", "headless", "clock", "fullscreen")
#: The input of a run with the window, and of one without, when none is given.
DEFAULT_INPUTS = {"window": "joystick", "headless": "model"}


def _default_input(headless: bool | None) -> str:
    return DEFAULT_INPUTS["headless" if headless else "window"]


def _window_input(name: str) -> bool:
    """Whether the input kind ``name`` needs the experiment window (it declares it)."""
    return kinds.input_kind(name).display


def _headless_inputs() -> str:
    """``--input model or --input scripted``: the kinds that run without a window."""
    return " or ".join(f"--input {k}" for k in kinds.session_inputs()
                       if not kinds.input_kind(k).display)


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


def _no_sim(*, headless: bool, input_kind: str, belt_url: str) -> str | None:
    """Why this run cannot be on a simulated clock (None: it can)."""
    if not headless:
        return "the experiment window runs in real time"
    if not kinds.input_kind(input_kind).simulated_time:
        return f"--input {input_kind} is a person, in real time"
    if not runs_on_simulated_time(belt_url):
        return f"the belt {belt_url} runs in real time"
    return None


def clock_kind(*, headless: bool, input_kind: str, belt_url: str,
               clock: str | None = None) -> str:
    """``sim`` or ``wall``: ``clock`` when given, else ``sim`` for a headless model or
    scripted run on the sim belt and ``wall`` for anything else.

    Raises:
        ConfigError: ``clock`` is not one of :data:`CLOCKS`, or ``sim`` for a run that
            cannot be simulated (a window, a person, a real belt).
    """
    if clock is not None and clock not in CLOCKS:
        raise ConfigError(f"unknown clock {clock!r}; allowed: {', '.join(CLOCKS)}")
    why = _no_sim(headless=headless, input_kind=input_kind, belt_url=belt_url)
    if clock == "sim" and why is not None:
        raise ConfigError(f"--clock sim is for a headless run (--headless) with --input "
                          f"model or scripted on the sim belt; here {why}: use --clock wall")
    return clock or ("sim" if why is None else "wall")


def choose_clock(*, headless: bool, input_kind: str, belt_url: str,
                 clock: str | None = None, realtime: bool = False) -> Clock:
    """The clock of :func:`clock_kind` (``realtime``: the old spelling of ``clock="wall"``):
    a SimClock or the wall clock."""
    kind = clock_kind(headless=headless, input_kind=input_kind, belt_url=belt_url,
                      clock="wall" if realtime and clock is None else clock)
    return SimClock() if kind == "sim" else WallClock()


def resume_command(req: RunRequest) -> str:
    """The command that continues the participant's session (as a shell line)."""
    push = ["--push", shlex.quote(req.push.url)] if req.push else []
    site = ["--site", shlex.quote(req.site)] if req.site else []
    lsl = (["--lsl"] + (["--lsl-wait", f"{req.lsl.wait_s:g}"] if req.lsl.wait_s else [])
           + (["--lsl-wait-all"] if req.lsl.wait_s and req.lsl.wait_all else [])
           if req.lsl else [])
    return " ".join(["tactorbelt", "run", shlex.quote(str(req.study_file)), "--participant",
                     shlex.quote(req.participant.strip()), "--db", shlex.quote(str(req.db)),
                     *push, *site, *lsl, "--resume"])


def stored_options(store: Store, session: dict[str, Any]) -> dict[str, Any]:
    """The run options stored with a session (older sessions: their input and belt)."""
    opts = store.run_options(session["session_id"])
    if opts is None:
        return {"input_kind": session.get("input"), "belt_url": session.get("belt")}
    if "clock" not in opts:  # stored before --clock: realtime true or false
        opts["clock"] = "wall" if opts.get("realtime") else None
    return opts


def _resolve(req: RunRequest, stored: dict[str, Any]) -> RunRequest:
    """The request with stored values for what it does not give, then the defaults."""
    got = asdict(req)
    if got["clock"] is None and req.realtime:
        got["clock"] = "wall"
    if req.headless is None and req.input_kind is not None and _window_input(req.input_kind):
        got["headless"] = False  # a live input given again brings the window back
    for name in _STORED:
        if got[name] is None:
            got[name] = stored.get(name)
    joy = dict(stored.get("joystick") or {})
    joy.update({k: v for k, v in got["joystick"].items() if v is not None})
    got["joystick"] = JoystickOptions(**joy)
    got["push"], got["lsl"] = req.push, req.lsl
    res = RunRequest(**got)
    res.belt_url = res.belt_url or "sim"
    res.headless = bool(res.headless)
    res.realtime = res.clock == "wall"
    res.fullscreen = bool(res.fullscreen)
    if res.input_kind is None:
        res.input_kind = _default_input(res.headless)
    return res


def _check_session(store: Store, req: RunRequest) -> dict[str, Any]:
    """The session policy; returns the stored options to reuse."""
    pid = req.participant
    existing = store.find_resumable(pid)
    if req.resume:
        if existing is None:
            raise StoreError(f"participant {pid!r} has no unfinished session in {req.db}; "
                             "run without --resume to start one")
        return stored_options(store, existing)
    if existing is not None and not req.new_session:
        done = len(store.finished_indices(existing["session_id"]))
        raise StoreError(
            f"participant {pid!r} has an unfinished session {existing['session_id']} in "
            f"{req.db} ({done}/{existing['n_trials']} trials done, {existing['status']}); "
            "continue it with --resume, or start another with --new-session")
    complete = [s for s in store.sessions(pid) if s["status"] == "complete"]
    if complete and not req.new_session:
        raise StoreError(
            f"participant {pid!r} has completed session {complete[-1]['session_number']} in "
            f"{req.db}; start another session for them with --new-session (or check the "
            "participant id)")
    return {}


class _RunListener(NullListener):
    """The run's own listener: stores the run's options when the session starts, and
    tells the background push of each trial stored."""

    def __init__(self, store: Store, opts: dict[str, Any], slow_s: float,
                 pusher: Pusher | None = None) -> None:
        self.store, self.opts, self.slow_s = store, opts, slow_s
        self.pusher = pusher

    def on_session_start(self, info: SessionInfo, schedule: list[ScheduledTrial]) -> None:
        self.store.set_run_options(info.session_id, self.opts)
        if self.pusher is not None:
            self.pusher.watch(info.session_id)

    def on_trial_done(self, result: TrialResult) -> None:
        if self.pusher is not None:
            self.pusher.notify()
        if self.slow_s > 0:
            time.sleep(self.slow_s)


def _check_options(r: RunRequest, given: bool = False) -> None:
    """Refuse an unknown input, a window input without a window, an unknown belt URL,
    an unknown clock; ``given`` (the request as given): ``sim`` with LSL, and (a new
    session) ``sim`` where it cannot be."""
    if r.input_kind is not None:
        kinds.input_kind(r.input_kind)
    if r.headless and r.input_kind is not None and _window_input(r.input_kind):
        raise ConfigError(f"--input {r.input_kind} needs the experiment window; drop "
                          f"--headless, or use {_headless_inputs()}")
    if r.belt_url is not None:
        parse_url(r.belt_url)
    if r.clock is not None and r.clock not in CLOCKS:
        raise ConfigError(f"unknown clock {r.clock!r}; allowed: {', '.join(CLOCKS)}")
    if given and r.clock == "sim" and r.lsl is not None:
        raise ConfigError("--lsl runs on the wall clock (LSL timestamps are real times); "
                          "drop --clock sim")
    if given and r.clock == "sim" and not r.resume:
        clock_kind(headless=bool(r.headless), belt_url=r.belt_url or "sim", clock="sim",
                   input_kind=r.input_kind or _default_input(bool(r.headless)))


def _pick_clock(req: RunRequest, r: RunRequest, headless: bool) -> tuple[str | None, str]:
    """(the clock to store with the session, the clock of this run): the one given, else
    the stored one where it still fits (a stored ``sim`` does not once the window is
    back, nor with ``lsl``), else the default; ``lsl`` runs on the wall clock."""
    given = req.clock or ("wall" if req.realtime else None)
    keep = given if given is not None else r.clock
    if given is None and keep == "sim" and (req.lsl is not None or _no_sim(
            headless=headless, input_kind=str(r.input_kind), belt_url=str(r.belt_url))):
        keep = None
    want = "wall" if req.lsl is not None else keep
    return keep, clock_kind(headless=headless, input_kind=str(r.input_kind),
                            belt_url=str(r.belt_url), clock=want)


def reuse_lines(req: RunRequest, r: RunRequest, stored: dict[str, Any],
                session: dict[str, Any], n_done: int, *, headless: bool,
                clock: str) -> list[str]:
    """What a resumed run says about its options: for each, its value in this run, where
    it comes from (given again, the session's stored one, or the default) and the option
    that overrides it.

    Args:
        req: the request as given (None: not given).
        r: the request with the stored options filled in (``_resolve``).
        stored: the options stored with the session (:func:`stored_options`).
        session: the session's row; ``n_done``: its trials done.
        headless: the run has no window; ``clock``: ``sim`` or ``wall``, this run's.
    """
    def source(given: bool, key: str, now: Any) -> str:
        was = stored.get(key)
        if key == "headless" and was is not None:
            was = "none" if was else "yes"
        if given:
            return "given" + (f" (stored: {was})" if was is not None and was != now else "")
        if was is None:
            return "default"
        return "stored" if was == now else f"default (stored {was} does not fit)"

    joy = r.joystick
    no_sim = _no_sim(headless=headless, input_kind=str(r.input_kind),
                     belt_url=str(r.belt_url))
    clock_how = ("--lsl runs in real time" if req.lsl is not None else "--clock wall"
                 if clock == "sim" else "--clock sim" if no_sim is None else f"none ({no_sim})")
    window_given = req.headless is not None or (req.fullscreen is not None and not headless)
    rows: list[tuple[str, str, str, str]] = [
        ("input", str(r.input_kind),
         source(req.input_kind is not None, "input_kind", r.input_kind),
         "--input " + "|".join(k for k in kinds.session_inputs() if k != r.input_kind)),
        ("window", "none (headless)" if headless else "full screen" if r.fullscreen
         else "yes", source(window_given, "headless", "none" if headless else "yes"),
         "--window" if headless else
         "--headless, " + ("--no-fullscreen" if r.fullscreen else "--fullscreen")),
        ("belt", str(r.belt_url), source(req.belt_url is not None, "belt_url", r.belt_url),
         "--belt URL"),
        ("calibration", r.calibration or "none",
         source(req.calibration is not None, "calibration", r.calibration),
         "--calibration FILE"),
        ("clock", f"{clock} ({'simulated time' if clock == 'sim' else 'real time'})",
         "--lsl" if req.lsl is not None and req.clock is None else
         source(req.clock is not None or bool(req.realtime), "clock", clock), clock_how),
    ]
    if kinds.input_kind(str(r.input_kind)).stick:
        inv = [a for a, on in (("x", joy.invert_x), ("y", joy.invert_y)) if on]
        rows.append(("joystick", f"{joy.device or 'the first stick'}, axes {joy.axes or '0,1'}"
                     f", dead zone {0.05 if joy.dead_zone is None else joy.dead_zone:g}"
                     + (f", {' and '.join(inv)} inverted" if inv else ""),
                     "given" if req.joystick != JoystickOptions() else "stored",
                     "--joystick, --axes, --dead-zone, --[no-]invert-x, --[no-]invert-y"))
    rows.append(("seed", str(session["seed"]), "stored",
                 "none (the session's schedule is stored)"))
    head = (f"resuming session {session['session_id']} of {r.participant} ({n_done}/"
            f"{session['n_trials']} trials done) with these options:")
    wn = max(len(n) for n, _, _, _ in rows)
    wv = max(len(v) for _, v, _, _ in rows)
    ws = max(len(src) for _, _, src, _ in rows)
    return [head] + [f"  {name:<{wn}s} {value:<{wv}s}  {src:<{ws}s}  override: {how}"
                     for name, value, src, how in rows]


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
    req.participant = check_participant(req.participant)
    if req.resume and req.new_session:
        raise ConfigError("--resume and --new-session exclude each other")
    text = req.study_file.read_text(encoding="utf-8") if req.study_file.is_file() else None
    study = load_study(req.study_file)
    push_lines: list[str] = []
    _check_push(req)  # before anything is written
    _check_options(req, given=True)  # what the request gives: before a store file is created
    if req.lsl is not None:
        load_pylsl()  # no liblsl: an error now, before a store file is created
    with open_store(req.db) as store:
        stored = _check_session(store, req)
        r = _resolve(req, stored)
        assert r.input_kind is not None and r.belt_url is not None
        _check_options(r)  # with the stored options of a resumed session
        calibration = None
        if r.calibration is not None:  # a bad file is an error before the session starts
            calibration = Calibration.load(r.calibration)
        window = None if r.headless else _window_factory(r.input_kind, note)
        check_display(window is not None)
        headless = window is None
        r.clock, kind = _pick_clock(req, r, headless)
        clock = choose_clock(headless=headless, input_kind=r.input_kind,
                             belt_url=r.belt_url, clock=kind)
        opts = {k: getattr(r, k) for k in _STORED} | {"headless": headless,
                                                      "joystick": asdict(r.joystick)}
        if req.resume:
            row = store.find_resumable(req.participant)
            assert row is not None
            schedule = store.schedule(int(row["session_id"]), study)
            seed = int(row["seed"])
            if note is not None:
                done = len(store.finished_indices(int(row["session_id"])))
                for line in reuse_lines(req, r, stored, row, done, headless=headless,
                                        clock=kind):
                    note(line)
        else:
            seed = study.session.seed if r.seed is None else r.seed
            schedule = None
        slow_s = float(os.environ.get(SLOW_TRIAL_ENV, "0") or 0)
        pusher = _start_push(req)
        with _closing_push(pusher, req, push_lines), \
                devices.open_belt(r.belt_url, clock=clock, layout=study.layout_obj(),
                          **({} if calibration is None else {"calibration": calibration})
                          ) as belt:
            kwargs: dict[str, Any] = dict(seed=seed, resume=req.resume, limit=req.limit,
                                          study_toml=text, input_name=r.input_kind,
                                          site=req.site)
            cursor = None
            lsl = _lsl(req, clock, belt, note)  # None without --lsl
            if not _window_input(r.input_kind):  # the window makes its own kinds' cursors
                if schedule is None:  # the schedule the session will have (its answers)
                    schedule = SessionRecorder.schedule_for(study, req.participant, seed)[0]
                cursor = make_cursor(r.input_kind, study=study, belt=belt, clock=clock,
                                     participant=req.participant, seed=seed,
                                     schedule=schedule)
            listeners: list[SessionListener] = [_RunListener(store, opts, slow_s, pusher)]
            try:
                if window is None:
                    assert cursor is not None
                    if lsl is not None:
                        listeners.append(lsl)
                    result = run_session(study, req.participant, belt, cursor, store, clock,
                                         progress=progress, listeners=listeners, **kwargs)
                else:
                    with window(study, input=r.input_kind, participant=req.participant,
                                clock=clock, belt=belt, fullscreen=r.fullscreen,
                                screenshot_dir=r.screenshot_dir,
                                joystick=r.joystick.config()) as win:
                        src = cursor if cursor is not None else win.cursor
                        if src is None:
                            raise ConfigError(f"the window gave no cursor for --input "
                                              f"{r.input_kind}")
                        if lsl is not None:
                            lsl.operator = win.observer
                            listeners.append(lsl)
                        result = win.run(lambda: run_session(
                            study, req.participant, belt, src, store, clock,
                            listeners=listeners, observer=win.observer, **kwargs))
            finally:
                if cursor is not None:
                    cursor.close()
                if lsl is not None:
                    lsl.close()
        trials = store.trials(result.session_id)
        events = store.task_events(result.session_id) if study.tasks else []
    return RunOutcome(result, req.db, trials, req.resume, push_lines, events)


def _lsl(req: RunRequest, clock: Clock, belt: Any,
         note: Callable[[str], None] | None) -> LslListener | None:
    """With ``req.lsl``: the LSL observer (tactorbelt.lsl; its streams open when the
    session starts); else None."""
    if req.lsl is None:
        return None
    return LslListener(clock, belt, wait_s=req.lsl.wait_s, wait_all=req.lsl.wait_all,
                       report=note)


def _check_push(req: RunRequest) -> None:
    """With ``req.push``: no password in the URL; unless offline, the shared store is
    reachable, this login writes the site, and the participant id is free there
    (:func:`~tactorbelt.experiment.sync.check_push`)."""
    if req.push is None:
        return
    check_url(req.push.url)
    if not req.push.offline:
        check_push(req.push.url, req.participant, req.site or default_site())


def _start_push(req: RunRequest) -> Pusher | None:
    """The background push of ``req.push`` (None without one, or offline)."""
    if req.push is None or req.push.offline:
        return None
    return Pusher(req.db, req.push.url, site=req.site or default_site()).start()


@contextlib.contextmanager
def _closing_push(pusher: Pusher | None, req: RunRequest, lines: list[str]) -> Iterator[None]:
    """Let the push catch up at the end of the run (even an interrupted one) and say
    what is left for ``tactorbelt sync``."""
    try:
        yield
    finally:
        if req.push is not None:
            url = req.push.url
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


def _window_factory(input_kind: str, note: Callable[[str], None] | None) -> Any:
    """``tactorbelt.gui.session_window``, or None (headless) when it is not installed."""
    try:
        from ..gui.window import session_window
    except ImportError:
        if _window_input(input_kind):
            raise ConfigError(
                f"--input {input_kind} needs the experiment window (tactorbelt.gui), which "
                f"is not available in this installation; use --headless with "
                f"{_headless_inputs()}") from None
        if note is not None:
            note("note: the experiment window is not available; running headless")
        return None
    return session_window
