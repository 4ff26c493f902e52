"""Parameters of the model participant, each with its source or marked as an assumption.

The model participant is a *model*: a simulated observer whose behaviour follows from
the assumptions below. Nothing it does is evidence about people (see
docs/participant-model.md).

:class:`ModelParams` holds one observer's parameters (the defaults describe a typical
observer). :func:`draw_participant` draws an individual observer around them, for
demos and power analyses with between-participant variability.

Pure: imports only the standard library, NumPy and tactorbelt._errors.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np

from .._errors import ConfigError
from .._registry import check_option

__all__ = ["ModelParams", "Spread", "draw_participant"]


@dataclass(frozen=True)
class ModelParams:
    """One model observer. Angles in degrees, times in seconds.

    Perception (what is felt where):

    Attributes:
        gamma: location weight of a tactor is ``w = A**gamma`` with A its vibration
            amplitude (2.0). Source: the energy model of funnelling, Israr & Poupyrev
            2011 ("Tactile Brush"): with gamma = 2 a location rendered with the
            ``energy`` law (A = sqrt(1 - D/s)) is felt exactly where it is rendered.
        detect_amplitude: a tactor is felt when its vibration amplitude exceeds this
            (0.02 of the rated vibration). Assumption.
        weber_amplitude: Weber fraction of vibration amplitude (0.3): each tactor's
            felt amplitude carries log-normal noise of this SD, so the log ratio of
            two weights has SD ``gamma * sqrt(2) * weber_amplitude``. Assumption, of the
            order of published vibrotactile intensity-discrimination Weber fractions
            (about 0.1 to 0.4) and chosen so that static between-tactor identification
            is poor, as the paper reports.
        weber_duration: Weber fraction of a felt dwell duration (0.3): the log ratio
            of the two dwell times has SD ``sqrt(2) * weber_duration``. Assumption, of
            the order of tactile duration-discrimination Weber fractions (0.1 to 0.3).
        dominance_margin: a tactor of the pair *dominates* while its share of the
            pair's weight is above ``0.5 + margin`` (0.1). Assumption.
        min_dwell_s: the dynamic cue is used only when each tactor of the pair
            dominated at least this long in the observed window (0.05 s). Assumption.
        p_two_points: chance that two tactors vibrating together are felt as two
            points rather than one funnelled point (0.1), scaled by the share of the
            window in which both are felt; the observer then answers at the stronger
            one. Assumption (funnelling needs simultaneous stimulation; Israr &
            Poupyrev 2011 report reliable funnelling at their spacing).
        loc_sd_min_deg, loc_sd_max_deg: SD of the felt body site (which tactor or
            pair), ``min + (max - min) * sin(theta)**2``: smallest at the navel and the
            spine (anatomical anchor points), largest at the flanks (8 and 16 deg).
            Source: fitted so that single-tactor localisation with 6, 8 and 12 evenly
            spaced tactors (one at the navel) comes out near 97, 92 and 74 % correct,
            as Cholewiak, Brill & Schwab 2004 report; the range matches "about 8 to 17
            deg".
        midline_bias_deg: the felt body site is pulled towards the navel and the spine
            by ``-bias * sin(2 * theta)``: up to this many degrees at oblique directions,
            none at the midline and the flanks (9 deg). Source: van Erp 2005,
            "Presenting directions with a vibrotactile torso display" (biases towards
            the midsagittal plane of up to about 10 deg).
        lapse: chance of answering a random target, whatever was felt (0.01).
            Assumption (a usual lapse rate in psychophysics).

    Timing (RT = non-decision + observation + Hick-Hyman + ex-Gaussian):

    Attributes:
        observe_static_s: time the observer feels a stimulus before deciding in a
            static block (0.3 s). Assumption.
        observe_dynamic_s: the same in a dynamic block (0.9 s): long enough to feel
            the first dwell, the move and the second dwell of a 1 s perturbation
            (0.9 of its period). Assumption; scale it with the study's period
            (:meth:`for_period`).
        nondecision_s: encoding and response initiation (0.25 s). Assumption, of
            the order of non-decision times fitted to choice RTs (0.2 to 0.4 s).
        hick_s_per_bit: Hick-Hyman slope: ``hick_s_per_bit * log2(number of
            targets)`` (0.15 s/bit). Source: Hick 1952, Hyman 1953 (about 0.15 s/bit).
        exgauss_sigma_s, exgauss_tau_s: ex-Gaussian noise added to the decision time:
            normal (mean 0, SD sigma) plus exponential (mean tau) (0.05 s, 0.2 s).
            Assumption, typical of fitted choice-RT distributions.

    Movement (what the runner and the store see):

    Attributes:
        movement_s: duration of the minimum-jerk movement from home to the chosen
            target (0.35 s). Assumption (joystick aiming movements).
        endpoint_sd_deg: SD of the movement's direction around the chosen target
            (1.5 deg; small against the 15 deg between targets). Assumption.
        reach_radius: how far out the movement goes (1.0 = the ellipse).
        jitter: SD of the sensor noise on each cursor sample (0.002). Assumption.
        return_s: time to spring back home after a trial (0.25 s). Assumption.
    """

    gamma: float = 2.0
    detect_amplitude: float = 0.02
    weber_amplitude: float = 0.3
    weber_duration: float = 0.3
    dominance_margin: float = 0.1
    min_dwell_s: float = 0.05
    p_two_points: float = 0.1
    loc_sd_min_deg: float = 8.0
    loc_sd_max_deg: float = 16.0
    midline_bias_deg: float = 9.0
    lapse: float = 0.01
    observe_static_s: float = 0.3
    observe_dynamic_s: float = 0.9
    nondecision_s: float = 0.25
    hick_s_per_bit: float = 0.15
    exgauss_sigma_s: float = 0.05
    exgauss_tau_s: float = 0.2
    movement_s: float = 0.35
    endpoint_sd_deg: float = 1.5
    reach_radius: float = 1.0
    jitter: float = 0.002
    return_s: float = 0.25

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise ConfigError(f"ModelParams.{f.name} must be a finite number, got {v!r}")
            if v < 0:
                raise ConfigError(f"ModelParams.{f.name} must be >= 0, got {v!r}")
        for name in ("p_two_points", "lapse"):
            if getattr(self, name) > 1:
                raise ConfigError(f"ModelParams.{name} is a probability in [0, 1], "
                                  f"got {getattr(self, name)!r}")
        if self.gamma <= 0:
            raise ConfigError(f"ModelParams.gamma must be > 0, got {self.gamma!r}")
        if self.dominance_margin >= 0.5:
            raise ConfigError("ModelParams.dominance_margin must be in [0, 0.5), "
                              f"got {self.dominance_margin!r}")
        if self.loc_sd_max_deg < self.loc_sd_min_deg:
            raise ConfigError("ModelParams.loc_sd_max_deg must be >= loc_sd_min_deg")
        if not 0 < self.reach_radius <= 1.5:
            raise ConfigError(f"ModelParams.reach_radius must be in (0, 1.5], "
                              f"got {self.reach_radius!r}")
        if self.movement_s <= 0 or self.return_s <= 0:
            raise ConfigError("ModelParams.movement_s and return_s must be > 0")

    def replace(self, **changes: Any) -> ModelParams:
        """A copy with some fields changed (validated)."""
        for name in sorted(changes):
            check_option("model parameter", name, [f.name for f in fields(self)])
        return replace(self, **changes)

    def for_period(self, period_s: float) -> ModelParams:
        """The same observer for a study whose dynamic period is ``period_s``.

        ``observe_dynamic_s`` is read as the time for a 1 s period (0.9 s by default) and
        scaled to ``period_s`` (never below ``observe_static_s``).
        """
        if not (math.isfinite(period_s) and period_s > 0):
            raise ConfigError(f"period must be a positive number of seconds, got {period_s!r}")
        share = self.observe_dynamic_s / 1.0
        return self.replace(observe_dynamic_s=max(self.observe_static_s, share * period_s))

    def to_dict(self) -> dict[str, float]:
        """The parameters as a plain dict (for JSON)."""
        return {f.name: float(getattr(self, f.name)) for f in fields(self)}


@dataclass(frozen=True)
class Spread:
    """How much individual observers differ (all assumptions, for power analyses).

    Each listed parameter is multiplied by ``exp(N(0, sd))`` (a log-normal factor with
    median 1); probabilities are clipped to [0, 1]. gamma and the observation times are
    shared by everyone (the stimulus and the task are the same for all).

    Attributes:
        perceptual_sd: SD of the log factor on the Weber fractions (0.25).
        localisation_sd: SD of the log factor on the localisation SDs and the bias (0.15).
        rate_sd: SD of the log factor on the two-point chance and the lapse rate (0.5).
        timing_sd: SD of the log factor on the non-decision time, the Hick-Hyman slope,
            the ex-Gaussian tau and the movement time (0.15).
    """

    perceptual_sd: float = 0.25
    localisation_sd: float = 0.15
    rate_sd: float = 0.5
    timing_sd: float = 0.15


_GROUPS: dict[str, tuple[str, ...]] = {
    "perceptual_sd": ("weber_amplitude", "weber_duration"),
    "localisation_sd": ("loc_sd_min_deg", "loc_sd_max_deg", "midline_bias_deg"),
    "rate_sd": ("p_two_points", "lapse"),
    "timing_sd": ("nondecision_s", "hick_s_per_bit", "exgauss_tau_s", "movement_s"),
}


def draw_participant(rng: np.random.Generator, base: ModelParams | None = None,
                     spread: Spread | None = None) -> ModelParams:
    """Draw one individual observer around ``base`` (default: the typical observer).

    Each parameter group gets one log-normal factor per observer (so, for instance,
    an observer with poor amplitude discrimination also has poor duration
    discrimination); the factors of different groups are independent.
    """
    base = base if base is not None else ModelParams()
    spread = spread if spread is not None else Spread()
    changes: dict[str, float] = {}
    for group, names in _GROUPS.items():
        factor = float(np.exp(rng.normal(0.0, getattr(spread, group))))
        for name in names:
            v = getattr(base, name) * factor
            if name in ("p_two_points", "lapse"):
                v = min(v, 1.0)
            changes[name] = v
    return base.replace(**changes)
