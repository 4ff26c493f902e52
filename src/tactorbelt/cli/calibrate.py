"""``tactorbelt calibrate``: walk an experimenter through each tactor (the level where it
is first felt, then a comfortable maximum) and write a calibration file; ``calibrate
perceptual`` (:mod:`.perceptual`) measures a wearer's profile.

Every path ends with the motors off; Ctrl-C exits 130. Heavy imports are inside commands.
"""

from __future__ import annotations

from pathlib import Path

import click

from ..devices import open_belt_for
from ._options import belt_option, number, output_option
from ._terminal import Keys, describe_belt
from .perceptual import perceptual

__all__ = ["calibrate"]


@click.group(invoke_without_command=True)
@belt_option("The belt to calibrate")
@output_option("file", "Write the calibration here [default: print it to stdout].")
@click.option("--step", type=number(float, 0, 0.5, lo_open=True), default=0.02,
              show_default=True, help="Level change per + or - key.")
@click.pass_context
def calibrate(ctx: click.Context, belt_url: str, out: Path | None, step: float) -> None:
    """Walk through each tactor: the level where it is first felt, then a comfortable maximum.

    `tactorbelt calibrate perceptual` measures a wearer's perceptual profile instead.

    For each tactor: raise the level with + until the vibration is just felt and
    press enter (that is the tactor's start level, below which it does not spin);
    then raise it to the strongest level that is still comfortable and press enter
    (its ceiling). Works with piped input too: `printf '+++\\n+++++\\n...' |
    tactorbelt calibrate`. Prompts go to stderr; the calibration (TOML) to FILE or
    stdout.
    """
    if ctx.invoked_subcommand is not None:
        return
    from ..calibration.motor import KEYS_HELP, CalibrationQuit, walk_calibration
    from ..clock import WallClock

    keys = Keys()
    from ..geometry import region_name

    belt, _ = open_belt_for(belt_url, None)
    with belt:
        clock = belt.clock or WallClock()
        click.echo(f"calibrating {describe_belt(belt)}; {KEYS_HELP}", err=True)
        try:
            calibration = walk_calibration(belt, clock, keys.read, step,
                                           lambda line: click.echo(line, err=True),
                                           region=region_name)
        except CalibrationQuit as exc:
            click.echo(str(exc), err=True)
            raise click.exceptions.Exit(1) from None
    if out:
        path = calibration.save(out, belt=belt_url, angles_deg=belt.tactor_angles_deg)
        click.echo(f"wrote {path}", err=True)
    else:
        click.echo(calibration.to_toml(belt=belt_url, angles_deg=belt.tactor_angles_deg), nl=False)


calibrate.add_command(perceptual)
