"""``tactorbelt validate stimulus``: the felt stimulus against the intended one.

Parses, calls :func:`tactorbelt.validation.stimulus.run_stimulus`, prints (docs/
validation.md, "The felt stimulus"). Heavy imports are inside the command.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from ..interrupts import Terminated
from ._options import POSITIVE, belt_option, number, output_option
from ._terminal import counting_progress
from ._validate_common import DRIVE, sense_help

__all__ = ["stimulus"]


@click.command("stimulus")
@belt_option("The belt to validate")
@click.option("--sense", "sense_url", default=None, metavar="URL", help=sense_help())
@click.option("--target", "target", type=number(int, 0, 359), default=None, metavar="N",
              help="The target to play, numbered as the study numbers them (0: at 0 deg).")
@click.option("--all", "all_targets", is_flag=True, help="Every target of the study.")
@click.option("--condition", type=click.Choice(["static", "dynamic"]), required=True,
              help="The stimulus condition.")
@DRIVE
@click.option("--study", "study_file", default=None, metavar="FILE",
              help="The study whose layout, targets and [stimulus] (its drive too, unless "
                   "--drive) are played [default: the paper's, plain].")
@click.option("--duration", "duration_s", type=POSITIVE, default=2.0, show_default=True,
              help="Seconds each stimulus plays.")
@click.option("--calibration", "calibration_file", default=None, metavar="FILE",
              help="Drive the belt through this calibration file.")
@output_option("directory", "Directory for stimulus.json and stimulus.png.", required=True)
@click.option("--force", is_flag=True, help="Replace an earlier stimulus.json there.")
def stimulus(belt_url: str, sense_url: str | None, target: int | None, all_targets: bool,
             condition: str, drive: str | None, study_file: str | None, duration_s: float,
             calibration_file: str | None, out: Path, force: bool) -> None:
    """Play a study's stimulus, sense every tactor, and compare felt with intended.

    Writes per tactor the RMS error of the felt envelope against the intended one (the
    law's amplitudes through the tactor's static response, both over its steady amplitude
    at full level) and its onset and offset errors (docs/validation.md). A sensor that
    senses the tactors together (--sense board, one input channel) gets each tactor's
    envelope from a play of the stimulus with every other tactor off. Example:
    `tactorbelt validate stimulus --belt sim:virtual --all --condition dynamic -o out`.
    """
    from ..validation.stimulus import MAX_SKIPPED, run_stimulus

    if (target is None) == (not all_targets):
        raise click.UsageError("give --target N or --all")
    study = None
    if study_file is not None:
        from ..experiment.study import load_study

        study = load_study(study_file)

    def opened(belt: Any, sensor: Any) -> None:
        click.echo(f"validating the {condition} stimulus on {belt.name} ({belt.url}, drive "
                   f"{belt.drive}) sensed by {sensor.description}")

    try:
        with counting_progress("plays") as progress:
            result, paths = run_stimulus(
                belt_url, out, targets=None if all_targets else [int(target or 0)],
                condition=condition, sense_url=sense_url, drive=drive, study=study,
                duration_s=duration_s, force=force, calibration_file=calibration_file,
                progress=progress, on_open=opened)
    except (KeyboardInterrupt, Terminated):
        click.echo("stopped: motors off; nothing written", err=True)
        raise
    click.echo(f"{'target':>6} {'deg':>6}  {'RMS':>6}  tactor: RMS, onset/offset error ms")
    for row in result.targets:
        parts = [f"{t['tactor']}: {t['rms_error']:.3f}, {_err(t['onset_error_ms'])}/"
                 f"{_err(t['offset_error_ms'])}" for t in row["tactors"] if t["driven"]]
        silent = [str(t["tactor"]) for t in row["tactors"] if t["felt"] == "silent"]
        if silent:
            parts.append(f"silent (not played): {','.join(silent)}")
        click.echo(f"{row['target']:>6} {row['target_deg']:>6g}  {row['rms_error']:.3f}  "
                   + "; ".join(parts))
    between = ("" if result.between_tactor_rms_error is None else
               f" (between tactors {result.between_tactor_rms_error:.4f})")
    click.echo(f"RMS error {result.rms_error:.4f}{between}; drive {result.drive}; "
               f"{result.how_sensed}")
    if result.replayed_late:
        click.echo(f"{result.replayed_late} plays were made again: the player skipped more "
                   f"than {MAX_SKIPPED:.0%} of their frames (a busy computer)")
    if result.missed_frames:
        click.echo(f"warning: the player skipped {result.missed_frames} frames of the plays "
                   "measured (a busy computer): the felt envelope shows them late", err=True)
    for what, path in paths.items():
        click.echo(f"wrote {what}: {path}")
    if result.stopped is not None:  # the belt or the sensor failed: what was measured is kept
        from .._errors import DeviceError

        n = len(result.targets)
        raise DeviceError(f"stopped after {n} target{'' if n == 1 else 's'}, {result.stopped} "
                          "(the targets measured before it are written)")
    click.echo("done: motors off")


def _err(v: float | None) -> str:
    return "n/a" if v is None else f"{v:+.1f}"
