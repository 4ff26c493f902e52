"""Response timing and movement of the model participant.

RT (stimulus onset to target acquisition) is built from:

- the observation time: how long the stimulus is felt before deciding (longer in a
  dynamic block, where a perturbation must be felt for most of a period);
- the decision time: non-decision time + Hick-Hyman term ``slope * log2(targets)`` +
  ex-Gaussian noise (normal plus exponential);
- the movement: a minimum-jerk reach from home to the chosen target, of which the part
  up to the acquisition radius counts.

Also the minimum-jerk profile and its inverse, vectorised.

Pure: imports NumPy and participant.params only.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .params import ModelParams

__all__ = [
    "decision_s",
    "min_jerk",
    "min_jerk_inverse",
    "observation_s",
    "one_decision_s",
    "reach_fraction",
]

FloatArray = NDArray[np.float64]

#: Decision times are never shorter than this (the ex-Gaussian's normal part can be < 0).
MIN_DECISION_S = 0.05


def min_jerk(s: ArrayLike) -> FloatArray:
    """Minimum-jerk position profile: 0 for s <= 0, 1 for s >= 1, ``10s^3 - 15s^4 + 6s^5``."""
    x = np.clip(np.asarray(s, dtype=float), 0.0, 1.0)
    return np.asarray(x * x * x * (10.0 - 15.0 * x + 6.0 * x * x))


_GRID = np.linspace(0.0, 1.0, 4097)
_PROFILE = min_jerk(_GRID)


def min_jerk_inverse(p: ArrayLike) -> FloatArray:
    """The time share at which the minimum-jerk profile reaches ``p`` (in [0, 1])."""
    return np.asarray(np.interp(np.clip(np.asarray(p, dtype=float), 0.0, 1.0),
                                _PROFILE, _GRID))


def reach_fraction(threshold: float, reach_radius: float) -> float:
    """Share of a home-to-``reach_radius`` movement after which ``threshold`` is crossed."""
    if reach_radius <= 0:
        return 1.0
    return float(min_jerk_inverse(min(threshold / reach_radius, 1.0)))


def observation_s(condition: str, params: ModelParams) -> float:
    """How long the observer feels the stimulus before deciding, in a block of ``condition``.

    In a dynamic block the observer waits for the perturbation even when the stimulus
    turns out to be static (an on-tactor target): at onset it cannot tell.
    """
    if condition == "dynamic":
        return max(params.observe_dynamic_s, params.observe_static_s)
    return params.observe_static_s


def _hick_s(n_targets: int, params: ModelParams) -> float:
    """The Hick-Hyman term of a choice among ``n_targets`` (0 for one or none)."""
    return params.hick_s_per_bit * math.log2(max(int(n_targets), 1))


def decision_s(rng: np.random.Generator, n: int, n_targets: int,
               params: ModelParams) -> FloatArray:
    """Decision times after the observation, until the movement starts (n draws).

    ``nondecision + hick * log2(n_targets) + N(0, sigma) + Exp(tau)``, at least 0.05 s.
    """
    hick = _hick_s(n_targets, params)
    normal = rng.standard_normal(n) * params.exgauss_sigma_s
    expo = rng.exponential(1.0, n) * params.exgauss_tau_s
    return np.asarray(np.maximum(params.nondecision_s + hick + normal + expo, MIN_DECISION_S))


def one_decision_s(rng: np.random.Generator, n_targets: int, params: ModelParams) -> float:
    """:func:`decision_s` of one draw: the same draws and arithmetic on scalars (a draw
    without a size is the draw of size 1; a model session takes one per trial)."""
    hick = _hick_s(n_targets, params)
    normal = rng.standard_normal() * params.exgauss_sigma_s
    expo = rng.exponential(1.0) * params.exgauss_tau_s
    return max(params.nondecision_s + hick + normal + expo, MIN_DECISION_S)
