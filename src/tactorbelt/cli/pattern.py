"""``tactorbelt pattern``: haptic patterns (docs/patterns.md).

- ``import FILE -o OUT.json``: AHAP, ``.haptic`` or ``.tact`` to ``tactorbelt.pattern/1``,
  saying what each maps to on a belt and what is dropped;
- ``play FILE --belt URL``: play a pattern (or any file ``import`` reads) on a belt;
- ``export FILE --format wav|csv|ahap -o OUT``;
- ``show FILE -o OUT.png``: each tactor's envelope.

Parses options, calls the patterns package, prints. Heavy imports are inside commands.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click

from .._lawnames import LAWS
from ._options import (
    FLOAT,
    POSITIVE,
    belt_options,
    build_layout,
    load_calibration,
    number,
    output_option,
    stimulus_options,
)

__all__ = ["pattern"]

_ANGLE_HELP = ("Where an AHAP or .haptic pattern is placed, degrees (0 = the navel, "
               "clockwise); a .tact keeps its layout's places.")


def _law_option(func: Any) -> Any:
    return click.option("--law", type=click.Choice(LAWS), default=None,
                        help="Amplitude law for angles and paths [default: the pattern's, "
                             "else paper].")(func)


def _layout_options(func: Any) -> Any:
    func = click.option("--tactor-angles", default=None,
                        help="Render on these tactor angles, e.g. 30,90,150,210,270,330.")(func)
    return click.option("--tactors", type=number(int, 2), default=None,
                        help="Render on N evenly spaced tactors [default: the pattern's own "
                             "places (.tact), else 6].")(func)


def _layout(pattern: Any, tactors: int | None, tactor_angles: str | None) -> Any:
    from ..patterns.io import pattern_layout

    given = tactors is not None or tactor_angles is not None
    return pattern_layout(pattern, build_layout(tactors, tactor_angles) if given else None)


def _say_dropped(what: str, notes: list[str]) -> None:
    for note in notes:
        click.echo(f"{what}: {note}")


@click.group()
def pattern() -> None:
    """Haptic patterns: import AHAP, .haptic and .tact; play, export and draw them."""


@pattern.command("import")
@click.argument("file", type=click.Path(dir_okay=False))
@output_option("file", "Write the tactorbelt.pattern/1 JSON here.", required=True)
@click.option("--angle", type=FLOAT, default=0.0, show_default=True, help=_ANGLE_HELP)
def import_(file: str, out: Path, angle: float) -> None:
    """Convert FILE (AHAP .ahap, Meta Haptics Studio .haptic, bHaptics .tact) to a pattern."""
    from ..patterns.ahap import TRANSIENT_MS
    from ..patterns.io import read_any
    from ..patterns.model import save_pattern

    p = read_any(file, angle)
    kind = p.source.get("format", "tactorbelt")
    counts = {k: sum(e.place == k for e in p.events) for k in ("tactor", "angle", "path")}
    if kind in ("ahap", "haptic"):
        where = f"placed at {angle % 360.0:g} deg, rendered with the belt's law"
    elif kind == "tact":
        where = (f"on the vest's columns at {', '.join(f'{a:g}' for a in p.layout_deg)} deg "
                 "(tactor events), paths rendered with the belt's law")
    else:
        where = "as written"
    transients = sum(e.transient for e in p.events)
    taps = f"; {transients} transients as {TRANSIENT_MS:g} ms pulses" if transients else ""
    click.echo(f"{Path(file).name} ({kind}): {len(p.events)} events "
               f"({counts['tactor']} on tactors, {counts['angle']} at angles, {counts['path']} "
               f"paths{taps}), {p.duration_ms:g} ms, {where}")
    _say_dropped("dropped", p.dropped)
    save_pattern(p, out)
    click.echo(f"wrote {out}")


@pattern.command("play")
@click.argument("file", type=click.Path(dir_okay=False))
@belt_options
@click.option("--angle", type=FLOAT, default=0.0, show_default=True, help=_ANGLE_HELP)
@_law_option
@stimulus_options("falloff")
@click.option("--rate", type=POSITIVE, default=None,
              help="Stream at this rate (Hz) [default: the belt's].")
@click.option("--stats", is_flag=True, help="Print the player's deadline statistics as one "
                                            "JSON line, last.")
def play(file: str, belt_url: str, calibration_file: str | None, angle: float,
         law: str | None, falloff: float, rate: float | None, stats: bool) -> None:
    """Play pattern FILE once on a belt. Ctrl-C stops with the motors off."""
    from ..patterns.io import read_any
    from ..patterns.play import play_pattern

    p = read_any(file, angle)

    def started(belt: Any, playback: Any, player: Any) -> None:
        click.echo(f"playing {Path(file).name}: {len(p.events)} events, {p.duration_ms:g} ms "
                   f"on {belt.name} ({belt.url}, {belt.n_tactors} tactors), {playback.law} "
                   f"law, streamed at {player.rate_hz:g} Hz")

    try:
        result = play_pattern(p, belt_url, law=law, falloff_deg=falloff, rate_hz=rate,
                              calibration=load_calibration(calibration_file),
                              calibration_file=calibration_file, source=file, started=started)
    except KeyboardInterrupt:
        click.echo("stopped: motors off", err=True)
        raise
    click.echo("done: motors off")
    if stats:
        click.echo(json.dumps(result.stats.to_dict()))


@pattern.command("export")
@click.argument("file", type=click.Path(dir_okay=False))
@click.option("--format", "fmt", type=click.Choice(["wav", "csv", "ahap"]), required=True,
              help="wav: one channel per tactor (Syntacts, audio belts); csv: t_s,tactor_0,...; "
                   "ahap: Apple Core Haptics (one actuator).")
@output_option("file", "Write the export here.", required=True)
@click.option("--angle", type=FLOAT, default=0.0, show_default=True, help=_ANGLE_HELP)
@_layout_options
@_law_option
@click.option("--rate", type=POSITIVE, default=None,
              help="Samples per second [default: csv 1000, wav 48000].")
@click.option("--carrier-hz", type=number(float, 0), default=250.0, show_default=True,
              help="WAV: the sine each tactor's amplitude modulates (0: the amplitude itself).")
def export(file: str, fmt: str, out: Path, angle: float, tactors: int | None,
           tactor_angles: str | None, law: str | None, rate: float | None,
           carrier_hz: float) -> None:
    """Export pattern FILE as a multichannel WAV, a CSV of amplitudes, or AHAP."""
    from ..patterns.io import export_pattern, read_any

    p = read_any(file, angle)
    layout = _layout(p, tactors, tactor_angles)
    notes = export_pattern(p, fmt, out, layout=layout, law=law, rate_hz=rate,
                           carrier_hz=carrier_hz, source=file)
    _say_dropped("not in the export", notes)
    on = "" if fmt == "ahap" else f" on {layout.n} tactors at {layout.to_list()} deg"
    click.echo(f"wrote {out} ({fmt}{on})")


@pattern.command("show")
@click.argument("file", type=click.Path(dir_okay=False))
@output_option("file", "Write the PNG here.", required=True)
@click.option("--angle", type=FLOAT, default=0.0, show_default=True, help=_ANGLE_HELP)
@_layout_options
@_law_option
def show(file: str, out: Path, angle: float, tactors: int | None, tactor_angles: str | None,
         law: str | None) -> None:
    """Draw each tactor's envelope of pattern FILE to a PNG."""
    from ..patterns.io import read_any, require_events
    from ..patterns.show import show_pattern

    p = read_any(file, angle)
    require_events(p, file)
    path = show_pattern(p, _layout(p, tactors, tactor_angles), out, law, source=file)
    click.echo(f"wrote {path}")
