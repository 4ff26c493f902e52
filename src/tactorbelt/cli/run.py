"""``tactorbelt run`` (one participant's session) and ``tactorbelt export`` (CSV or BIDS).

The run command opens the store first (a store that is not SQLite, read-only or in
use by another run fails before anything else happens), then the belt (as a context
manager: motors off on every exit path), then the cursor source, and calls
:func:`tactorbelt.experiment.runner.run_session`.

Clocks: ``--headless`` runs with ``--input model`` or ``scripted`` on the simulated
belt use a SimClock (as fast as the CPU allows) unless ``--realtime``; everything else
runs on the wall clock.

Imports click at import time; everything else (NumPy, pydantic, rich, the window,
the model participant) only when a command runs.
"""

from __future__ import annotations

import hashlib
import statistics
from pathlib import Path
from typing import TYPE_CHECKING, Any

import click

from .._errors import ConfigError, StoreError
from ._options import belt_option

if TYPE_CHECKING:
    from ..clock import Clock
    from ..devices.base import Belt
    from ..experiment.study import Study
    from ..inputs.base import CursorSource

__all__ = ["export", "run"]

INPUTS = ("joystick", "mouse", "model", "scripted")


def _model_cursor(belt: Belt, clock: Clock, seed: int, period_s: float) -> CursorSource:
    """The model participant, timed for the study's dynamic period."""
    from ..inputs.model import make_model_cursor
    from ..participant.params import ModelParams

    return make_model_cursor(belt, clock, seed, params=ModelParams().for_period(period_s))


def _window_factory() -> Any:
    """``tactorbelt.gui.session_window``, or None when the window is not available."""
    try:
        from .. import gui
    except ImportError:
        return None
    return getattr(gui, "session_window", None)


def _stable_seed(seed: int, participant: str) -> int:
    h = hashlib.sha256(f"{seed}:{participant}".encode()).digest()
    return int.from_bytes(h[:4], "little")


