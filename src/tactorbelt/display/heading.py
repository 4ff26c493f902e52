"""Headings for ``tactorbelt point``: parse them, and keep a bearing on a display.

:class:`HeadingReader` parses heading lines (one number per line, or a CSV with a header
naming ``heading_deg`` and optionally ``t_s``); :func:`read_headings` reads a file.
:func:`run_point` drives a :class:`~tactorbelt.display.DirectionDisplay`: a fixed body
angle, a sweep round the body, a heading file replayed at its times, or headings from a
stream as lines arrive. Waits go through the display's clock (a simulated clock is
pumped, not slept).

Imports the standard library; the display is passed in.
"""

from __future__ import annotations

import math
import queue
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING

from .._errors import ConfigError

if TYPE_CHECKING:
    from .direction import DirectionDisplay

__all__ = ["HeadingReader", "HeadingSample", "PointReport", "read_headings", "run_point"]

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
        heading = self._number(line_no, fields[self._heading_col or 0], "heading", "degrees")
        t: float | None = None
        if self._time_col is not None:
            t = self._number(line_no, fields[self._time_col], "time", "seconds")
            if self._last_t is not None and t < self._last_t:
                raise ConfigError(f"{self._where(line_no)}: time {t:g} s is earlier than "
                                  f"the line before ({self._last_t:g} s); times must not "
                                  "decrease")
            self._last_t = t
        return HeadingSample(line_no, t, heading)

    def _number(self, line_no: int, raw: str, what: str, unit: str) -> float:
        if not _is_number(raw):
            raise ConfigError(f"{self._where(line_no)}: {what} {raw!r} is not a number of {unit}")
        return float(raw)

    def _header(self, line_no: int, fields: list[str]) -> None:
        names = [f.lower() for f in fields]
        self._n_cols = len(names)
        self._heading_col, self._time_col = (
            next((names.index(n) for n in columns if n in names), None)
            for columns in (_HEADING_COLUMNS, _TIME_COLUMNS))
        if self._heading_col is None:
            raise ConfigError(
                f"{self._where(line_no)}: {fields[0]!r} is not a heading; a CSV header "
                f"needs a heading_deg column (got {','.join(fields)})")


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
        text = path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError:
        raise ConfigError(f"cannot read headings from {path}: not a text file (one heading "
                          "per line, or CSV, as UTF-8 text)") from None
    except OSError as exc:
        raise ConfigError(f"cannot read headings from {path}: {exc.strerror or exc}") from None
    reader = HeadingReader(str(path))
    samples = [s for i, line in enumerate(text.splitlines(), start=1)
               if (s := reader.feed(i, line)) is not None]
    if not samples:
        raise ConfigError(f"{path}: no headings in the file")
    return samples, reader.has_time


class PointRun:
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
            self.display.show_bearing(bearing, s.heading_deg, s.t_s)
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
            samples = [s for i, line in enumerate(stream, start=1)
                       if (s := reader.feed(i, line)) is not None]
            if not samples:
                raise ConfigError("stdin: no headings")
            self.replay(bearing, samples, reader.has_time, rate_hz)
            return
        lines: queue.Queue[tuple[int, str] | None] = queue.Queue()

        def pump_lines() -> None:
            try:
                for item in enumerate(stream, start=1):
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


@dataclass(frozen=True)
class PointReport:
    """How a ``point`` run ended."""

    interrupted: bool
    elapsed_s: float
    headings: int
    sent: str


def run_point(display: DirectionDisplay, *, bearing_deg: float, sweep_s: float | None,
              samples: list[HeadingSample] | None, timed: bool, rate_hz: float,
              from_stdin: bool, limit_s: float | None, quiet: bool) -> PointReport:
    """Keep ``bearing_deg`` displayed (or sweep, one turn per ``sweep_s``) until the
    headings end, ``limit_s`` passes, or Ctrl-C (``interrupted``; the display is
    closed, motors off, on every way out).

    Headings: ``samples`` from a file, ``from_stdin`` (lines as they arrive), or
    neither (``bearing_deg`` is then a body angle).
    """
    started = time.monotonic()
    interrupted = False
    run = PointRun(display, limit_s, quiet)
    try:
        with display:
            if sweep_s is not None:
                run.sweep(sweep_s)
            elif samples is not None:
                run.replay(bearing_deg, samples, timed, rate_hz)
            elif from_stdin:
                run.stdin(bearing_deg, sys.stdin, rate_hz)
            else:
                run.fixed(bearing_deg)
    except KeyboardInterrupt:
        interrupted = True
    finally:
        run.clear_status()
    elapsed = display.clock.now_ns() / 1e9 - run.t0_s if display.clock.simulated \
        else time.monotonic() - started
    plays = display.plays_sent
    sent = f"{plays} direction{'s' if plays != 1 else ''} sent to the belt" \
        if display.device_render else f"{display.frames_written} frames"
    return PointReport(interrupted, elapsed, run.headings, sent)
