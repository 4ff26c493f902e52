"""``tactorbelt render`` and ``tactorbelt figure``: the stimulus engine from the command line."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

import click

from ._options import (
    POSITIVE,
    AngleCommand,
    build_stimulus,
    number,
    output_option,
    stimulus_options,
)


def _write_text(text: str, out: Path | None) -> None:
    if out is None:
        sys.stdout.write(text)
    else:
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(text)
        click.echo(f"wrote {out}", err=True)


@click.command(cls=AngleCommand)
@click.argument("angle", metavar="ANGLE")
@stimulus_options()
@click.option("--rate", type=POSITIVE, default=1000.0, show_default=True,
              help="Samples per second.")
@click.option("--duration", type=POSITIVE, default=None,
              help="Seconds to render [default: one period].")
@click.option("--format", "fmt", type=click.Choice(["csv", "json", "png"]), default="csv",
              show_default=True, help="Output format.")
@output_option("file", "Output file [default: stdout; required for png].")
def render(angle: str, rate: float, duration: float | None, fmt: str, out: Path | None,
           **stim: Any) -> None:
    """Render the stimulus for direction ANGLE (degrees, 0 = navel, clockwise).

    CSV: header t_s,tactor_0,...,tactor_{N-1}, one row per sample at t = i/rate,
    9 decimals. JSON: parameters, times and amplitudes. PNG: amplitude against time.
    """
    stimulus = build_stimulus(angle, **stim)
    duration_s = stimulus.period_s if duration is None else duration
    t, amps = stimulus.render(rate, duration_s)  # checks the rate and the duration
    if fmt == "csv":
        import io

        import numpy as np

        buf = io.StringIO()
        header = "t_s," + ",".join(f"tactor_{k}" for k in range(amps.shape[1]))
        np.savetxt(buf, np.column_stack([t, amps]), delimiter=",", fmt="%.9f",
                   header=header, comments="")
        _write_text(buf.getvalue(), out)
    elif fmt == "json":
        doc = {
            "stimulus": stimulus.describe(),
            "rate_hz": rate,
            "duration_s": duration_s,
            "t_s": [round(float(v), 9) for v in t],
            "amplitudes": [[round(float(v), 9) for v in row] for row in amps],
        }
        _write_text(json.dumps(doc) + "\n", out)
    else:
        if out is None:
            raise click.UsageError("--format png needs -o FILE")
        from ..figures import save_figure, stimulus_figure

        save_figure(stimulus_figure(stimulus, t, amps), out)
        click.echo(f"wrote {out}", err=True)


@click.group()
def figure() -> None:
    """Draw the paper's figures."""


@figure.command("amplitudes")
@stimulus_options("law", "falloff")
@click.option("--tactors", type=number(int, 2), default=None,
              help="Evenly spaced tactors [default: 6].")
@click.option("--tactor-angles", default=None, help="Explicit tactor angles, e.g. 30,90,150.")
@click.option("--targets", type=number(int, 1, 360), default=24, show_default=True,
              help="Number of targets.")
@output_option("file", "PNG file to write.", default=Path("amplitudes.png"))
def figure_amplitudes(law: str, falloff: float, tactors: int | None, tactor_angles: str | None,
                      targets: int, out: Path) -> None:
    """Amplitude of each tactor against target direction (top of the paper's Fig. 1(B))."""
    from ..figures import amplitude_figure, save_figure
    from ..geometry import TargetSet
    from ..laws import check_law
    from ._options import build_layout

    check_law(law, falloff)
    layout = build_layout(tactors, tactor_angles)
    save_figure(amplitude_figure(layout, TargetSet.even(targets), law, falloff), out)
    click.echo(f"wrote {out}")
