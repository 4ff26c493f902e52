"""``tactorbelt validate``: check a belt against a sensor before a study.

- ``validate onsets``: pulse each tactor, sense it, and report per tactor the latency
  (command to 10 % of the steady vibration), the 10-90 % rise, the 90-10 % fall and the
  amplitude against level; ``validation.json`` and ``onsets.png`` in the output
  directory, the timings into ``--calibration FILE`` (docs/validation.md); ``--drive``
  plain or shaped, ``--tune`` fits the shaping;
- ``validate stimulus``: play a study's stimuli, sense every tactor, compare felt with
  intended; ``stimulus.json`` and ``stimulus.png``.

Parses, calls :func:`tactorbelt.validation.run.run_onsets` or
:func:`tactorbelt.validation.stimulus.run_stimulus`, prints. Ctrl-C and SIGTERM
stop with the motors off (the belt's ``with`` block) and write nothing. Heavy imports are
inside the command.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from ..interrupts import Terminated
from ._options import POSITIVE, belt_option, number, output_option
from ._terminal import counting_progress
from ._validate_common import DRIVE as _DRIVE
from ._validate_common import sense_help as _sense_help

__all__ = ["validate"]


def _levels(ctx: click.Context, param: click.Parameter, value: str) -> tuple[float, ...]:
    from .._errors import ConfigError
    from ..validation.run import parse_levels

    try:
        return parse_levels(value)
    except ConfigError as exc:
        raise click.BadParameter(f"{exc}".replace("levels must be", "must be"),
                                 ctx, param) from None




def _ms(mean: float | None, sd: float | None) -> str:
    return "n/a" if mean is None else f"{mean:7.1f} ± {sd or 0.0:4.1f}"


@click.group("validate")
def validate() -> None:
    """Check a belt's timing against a sensor before a study (docs/validation.md)."""


@validate.command("onsets")
@belt_option("The belt to validate")
@click.option("--sense", "sense_url", default=None, metavar="URL", help=_sense_help())
@click.option("--pulses", type=number(int, 1, 1000), default=10, show_default=True,
              help="Pulses of each tactor at each level.")
@click.option("--levels", default="1.0", show_default=True, metavar="LIST",
              callback=_levels, help="Amplitudes pulsed, in (0, 1], comma-separated "
              "(through the calibration), e.g. 0.5,1.0.")
@click.option("--on", "on_s", type=POSITIVE, default=0.3, show_default=True,
              help="Seconds each pulse is on (the vibration must settle).")
@click.option("--off", "off_s", type=POSITIVE, default=0.3, show_default=True,
              help="Seconds each tactor rests after a pulse (its vibration must stop).")
@click.option("--calibration", "calibration_file", default=None, metavar="FILE",
              help="Drive the belt through this calibration file and write the measured "
                   "timings into it (in place; created when missing).")
@_DRIVE
@click.option("--tune", is_flag=True, help="Validate plain, fit each tactor's time constants, "
              "write them into --calibration FILE, and validate again shaped.")
@output_option("directory", "Directory for validation.json and onsets.png.", required=True)
@click.option("--force", is_flag=True, help="Replace an earlier validation.json there.")
def onsets(belt_url: str, sense_url: str | None, pulses: int, levels: tuple[float, ...],
           on_s: float, off_s: float, calibration_file: str | None, drive: str | None,
           tune: bool, out: Path, force: bool) -> None:
    """Pulse each tactor, sense it, and measure its latency, rise and fall.

    The latency runs from the command (the onset a study stores) to 10 % of the steady
    vibration. Examples: `tactorbelt validate onsets --belt sim:virtual -o val`,
    `tactorbelt validate onsets --belt serial:auto --sense "audio:USB?channel=0"
    --levels 0.5,1.0 --calibration belt.toml -o val`. Ctrl-C stops with the motors off.
    """
    from ..validation.run import OnsetSettings, run_onsets

    settings = OnsetSettings(pulses=pulses, levels=levels, on_s=on_s, off_s=off_s)

    def opened(belt: Any, sensor: Any) -> None:
        n = len(levels) * pulses * belt.n_tactors
        click.echo(f"validating onsets of {belt.name} ({belt.url}, {belt.n_tactors} tactors, "
                   f"drive {belt.drive}) sensed by {sensor.description}: {n} pulses of "
                   f"{on_s:g} s")

    try:
        with counting_progress("pulses") as progress:
            result, paths = run_onsets(belt_url, out, sense_url=sense_url, settings=settings,
                                       calibration_file=calibration_file, force=force,
                                       progress=progress, on_open=opened, drive=drive,
                                       tune=tune)
    except (KeyboardInterrupt, Terminated):
        click.echo("stopped: motors off; nothing written", err=True)
        raise
    if result.plain is not None:
        click.echo("plain:")
        _table(result.plain)
        click.echo("fitted time constants (ms): " + "; ".join(
            f"tactor {f['tactor']}: rise {f['rise_tau_ms']:.1f}, fall {f['fall_tau_ms']:.1f}"
            for f in result.shaping or []))
        click.echo("shaped, with them:")
    _table(result)
    if result.repeats:
        click.echo(f"{len(result.repeats)} pulse(s) repeated: samples lost "
                   f"({result.repeats[0]['reason']})")
    for warning in result.warnings:
        click.echo(f"warning: {warning}", err=True)
    click.echo(f"onsets from {result.onset_reference}; method: {result.method}; "
               f"drive: {result.drive}")
    for what, path in paths.items():
        click.echo(f"wrote {what}: {path}")
    if result.stopped is not None:  # the belt or the sensor failed: what was measured is kept
        from .._errors import DeviceError

        unchanged = "" if calibration_file is None else "; the calibration file is unchanged"
        raise DeviceError(f"stopped at {result.stopped} (the pulses measured are written"
                          f"{unchanged})")
    click.echo("done: motors off")


def _table(result: Any) -> None:
    click.echo(f"{'tactor':>6}  {'latency ms':>14}  {'rise 10-90 ms':>14}  "
               f"{'fall 90-10 ms':>14}  amplitude by level")
    for t in result.tactors:
        d = t.to_dict()
        amps = ", ".join(f"{lv:g}: {a:.3g}" for lv, a in zip(d["levels"], d["amplitudes"],
                                                             strict=True))
        click.echo(f"{t.tactor:>6}  {_ms(d['latency_ms'], d['latency_sd_ms']):>14}  "
                   f"{_ms(d['rise_ms'], d['rise_sd_ms']):>14}  "
                   f"{_ms(d['fall_ms'], d['fall_sd_ms']):>14}  {amps}")
        fit = d["linearity"]
        if fit is not None:
            click.echo(f"{'':>6}  amplitude = {fit['slope']:.3g} x level "
                       f"{fit['intercept']:+.3g} (r^2 {fit['r2']:.4f})")


from .validate_stimulus import stimulus as _stimulus  # noqa: E402 - after the group

validate.add_command(_stimulus)
