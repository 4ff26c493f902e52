"""Clocks: the wall clock and a simulated clock that advances without sleeping.

Every layer that needs time takes a :class:`Clock`, so tests and simulations run
exactly and fast on :class:`SimClock`. Times are integer nanoseconds on a monotonic
scale (``time.perf_counter_ns`` for the wall clock).

Imports only the standard library (numpy in :meth:`Deadlines.deadlines`).
"""

from __future__ import annotations

import functools
import math
import time
from fractions import Fraction
from typing import TYPE_CHECKING, Protocol, runtime_checkable

if TYPE_CHECKING:
    import numpy as np
    from numpy.typing import NDArray

__all__ = ["Clock", "Deadlines", "SimClock", "WallClock"]

#: The wall clock sleeps until this long before a deadline, then spins.
SPIN_NS = 1_000_000


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

    @property
    def exact(self) -> bool:
        """True without jitter: every wake-up is exactly at its deadline, so one
        ``sleep_until_ns(t)`` ends where any series of earlier sleeps and then it would."""
        return self._jitter is None

    def sleep_until_ns(self, deadline_ns: int) -> None:
        if self._jitter is None:
            t = int(deadline_ns)
            if t > self._now:
                self._now = t
            return
        late = int(self._jitter()) if callable(self._jitter) else 0
        self._now = max(self._now, int(deadline_ns) + late)

    def advance(self, dt_ns: int) -> None:
        """Move the clock forward by ``dt_ns``."""
        if dt_ns < 0:
            raise ValueError("a clock cannot go backwards")
        self._now += int(dt_ns)


@functools.lru_cache(maxsize=64)
def _period(rate_hz: float) -> tuple[int, int, int]:
    """The period of ``rate_hz`` as the fraction p/q ns, and in whole ns (a display
    driven by hand makes a Deadlines per frame: the Fraction arithmetic is done once)."""
    period = Fraction(10**9) / Fraction(rate_hz).limit_denominator(1_000_000)
    return period.numerator, period.denominator, int(period)


class Deadlines:
    """The one deadline loop: frame ``i`` is due at ``onset + floor(i * 1e9 / rate)`` ns.

    Deadlines are computed from integers, never accumulated, so nothing drifts however
    long a loop runs. :meth:`wait` sleeps (then spins, on the wall clock) until a frame is
    due; a frame woken up so late that a later frame is already due is skipped, and
    counted in :attr:`missed`. The player, the direction display, the runner's cursor
    sampling and the window's frames all keep time with this class.

    Args:
        clock: the clock to wait on.
        rate_hz: frames per second, in (0, 100000].
        onset_ns: the deadline of frame 0 (default: now).

    Raises:
        ValueError: a rate that is not a positive finite number up to 100 kHz.
    """

    def __init__(self, clock: Clock, rate_hz: float, onset_ns: int | None = None) -> None:
        rate = float(rate_hz)
        if not (math.isfinite(rate) and 0 < rate <= 100_000):
            raise ValueError(f"rate must be a number of Hz in (0, 100000], got {rate_hz!r}")
        self.clock = clock
        self.rate_hz = rate
        self._p, self._q, self.period_ns = _period(rate)
        self.onset_ns = int(clock.now_ns()) if onset_ns is None else int(onset_ns)
        #: the next frame index :meth:`wait` will return (or a later one, when late).
        self.next_index = 0
        #: frames skipped because their time had passed.
        self.missed = 0

    def deadline(self, i: int) -> int:
        """The deadline of frame ``i`` (integer ns)."""
        return self.onset_ns + (i * self._p) // self._q

    def deadlines(self, first: int, n: int) -> NDArray[np.int64]:
        """The deadlines of frames ``first`` .. ``first + n - 1`` (int64 ns), as
        :meth:`deadline` computes them one by one."""
        import numpy as np

        last = first + max(int(n), 1) - 1
        if first < 0 or last * self._p >= 2**62 or abs(self.onset_ns) >= 2**62:
            return np.array([self.deadline(i) for i in range(first, first + int(n))],
                            dtype=np.int64)
        i = np.arange(first, first + int(n), dtype=np.int64)
        return np.asarray(self.onset_ns + (i * self._p) // self._q, dtype=np.int64)

    def time_s(self, i: int) -> float:
        """The time of frame ``i`` since the onset, in seconds."""
        return ((i * self._p) // self._q) / 1e9

    def last_due(self, now_ns: int) -> int:
        """The largest frame index whose deadline is at or before ``now_ns`` (-1 before onset)."""
        return ((now_ns - self.onset_ns + 1) * self._q - 1) // self._p

    def wait(self, limit: int | None = None) -> tuple[int, int]:
        """Wait for the next frame and return ``(index, now_ns)``.

        Sleeps until the deadline of :attr:`next_index`; if it woke up so late that later
        frames are due, returns the latest frame due now and counts the skipped ones in
        :attr:`missed`. ``limit`` caps the index (a playback of ``limit`` frames counts the
        frames it overslept past its end as missed and returns ``limit``).
        """
        i = self.next_index
        clock = self.clock
        onset, p, q = self.onset_ns, self._p, self._q
        clock.sleep_until_ns(onset + (i * p) // q)  # self.deadline(i)
        now = int(clock.now_ns())
        j = ((now - onset + 1) * q - 1) // p  # self.last_due(now)
        if j < i:
            j = i
        if limit is not None and j > limit:
            j = limit
        self.missed += j - i
        self.next_index = j + 1
        return j, now

    def due(self, now_ns: int) -> int | None:
        """The frame due at ``now_ns`` without waiting, or None when none is due yet.

        For loops that are woken by something else (a window polled by the runner, an
        event queue): returns the latest frame due (skipped ones are counted in
        :attr:`missed`) and moves :attr:`next_index` past it.
        """
        i = self.next_index
        if now_ns < self.deadline(i):
            return None
        j = max(i, self.last_due(int(now_ns)))
        self.missed += j - i
        self.next_index = j + 1
        return j