@click.command("run")
@click.argument("study_file", metavar="STUDY", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--participant", "-p", required=True, help="Participant id (e.g. P01).")
@belt_option()
@click.option("--input", "input_kind", type=click.Choice(INPUTS), default=None,
              help="Cursor source [default: joystick; model with --headless].")
@click.option("--db", type=click.Path(path_type=Path), default=Path("study.sqlite"),
              show_default=True, help="The session store (SQLite).")
@click.option("--resume", is_flag=True,
              help="Continue the participant's unfinished session (its stored schedule).")
@click.option("--new-session", is_flag=True,
              help="Start a new session even though the participant has an unfinished one.")
@click.option("--headless", is_flag=True, help="No window (model or scripted input only).")
@click.option("--limit", type=click.IntRange(min=0), default=None,
              help="Stop after N test trials (the session stays resumable).")
@click.option("--seed", type=click.IntRange(min=0), default=None,
              help="Randomisation seed [default: the study's session.seed].")
@click.option("--realtime", is_flag=True,
              help="Run a headless simulated session on the wall clock (real time).")
@click.option("--fullscreen", is_flag=True, help="Open the window full screen.")
@click.option("--screenshot", "screenshot_dir", type=click.Path(file_okay=False, path_type=Path),
              default=None, help="Save a PNG of each kind of screen into DIR.")
@click.option("--joystick", "joystick_device", default=None,
              help="Which stick: an index or a name substring [default: the first stick "
                   "that is not a throttle].")
@click.option("--axes", default="0,1", show_default=True,
              help="Stick axis indices for left/right and front/back.")
@click.option("--dead-zone", type=click.FloatRange(0.0, 1.0, max_open=True), default=0.05,
              show_default=True, help="Radial dead zone of the stick.")
@click.option("--invert-x", is_flag=True, help="Mirror the stick's left/right axis.")
@click.option("--invert-y", is_flag=True, help="Mirror the stick's front/back axis.")
def run(study_file: Path, participant: str, belt_url: str, input_kind: str | None, db: Path,
        resume: bool, new_session: bool, headless: bool, limit: int | None, seed: int | None,
        realtime: bool, fullscreen: bool, screenshot_dir: Path | None,
        joystick_device: str | None, axes: str, dead_zone: float, invert_x: bool,
        invert_y: bool) -> None:
    """Run a study session for one participant, storing every trial in --db."""
    from ..clock import SimClock, WallClock
    from ..devices import open_belt, parse_url
    from ..experiment.schedule import make_schedule, schedule_from_json
    from ..experiment.store import Store
    from ..experiment.study import load_study

    participant = participant.strip()
    if not participant:
        raise click.BadParameter("must not be empty", param_hint="--participant")
    if resume and new_session:
        raise click.UsageError("--resume and --new-session exclude each other")
    if input_kind is None:
        input_kind = "model" if headless else "joystick"
    if headless and input_kind in ("joystick", "mouse"):
        raise click.UsageError(
            f"--input {input_kind} needs the experiment window; drop --headless, or use "
            "--input model or --input scripted"
        )
    scheme, _ = parse_url(belt_url)
    text = study_file.read_text(encoding="utf-8") if study_file.is_file() else None
    study = load_study(study_file)

    window = None
    if not headless:
        window = _window_factory()
        if window is None:
            if input_kind in ("joystick", "mouse"):
                raise click.UsageError(
                    f"--input {input_kind} needs the experiment window (tactorbelt.gui), "
                    "which is not available in this installation; use --headless with "
                    "--input model or --input scripted"
                )
            click.echo("note: the experiment window is not available; running headless",
                       err=True)
            headless = True

    simulated = headless and input_kind in ("model", "scripted") and not realtime \
        and scheme == "sim"
    clock: Clock = SimClock() if simulated else WallClock()

    with Store.open(db) as store:
        existing = store.find_resumable(participant)
        if resume:
            if existing is None:
                raise StoreError(
                    f"participant {participant!r} has no unfinished session in {db}; "
                    "run without --resume to start one"
                )
            schedule = schedule_from_json(existing["schedule_json"])
            eff_seed = int(existing["seed"])
        else:
            if existing is not None and not new_session:
                done = len(store.finished_indices(existing["session_id"]))
                raise StoreError(
                    f"participant {participant!r} has an unfinished session "
                    f"{existing['session_id']} in {db} ({done}/{existing['n_trials']} trials "
                    f"done, {existing['status']}); continue it with --resume, or start "
                    "another with --new-session"
                )
            eff_seed = study.session.seed if seed is None else seed
            schedule = make_schedule(study, participant, eff_seed)
        with open_belt(belt_url, clock=clock, layout=study.layout_obj()) as belt:
            cursor = _make_cursor(input_kind, study, belt, clock, schedule, eff_seed,
                                  participant)
            kwargs: dict[str, Any] = dict(seed=eff_seed, resume=resume, limit=limit,
                                          study_toml=text, input_name=input_kind)
            try:
                if window is not None:
                    window_options = dict(
                        fullscreen=fullscreen, screenshot_dir=screenshot_dir,
                        joystick=_joystick_config(joystick_device, axes, dead_zone,
                                                  invert_x, invert_y))
                    result = _run_windowed(window, study, participant, input_kind, belt,
                                           cursor, store, clock, kwargs, window_options)
                else:
                    result = _run_headless(study, participant, belt, cursor, store, clock,
                                           kwargs)
            except KeyboardInterrupt:
                click.echo(
                    f"interrupted: the trial in flight was stored as aborted; continue with "
                    f"'tactorbelt run {study_file} --participant {participant} --db {db} "
                    "--resume'", err=True)
                raise click.exceptions.Exit(130) from None
            finally:
                if cursor is not None:
                    cursor.close()
        _report(result, db, store)


def _make_cursor(input_kind: str, study: Study, belt: Belt, clock: Clock,
                 schedule: list[Any], seed: int, participant: str) -> CursorSource | None:
    if input_kind == "scripted":
        from ..inputs.scripted import ScriptedCursor

        return ScriptedCursor(answers={t.trial_index: t.target_deg for t in schedule})
    if input_kind == "model":
        return _model_cursor(belt, clock, _stable_seed(seed, participant), study.stimulus.period_s)
    return None  # joystick / mouse: the window provides it


def _run_headless(study: Study, participant: str, belt: Belt, cursor: CursorSource | None,
                  store: Any, clock: Clock, kwargs: dict[str, Any]) -> Any:
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    from ..experiment.runner import run_session

    assert cursor is not None
    console = Console(stderr=True)
    with Progress("[progress.description]{task.description}", BarColumn(),
                  MofNCompleteColumn(), TimeElapsedColumn(), console=console,
                  disable=not console.is_terminal) as bar:
        task = bar.add_task(f"{participant}", total=study.n_trials())

        def progress(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        return run_session(study, participant, belt, cursor, store, clock,
                           progress=progress, **kwargs)


def _run_windowed(window_factory: Any, study: Study, participant: str, input_kind: str,
                  belt: Belt, cursor: CursorSource | None, store: Any, clock: Clock,
                  kwargs: dict[str, Any], window_options: dict[str, Any]) -> Any:
    """Run with the experiment window (``tactorbelt.gui.session_window``; the window and
    the runner share the main thread: the runner calls ``observer.poll`` every 10 ms)."""
    from ..experiment.runner import run_session

    with window_factory(study, input=input_kind, participant=participant, clock=clock,
                        belt=belt, **window_options) as win:
        src = cursor if cursor is not None else win.cursor
        if src is None:
            raise ConfigError(f"the window gave no cursor for --input {input_kind}")
        return win.run(lambda: run_session(study, participant, belt, src, store, clock,
                                           observer=win.observer, **kwargs))


def _joystick_config(device: str | None, axes: str, dead_zone: float, invert_x: bool,
                     invert_y: bool) -> Any:
    """The stick options as a JoystickConfig (the device by index or name substring)."""
    from ..inputs.joystick import JoystickConfig

    try:
        ax, ay = (int(a) for a in axes.split(","))
    except ValueError:
        raise click.BadParameter(f"expected two axis indices like 0,1, got {axes!r}",
                                 param_hint="--axes") from None
    dev: int | str | None = device
    if device is not None and device.strip().isdigit():
        dev = int(device)
    return JoystickConfig(device=dev, axis_x=ax, axis_y=ay, dead_zone=dead_zone,
                          invert_x=invert_x, invert_y=invert_y)


def _report(result: Any, db: Path, store: Any) -> None:
    test = [r for r in result.results if r.trial.block == "test" and r.status != "aborted"]
    click.echo(f"session {result.session_id}: {result.status}, {result.n_done}/"
               f"{result.n_total} trials done ({result.n_run} this run), stored in {db}")
    for cond in ("static", "dynamic"):
        rs = [r for r in test if r.trial.condition == cond]
        if rs:
            acc = sum(1 for r in rs if r.correct) / len(rs)
            rts = [r.rt_s for r in rs if r.rt_s is not None]
            med = f"{statistics.median(rts):.2f} s" if rts else "n/a (no response)"
            click.echo(f"  {cond:<8s} {len(rs):4d} test trials, accuracy {acc:.1%}, "
                       f"median RT {med}")
    if result.status != "complete":
        click.echo(f"  continue with --resume (session {result.session_id})", err=True)


@click.command("export")
@click.argument("db", type=click.Path(dir_okay=False, path_type=Path))
@click.argument("out", type=click.Path(file_okay=False, path_type=Path))
@click.option("--format", "fmt", type=click.Choice(["csv", "bids"]), default="csv",
              show_default=True, help="Tidy CSV files, or a BIDS-style dataset.")
def export(db: Path, out: Path, fmt: str) -> None:
    """Export the store DB into directory OUT (trials and cursor samples)."""
    from ..experiment.export import export_bids, export_csv

    files = export_csv(db, out) if fmt == "csv" else export_bids(db, out)
    click.echo(f"wrote {len(files)} files to {out}")
