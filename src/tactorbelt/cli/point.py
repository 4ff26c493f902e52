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

import math
import queue
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

import click

from .._errors import ConfigError
from ._options import belt_option, parse_number

if TYPE_CHECKING:
    from ..display import DirectionDisplay

__all__ = ["HeadingReader", "HeadingSample", "point"]

_HEADING_COLUMNS = ("heading_deg", "heading")
_TIME_COLUMNS = ("t_s", "time_s", "t")
#: How often the sweep moves the requested direction (Hz).
_SWEEP_UPDATE_HZ = 50.0
#: How often the status line is refreshed on a terminal (s).
_STATUS_EVERY_S = 0.25


@dataclass(frozen=True)
class HeadingSample:
    """One heading reading: its line number, time (s, None if the input has none), degrees."""

    line: int
    t_s: float | None
    heading_deg: float


class HeadingReader:
    """Parse heading lines: one number per line, or CSV with a header.

    Blank lines and lines starting with ``#`` are skipped. The first other line is a
    header when it is not a number; the header must name a ``heading_deg`` (or
    ``heading``) column and may name a ``t_s`` (or ``time_s``, ``t``) column.

    Args:
        source: names the input in messages (a path, or ``stdin``).
    """

    def __init__(self, source: str) -> None:
        self.source = source
        self._started = False
        self._heading_col: int | None = None
        self._time_col: int | None = None
        self._n_cols = 1
        self._last_t: float | None = None

    @property
    def has_time(self) -> bool:
        return self._time_col is not None

    def _where(self, line: int) -> str:
        return f"{self.source} line {line}"

    def feed(self, line_no: int, text: str) -> HeadingSample | None:
        """Parse one line; None for blank, comment and header lines.

        Raises:
            ConfigError: a line that is not a heading, naming the line number.
        """
        s = text.strip()
        if not s or s.startswith("#"):
            return None
        fields = [f.strip() for f in s.split(",")]
        if not self._started:
            self._started = True
            if not _is_number(fields[0]):
                self._header(line_no, fields)
                return None
        if len(fields) != self._n_cols:
            if self._heading_col is None:
                raise ConfigError(
                    f"{self._where(line_no)}: expected one heading (a number of degrees) "
                    f"per line, got {s!r}; for several columns start with a header such "
                    "as t_s,heading_deg")
            raise ConfigError(f"{self._where(line_no)}: expected {self._n_cols} fields "
                              f"as in the header, got {len(fields)}: {s!r}")
        hcol = self._heading_col or 0
        raw = fields[hcol]
        if not _is_number(raw):
            raise ConfigError(f"{self._where(line_no)}: heading {raw!r} is not a number "
                              "of degrees")
        heading = float(raw)
        t: float | None = None
        if self._time_col is not None:
            traw = fields[self._time_col]
            if not _is_number(traw):
                raise ConfigError(f"{self._where(line_no)}: time {traw!r} is not a number "
                                  "of seconds")
            t = float(traw)
            if self._last_t is not None and t < self._last_t:
                raise ConfigError(f"{self._where(line_no)}: time {t:g} s is earlier than "
                                  f"the line before ({self._last_t:g} s); times must not "
                                  "decrease")
            self._last_t = t
        return HeadingSample(line_no, t, heading)

    def _header(self, line_no: int, fields: list[str]) -> None:
        names = [f.lower() for f in fields]
        self._n_cols = len(names)
        for name in _HEADING_COLUMNS:
            if name in names:
                self._heading_col = names.index(name)
                break
        else:
            raise ConfigError(
                f"{self._where(line_no)}: {fields[0]!r} is not a heading; a CSV header "
                f"needs a heading_deg column (got {','.join(fields)})")
        for name in _TIME_COLUMNS:
            if name in names:
                self._time_col = names.index(name)
                break


def _is_number(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


def read_headings(path: Path) -> tuple[list[HeadingSample], bool]:
    """All headings of a file, and whether they have times.

    Raises:
        ConfigError: unreadable file, a bad line (with its number), or no heading.
    """
    try:
        text = path.read_text()
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"cannot read headings from {path}: {exc}") from None
    reader = HeadingReader(str(path))
    samples = [s for i, line in enumerate(text.splitlines(), start=1)
               if (s := reader.feed(i, line)) is not None]
    if not samples:
        raise ConfigError(f"{path}: no headings in the file")
    return samples, reader.has_time


def _stdin_lines(stream: IO[str]) -> Iterator[tuple[int, str]]:
    yield from enumerate(stream, start=1)


@click.command()
@belt_option()
@click.option("--bearing", default=None,
              help="Direction to keep displayed, degrees clockwise from the heading's "
                   "reference (north); without --heading-from, a body angle.")
@click.option("--heading-from", "heading_from", default=None, metavar="FILE|-",
              help="Headings: one number per line, or CSV with a header t_s,heading_deg; "
                   "'-' reads stdin as lines arrive.")
@click.option("--heading-rate", default="10", show_default=True,
              help="Replay rate (Hz) of a heading file without timestamps.")
@click.option("--sweep", is_flag=True,
              help="Turn the displayed direction slowly round the body.")
