"""``tactorbelt point``: keep a bearing displayed on a belt as the wearer's heading changes.

Headings come from a file or stdin (``--heading-from``): one number per line, or a CSV
with a header that has a ``heading_deg`` column and optionally a ``t_s`` column
(seconds). A file is replayed at its timestamps (or at ``--heading-rate`` without
them); stdin is applied as lines arrive. ``--sweep`` turns the displayed direction
slowly round the body instead. The run ends when the headings end, after ``--seconds``,
or on Ctrl-C; the motors are off on every way out.

Imports click at import time; NumPy and the belt only when the command runs.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import click

from .._errors import ConfigError
from ..display.heading import HeadingSample, read_headings
from ._options import FLOAT, POSITIVE, belt_option, number, stimulus_options

__all__ = ["point"]


@click.command()
@belt_option()
@click.option("--bearing", type=FLOAT, default=None,
              help="Direction to keep displayed, degrees clockwise from the heading's "
                   "reference (north); without --heading-from, a body angle.")
@click.option("--heading-from", "heading_from", default=None, metavar="FILE|-",
              help="Headings: one number per line, or CSV with a header t_s,heading_deg; "
                   "'-' reads stdin as lines arrive.")
@click.option("--heading-rate", type=POSITIVE, default=10.0, show_default=True,
              help="Replay rate (Hz) of a heading file without timestamps.")
@click.option("--sweep", is_flag=True,
              help="Turn the displayed direction slowly round the body.")
@click.option("--sweep-period", type=POSITIVE, default=20.0, show_default=True,
              help="Seconds per turn of --sweep.")
@click.option("--seconds", type=POSITIVE, default=None, help="Stop after this many seconds.")
@stimulus_options("mode", "law", "falloff", "period", "transit")
@click.option("--slew", type=POSITIVE, default=180.0, show_default=True,
              help="Top speed of the displayed direction, deg/s.")
@click.option("--hysteresis", type=number(float, 0), default=4.0, show_default=True,
              help="Margin past a tactor's sector before the cue changes tactor, degrees.")
@click.option("--stream", is_flag=True,
              help="Stream frames from the host even if the belt can render itself.")
@click.option("--profile", "profile_file", default=None, metavar="FILE",
              help="Render for this wearer's profile (TOML, from `tactorbelt calibrate "
                   "perceptual -o`); streamed.")
@click.option("--drive", type=click.Choice(["plain", "shaped"]), default=None,
              help="Play plain, or shaped: overdrive kicks and brake pulses (docs/belts.md) "
                   "[default: the belt's].")
@click.option("-q", "--quiet", is_flag=True, help="Print nothing but errors.")
def point(belt_url: str, bearing: float | None, heading_from: str | None,
          heading_rate: float, sweep: bool, sweep_period: float, seconds: float | None,
          mode: str, law: str, falloff: float, period: float, transit: float, slew: float,
          hysteresis: float, stream: bool, profile_file: str | None, drive: str | None,
          quiet: bool) -> None:
    """Keep a bearing displayed on a belt while the wearer's heading changes.

    The belt shows BEARING - HEADING (0 = navel, clockwise). Examples:

      tactorbelt point --bearing 90 --seconds 10

      tactorbelt point --bearing 45 --heading-from track.csv

      my-compass | tactorbelt point --belt ble:Belt --bearing 45 --heading-from -

      tactorbelt point --sweep --sweep-period 20

    Ends when the headings end, after --seconds (exit 0), or on Ctrl-C (exit 130); motors
    off.
    """
    from ..geometry import Layout, parse_angle
    from ..stimuli import make_stimulus

    # -- validate everything before touching the belt --------------------------------------
    if sweep and bearing is not None:
        raise click.UsageError("give either --bearing DEG or --sweep, not both")
    if not sweep and bearing is None:
        raise click.UsageError("give --bearing DEG (the direction to show) or --sweep")
    if sweep and heading_from is not None:
        raise click.UsageError("--heading-from needs --bearing, not --sweep")
    bearing_deg = parse_angle(bearing, "--bearing") if bearing is not None else 0.0
    display_opts: dict[str, Any] = {
        "mode": mode, "law": law, "falloff_deg": falloff, "period_s": period,
        "transit_s": transit, "slew_deg_per_s": slew, "hysteresis_deg": hysteresis,
    }
    make_stimulus(Layout.even(6), 0.0, mode, law, display_opts["falloff_deg"],
                  display_opts["period_s"], display_opts["transit_s"])
    if profile_file is not None:
        from ..wearer import WearerProfile

        profile = WearerProfile.load(profile_file)
        display_opts["profile"] = profile
    samples: list[HeadingSample] | None = None
    timed = False
    if heading_from is not None and heading_from != "-":
        samples, timed = read_headings(Path(heading_from))

    from ..devices import open_belt
    from ..display import DirectionDisplay
    from ..display.heading import run_point

    say = (lambda msg: None) if quiet else (lambda msg: click.echo(msg, err=True))
    with open_belt(belt_url) as belt:
        if drive is not None:
            belt.set_drive(drive)
        if stream:
            display_opts["device_render"] = False
        if profile_file is not None:
            profile.check_layout(belt.layout, source=profile_file)
        display = DirectionDisplay(belt, **display_opts)
        if display.clock.simulated and seconds is None and heading_from is None:
            raise ConfigError(f"belt {belt.url!r} runs on a simulated clock, where only "
                              "--seconds (or the end of --heading-from) ends the run; "
                              "give --seconds")
        how = "device rendering" if display.device_render else \
            f"streaming at {display.rate_hz:g} Hz"
        what = "a sweep" if sweep else f"bearing {bearing_deg:g} deg"
        say(f"showing {what} on {belt.url} ({belt.n_tactors} tactors, {mode}, {law} law, "
            f"{how}{', drive ' + belt.drive if belt.can_shape else ''}); Ctrl-C stops")
        report = run_point(display, bearing_deg=bearing_deg,
                           sweep_s=sweep_period if sweep else None, samples=samples,
                           timed=timed, rate_hz=heading_rate, from_stdin=heading_from == "-",
                           limit_s=seconds, quiet=quiet)
    say(f"{'stopped (Ctrl-C)' if report.interrupted else 'done'} after "
        f"{report.elapsed_s:.1f} s: {report.headings} headings, {report.sent}; motors off")
    if report.interrupted:
        raise click.exceptions.Exit(130)

