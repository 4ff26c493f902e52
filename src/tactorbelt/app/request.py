"""What ``tactorbelt run`` was asked (:class:`RunRequest`) and the one place of the rules
that fill in what it was not asked:

- the session policy (:func:`check_session`): with ``resume`` the participant's
  unfinished session; without, a new one, refused when the participant has an unfinished
  one (resume it) or a complete one (ask for ``new_session``);
- what a session stores and a resumed run reuses unless given again (:data:`STORED`,
  :data:`JOYSTICK`; :func:`resolve`), then the defaults (:data:`DEFAULTS`);
- the clock (:func:`clock_kind`, :func:`pick_clock`): ``sim`` (as fast as the CPU allows;
  only for a headless model or scripted run on the sim belt) or ``wall``; not given, ``sim``
  where it can be, else ``wall``; ``lsl`` runs on the wall clock;
- what a resumed run says about each option (:func:`reuse_lines`).

The options are kept in the store's ``meta`` table under ``run_options:<session_id>``
(JSON: the keys of :data:`STORED`, and ``joystick`` with those of :data:`JOYSTICK`).
"""

from __future__ import annotations

import shlex
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from .._errors import ConfigError, StoreError
from .._registry import check_option
from ..devices import parse_url, runs_on_simulated_time
from ..experiment.store import Store
from ..inputs import kinds
from ..inputs.kinds import JoystickConfig

__all__ = ["CLOCKS", "RunRequest", "clock_kind", "resolve_db", "resume_command",
           "reuse_lines", "stored_options"]

#: The values of ``RunRequest.clock`` (``--clock``).
CLOCKS = ("sim", "wall")
#: The options stored with a session and reused on resume: request field -> stored key.
STORED = {"belt_url": "belt_url", "calibration_file": "calibration", "input_kind": "input_kind",
          "headless": "headless", "clock": "clock", "fullscreen": "fullscreen"}
#: The stick options, stored under ``joystick``: request field -> stored key.
JOYSTICK = {"joystick_device": "device", "axes": "axes", "dead_zone": "dead_zone",
            "invert_x": "invert_x", "invert_y": "invert_y"}
#: What neither the request nor the session gives (the input: :data:`DEFAULT_INPUTS`).
DEFAULTS = {"belt_url": "sim", "headless": False, "fullscreen": False}
#: The input of a run with the window, and of one without, when none is given.
DEFAULT_INPUTS = {False: "joystick", True: "model"}


@dataclass
class RunRequest:
    """What ``tactorbelt run`` was asked, by its options' names (``tactorbelt run
    --help``). ``None``: not given (a default, or on resume the session's stored value)."""

    study_file: Path
    participant: str
    #: the local store (``postgresql://...``: push there; :func:`resolve_db`)
    db: Path | str = Path("study.sqlite")
    belt_url: str | None = None
    #: the belt's calibration file (motor levels; with ``validate onsets``' measured
    #: latencies, each trial's skin onset is stored)
    calibration_file: str | None = None
    input_kind: str | None = None
    headless: bool | None = None
    resume: bool = False
    new_session: bool = False
    limit: int | None = None
    seed: int | None = None
    #: ``sim`` or ``wall`` (:data:`CLOCKS`); None: sim where it can be, else wall
    clock: str | None = None
    #: the old spelling of ``clock="wall"`` (``--realtime``)
    realtime: bool = False
    fullscreen: bool | None = None
    screenshot_dir: Path | None = None
    #: the stick (:data:`JOYSTICK`): which one, its axes ("0,1"), dead zone, mirrored axes
    joystick_device: str | None = None
    axes: str | None = None
    dead_zone: float | None = None
    invert_x: bool | None = None
    invert_y: bool | None = None
    #: the lab running the session (default: provenance.default_site)
    site: str | None = None
    #: copy each trial to this shared store (``postgresql://user@host/dbname``) in the
    #: background; ``offline``: run on the local store alone (``tactorbelt sync`` later)
    push: str | None = None
    offline: bool = False
    #: LSL marker and cursor streams (tactorbelt.lsl; the run is then on the wall clock),
    #: waiting ``lsl_wait`` seconds for a consumer of the markers (``lsl_wait_all``: of
    #: every stream) before the first trial
    lsl: bool = False
    lsl_wait: float = 0.0
    lsl_wait_all: bool = False

    def __post_init__(self) -> None:
        self.db, self.push = resolve_db(str(self.db), self.push, self.study_file)
        if self.realtime and self.clock is None:
            self.clock = "wall"

    def stored(self) -> dict[str, Any]:
        """The options stored with the session (reused on resume)."""
        return ({key: getattr(self, f) for f, key in STORED.items()}
                | {"joystick": {key: getattr(self, f) for f, key in JOYSTICK.items()}})

    def joystick(self) -> JoystickConfig:
        """The stick's options as a JoystickConfig (defaults for what is not given)."""
        axes = self.axes or "0,1"
        try:
            ax, ay = (int(a) for a in axes.split(","))
        except ValueError:
            raise ConfigError(f"--axes: expected two axis indices like 0,1, got {axes!r}") \
                from None
        return JoystickConfig(device=JoystickConfig.parse_device(self.joystick_device),
                              axis_x=ax, axis_y=ay, dead_zone=0.05 if self.dead_zone is None
                              else self.dead_zone, invert_x=bool(self.invert_x),
                              invert_y=bool(self.invert_y))


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