@click.option("--sweep-period", default="20", show_default=True,
              help="Seconds per turn of --sweep.")
@click.option("--seconds", default=None, help="Stop after this many seconds.")
@click.option("--mode", type=click.Choice(["static", "dynamic"]), default="static",
              show_default=True, help="Static amplitudes or the dynamic perturbation.")
@click.option("--law", type=click.Choice(["paper", "linear", "energy"]), default="paper",
              show_default=True, help="Amplitude law.")
@click.option("--falloff", default="15", show_default=True,
              help="T of the paper law, degrees.")
@click.option("--period", default="1.0", show_default=True,
              help="Period of the dynamic perturbation, seconds.")
@click.option("--transit", default="0.1", show_default=True,
              help="Time to move between the two tactors, seconds.")
@click.option("--slew", default="180", show_default=True,
              help="Top speed of the displayed direction, deg/s.")
@click.option("--hysteresis", default="4", show_default=True,
              help="Margin past a tactor's sector before the cue changes tactor, degrees.")
@click.option("--stream", is_flag=True,
              help="Stream frames from the host even if the belt can render itself.")
@click.option("-q", "--quiet", is_flag=True, help="Print nothing but errors.")
def point(belt_url: str, bearing: str | None, heading_from: str | None, heading_rate: str,
          sweep: bool, sweep_period: str, seconds: str | None, mode: str, law: str,
          falloff: str, period: str, transit: str, slew: str, hysteresis: str,
          stream: bool, quiet: bool) -> None:
    """Keep a bearing displayed on a belt while the wearer's heading changes.

    The belt shows BEARING - HEADING (0 = navel, clockwise). Examples:

      tactorbelt point --bearing 90 --seconds 10

      tactorbelt point --bearing 45 --heading-from track.csv

      my-compass | tactorbelt point --belt ble:Belt --bearing 45 --heading-from -

      tactorbelt point --sweep --sweep-period 20

    Ends when the headings end, after --seconds, or on Ctrl-C (exit 0); motors off.
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
    sweep_s = _positive(sweep_period, "--sweep-period")
    rate = _positive(heading_rate, "--heading-rate")
    limit_s = _positive(seconds, "--seconds") if seconds is not None else None
    display_opts: dict[str, Any] = {
        "mode": mode, "law": law,
        "falloff_deg": parse_number(falloff, "--falloff"),
        "period_s": parse_number(period, "--period"),
        "transit_s": parse_number(transit, "--transit"),
        "slew_deg_per_s": _positive(slew, "--slew"),
        "hysteresis_deg": parse_number(hysteresis, "--hysteresis"),
    }
    make_stimulus(Layout.even(6), 0.0, mode, law, display_opts["falloff_deg"],
                  display_opts["period_s"], display_opts["transit_s"])
    samples: list[HeadingSample] | None = None
    timed = False
    if heading_from is not None and heading_from != "-":
        samples, timed = read_headings(Path(heading_from))

    from ..devices import open_belt
    from ..display import DirectionDisplay

    say = (lambda msg: None) if quiet else (lambda msg: click.echo(msg, err=True))
    started = time.monotonic()
    interrupted = False
    with open_belt(belt_url) as belt:
        if stream:
            display_opts["device_render"] = False
        display = DirectionDisplay(belt, **display_opts)
        if display.clock.simulated and limit_s is None and heading_from is None:
            raise ConfigError(f"belt {belt.url!r} runs on a simulated clock, where only "
                              "--seconds (or the end of --heading-from) ends the run; "
                              "give --seconds")
        how = "device rendering" if display.device_render else \
            f"streaming at {display.rate_hz:g} Hz"
        what = "a sweep" if sweep else f"bearing {bearing_deg:g} deg"
        say(f"showing {what} on {belt.url} ({belt.n_tactors} tactors, {mode}, {law} law, "
            f"{how}); Ctrl-C stops")
        run = _Run(display, limit_s, quiet)
        try:
            with display:
                if sweep:
                    run.sweep(sweep_s)
                elif heading_from is None:
                    run.fixed(bearing_deg)
                elif samples is not None:
                    run.replay(bearing_deg, samples, timed, rate)
                else:
                    run.stdin(bearing_deg, sys.stdin, rate)
        except KeyboardInterrupt:
            interrupted = True
        finally:
            run.clear_status()
        elapsed = display.clock.now_ns() / 1e9 - run.t0_s if display.clock.simulated \
            else time.monotonic() - started
        sent = f"{display.plays_sent} PLAY_TARGET" if display.device_render else \
            f"{display.frames_written} frames"
        say(f"{'stopped (Ctrl-C)' if interrupted else 'done'} after {elapsed:.1f} s: "
            f"{run.headings} headings, {sent}; motors off")


def _positive(text: object, what: str) -> float:
    value = parse_number(text, what)
    if value <= 0:
        raise ConfigError(f"{what} must be positive, got {text!r}")
    return value


class _Run:
    """The loop of one ``point`` run: feeds the display, waits on its clock, prints status."""

    def __init__(self, display: DirectionDisplay, limit_s: float | None, quiet: bool) -> None:
        self.display = display
        self.clock = display.clock
        self.t0_s = self.clock.now_ns() / 1e9
        self.end_ns = None if limit_s is None else self.clock.now_ns() + round(limit_s * 1e9)
        self.headings = 0
        self.live = not quiet and sys.stderr.isatty()
        self._status_at = 0.0
        self._status_len = 0

    def wait_until(self, t_ns: int) -> bool:
        """Wait (or pump a simulated clock) until ``t_ns``; False when past --seconds."""
        stop = self.end_ns is not None and t_ns >= self.end_ns
        target = min(t_ns, self.end_ns) if self.end_ns is not None else t_ns
        if self.clock.simulated:
            self.display.pump(target)
        else:
            self.clock.sleep_until_ns(target)
        return not stop

    def status(self, text: str) -> None:
        if not self.live:
            return
        now = time.monotonic()
        if now - self._status_at < _STATUS_EVERY_S:
            return
        self._status_at = now
        line = text.ljust(self._status_len)
        self._status_len = len(text)
        sys.stderr.write("\r" + line)
        sys.stderr.flush()

    def clear_status(self) -> None:
        if self.live and self._status_len:
            sys.stderr.write("\r" + " " * self._status_len + "\r")
            sys.stderr.flush()

    def _describe(self, bearing: float | None = None) -> str:
        d = self.display
        body = d.requested_deg
        parts = []
        if bearing is not None:
            parts.append(f"bearing {bearing:6.1f}")
        if d.filtered_heading_deg is not None:
            parts.append(f"heading {d.filtered_heading_deg:6.1f}")
        if body is not None:
            parts.append(f"body {body:6.1f} deg")
        if d.dominant_tactor is not None:
            parts.append(f"tactor {d.dominant_tactor}")
        return "  ".join(parts)

    def fixed(self, bearing: float) -> None:
        """Show one body angle until --seconds or Ctrl-C."""
        self.display.show(bearing)
        step = round(1e9 if self.clock.simulated else 2e8)
        t = self.clock.now_ns()
        while True:
            t += step
            if not self.wait_until(t):
                return
            self.status(self._describe())

    def sweep(self, period_s: float) -> None:
        """Turn the displayed direction round the body, one turn per ``period_s``."""
        step = round(1e9 / _SWEEP_UPDATE_HZ)
        t_start = self.clock.now_ns()
        t = t_start
        while True:
            angle = 360.0 * ((t - t_start) / 1e9 / period_s) % 360.0
            self.display.show(angle)
            self.status(self._describe())
            t += step
            if not self.wait_until(t):
                return

    def replay(self, bearing: float, samples: list[HeadingSample], timed: bool,
               rate_hz: float) -> None:
        """Apply file headings at their times (or at ``rate_hz``)."""
        t_start = self.clock.now_ns()
        first_t = samples[0].t_s if timed and samples[0].t_s is not None else 0.0
        for i, s in enumerate(samples):
            rel = (s.t_s - first_t) if timed and s.t_s is not None else i / rate_hz
            if not self.wait_until(t_start + round(rel * 1e9)):
                return
            self.display.show_bearing(bearing, s.heading_deg,
                                      None if s.t_s is None else s.t_s)
            self.headings += 1
            self.status(self._describe(bearing))
        # hold the last heading for one sample interval
        last = (samples[-1].t_s - first_t) if timed and samples[-1].t_s is not None \
            else (len(samples) - 1) / rate_hz
        hold = 1.0 / rate_hz if not timed or len(samples) < 2 else \
            max(0.0, (samples[-1].t_s or 0.0) - (samples[-2].t_s or 0.0))
        self.wait_until(t_start + round((last + hold) * 1e9))

    def stdin(self, bearing: float, stream: IO[str], rate_hz: float) -> None:
        """Apply headings from stdin as lines arrive (on a simulated clock: as a file)."""
        reader = HeadingReader("stdin")
        if self.clock.simulated:
            samples = [s for i, line in _stdin_lines(stream)
                       if (s := reader.feed(i, line)) is not None]
            if not samples:
                raise ConfigError("stdin: no headings")
            self.replay(bearing, samples, reader.has_time, rate_hz)
            return
        lines: queue.Queue[tuple[int, str] | None] = queue.Queue()

        def pump_lines() -> None:
            try:
                for item in _stdin_lines(stream):
                    lines.put(item)
            finally:
                lines.put(None)

        threading.Thread(target=pump_lines, name="tactorbelt-stdin", daemon=True).start()
        while True:
            timeout = 0.2
            if self.end_ns is not None:
                left = (self.end_ns - self.clock.now_ns()) / 1e9
                if left <= 0:
                    return
                timeout = min(timeout, left)
            try:
                item = lines.get(timeout=timeout)
            except queue.Empty:
                self.status(self._describe(bearing))
                continue
            if item is None:
                if self.headings == 0:
                    raise ConfigError("stdin: no headings")
                return
            sample = reader.feed(*item)
            if sample is not None:
                self.display.show_bearing(bearing, sample.heading_deg, sample.t_s)
                self.headings += 1
                self.status(self._describe(bearing))
