"""The ideal model observer, for the tests of the model participant's perception."""

from __future__ import annotations

from tactorbelt.participant import ModelParams


def noiseless(params: ModelParams | None = None) -> ModelParams:
    """``params`` (default: the typical observer) as the ideal observer: no perceptual
    noise, bias, lapse or two-point percepts.

    Timing keeps its means (no ex-Gaussian spread); movement keeps no endpoint noise.
    """
    return (params or ModelParams()).replace(
        weber_amplitude=0.0, weber_duration=0.0, p_two_points=0.0, loc_sd_min_deg=0.0,
        loc_sd_max_deg=0.0, midline_bias_deg=0.0, lapse=0.0, exgauss_sigma_s=0.0,
        exgauss_tau_s=0.0, endpoint_sd_deg=0.0, jitter=0.0)
