"""Map the device's microsecond clock to the host's clock from request round trips.

Each PING/PONG or GET_DIAG/DIAG round trip gives a sample: the host time just before
the request was written (``send_ns``), the host time its reply was read (``recv_ns``)
and the device time in the reply (``device_us``). The device read its clock somewhere
in between, so the offset ``host_ns - device_us * 1000`` at that moment lies in
``[send_ns - d, recv_ns - d]``; the midpoint is wrong by at most half the round trip
(RTT), and by less the more symmetric the link is.

:class:`ClockSync` keeps the last :data:`WINDOW` samples and fits, as NTP's clock
filter and LSL's time correction do, only the fastest of them (the quarter with the
smallest RTT, at least :data:`MIN_BEST`): least squares of the offset against device
time (offset and drift) once they span :data:`MIN_DRIFT_SPAN_US`, else their mean
offset. A mapped time comes with an uncertainty: half the median RTT of the fitted
samples (the asymmetry a round trip cannot see), plus the standard error of the fit at
that device time, plus half a microsecond of device clock resolution.

Pure: standard library only. Host times are ``time.perf_counter_ns`` (the wall clock
of :class:`tactorbelt.clock.WallClock`).
"""

from __future__ import annotations

import math
import threading
from collections import deque
from dataclasses import dataclass
from typing import Any, Final

__all__ = ["MIN_BEST", "WINDOW", "ClockFit", "ClockSync"]

#: Round trips kept.
WINDOW: Final = 64
#: At least this many of the fastest round trips are fitted (all when fewer).
MIN_BEST: Final = 4
#: The drift is fitted only once the fitted samples span this much device time.
MIN_DRIFT_SPAN_US: Final = 2_000_000
_WRAP: Final = 1 << 32


@dataclass(frozen=True)
class ClockFit:
    """``host_ns = device_us * 1000 + offset_ns + drift * (device_us - ref_us) * 1000``.

    Attributes:
        offset_ns: the offset at ``ref_us``.
        drift: the device clock's rate error (dimensionless; 20e-6 = 20 ppm).
        ref_us: the mean device time of the fitted samples.
        half_rtt_ns: half the median round trip of the fitted samples.
        residual_ns: the RMS residual of the fit.
        n: samples fitted.
        sxx: sum of squared deviations of their device times (us^2), for the error.
    """

    offset_ns: float
    drift: float
    ref_us: float
    half_rtt_ns: float
    residual_ns: float
    n: int
    sxx: float

    def host_ns(self, device_us: Any) -> Any:
        """The host time (ns, not rounded) of a device time, or of an array of them."""
        return device_us * 1000.0 + self.offset_ns + self.drift * (device_us - self.ref_us) * 1000.0

    def device_us(self, host_ns: float) -> float:
        """The device time of a host time (the inverse of :meth:`host_ns`)."""
        return (host_ns - self.offset_ns + self.drift * self.ref_us * 1000.0) / (
            1000.0 * (1.0 + self.drift))

    def to_host(self, device_us: int) -> tuple[int, int]:
        """(host_ns, uncertainty_ns) of a device time."""
        dx = device_us - self.ref_us
        se = self.residual_ns * math.sqrt(1.0 / self.n + (dx * dx / self.sxx if self.sxx > 0
                                                          else 0.0))
        return round(self.host_ns(device_us)), round(self.half_rtt_ns + se + 500.0)


class ClockSync:
    """A running estimate of the device clock on the host's clock (thread-safe)."""

    def __init__(self, window: int = WINDOW) -> None:
        self._samples: deque[tuple[int, int, int]] = deque(maxlen=window)
        self._lock = threading.Lock()
        self._fit: ClockFit | None = None
        self._last: tuple[int, int] | None = None  # (host mid ns, device us)

    def __len__(self) -> int:
        return len(self._samples)

    def reset(self) -> None:
        """Forget every sample (the device restarted its clock)."""
        with self._lock:
            self._samples.clear()
            self._fit = None
            self._last = None

    def unwrap32(self, device_us32: int, send_ns: int, recv_ns: int) -> int:
        """A PONG's 32-bit device time as the full time, nearest to the prediction."""
        with self._lock:
            last = self._last
        if last is None:
            return device_us32
        predicted = last[1] + ((send_ns + recv_ns) // 2 - last[0]) / 1000.0
        k = round((predicted - device_us32) / _WRAP)
        return device_us32 + max(k, 0) * _WRAP

    def add(self, send_ns: int, recv_ns: int, device_us: int) -> None:
        """One round trip: host send and receive times, device time in the reply."""
        if recv_ns < send_ns:
            return
        with self._lock:
            self._samples.append((send_ns, recv_ns, device_us))
            self._fit = None
            self._last = ((send_ns + recv_ns) // 2, device_us)

    def fit(self) -> ClockFit | None:
        """The current fit, or None before the first sample."""
        with self._lock:
            if self._fit is None and self._samples:
                self._fit = _fit(list(self._samples))
            return self._fit

    def to_host(self, device_us: int) -> tuple[int, int] | None:
        """(host_ns, uncertainty_ns) of a device time, or None before the first sample."""
        f = self.fit()
        return None if f is None else f.to_host(device_us)


def _fit(samples: list[tuple[int, int, int]]) -> ClockFit:
    by_rtt = sorted(samples, key=lambda s: s[1] - s[0])
    best = by_rtt[: max(MIN_BEST, len(samples) // 4)]
    rtts = sorted(r - s for s, r, _ in best)
    half_rtt = rtts[len(rtts) // 2] / 2.0
    xs = [float(d) for _, _, d in best]
    ys = [(s + r) / 2.0 - d * 1000.0 for s, r, d in best]
    n = len(best)
    x0 = sum(xs) / n
    y0 = sum(ys) / n
    sxx = sum((x - x0) ** 2 for x in xs)
    drift = 0.0
    if n >= 3 and max(xs) - min(xs) >= MIN_DRIFT_SPAN_US and sxx > 0:
        # ys are ns, xs us: the slope in ns/us is 1000 * drift
        drift = sum((x - x0) * (y - y0) for x, y in zip(xs, ys, strict=True)) / sxx / 1000.0
    resid = [y - (y0 + drift * (x - x0) * 1000.0) for x, y in zip(xs, ys, strict=True)]
    dof = max(n - (2 if drift else 1), 1)
    rms = math.sqrt(sum(e * e for e in resid) / dof) if n > 1 else half_rtt
    return ClockFit(y0, drift, x0, half_rtt, rms, n, sxx if drift else 0.0)