def resume_command(req: RunRequest) -> str:
    """The command that continues the participant's session (as a shell line)."""
    push = ["--push", shlex.quote(req.push)] if req.push else []
    site = ["--site", shlex.quote(req.site)] if req.site else []
    wait = ["--lsl-wait", f"{req.lsl_wait:g}"] if req.lsl_wait else []
    lsl = ["--lsl", *wait, *(["--lsl-wait-all"] if wait and req.lsl_wait_all else [])]
    return " ".join(["tactorbelt", "run", shlex.quote(str(req.study_file)), "--participant",
                     shlex.quote(req.participant.strip()), "--db", shlex.quote(str(req.db)),
                     *push, *site, *(lsl if req.lsl else []), "--resume"])


def stored_options(store: Store, session: dict[str, Any]) -> dict[str, Any]:
    """The run options stored with a session (older sessions: their input and belt)."""
    opts = store.run_options(session["session_id"])
    if opts is None:
        return {"input_kind": session.get("input"), "belt_url": session.get("belt")}
    if "clock" not in opts:  # stored before --clock: realtime true or false
        opts["clock"] = "wall" if opts.get("realtime") else None
    return opts


def check_session(store: Store, req: RunRequest) -> dict[str, Any]:
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


def resolve(req: RunRequest, stored: dict[str, Any]) -> RunRequest:
    """The request with stored values for what it does not give, then the defaults."""
    got: dict[str, Any] = {f: getattr(req, f) for f in (*STORED, *JOYSTICK)}
    if req.headless is None and req.input_kind and kinds.input_kind(req.input_kind).display:
        got["headless"] = False  # a live input given again brings the window back
    joy = stored.get("joystick") or {}
    for f, key in [*STORED.items(), *JOYSTICK.items()]:
        if got[f] is None:
            got[f] = (joy if f in JOYSTICK else stored).get(key)
        if got[f] is None:
            got[f] = DEFAULTS.get(f)
    got["input_kind"] = got["input_kind"] or DEFAULT_INPUTS[bool(got["headless"])]
    return replace(req, **got)


def headless_inputs() -> str:
    """``--input model or --input scripted``: the kinds that run without a window."""
    return " or ".join(f"--input {k}" for k in kinds.session_inputs()
                       if not kinds.input_kind(k).display)


def check_options(r: RunRequest, given: bool = False) -> None:
    """Refuse an unknown input, a window input without a window, an unknown belt URL,
    an unknown clock; ``given`` (the request as given): ``sim`` with LSL, and (a new
    session) ``sim`` where it cannot be."""
    if r.input_kind is not None and kinds.input_kind(r.input_kind).display and r.headless:
        raise ConfigError(f"--input {r.input_kind} needs the experiment window; drop "
                          f"--headless, or use {headless_inputs()}")
    if r.belt_url is not None:
        parse_url(r.belt_url)
    if r.clock is not None:
        check_option("clock", r.clock, CLOCKS)
    if given and r.clock == "sim" and r.lsl:
        raise ConfigError("--lsl runs on the wall clock (LSL timestamps are real times); "
                          "drop --clock sim")
    if given and r.clock == "sim" and not r.resume:
        clock_kind(headless=bool(r.headless), belt_url=r.belt_url or "sim", clock="sim",
                   input_kind=r.input_kind or DEFAULT_INPUTS[bool(r.headless)])


