"""Envelopes, crossings and statistics of sensed vibration pulses (pure NumPy).

A pulse is one tactor driven at one level from ``t_on`` to ``t_off`` (the command times,
on the clock the commands were stamped with), sensed over a window from a little before
``t_on`` to the next command. :func:`measure_pulse` reads in it:

- the **baseline** (median of the envelope before ``t_on``) and its noise (1.4826 x the
  median absolute deviation);
- the **steady amplitude** (median over the last :data:`STEADY_FRACTION` of the on-time,
  minus the baseline); the pulse is *seen* when it exceeds :data:`MIN_SNR` times the
  noise and :data:`MIN_AMPLITUDE` (a silent or unconnected input is never seen);
- on the envelope normalised to 0 (baseline) .. 1 (steady): the **latency** from ``t_on``
  to the 10 % crossing, the **rise** from the 10 % to the 90 % crossing, the **fall** from
  the 90 % to the 10 % crossing after ``t_off`` (and the stop latency, ``t_off`` to 90 %).

Crossings are linear interpolations between samples, found from the middle out so noise
at the foot or the top does not decide them: the first sample at or above 50 % in the
window; the 10 % crossing is the last upward crossing of 10 % before it, the 90 % one
the first upward crossing of 90 % from it; mirrored for the fall, from the steady
stretch on. A crossing may come before its command (a latency below 0): an estimator's
smoothing spreads a fast edge half a window early.

:func:`rectified_envelope` is the estimator for raw signals (a sound card's input, an
accelerometer): the full-wave rectified signal, a centred moving mean over ``window_s``
(about one carrier period), times pi/2 so a steady sine of amplitude A reads A. Its bias
(docs/validation.md): zero-phase, so it moves no crossing of a linearly changing envelope;
it spreads a corner of the envelope over half a window each side (a step reads as a ramp
of one window), and bends a curved stretch by ``w**2 / 24`` times the envelope's second
derivative (for a first-order rise of time constant tau, a delay of ``w**2 / (24 tau)``:
0.07 ms for w = 4 ms, tau = 10 ms). A window that is not a whole number of half-periods
of the vibration leaves a ripple of at most about ``1 / (2 * periods)`` of the amplitude.

Imports NumPy only.
"""

from __future__ import annotations

import itertools
import math
import operator
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "HIGH",
    "LOW",
    "MIN_AMPLITUDE",
    "MIN_SNR",
    "STEADY_FRACTION",
    "PulseMeasure",
    "TactorSummary",
    "linearity",
    "measure_pulse",
    "rectified_envelope",
    "summarise",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

#: The onset and top thresholds, of the steady amplitude above the baseline.
LOW: Final = 0.1
HIGH: Final = 0.9
#: The steady amplitude is the median over this last fraction of the on-time.
STEADY_FRACTION: Final = 0.2
#: A pulse is seen when its steady amplitude exceeds this many times the baseline noise...
MIN_SNR: Final = 10.0
#: ... and this much (sensor units: an exactly silent input is never a pulse).
MIN_AMPLITUDE: Final = 1e-6
#: The overshoot is the peak of the envelope's running mean over this many ms.
OVERSHOOT_WINDOW_MS: Final = 5.0
#: A pulse has settled when the two halves of its steady stretch differ by less than this
#: fraction of its amplitude.
SETTLED: Final = 0.02
#: Points of each pulse's trace kept for the figure (at most).
TRACE_POINTS: Final = 1500


