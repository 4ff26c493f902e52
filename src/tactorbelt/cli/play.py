"""``tactorbelt play``, ``tactorbelt belt-test`` and ``tactorbelt calibrate``: belts by hand.

- ``play ANGLE``: play a static or dynamic stimulus on a belt (``--stats`` prints the
  player's deadline statistics as one JSON line, last).
- ``belt-test``: pulse each tactor in turn, saying which one, to catch a wrongly wired
  belt before a study.
- ``calibrate``: walk an experimenter through each tactor (the level where it is first
  felt, then a comfortable maximum) and write a calibration file.

Every path ends with the motors off (the belt is a context manager); Ctrl-C stops the
motors and exits with code 130. Heavy imports happen inside the commands.
"""

from __future__ import annotations

import json
import math
import sys
from typing import TYPE_CHECKING, Any

import click

from ._options import (
    AngleCommand,
    belt_option,
    belt_options,
    build_stimulus,
    layout_given,
    load_calibration,
    open_belt_for,
    region_name,
    stimulus_options,
)

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

    from ..devices.base import Belt
    from ..geometry import Layout

__all__ = ["belt_test", "calibrate", "play"]


def _positive(value: float, option: str) -> float:
    if not (math.isfinite(value) and value > 0):
        raise click.BadParameter(f"must be a positive, finite number, got {value!r}",
                                 param_hint=option)
    return value


def _describe(belt: Belt) -> str:
    return f"{belt.name} ({belt.url}, {belt.n_tactors} tactors)"


@click.command(cls=AngleCommand)
@click.argument("angle", metavar="ANGLE")
@stimulus_options
@belt_options
@click.option("--seconds", type=float, default=3.0, show_default=True,
              help="How long to play.")
@click.option("--rate", type=float, default=None,
              help="Stream frames at this rate (Hz) instead of letting a belt that can "
                   "render do it [default: the belt's rate, 1000 Hz; 40 Hz over BLE].")
@click.option("--stats", is_flag=True,
              help="Print the player's deadline statistics as one JSON line, last "
                   "(0 frames when the belt renders the stimulus itself; add --rate).")
def play(angle: str, belt_url: str, calibration_file: str | None, seconds: float,
         rate: float | None, stats: bool, **stim: Any) -> None:
    """Play the stimulus for direction ANGLE (degrees, 0 = navel, clockwise) on a belt.

    Examples: `tactorbelt play 15 --mode dynamic`, `tactorbelt play -30 --belt
    serial:auto --seconds 5`. Ctrl-C stops with the motors off.
    """
    from ..player import Player

    _positive(seconds, "--seconds")
    if rate is not None:
        _positive(rate, "--rate")
    stimulus = build_stimulus(angle, **stim)
    calibration = load_calibration(calibration_file)
    belt, stimulus_on_belt = open_belt_for(belt_url, stimulus,
                                           explicit_layout=layout_given(**stim),
                                           calibration=calibration,
                                           calibration_file=calibration_file)
    assert stimulus_on_belt is not None
    with belt:
        player = Player(belt, rate_hz=rate, device_render=False if rate is not None else None)
        how = ("rendered by the belt" if player.renders_on_device(stimulus_on_belt)
               else f"streamed at {player.rate_hz:g} Hz")
        kind = "on-tactor" if stimulus_on_belt.on_tactor else "between-tactor"
        click.echo(f"playing {stimulus_on_belt.mode} {kind} {stimulus_on_belt.target_deg:g} deg "
                   f"({stimulus_on_belt.law} law) on {_describe(belt)} for {seconds:g} s, {how}")
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
@click.option("--seconds-each", type=float, default=0.5, show_default=True,
              help="How long each tactor vibrates.")
@click.option("--gap", type=float, default=0.25, show_default=True,
              help="Pause between tactors, seconds.")
@click.option("--level", type=float, default=1.0, show_default=True,
              help="Amplitude of each pulse, in (0, 1] (through the calibration).")
def belt_test(belt_url: str, calibration_file: str | None, seconds_each: float, gap: float,
              level: float) -> None:
    """Pulse each tactor in turn, saying which one, to check the wiring.

    Each tactor should be felt where the message says: tactor 0 is the first
    clockwise of the navel (30 deg on the default 6-tactor belt).
    """
    from ..clock import WallClock
    from ..player import Player

    _positive(seconds_each, "--seconds-each")
    if not (math.isfinite(gap) and gap >= 0):
        raise click.BadParameter(f"must be 0 or more, got {gap!r}", param_hint="--gap")
    if not (math.isfinite(level) and 0 < level <= 1):
        raise click.BadParameter(f"must be in (0, 1], got {level!r}", param_hint="--level")
    calibration = load_calibration(calibration_file)
    belt, _ = open_belt_for(belt_url, None, calibration=calibration,
                            calibration_file=calibration_file)
    with belt:
        clock = belt.clock or WallClock()
        player = Player(belt, clock=clock, device_render=False)
        click.echo(f"belt-test on {_describe(belt)}: {seconds_each:g} s per tactor")
        for k, angle in enumerate(belt.tactor_angles_deg):
            click.echo(f"tactor {k} at {angle:g} deg ({region_name(angle)})")
            player.play(_OneTactor(belt.layout, k, level), seconds_each)  # type: ignore[arg-type]
            if gap > 0 and k + 1 < belt.n_tactors:
                clock.sleep_until_ns(clock.now_ns() + round(gap * 1e9))
    click.echo("done: all motors off")


