"""``tactorbelt run`` (one participant's session); ``export`` lives in ``cli/export.py``
(imported here for the command table).

The run command passes the options given (by their names) into a
:class:`tactorbelt.app.request.RunRequest` and calls :func:`tactorbelt.app.run.run_study`;
:mod:`tactorbelt.app.request` holds the rules (session, resume, clock). Options not given
are left out, so ``--resume`` reuses what the session stored (and says which, with the
option that overrides each).

Imports click at import time; everything else only when a command runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from ..inputs.kinds import session_inputs
from ._options import belt_options, number, seed_option
from ._terminal import counting_progress
from .export import export

__all__ = ["export", "run"]


@click.command("run")
@click.argument("study_file", metavar="STUDY", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--participant", "-p", required=True,
              help="Participant id: letters, digits, '-' or '_' (e.g. P01).")
@belt_options
@click.option("--input", "input_kind", type=click.Choice(session_inputs()), default=None,
              help="Cursor source [default: joystick; model with --headless].")
@click.option("--db", default="study.sqlite", show_default=True, metavar="STORE",
              help="The session store (SQLite), written first; postgresql://user@host/db: "
                   "push there, with the local store STUDY.sqlite next to the study file.")
@click.option("--push", default=None, metavar="URL",
              help="Also copy each trial to this shared store (postgresql://user@host/db) "
                   "in the background; credentials from ~/.pgpass or PGPASSWORD.")
@click.option("--site", default=None, metavar="NAME",
              help="The lab running the session [default: $TACTORBELT_SITE, else the host "
                   "name].")
@click.option("--offline", is_flag=True,
              help="With --push: run on the local store alone (push later with "
                   "'tactorbelt sync').")
@click.option("--resume", is_flag=True,
              help="Continue the participant's unfinished session (its stored schedule, "
                   "input, belt, window and clock options unless given again; it prints "
                   "them, each with the option that overrides it).")
@click.option("--new-session", is_flag=True,
              help="Start a new session even though the participant has an unfinished or "
                   "a complete one.")
@click.option("--headless/--window", default=None,
              help="--headless: no window (model or scripted input only); --window: the "
                   "experiment window (the default; brings it back on --resume).")
@click.option("--limit", type=number(int, 0), default=None,
              help="Stop after this many test trials (the session stays resumable).")
@seed_option("Randomisation seed [default: the study's session.seed].")
@click.option("--clock", type=click.Choice(("sim", "wall")), default=None,
              help="sim: simulated time, as fast as the CPU allows (a headless model or "
                   "scripted run on the sim belt); wall: real time [default: sim where it "
                   "can be, else wall; on --resume the session's].")
@click.option("--realtime", is_flag=True, hidden=True)  # the old spelling of --clock wall
@click.option("--fullscreen/--no-fullscreen", default=None,
              help="Open the window full screen, or not [default: not].")
@click.option("--screenshot", "screenshot_dir", type=click.Path(file_okay=False, path_type=Path),
              default=None, metavar="DIRECTORY",
              help="Save a PNG of each kind of screen into DIRECTORY.")
@click.option("--joystick", "joystick_device", default=None,
              help="Which stick: an index or a name substring [default: the first stick "
                   "that is not a throttle].")
@click.option("--axes", default="0,1", show_default=True,
              help="Stick axis indices for left/right and front/back.")
@click.option("--dead-zone", type=number(float, 0.0, 1.0, hi_open=True), default=0.05,
              show_default=True, help="Radial dead zone of the stick.")
@click.option("--invert-x/--no-invert-x", default=None,
              help="Mirror the stick's left/right axis, or not.")
@click.option("--invert-y/--no-invert-y", default=None,
              help="Mirror the stick's front/back axis, or not.")
@click.option("--lsl", is_flag=True,
              help="Send Lab Streaming Layer streams: event markers and the cursor (needs "
                   "pylsl; a simulated run then runs in real time).")
@click.option("--lsl-wait", type=number(float, 0.0, 3600.0), default=0.0, show_default=True,
              help="With --lsl: seconds to wait for a recorder (LabRecorder) before the "
                   "first trial; it starts as soon as the markers stream has one.")
@click.option("--lsl-wait-all", is_flag=True,
              help="With --lsl-wait: wait for a consumer of every stream (the cursor too).")
@click.pass_context
def run(ctx: click.Context, **opts: Any) -> None:
    """Run a study session for one participant, storing every trial in --db.

    Exit status: 0 the run ended (complete, or --limit reached), 130 stopped by the
    experimenter (Ctrl-C, Esc Esc or Ctrl-Q in the window), 143 SIGTERM, 129 SIGHUP;
    the session can then be resumed with the command printed.
    """
    from ..app.display import check_display
    from ..interrupts import Terminated

    if opts["lsl_wait"] and not opts["lsl"]:
        raise click.UsageError("--lsl-wait is for --lsl")
    if opts["lsl_wait_all"] and not opts["lsl_wait"]:
        raise click.UsageError("--lsl-wait-all is for --lsl-wait SECONDS")
    if opts["realtime"] and opts["clock"] == "sim":
        raise click.UsageError("--realtime is --clock wall; give --clock once")
    if not opts["participant"].strip():
        raise click.BadParameter("must not be empty", param_hint="--participant")
    check_display(not opts["resume"] and not opts["headless"])  # before the heavy imports
    from ..app.run import RunRequest, resume_command, run_study

    # the options given (not their defaults: --resume reuses the session's stored ones)
    defaults = (None, click.core.ParameterSource.DEFAULT, click.core.ParameterSource.DEFAULT_MAP)
    req = RunRequest(**{name: value for name, value in opts.items()
                        if ctx.get_parameter_source(name) not in defaults})
    try:
        with counting_progress(req.participant) as progress:
            outcome = run_study(req, progress=progress,
                                note=lambda line: click.echo(line, err=True))
    except (KeyboardInterrupt, Terminated) as exc:
        why = "interrupted" if isinstance(exc, KeyboardInterrupt) else f"terminated by {exc.name}"
        click.echo(f"{why}: motors off, a trial in flight is stored as aborted; continue "
                   f"with '{resume_command(req)}'", err=True)
        raise
    out, err = outcome.summary()
    for line in out:
        click.echo(line)
    for line in err:
        click.echo(line, err=True)
    if outcome.result.status == "aborted":
        click.echo(f"stopped by the experimenter; continue with '{resume_command(req)}'",
                   err=True)
        raise click.exceptions.Exit(130)
