"""The ``tactorbelt`` command.

Subcommands live in their own modules and are imported only when run, so that
``tactorbelt --help`` starts fast (no NumPy, matplotlib, pygame, pyserial or bleak).

Exit status, one rule for every command (also in ``tactorbelt --help``): 0 finished;
130 stopped by the user (Ctrl-C; the window's Esc Esc or Ctrl-Q); 143 terminated
(SIGTERM) and 129 (SIGHUP), with the motors off and the trial in flight stored
``aborted``; 2 a usage or user error (``error: ...`` on stderr); 3 a device error. A
user's own stop prints no ``error:`` line. Never a traceback (set
``TACTORBELT_DEBUG=1`` to see one).
"""

from __future__ import annotations

import logging
import os
import sys
from typing import Any

import click

from .._errors import DeviceError, TactorbeltError
from .._registry import resolve
from ..interrupts import Terminated, terminate_on_signals

__all__ = ["COMMANDS", "EXIT_CODES", "main"]

#: The exit statuses of every command.
EXIT_CODES = """Exit status: 0 finished; 130 stopped by the user (Ctrl-C, or Esc Esc / Ctrl-Q in
the experiment window); 143 terminated by SIGTERM, 129 by SIGHUP (motors off, the trial in
flight stored as aborted); 2 usage or user error; 3 device error."""

#: name -> ("module:attribute", one-line help). The help is shown without importing.
COMMANDS: dict[str, tuple[str, str]] = {
    "render": ("tactorbelt.cli.render:render", "Render a stimulus to CSV, JSON or PNG."),
    "figure": ("tactorbelt.cli.render:figure", "Draw the paper's figures (amplitude law)."),
    "play": ("tactorbelt.cli.play:play", "Play a stimulus on a belt."),
    "belt-test": ("tactorbelt.cli.play:belt_test", "Pulse each tactor in turn to check wiring."),
    "calibrate": ("tactorbelt.cli.calibrate:calibrate", "Walk through each tactor's calibration."),
    "devices": ("tactorbelt.cli.devices:devices", "List serial ports and BLE belts."),
    "firmware": ("tactorbelt.cli.firmware:firmware",
                 "Export, build or upload the belt's firmware (Nano 33 BLE)."),
    "study": ("tactorbelt.cli.study:study", "Write or check a study file."),
    "run": ("tactorbelt.cli.run:run", "Run a study session for one participant."),
    "export": ("tactorbelt.cli.run:export",
               "Export a store: CSV, BIDS, Parquet, a table for R and JASP, PsychoPy CSV."),
    "sync": ("tactorbelt.cli.sync:sync", "Push a local store's missing trials to PostgreSQL."),
    "demo": ("tactorbelt.cli.demo:demo", "Run the paper's study with model participants."),
    "power": ("tactorbelt.cli.power:power", "Plan a study's size by simulation."),
    "analyze": ("tactorbelt.cli.analyze:analyze",
                "Analyze one or more stores and write the report."),
    "point": ("tactorbelt.cli.point:point", "Keep a bearing displayed on a belt."),
    "validate": ("tactorbelt.cli.validate:validate", "Check a belt's onsets against a sensor."),
    "pattern": ("tactorbelt.cli.pattern:pattern",
                "Import, play, export or draw haptic patterns (AHAP, .haptic, .tact)."),
    "serve": ("tactorbelt.cli.serve:serve",
              "Serve a browser study (jsPsych) through a local WebSocket bridge to a belt."),
}


class LazyGroup(click.Group):
    """A group whose subcommands are imported on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return list(COMMANDS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in COMMANDS:
            return None
        target, _ = COMMANDS[cmd_name]
        try:
            command: click.Command = resolve(target)
        except ModuleNotFoundError as exc:
            if exc.name == target.partition(":")[0]:
                raise click.UsageError(f"command {cmd_name!r} is not available yet") from None
            raise
        return command

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        rows = [(name, short) for name, (_, short) in COMMANDS.items()]
        with formatter.section("Commands"):
            formatter.write_dl(rows)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]},
             epilog=EXIT_CODES)
@click.version_option(package_name="tactorbelt", message="tactorbelt %(version)s")
def cli() -> None:
    """tactorbelt: directions between the motors of a vibrotactile belt.

    Everything runs on the simulated belt (`--belt sim`) unless told otherwise.
    """


class _OncePerMessage(logging.Filter):
    """Print each warning once: a lost belt is reported by several threads."""

    def __init__(self) -> None:
        super().__init__()
        self._seen: set[str] = set()

    def filter(self, record: logging.LogRecord) -> bool:
        message = record.getMessage()
        if message in self._seen:
            return False
        self._seen.add(message)
        return True


def _setup_logging(debug: bool) -> None:
    """Library warnings go to stderr as ``warning: ...`` (each once)."""
    logger = logging.getLogger("tactorbelt")
    if any(getattr(h, "_tactorbelt_cli", False) for h in logger.handlers):
        return
    handler = logging.StreamHandler()
    handler.setFormatter(logging.Formatter("%(levelname)s: %(message)s"))
    handler.addFilter(_OncePerMessage())
    handler._tactorbelt_cli = True  # type: ignore[attr-defined]
    logger.addHandler(handler)
    logger.setLevel(logging.DEBUG if debug else logging.WARNING)
    logger.propagate = False
    logging.addLevelName(logging.WARNING, "warning")


def main(argv: list[str] | None = None) -> Any:
    """Entry point: run the CLI and turn every error into a message and an exit code."""
    debug = bool(os.environ.get("TACTORBELT_DEBUG"))
    _setup_logging(debug)
    try:
        with terminate_on_signals():
            rv = cli.main(args=argv, prog_name="tactorbelt", standalone_mode=False)
        # click returns (rather than raises) the code of ctx.exit(code) here
        if isinstance(rv, int) and not isinstance(rv, bool):
            sys.exit(rv)
        return rv
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except Terminated as exc:
        sys.exit(exc.exit_code)
    except click.exceptions.Abort as exc:
        # click turns Ctrl-C into Abort: the user's own stop, no error line
        if not isinstance(exc.__cause__, KeyboardInterrupt):
            click.echo("error: aborted (input ended)", err=True)
        sys.exit(130)
    except click.ClickException as exc:
        if isinstance(exc, click.UsageError) and exc.ctx is not None and debug:
            click.echo(exc.ctx.get_usage(), err=True)
        msg = exc.format_message()
        if isinstance(exc, click.UsageError) and exc.ctx is not None:
            msg += f" (see 'tactorbelt {exc.ctx.command_path.partition(' ')[2]} --help')".replace(
                "tactorbelt  ", "tactorbelt "
            )
        click.echo(f"error: {msg}", err=True)
        sys.exit(exc.exit_code if exc.exit_code != 1 else 2)
    except TactorbeltError as exc:
        if debug:
            raise
        click.echo(f"error: {exc}", err=True)
        sys.exit(3 if isinstance(exc, DeviceError) else 2)
    except KeyboardInterrupt:
        sys.exit(130)
    except BrokenPipeError:
        sys.exit(0)