class _OneTactor:
    """A constant frame with one tactor on (duck-types the Stimulus the player needs)."""

    def __init__(self, layout: Layout, k: int, level: float) -> None:
        import numpy as np

        self.layout = layout
        self.frame = np.zeros(layout.n)
        self.frame[k] = level

    def amplitudes(self, t: Any) -> NDArray[np.float64]:
        import numpy as np

        ta = np.asarray(t, dtype=float)
        return np.broadcast_to(self.frame, (*ta.shape, self.frame.shape[0])).copy()


# -- calibrate ----------------------------------------------------------------------------------

_KEYS_HELP = ("keys: + / - = up / down by one step, ] / [ = five steps, enter = accept, "
              "q = quit without saving")


class _Keys:
    """Single key presses from a terminal, or characters from piped input."""

    def __init__(self) -> None:
        self._stdin = sys.stdin
        self._tty = self._stdin.isatty()
        self._last = ""

    def read(self) -> str:
        while True:
            ch = click.getchar() if self._tty else self._stdin.read(1)
            if ch == "":
                raise click.UsageError("input ended before the calibration was finished; "
                                       "nothing was written")
            prev, self._last = self._last, ch
            if ch == "\n" and prev == "\r":  # a CR LF pair is one enter
                continue
            return ch


def _adjust(keys: _Keys, show: Any, level: float, step: float, lo: float) -> float:
    """Let the user move ``level`` within [lo, 1] until enter; returns the level."""
    moves = {"+": 1, "=": 1, "-": -1, "_": -1, "]": 5, "[": -5}
    show(level)
    while True:
        ch = keys.read()
        if ch in ("\r", "\n"):
            return level
        if ch in ("q", "Q"):
            click.echo("calibration abandoned; nothing was written", err=True)
            raise click.exceptions.Exit(1)
        if ch in moves:
            level = round(min(1.0, max(lo, level + moves[ch] * step)), 6)
            show(level)


@click.command()
@belt_option("The belt to calibrate")
@click.option("-o", "--output", default=None, metavar="FILE",
              help="Write the calibration here [default: print it to stdout].")
@click.option("--step", type=float, default=0.02, show_default=True,
              help="Level change per + or - key.")
def calibrate(belt_url: str, output: str | None, step: float) -> None:
    """Walk through each tactor: the level where it is first felt, then a comfortable maximum.

    For each tactor: raise the level with + until the vibration is just felt and
    press enter (that is the tactor's start level, below which it does not spin);
    then raise it to the strongest level that is still comfortable and press enter
    (its ceiling). Works with piped input too: `printf '+++\\n+++++\\n...' |
    tactorbelt calibrate`. Prompts go to stderr; the calibration (TOML) to FILE or
    stdout.
    """
    from ..clock import WallClock
    from ..devices.calibration import Calibration, TactorCalibration
    from ..player import Player

    if not (math.isfinite(step) and 0 < step <= 0.5):
        raise click.BadParameter(f"must be in (0, 0.5], got {step!r}", param_hint="--step")
    keys = _Keys()
    belt, _ = open_belt_for(belt_url, None)
    with belt:
        clock = belt.clock or WallClock()
        # stream on a real clock (a hardware belt's heartbeat needs frames); on a
        # simulated clock just set the levels
        player = None if clock.simulated else Player(belt, clock=clock, device_render=False)
        click.echo(f"calibrating {_describe(belt)}; {_KEYS_HELP}", err=True)
        rows: list[TactorCalibration] = []
        for k, angle in enumerate(belt.tactor_angles_deg):

            def show(level: float, k: int = k) -> None:
                frame = _OneTactor(belt.layout, k, level)
                if player is None:
                    belt.set_amplitudes(frame.frame)
                elif level <= 0:
                    player.stop()
                elif player.playing:
                    player.switch(frame)  # type: ignore[arg-type]
                else:
                    player.start(frame)  # type: ignore[arg-type]
                click.echo(f"  tactor {k}: level {level:.2f}", err=True)

            click.echo(f"tactor {k} at {angle:g} deg ({region_name(angle)}): raise the level "
                       "until you just feel it, then press enter", err=True)
            start = _adjust(keys, show, 0.0, step, 0.0)
            click.echo(f"tactor {k}: now raise it to a comfortable maximum, then press enter",
                       err=True)
            ceiling = _adjust(keys, show, max(start, step), step, start)
            if player is not None:
                player.stop()
            belt.stop()
            rows.append(TactorCalibration(start=start, gain=1.0, ceiling=max(ceiling, start)))
            click.echo(f"tactor {k}: start {start:.2f}, ceiling {max(ceiling, start):.2f}",
                       err=True)
    calibration = Calibration(tuple(rows))
    if output:
        path = calibration.save(output, belt=belt_url, angles_deg=belt.tactor_angles_deg)
        click.echo(f"wrote {path}", err=True)
    else:
        click.echo(calibration.to_toml(belt=belt_url, angles_deg=belt.tactor_angles_deg), nl=False)
