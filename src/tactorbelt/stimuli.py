"""Static and dynamic between-tactor stimuli.

A stimulus is a felt location that may move in time, ``location(t)``, and the
amplitudes it produces, ``amplitudes(t) = law(location(t))``.

- Static: the location stays on the target.
- Dynamic (Eguchi et al.'s perturbation), for a between-tactor target x between
  tactors n (nearer) and f (farther), at distances ``D_n <= D_f``: the location moves
  on a trapezoid of period P. It dwells on n for ``(P - 2*transit) * D_f/(D_n+D_f)``,
  moves linearly to f in ``transit``, dwells on f for ``(P - 2*transit) * D_n/(D_n+D_f)``,
  and moves back in ``transit``. t = 0 starts the dwell on n; at an exact midpoint the
  counter-clockwise tactor counts as n. On-tactor targets render as static.

  The transit goes through the target (across the gap that holds it); for every gap
  under 180 degrees that is the short way round.

A stimulus may carry a wearer profile (:mod:`tactorbelt.wearer`, from the perceptual
calibration): its amplitudes are then ``gains * law(warp(location(t)))``, so a static
point is rendered where this wearer feels the intended point. The firmware knows no
profile: a belt renders such a stimulus itself only when it declares
``renders_profiles`` (the audio belt); every other belt streams it
(:meth:`tactorbelt.devices.base.Belt.can_render`).

Rendering samples at ``t = i/rate`` for ``i in range(round(duration*rate))``.
Everything is vectorised over t (and over targets in :func:`render_batch`).

Pure: imports only NumPy and tactorbelt.geometry / laws.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Final, Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._errors import ConfigError
from ._registry import check_option
from .geometry import Layout, normalize, wrap
from .laws import DEFAULT_FALLOFF_DEG, amplitudes, check_law

if TYPE_CHECKING:
    from .wearer import WearerProfile

__all__ = [
    "DEFAULT_PERIOD_S",
    "DEFAULT_TRANSIT_S",
    "MODES",
    "Stimulus",
    "make_stimulus",
    "render_batch",
]

MODES: Final = ("static", "dynamic")
DEFAULT_PERIOD_S: Final = 1.0
DEFAULT_TRANSIT_S: Final = 0.1

Mode = Literal["static", "dynamic"]


def _finite_positive(value: float, what: str, unit: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ConfigError(f"{what} must be a positive number of {unit}, got {value!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise ConfigError(f"{what} must be a positive, finite number of {unit}, got {value!r}")
    return v


def sample_times(rate_hz: float, duration_s: float) -> NDArray[np.float64]:
    """``t = i/rate`` for ``i in range(round(duration*rate))``, the rate and the duration
    checked (both positive and finite, at least one sample)."""
    rate = _finite_positive(rate_hz, "rate", "Hz")
    duration = _finite_positive(duration_s, "duration", "seconds")
    if round(duration * rate) < 1:
        raise ConfigError(
            f"duration {duration:g} s at {rate:g} Hz gives no sample; "
            "make the duration at least one sample period"
        )
    return np.arange(round(duration * rate), dtype=float) / rate


@dataclass(frozen=True)
class Stimulus:
    """A static or dynamic stimulus for one target on one layout.

    Build it with :func:`make_stimulus`, which validates the arguments.

    Attributes:
        layout: the tactor layout.
        target_deg: the target direction.
        mode: ``static`` or ``dynamic`` as asked for.
        law: the amplitude law.
        falloff_deg: T of the paper law.
        period_s: period P of the dynamic perturbation.
        transit_s: time to move between the two tactors.
        on_tactor: True when the target coincides with a tactor (then always static).
        near_idx, far_idx: the nearer and farther bracketing tactors (equal when on-tactor).
        dwell_near_s, dwell_far_s: dwell times of the perturbation (0 when static).
        profile: the wearer profile it is rendered for (None: as the law says).
    """

    layout: Layout
    target_deg: float
    mode: Mode
    law: str
    falloff_deg: float
    period_s: float
    transit_s: float
    on_tactor: bool
    near_idx: int
    far_idx: int
    dwell_near_s: float
    dwell_far_s: float
    profile: WearerProfile | None = None

    @property
    def is_dynamic(self) -> bool:
        """True when the location moves (dynamic mode on a between-tactor target)."""
        return self.mode == "dynamic" and not self.on_tactor

    @property
    def near_deg(self) -> float:
        return self.layout.angles_deg[self.near_idx]

    @property
    def far_deg(self) -> float:
        return self.layout.angles_deg[self.far_idx]

    def location(self, t: ArrayLike) -> NDArray[np.float64]:
        """The felt location (degrees, [0, 360)) at time(s) t in seconds."""
        ta = np.asarray(t, dtype=float)
        if not self.is_dynamic:
            return np.full(ta.shape, self.target_deg)
        p, tr = self.period_s, self.transit_s
        dn, df = self.dwell_near_s, self.dwell_far_s
        phase = np.mod(ta, p)
        span = wrap(self.far_deg - self.near_deg)
        # the short way is the way through the target: fix the sign from the target side
        through = wrap(self.target_deg - self.near_deg)
        if np.sign(span) != np.sign(through):
            span = span - math.copysign(360.0, span)
        t1, t2, t3 = dn, dn + tr, dn + tr + df
        frac = np.select(
            [phase < t1, phase < t2, phase < t3],
            [0.0, (phase - t1) / tr, 1.0],
            default=1.0 - (phase - t3) / tr,
        )
        frac = np.clip(frac, 0.0, 1.0)
        return np.asarray(normalize(self.near_deg + span * frac), dtype=float)

    def amplitudes(self, t: ArrayLike) -> NDArray[np.float64]:
        """Amplitudes at time(s) t: shape ``t.shape + (N,)``, values in [0, 1]."""
        return self.amplitudes_at(self.location(t))

    def amplitudes_at(self, loc: ArrayLike) -> NDArray[np.float64]:
        """The amplitudes of felt locations ``loc`` (degrees, any shape) by the stimulus's
        law and wearer profile: shape ``loc.shape + (N,)``."""
        if self.profile is None:
            return amplitudes(self.layout, loc, self.law, self.falloff_deg)
        loc = self.profile.warp_deg(self.layout, loc)
        return self.profile.apply_gains(amplitudes(self.layout, loc, self.law,
                                                   self.falloff_deg))

    def with_profile(self, profile: WearerProfile | None) -> Stimulus:
        """The same stimulus rendered for a wearer (None: without a profile).

        Raises:
            ConfigError: the profile was measured on another layout.
        """
        from dataclasses import replace

        if profile is not None:
            profile.check_layout(self.layout)
        return replace(self, profile=profile)

    def render(self, rate_hz: float = 1000.0, duration_s: float | None = None) -> tuple[
        NDArray[np.float64], NDArray[np.float64]
    ]:
        """Sample the stimulus: ``(t, amplitudes)`` with t of shape (n,), amps (n, N).

        ``duration_s`` defaults to one period.
        """
        t = sample_times(rate_hz, self.period_s if duration_s is None else duration_s)
        return t, self.amplitudes(t)

    def describe(self) -> dict[str, object]:
        """A plain dict of the parameters, for JSON and the store."""
        out: dict[str, object] = {
            "target_deg": self.target_deg,
            "mode": self.mode,
            "law": self.law,
            "falloff_deg": self.falloff_deg,
            "period_s": self.period_s,
            "transit_s": self.transit_s,
            "on_tactor": self.on_tactor,
            "tactor_angles_deg": list(self.layout.angles_deg),
            "near_tactor": self.near_idx,
            "far_tactor": self.far_idx,
            "dwell_near_s": self.dwell_near_s,
            "dwell_far_s": self.dwell_far_s,
        }
        if self.profile is not None:
            out["wearer_profile"] = self.profile.participant or "unnamed"
        return out


def make_stimulus(
    layout: Layout,
    target_deg: float,
    mode: str = "static",
    law: str = "paper",
    falloff_deg: float = DEFAULT_FALLOFF_DEG,
    period_s: float = DEFAULT_PERIOD_S,
    transit_s: float = DEFAULT_TRANSIT_S,
    profile: WearerProfile | None = None,
) -> Stimulus:
    """Build a validated stimulus (rendered for a wearer's ``profile`` when given).

    Raises:
        ConfigError: unknown mode or law, a non-finite angle, a non-positive falloff
            or period, a negative transit, ``2*transit >= period``, or a profile
            measured on another layout.
    """
    if profile is not None:
        profile.check_layout(layout)
    check_option("mode", mode, MODES)
    check_law(law, falloff_deg)
    try:
        x = float(target_deg)
    except (TypeError, ValueError):
        raise ConfigError(f"target angle must be a number of degrees, got {target_deg!r}") from None
    if not math.isfinite(x):
        raise ConfigError(f"target angle must be a finite number of degrees, got {target_deg!r}")
    x = float(normalize(x))
    period = _finite_positive(period_s, "period", "seconds")
    try:
        transit = float(transit_s)
    except (TypeError, ValueError):
        raise ConfigError(f"transit must be a number of seconds, got {transit_s!r}") from None
    if not math.isfinite(transit) or transit <= 0:
        raise ConfigError(
            f"transit must be a positive, finite number of seconds, got {transit_s!r}"
        )
    if 2 * transit >= period:
        raise ConfigError(
            f"2*transit ({2 * transit:g} s) must be shorter than the period ({period:g} s)"
        )
    on = layout.tactor_at(x)
    if on >= 0:
        return Stimulus(layout, x, mode, law, float(falloff_deg), period, transit,  # type: ignore[arg-type]
                        True, int(on), int(on), 0.0, 0.0, profile)
    ccw, cw = layout.neighbours(x)
    d_ccw = abs(float(wrap(x - layout.angles_deg[ccw])))
    d_cw = abs(float(wrap(layout.angles_deg[cw] - x)))
    # nearer tactor; at an exact midpoint the counter-clockwise one counts as nearer
    if d_ccw <= d_cw:
        near, far, dn, df = ccw, cw, d_ccw, d_cw
    else:
        near, far, dn, df = cw, ccw, d_cw, d_ccw
    hold = period - 2 * transit
    dwell_near = hold * df / (dn + df)
    dwell_far = hold * dn / (dn + df)
    return Stimulus(layout, x, mode, law, float(falloff_deg), period, transit,  # type: ignore[arg-type]
                    False, int(near), int(far), dwell_near, dwell_far, profile)


def render_batch(
    stimuli: list[Stimulus], rate_hz: float = 1000.0, duration_s: float = 1.0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Render many stimuli on one layout at once.

    Returns ``(t, amps)`` with amps of shape ``(len(stimuli), n_samples, N)``.
    All stimuli must share layout, law and falloff.
    """
    if not stimuli:
        raise ConfigError("render_batch needs at least one stimulus")
    first = stimuli[0]
    for s in stimuli[1:]:
        if (s.layout != first.layout or s.law != first.law or s.falloff_deg != first.falloff_deg
                or s.profile != first.profile):
            raise ConfigError("render_batch: every stimulus must share layout, law, falloff "
                              "and wearer profile")
    t = sample_times(rate_hz, duration_s)
    return t, first.amplitudes_at(np.stack([s.location(t) for s in stimuli]))
