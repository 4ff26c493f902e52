"""Filters for a noisy heading: a One Euro filter on angles, and tactor hysteresis.

- :class:`OneEuroFilter` (Casiez, Roussel and Vogel, "1 Euro Filter", CHI 2012): a
  low-pass filter whose cutoff rises with the speed of the signal, so that jitter at
  rest is smoothed hard while fast turns pass with little lag. For angles
  (``angular=True``, the default) it filters the *unwrapped* angle, so a heading that
  crosses 0/360 is not dragged the long way round, and returns it normalised to
  [0, 360).
- :class:`Hysteresis`: holds the *dominant* tactor (the nearest one) until an angle has
  gone past the boundary of that tactor's sector by a margin, so a heading jittering
  around a boundary does not make the cue flicker between two tactors.

Default parameters (for a heading from a compass or an IMU at 10-50 Hz, a few degrees
of noise, a walking wearer who turns at up to about 90 deg/s):

- ``min_cutoff_hz = 0.5``: at rest the filter is a one-pole low-pass at 0.5 Hz (time
  constant 0.32 s). At 20 Hz this divides white heading noise by about 3.5
  (``+-3`` deg becomes about ``+-0.9`` deg), well below the spacing of the targets.
- ``beta = 0.02`` Hz per deg/s: a 90 deg/s turn raises the cutoff to about 2.3 Hz (time
  constant 0.07 s, about 6 deg of lag while turning); a sudden step raises it further.
  Noise alone (derivative about 20 deg/s after its own filter) raises it by only ~0.4 Hz.
- ``d_cutoff_hz = 1.0``: the cutoff of the speed estimate, the value of the paper.

Measured step response (``tests/test_filters.py``: a noiseless heading step, sampled at 20 Hz,
default parameters; lag = time until the output is within 10% of the step). Because the
cutoff rises with speed, big steps pass faster than small ones:

    step     5 deg   10 deg   30 deg   90 deg
    lag     0.60 s   0.45 s   0.20 s   0.05 s

0.20 s is the figure for a 30-degree step (a typical turn). A heading
that jitters by +-3 deg (uniform) at 20 Hz comes out with a standard deviation about
3.2 times smaller; during a steady 90 deg/s turn the output trails by about 6 deg.

Pure: imports only the standard library, tactorbelt.geometry (NumPy) and _errors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

from .._errors import ConfigError
from ..geometry import ANGLE_TOLERANCE_DEG, Layout, normalize, wrap

__all__ = [
    "DEFAULT_BETA",
    "DEFAULT_D_CUTOFF_HZ",
    "DEFAULT_HYSTERESIS_DEG",
    "DEFAULT_MIN_CUTOFF_HZ",
    "Hysteresis",
    "OneEuroFilter",
]

DEFAULT_MIN_CUTOFF_HZ: Final = 0.5
DEFAULT_BETA: Final = 0.02
DEFAULT_D_CUTOFF_HZ: Final = 1.0
#: Hysteresis margin past a sector boundary before the dominant tactor changes.
DEFAULT_HYSTERESIS_DEG: Final = 4.0

#: A held angle stays this far inside the dominant tactor's sector (never on its edge).
_HOLD_INSIDE_DEG: Final = 0.01


def _positive(value: float, what: str, allow_zero: bool = False) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{what} must be a number, got {value!r}") from None
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        kind = "non-negative" if allow_zero else "positive"
        raise ConfigError(f"{what} must be a {kind}, finite number, got {value!r}")
    return v


def _alpha(cutoff_hz: float, dt_s: float) -> float:
    """Smoothing factor of a one-pole low-pass at ``cutoff_hz`` for a step of ``dt_s``."""
    tau = 1.0 / (2.0 * math.pi * cutoff_hz)
    return 1.0 / (1.0 + tau / dt_s)


class OneEuroFilter:
    """The One Euro filter (Casiez et al. 2012), for angles by default.

    Call it with each new sample and its time; it returns the filtered value. The
    cutoff is ``min_cutoff_hz + beta * |speed|``, where ``speed`` is the derivative
    of the input (units per second), itself low-passed at ``d_cutoff_hz``.

    Args:
        min_cutoff_hz: cutoff at rest, Hz (lower: smoother and slower).
        beta: how fast the cutoff rises with speed, Hz per (unit/s) (higher: less lag
            in fast movements, more jitter let through).
        d_cutoff_hz: cutoff of the speed estimate, Hz.
        angular: the input is an angle in degrees: filter the unwrapped angle and
            return it normalised to [0, 360).

    Timestamps must not decrease; a sample at the same time as the previous one is
    ignored (the last output is returned), so two readings with one timestamp do not
    divide by zero.

    Raises:
        ConfigError: a non-positive cutoff, a negative beta, a non-finite sample or
            a timestamp earlier than the previous one.
    """

    def __init__(
        self,
        min_cutoff_hz: float = DEFAULT_MIN_CUTOFF_HZ,
        beta: float = DEFAULT_BETA,
        d_cutoff_hz: float = DEFAULT_D_CUTOFF_HZ,
        angular: bool = True,
    ) -> None:
        self.min_cutoff_hz = _positive(min_cutoff_hz, "min_cutoff_hz")
        self.beta = _positive(beta, "beta", allow_zero=True)
        self.d_cutoff_hz = _positive(d_cutoff_hz, "d_cutoff_hz")
        self.angular = bool(angular)
        self.reset()

    def reset(self) -> None:
        """Forget the past: the next sample passes through unchanged."""
        self._t: float | None = None
        self._raw_prev = 0.0  # last raw input (for unwrapping)
        self._x_unwrapped = 0.0  # last raw input, unwrapped
        self._y = 0.0  # last output, unwrapped
        self._dx = 0.0  # last filtered speed

    @property
    def value(self) -> float | None:
        """The last output (None before the first sample)."""
        if self._t is None:
            return None
        return float(normalize(self._y)) if self.angular else self._y

    @property
    def speed(self) -> float:
        """The filtered speed estimate (units per second)."""
        return self._dx

    def __call__(self, x: float, t_s: float) -> float:
        """Filter one sample ``x`` taken at ``t_s`` seconds; return the filtered value."""
        try:
            xv, tv = float(x), float(t_s)
        except (TypeError, ValueError):
            raise ConfigError(f"filter input must be numbers, got {x!r} at {t_s!r}") from None
        if not (math.isfinite(xv) and math.isfinite(tv)):
            raise ConfigError(f"filter input must be finite, got {x!r} at {t_s!r}")
        if self._t is None:
            self._t = tv
            self._raw_prev = xv
            self._x_unwrapped = xv
            self._y = xv  # the speed is 0 (reset)
            return self.value  # type: ignore[return-value]
        dt = tv - self._t
        if dt < 0:
            raise ConfigError(
                f"filter timestamps must not decrease: {tv:g} s after {self._t:g} s"
            )
        if dt == 0:
            return self.value  # type: ignore[return-value]
        # unwrap: an angle moves the short way from its last raw value
        xu = self._x_unwrapped + float(wrap(xv - self._raw_prev)) if self.angular else xv
        speed = (xu - self._x_unwrapped) / dt
        self._dx += _alpha(self.d_cutoff_hz, dt) * (speed - self._dx)
        cutoff = self.min_cutoff_hz + self.beta * abs(self._dx)
        self._y += _alpha(cutoff, dt) * (xu - self._y)
        self._t = tv
        self._raw_prev = xv
        self._x_unwrapped = xu
        return self.value  # type: ignore[return-value]


@dataclass
class Hysteresis:
    """Hold the dominant tactor until an angle goes past its sector by ``margin_deg``.

    Tactor k's *sector* runs from the midpoint with its counter-clockwise neighbour to
    the midpoint with its clockwise neighbour (for an even layout of 6: tactor 0 at 30
    deg owns 0..60). While an angle stays within the dominant tactor's sector it passes
    through unchanged. When it leaves the sector by less than the margin it is *held*
    just inside the sector's edge (0.01 deg inside), so the dominant tactor stays the
    strongest; once it is past the edge by ``margin_deg`` or more, the dominant tactor
    becomes the one nearest the angle and the angle passes through again.

    The cost: near a boundary the displayed angle can be off by up to the margin. With
    the default 4 deg and the 60-deg spacing of 6 tactors that is well under the
    15-deg spacing of the study's targets.

    Args:
        layout: the tactor layout.
        margin_deg: the hysteresis margin, >= 0 and under half the smallest gap
            between tactors (0 turns hysteresis off).
    """

    layout: Layout
    margin_deg: float = DEFAULT_HYSTERESIS_DEG

    def __post_init__(self) -> None:
        self.margin_deg = _positive(self.margin_deg, "hysteresis margin", allow_zero=True)
        half_gap = float(self.layout.gaps_deg().min()) / 2.0
        if self.margin_deg >= half_gap:
            raise ConfigError(
                f"hysteresis margin {self.margin_deg:g} deg must be under half the smallest "
                f"gap between tactors ({half_gap:g} deg)"
            )
        self.dominant: int | None = None
        self.switches = 0
        gaps_cw = self.layout.gaps_deg()
        _, ccw = self.layout.neighbour_indices()
        self._sectors = [(-float(gaps_cw[ccw[k]]) / 2.0, float(gaps_cw[k]) / 2.0)
                         for k in range(self.layout.n)]

    def reset(self) -> None:
        """Forget the dominant tactor (the next angle picks the nearest)."""
        self.dominant = None

    def nearest(self, angle_deg: float) -> int:
        """The tactor nearest ``angle_deg`` (at an exact midpoint, the counter-clockwise one)."""
        ccw, cw = self.layout.neighbours(angle_deg)
        a = self.layout.angles_deg
        d_ccw = abs(float(wrap(angle_deg - a[ccw])))
        d_cw = abs(float(wrap(a[cw] - angle_deg)))
        return int(ccw) if d_ccw <= d_cw + ANGLE_TOLERANCE_DEG else int(cw)

    def sector(self, k: int) -> tuple[float, float]:
        """Tactor k's sector as ``(ccw_edge_offset, cw_edge_offset)``: degrees from d_k.

        The first is negative (counter-clockwise half-gap), the second positive.
        """
        return self._sectors[k]

    def __call__(self, angle_deg: float) -> float:
        """Pass ``angle_deg`` through the hysteresis; returns the angle to display.

        The dominant tactor after the call is in :attr:`dominant`.
        """
        x = float(normalize(angle_deg))
        if self.dominant is None:
            self.dominant = self.nearest(x)
            return x
        k = self.dominant
        lo, hi = self.sector(k)
        off = float(wrap(x - self.layout.angles_deg[k]))
        if lo <= off <= hi:
            return x
        past = (lo - off) if off < lo else (off - hi)
        if past >= self.margin_deg:
            new = self.nearest(x)
            if new != k:
                self.switches += 1
            self.dominant = new
            return x
        edge = lo + _HOLD_INSIDE_DEG if off < lo else hi - _HOLD_INSIDE_DEG
        return float(normalize(self.layout.angles_deg[k] + edge))