def rectified_envelope(x: Any, rate_hz: float, window_s: float,
                       scale: float = math.pi / 2) -> FloatArray:
    """The amplitude envelope of a vibration signal: ``scale`` (pi/2: a sine's amplitude)
    x the centred moving mean of ``|x|`` over ``round(window_s * rate_hz)`` samples (at
    least 1; the ends average the samples there are). See the module docstring for its
    bias."""
    a = np.abs(np.asarray(x, dtype=float))
    n = a.shape[0]
    w = max(1, round(window_s * rate_hz))
    if n == 0 or w == 1:
        return np.asarray(a * scale)
    c = np.concatenate([[0.0], np.cumsum(a)])
    i = np.arange(n)
    lo = np.clip(i - w // 2, 0, n)
    hi = np.clip(i - w // 2 + w, 0, n)
    return np.asarray((c[hi] - c[lo]) / (hi - lo) * scale)


def _cross(t: FloatArray, y: FloatArray, i: int, level: float) -> float:
    """Where the segment from sample i to i + 1 crosses ``level`` (linear)."""
    y0, y1 = y[i], y[i + 1]
    if y1 == y0:
        return float(t[i + 1])
    return float(t[i] + (level - y0) / (y1 - y0) * (t[i + 1] - t[i]))


def _edge(t: FloatArray, y: FloatArray, start: int, up: bool) -> tuple[float, float] | None:
    """The 10 % and 90 % crossings (in time order of the edge: up: 10 then 90; down: 90
    then 10) of the first edge from sample ``start`` on, found from its 50 % point; None
    when the envelope never crosses 50 % that way."""
    s = y[start:] if up else -y[start:]
    mid = np.flatnonzero(s >= (0.5 if up else -0.5))
    if mid.size == 0:
        return None
    m = start + int(mid[0])
    first, last = (LOW, HIGH) if up else (HIGH, LOW)
    # the last crossing of the first level before the midpoint
    before = y[start:m] < first if up else y[start:m] > first
    idx = np.flatnonzero(before)
    if idx.size == 0:  # already past it at the window's start
        return None
    i = start + int(idx[-1])
    t_first = _cross(t, y, i, first)
    # the first crossing of the second level from the midpoint on
    after = y[m:] >= last if up else y[m:] <= last
    jdx = np.flatnonzero(after)
    if jdx.size == 0:
        return None
    j = m + int(jdx[0])
    t_last = float(t[j]) if j == 0 else _cross(t, y, j - 1, last)
    return t_first, t_last


@dataclass
class PulseMeasure:
    """What one sensed pulse showed.

    Times in ms: ``latency_ms`` from the command to 10 %, ``rise_ms`` 10 to 90 %,
    ``stop_latency_ms`` from the stop command to 90 %, ``fall_ms`` 90 to 10 % (NaN when
    the envelope did not get there within the window). ``amplitude`` and ``baseline``
    are in the sensor's units. ``seen`` False: the sensor showed no pulse (the other
    figures are NaN). ``settled``: the steady stretch changed by less than
    :data:`SETTLED` of the amplitude; ``stopped``: so did the baseline (no motor still
    running down from before). ``overshoot``: how far the envelope went above its steady
    amplitude while on (its running mean over :data:`OVERSHOOT_WINDOW_MS`), as a fraction
    of it (0 when it never did; sensor noise counts).
    ``trace_ms``/``trace`` (from ``t_on``) and ``off_ms`` (``t_off`` from ``t_on``) draw it
    normalised.
    """

    tactor: int
    level: float
    seen: bool
    amplitude: float
    baseline: float
    noise: float
    latency_ms: float = math.nan
    rise_ms: float = math.nan
    stop_latency_ms: float = math.nan
    fall_ms: float = math.nan
    settled: bool = True
    stopped: bool = True
    off_ms: float = math.nan
    overshoot: float = math.nan
    trace_ms: FloatArray = field(default_factory=lambda: np.zeros(0), repr=False)
    trace: FloatArray = field(default_factory=lambda: np.zeros(0), repr=False)

    def to_dict(self) -> dict[str, Any]:
        return {"tactor": self.tactor, "level": self.level,
                "latency_ms": _num(self.latency_ms), "rise_ms": _num(self.rise_ms),
                "stop_latency_ms": _num(self.stop_latency_ms), "fall_ms": _num(self.fall_ms),
                "amplitude": _num(self.amplitude), "baseline": _num(self.baseline),
                "noise": _num(self.noise), "settled": self.settled,
                "stopped": self.stopped, "overshoot": _num(self.overshoot)}


def _num(v: float) -> float | None:
    return None if not math.isfinite(v) else float(v)


def measure_pulse(t_ns: IntArray, env: FloatArray, t_on_ns: int, t_off_ns: int, *,
                  tactor: int, level: float) -> PulseMeasure:
    """Measure one pulse from its sensed envelope ``env`` at times ``t_ns`` (increasing,
    on the commands' clock), commanded on at ``t_on_ns`` and off at ``t_off_ns``. The
    window must start before ``t_on_ns`` (the baseline) and may end at the next command.
    """
    t = np.asarray(t_ns, dtype=np.int64)
    y = np.asarray(env, dtype=float)
    pre = y[t < t_on_ns]
    if pre.size == 0 or t.size < 4:
        raise ValueError("the window must start before the pulse's command")
    on_ns = t_off_ns - t_on_ns
    steady_sel = (t >= t_off_ns - round(on_ns * STEADY_FRACTION)) & (t < t_off_ns)
    steady_y = y[steady_sel]
    if steady_y.size == 0:
        steady_y = y[(t >= t_on_ns) & (t < t_off_ns)][-1:]
    baseline = float(np.median(pre))
    noise = float(1.4826 * np.median(np.abs(pre - baseline)))
    amplitude = float(np.median(steady_y)) - baseline
    seen = amplitude > max(MIN_SNR * noise, MIN_AMPLITUDE)
    out = PulseMeasure(tactor, float(level), bool(seen), amplitude, baseline, noise)
    if not seen:
        return out
    half = steady_y.size // 2
    if half:
        drift = abs(float(np.mean(steady_y[half:]) - np.mean(steady_y[:half])))
        out.settled = drift < SETTLED * amplitude
    half = pre.size // 2
    if half:  # still falling from a pulse before
        out.stopped = float(np.mean(pre[:half]) - np.mean(pre[half:])) < SETTLED * amplitude
    rel = (t - t_on_ns).astype(float) / 1e6  # ms from the command
    norm = (y - baseline) / amplitude
    # an edge is searched from the stretch before it (the baseline; the steady part), not
    # from its command: an estimator's smoothing (or a stamp taken late) may put a
    # crossing a little before the command
    rise = _edge(rel, norm, 0, up=True)
    if rise is not None:
        out.latency_ms, t90 = rise
        out.rise_ms = t90 - out.latency_ms
    on = np.flatnonzero((t >= t_on_ns) & (t < t_off_ns))
    if on.size:  # over a 5 ms running mean: a lone sample (a sensor's glitch) is no overshoot
        dt_ms = float(np.median(np.diff(rel))) if rel.size > 1 else 1.0
        w = max(1, min(on.size, round(OVERSHOOT_WINDOW_MS / max(dt_ms, 1e-6))))
        mean = np.convolve(norm[on], np.ones(w) / w, mode="valid")
        out.overshoot = max(0.0, float(mean.max()) - 1.0)
    i_steady = int(np.searchsorted(t, t_off_ns - round(on_ns * STEADY_FRACTION)))
    off_ms = (t_off_ns - t_on_ns) / 1e6
    out.off_ms = off_ms
    if int(np.searchsorted(t, t_off_ns)) < t.size - 1:
        fall = _edge(rel, norm, i_steady, up=False)
        if fall is not None:
            out.stop_latency_ms = fall[0] - off_ms
            out.fall_ms = fall[1] - fall[0]
    step = max(1, rel.size // TRACE_POINTS)
    out.trace_ms = rel[::step].copy()
    out.trace = norm[::step].copy()
    return out


def linearity(levels: Sequence[float], amplitudes: Sequence[float]
              ) -> tuple[float, float, float] | None:
    """Least squares of amplitude against level: ``(slope, intercept, r2)``; None with
    fewer than two distinct levels. r2 is 1 for a perfect line (also when every amplitude
    is the same: then the slope is 0)."""
    x = np.asarray(levels, dtype=float)
    y = np.asarray(amplitudes, dtype=float)
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    if np.unique(x).size < 2:
        return None
    slope, intercept = np.polyfit(x, y, 1)
    ss_res = float(np.sum((y - (slope * x + intercept)) ** 2))
    ss_tot = float(np.sum((y - y.mean()) ** 2))
    r2 = 1.0 if ss_tot == 0.0 else 1.0 - ss_res / ss_tot
    return float(slope), float(intercept), r2


@dataclass
class TactorSummary:
    """A tactor's figures over its pulses (see :func:`summarise`)."""

    tactor: int
    pulses: list[PulseMeasure]

    def _over(self, name: str, level: float | None = None) -> tuple[float, float]:
        """The mean and sample standard deviation (0 for one value) of the finite values
        of ``name`` over the pulses (at ``level``)."""
        v = np.array([getattr(p, name) for p in self.pulses
                      if level is None or p.level == level], dtype=float)
        v = v[np.isfinite(v)]
        if v.size == 0:
            return math.nan, math.nan
        return float(v.mean()), float(v.std(ddof=1)) if v.size > 1 else 0.0

    def _times(self, names: Sequence[str], level: float | None = None) -> dict[str, Any]:
        """Each of ``names`` (``latency_ms``, ...) over the pulses (at ``level``): its
        mean, and its sd as ``latency_sd_ms``."""
        out = {}
        for name in names:
            mean, sd = self._over(name, level)
            out[name], out[name.replace("_ms", "_sd_ms")] = _num(mean), _num(sd)
        return out

    def to_dict(self) -> dict[str, Any]:
        """``validation.json``'s entry of this tactor."""
        row: dict[str, Any] = {"tactor": self.tactor, **self._times(
            ("latency_ms", "rise_ms", "fall_ms", "stop_latency_ms"))}
        levels = sorted({p.level for p in self.pulses})
        row["pulses"] = len(self.pulses)
        row["levels"] = levels
        amps = [self._over("amplitude", lv) for lv in levels]
        row["amplitudes"] = [_num(a[0]) for a in amps]
        row["amplitude_sds"] = [_num(a[1]) for a in amps]
        fit = linearity([p.level for p in self.pulses], [p.amplitude for p in self.pulses])
        row["linearity"] = (None if fit is None else
                            {"slope": fit[0], "intercept": fit[1], "r2": fit[2]})
        row["settled"] = all(p.settled for p in self.pulses)
        row["by_level"] = [{"level": lv, **self._times(("latency_ms", "rise_ms", "fall_ms"), lv),
                            "pulses": sum(1 for p in self.pulses if p.level == lv)}
                           for lv in levels]
        return row

    def timing(self) -> dict[str, float | None]:
        """The calibration file's timing keys of this tactor (None where not measured)."""
        row = self.to_dict()
        return {k: None if row[k] is None else round(row[k], 3)  # to the microsecond
                for k in ("latency_ms", "latency_sd_ms", "rise_ms", "rise_sd_ms", "fall_ms",
                          "fall_sd_ms")}


def summarise(pulses: Sequence[PulseMeasure]) -> list[TactorSummary]:
    """Group measured pulses by tactor (in tactor order; each tactor's in measured order)."""
    tactor = operator.attrgetter("tactor")
    return [TactorSummary(k, list(g))
            for k, g in itertools.groupby(sorted(pulses, key=tactor), key=tactor)]
