"""What every power analysis counts: one simulated study's outcome, and the power at one
study size (with its Clopper-Pearson interval).

A study *finds the effect* when its test's p-value is below alpha and, for an effect
with a predicted direction, the direction holds (:meth:`StudyOutcome.found`).

Pure: NumPy and SciPy.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.stats import beta

from .._errors import ConfigError

__all__ = ["PairedTest", "PowerRow", "StudyOutcome", "binomial_ci", "power_row"]

#: ``test(static_acc, dynamic_acc) -> p_value`` on paired per-participant accuracies.
PairedTest = Callable[[NDArray[np.float64], NDArray[np.float64]], float]


@dataclass(frozen=True)
class StudyOutcome:
    """One simulated study.

    Attributes:
        n_participants: its size.
        static_acc, dynamic_acc: per-participant between-tactor accuracy.
        p_value: the test's p-value (NaN when it could not be computed).
        directional: the effect has a predicted direction (dynamic higher); an
            interaction has none.
        direction_ok: the test's own estimate has the predicted sign (a model-based
            test); None: the direction is read from the mean accuracies.
    """

    n_participants: int
    static_acc: NDArray[np.float64]
    dynamic_acc: NDArray[np.float64]
    p_value: float
    directional: bool = True
    direction_ok: bool | None = None

    def found(self, alpha: float) -> bool:
        """The test found the effect (a difference: in the predicted direction)."""
        if not (np.isfinite(self.p_value) and self.p_value < alpha):
            return False
        if self.direction_ok is not None:
            return self.direction_ok
        return (not self.directional
                or bool(np.nanmean(self.dynamic_acc) > np.nanmean(self.static_acc)))


def binomial_ci(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Clopper-Pearson (exact) confidence interval of a proportion k/n."""
    if n <= 0:
        return float("nan"), float("nan")
    a = (1.0 - level) / 2.0
    lo = 0.0 if k == 0 else float(beta.ppf(a, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1.0 - a, k + 1, n - k))
    return lo, hi


@dataclass(frozen=True)
class PowerRow:
    """Power at one study size.

    Attributes:
        n_participants: the size.
        sims: simulated studies.
        found: studies that found the difference.
        power: found / sims.
        ci_low, ci_high: 95 % Clopper-Pearson interval of the power.
        static_acc, dynamic_acc: mean between-tactor accuracy over all simulated
            participants.
        median_p: median p-value.
    """

    n_participants: int
    sims: int
    found: int
    power: float
    ci_low: float
    ci_high: float
    static_acc: float
    dynamic_acc: float
    median_p: float


def power_row(outcomes: Sequence[StudyOutcome], alpha: float = 0.05) -> PowerRow:
    """Summarise the simulated studies of one size."""
    if not outcomes:
        raise ConfigError("no simulated studies to summarise")
    n = outcomes[0].n_participants
    k = sum(o.found(alpha) for o in outcomes)
    lo, hi = binomial_ci(k, len(outcomes))
    ps = np.array([o.p_value for o in outcomes])
    return PowerRow(
        n_participants=n, sims=len(outcomes), found=k, power=k / len(outcomes),
        ci_low=lo, ci_high=hi,
        static_acc=float(np.nanmean(np.concatenate([o.static_acc for o in outcomes]))),
        dynamic_acc=float(np.nanmean(np.concatenate([o.dynamic_acc for o in outcomes]))),
        median_p=float(np.nanmedian(ps)) if np.isfinite(ps).any() else float("nan"),
    )
