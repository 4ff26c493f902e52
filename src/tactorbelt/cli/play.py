"""``tactorbelt play`` and ``tactorbelt belt-test``: belts by hand.

- ``play ANGLE``: play a static or dynamic stimulus on a belt (``--stats`` prints the
  player's deadline statistics as one JSON line, last).
- ``belt-test``: pulse each tactor in turn, saying which one, to catch a wrongly wired
  belt before a study.

``tactorbelt calibrate`` is in :mod:`.calibrate`.

Every path ends with the motors off; Ctrl-C exits 130. Heavy imports are inside commands.
"""

from __future__ import annotations

import json
from typing import Any

import click

from ..devices import open_belt_for
from ._options import (
    POSITIVE,
    AngleCommand,
    belt_options,
    build_stimulus,
    layout_given,
    load_calibration,
    number,
    stimulus_options,
)
from ._terminal import describe_belt
from ._types import AliasOption

__all__ = ["belt_test", "play"]


@click.command(cls=AngleCommand)
@click.argument("angle", metavar="ANGLE")
@stimulus_options()
@belt_options
@click.option("--seconds", type=POSITIVE, default=3.0, show_default=True,
              help="How long to play.")
@click.option("--rate", type=POSITIVE, default=None,
              help="Stream frames at this rate (Hz) instead of letting a belt that can "
                   "render do it [default: the belt's rate, 1000 Hz; 40 Hz over BLE].")
@click.option("--stats", is_flag=True,
              help="Print the player's deadline statistics as one JSON line, last "
                   "(0 frames when the belt renders the stimulus itself; add --rate).")
@click.option("--profile", "profile_file", default=None, metavar="FILE",
              help="Render for this wearer's profile (TOML, from `tactorbelt calibrate "
                   "perceptual -o`).")
@click.option("--drive", type=click.Choice(["plain", "shaped"]), default=None,
              help="Play plain, or shaped: overdrive kicks and brake pulses (docs/belts.md) "
                   "[default: the belt's].")
def play(angle: str, belt_url: str, calibration_file: str | None, seconds: float,
         rate: float | None, stats: bool, profile_file: str | None, drive: str | None,
         **stim: Any) -> None:
    """Play the stimulus for direction ANGLE (degrees, 0 = navel, clockwise) on a belt.

    Examples: `tactorbelt play 15 --mode dynamic`, `tactorbelt play -30 --belt
    serial:auto --seconds 5`. Ctrl-C stops with the motors off.
    """
    from ..player import Player

    stimulus = build_stimulus(angle, **stim)
    calibration = load_calibration(calibration_file)
    profile = None
    if profile_file is not None:
        from ..wearer import WearerProfile

        profile = WearerProfile.load(profile_file)
    belt, stimulus_on_belt = open_belt_for(belt_url, stimulus,
                                           explicit_layout=layout_given(**stim),
                                           calibration=calibration,
                                           calibration_file=calibration_file)
    assert stimulus_on_belt is not None
    with belt:
        if drive is not None:
            belt.set_drive(drive)
        if profile is not None:  # refused here when measured on another layout
            profile.check_layout(belt.layout, source=str(profile_file))
            stimulus_on_belt = stimulus_on_belt.with_profile(profile)
        player = Player(belt, rate_hz=rate, device_render=False if rate is not None else None)
        how = ("rendered by the belt" if player.renders_on_device(stimulus_on_belt)
               else f"streamed at {player.rate_hz:g} Hz")
        kind = "on-tactor" if stimulus_on_belt.on_tactor else "between-tactor"
        click.echo(f"playing {stimulus_on_belt.mode} {kind} {stimulus_on_belt.target_deg:g} deg "
                   f"({stimulus_on_belt.law} law) on {describe_belt(belt)} for {seconds:g} s, {how}"
                   + (f", for wearer {profile.participant or '(unnamed)'}" if profile else "")
                   + (f", drive {belt.drive}" if belt.can_shape else ""))
        try:
            result = player.play(stimulus_on_belt, seconds)
        except KeyboardInterrupt:
            result = player.stop()
            click.echo("stopped: motors off", err=True)
            if stats:
                click.echo(json.dumps(result.to_dict()))
            raise
    click.echo("done: motors off")
    if stats:
        click.echo(json.dumps(result.to_dict()))


@click.command("belt-test")
@belt_options
@click.option("--seconds", "seconds_each", cls=AliasOption, hidden_aliases=("--seconds-each",),
              type=POSITIVE, default=0.5, show_default=True,
              help="How long each tactor vibrates.")
@click.option("--gap", type=number(float, 0), default=0.25, show_default=True,
              help="Pause between tactors, seconds.")
@click.option("--level", type=number(float, 0, 1, lo_open=True), default=1.0,
              show_default=True, help="Amplitude of each pulse (through the calibration).")
def belt_test(belt_url: str, calibration_file: str | None, seconds_each: float, gap: float,
              level: float) -> None:
    """Pulse each tactor in turn, saying which one, to check the wiring.

    Each tactor should be felt where the message says: tactor 0 is the first
    clockwise of the navel (30 deg on the default 6-tactor belt).
    """
    from ..calibration.motor import pulse_each
    from ..clock import WallClock

    calibration = load_calibration(calibration_file)
    from ..geometry import region_name

    belt, _ = open_belt_for(belt_url, None, calibration=calibration,
                            calibration_file=calibration_file)
    with belt:
        clock = belt.clock or WallClock()
        click.echo(f"belt-test on {describe_belt(belt)}: {seconds_each:g} s per tactor")
        pulse_each(belt, clock, seconds_each=seconds_each, gap=gap, level=level,
                   say=lambda k, angle: click.echo(
                       f"tactor {k} at {angle:g} deg ({region_name(angle)})"))
    click.echo("done: all motors off")