def no_sim(*, headless: bool, input_kind: str, belt_url: str) -> str | None:
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
    if clock is not None:
        check_option("clock", clock, CLOCKS)
    why = no_sim(headless=headless, input_kind=input_kind, belt_url=belt_url)
    if clock == "sim" and why is not None:
        raise ConfigError(f"--clock sim is for a headless run (--headless) with --input "
                          f"model or scripted on the sim belt; here {why}: use --clock wall")
    return clock or ("sim" if why is None else "wall")


def pick_clock(req: RunRequest, r: RunRequest) -> tuple[str | None, str]:
    """(the clock to store with the session, the clock of this run) of the request
    ``req`` as given and ``r`` resolved: the one given, else the stored one where it
    still fits (a stored ``sim`` does not once the window is back, nor with ``lsl``),
    else the default; ``lsl`` runs on the wall clock."""
    keep = r.clock
    if req.clock is None and keep == "sim" and (req.lsl or no_sim(
            headless=bool(r.headless), input_kind=str(r.input_kind), belt_url=str(r.belt_url))):
        keep = None
    return keep, clock_kind(headless=bool(r.headless), input_kind=str(r.input_kind),
                            belt_url=str(r.belt_url), clock="wall" if req.lsl else keep)


def reuse_lines(req: RunRequest, r: RunRequest, stored: dict[str, Any],
                session: dict[str, Any], n_done: int, clock: str) -> list[str]:
    """What a resumed run says about its options: for each, its value in this run, where
    it comes from (given again, the session's stored one, or the default) and the option
    that overrides it.

    Args:
        req: the request as given (None: not given); ``r``: resolved (:func:`resolve`).
        stored: the options stored with the session (:func:`stored_options`).
        session: the session's row; ``n_done``: its trials done.
        clock: ``sim`` or ``wall``, this run's.
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

    headless = bool(r.headless)
    why = no_sim(headless=headless, input_kind=str(r.input_kind), belt_url=str(r.belt_url))
    clock_how = ("--lsl runs in real time" if req.lsl else "--clock wall"
                 if clock == "sim" else "--clock sim" if why is None else f"none ({why})")
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
        ("calibration", r.calibration_file or "none",
         source(req.calibration_file is not None, "calibration", r.calibration_file),
         "--calibration FILE"),
        ("clock", f"{clock} ({'simulated time' if clock == 'sim' else 'real time'})",
         "--lsl" if req.lsl and req.clock is None else
         source(req.clock is not None, "clock", clock), clock_how),
    ]
    if kinds.input_kind(str(r.input_kind)).stick:
        inv = [a for a, on in (("x", r.invert_x), ("y", r.invert_y)) if on]
        rows.append(("joystick", f"{r.joystick_device or 'the first stick'}, axes "
                     f"{r.axes or '0,1'}, dead zone "
                     f"{0.05 if r.dead_zone is None else r.dead_zone:g}"
                     + (f", {' and '.join(inv)} inverted" if inv else ""),
                     "given" if any(getattr(req, f) is not None for f in JOYSTICK)
                     else "stored",
                     "--joystick, --axes, --dead-zone, --[no-]invert-x, --[no-]invert-y"))
    rows.append(("seed", str(session["seed"]), "stored",
                 "none (the session's schedule is stored)"))
    head = (f"resuming session {session['session_id']} of {r.participant} ({n_done}/"
            f"{session['n_trials']} trials done) with these options:")
    wn, wv, ws = (max(len(row[i]) for row in rows) for i in range(3))
    return [head] + [f"  {name:<{wn}s} {value:<{wv}s}  {src:<{ws}s}  override: {how}"
                     for name, value, src, how in rows]
