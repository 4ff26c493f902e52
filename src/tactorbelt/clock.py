"""Clocks: the wall clock and a simulated clock that advances without sleeping.

Every layer that needs time takes a :class:`Clock`, so tests and simulations run
exactly and fast on :class:`SimClock`. Times are integer nanoseconds on a monotonic
scale (``time.perf_counter_ns`` for the wall clock).

Imports only the standard library.
"""

from __future__ import annotations

import time
from typing import Protocol, runtime_checkable

__all__ = ["Clock", "SimClock", "WallClock", "ns", "seconds"]

#: The wall clock sleeps until this long before a deadline, then spins.
SPIN_NS = 1_000_000


def ns(seconds_: float) -> int:
    """Seconds (float) to integer nanoseconds, rounded."""
    return round(seconds_ * 1e9)


def seconds(nanoseconds: int) -> float:
    """Integer nanoseconds to seconds (float)."""
    return nanoseconds / 1e9


@runtime_checkable
class Clock(Protocol):
    """A monotonic clock in integer nanoseconds that can wait for a deadline."""

    #: True for a simulated clock: nothing waits in real time.
    simulated: bool

    def now_ns(self) -> int:
        """The current time."""
        ...

    def sleep_until_ns(self, deadline_ns: int) -> None:
        """Return at (or just after) ``deadline_ns``; return at once if it has passed."""
        ...


class WallClock:
    """``time.perf_counter_ns``; waits sleep most of the way, then spin briefly."""

    simulated = False

    def __init__(self, spin_ns: int = SPIN_NS) -> None:
        self.spin_ns = spin_ns

    def now_ns(self) -> int:
        return time.perf_counter_ns()

    def sleep_until_ns(self, deadline_ns: int) -> None:
        remaining = deadline_ns - time.perf_counter_ns()
        if remaining > self.spin_ns:
            time.sleep((remaining - self.spin_ns) / 1e9)
        while time.perf_counter_ns() < deadline_ns:
            pass


class SimClock:
    """A clock that only moves when told to: ``sleep_until_ns`` jumps to the deadline.

    Args:
        start_ns: the initial time.
        jitter: optional callable giving extra nanoseconds added to each wake-up
            (to test deadline statistics with a known error).
    """

    simulated = True

    def __init__(self, start_ns: int = 0, jitter: object | None = None) -> None:
        self._now = int(start_ns)
        self._jitter = jitter

    def now_ns(self) -> int:
        return self._now

    def sleep_until_ns(self, deadline_ns: int) -> None:
        late = int(self._jitter()) if callable(self._jitter) else 0
        self._now = max(self._now, int(deadline_ns) + late)

    def advance(self, dt_ns: int) -> None:
        """Move the clock forward by ``dt_ns``."""
        if dt_ns < 0:
            raise ValueError("a clock cannot go backwards")
        self._now += int(dt_ns)
