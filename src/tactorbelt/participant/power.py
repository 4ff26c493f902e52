"""Power analysis by simulation: how often a study of N model participants finds the effect.

For each study size N and each simulated study, N individual model observers are
drawn (:func:`~tactorbelt.participant.params.draw_participant`), their test trials are
simulated on the fast path (:mod:`tactorbelt.participant.simulate`), and the
static-versus-dynamic test is run on their per-participant between-tactor accuracies.
A study *finds the difference* when the test's p-value is below alpha and the mean
dynamic accuracy is above the mean static accuracy (the direction the model predicts).

Each simulated study draws from its own generator, seeded by ``(seed, N, index)``, so
results do not depend on how the work is split across processes.

The power is a property of the model's assumptions (docs/participant-model.md), not
of people: it says how large a study would need to be *if* people behaved like it.

Pure: imports NumPy (SciPy inside :func:`binomial_ci`) and participant; the test is
passed in.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from .._errors import ConfigError
from .params import ModelParams, Spread, draw_participant
from .simulate import Protocol, StimulusCues, between_accuracy, simulate_participant

__all__ = ["PowerRow", "StudyOutcome", "binomial_ci", "exact_signed_rank_p", "power_row",
           "simulate_studies"]

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


def simulate_studies(protocol: Protocol, cues: StimulusCues, n_participants: int,
                     indices: Sequence[int], seed: int, test: PairedTest,
                     base: ModelParams | None = None, spread: Spread | None = None,
                     progress: Callable[[int], None] | None = None) -> list[StudyOutcome]:
    """Simulate the studies ``indices`` of size ``n_participants``.

    Args:
        protocol: the study's protocol.
        cues: the stimuli's cues, sensed with ``base``.
        n_participants: participants per study (at least 2).
        indices: which simulated studies (their generators are seeded by
            ``(seed, n_participants, index)``).
        seed: the base seed.
        test: the paired test.
        base, spread: the typical observer and how individuals differ.
        progress: called with 1 after each study.
    """
    if n_participants < 2:
        raise ConfigError(f"a study needs at least 2 participants, got {n_participants}")
    conds = protocol.conditions
    if "static" not in conds or "dynamic" not in conds:
        raise ConfigError("the power analysis needs a static and a dynamic test block")
    base = base if base is not None else cues.params
    out: list[StudyOutcome] = []
    for i in indices:
        rng = np.random.default_rng([int(seed), int(n_participants), int(i)])
        st = np.empty(n_participants)
        dy = np.empty(n_participants)
        for j in range(n_participants):
            params = draw_participant(rng, base, spread)
            table = simulate_participant(protocol, cues, params, rng)
            st[j] = between_accuracy(table, "static")
            dy[j] = between_accuracy(table, "dynamic")
        try:
            p = float(test(st, dy))
        except (ValueError, ZeroDivisionError, FloatingPointError):
            p = float("nan")
        out.append(StudyOutcome(n_participants, st, dy, p))
        if progress is not None:
            progress(1)
    return out


def binomial_ci(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """Clopper-Pearson (exact) confidence interval of a proportion k/n."""
    from scipy.stats import beta

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


_SIGNS: dict[int, NDArray[np.float64]] = {}


def exact_signed_rank_p(diff: NDArray[np.float64]) -> float | None:
    """Two-sided p of ``scipy.stats.wilcoxon`` on paired differences ``diff`` where SciPy
    runs its exact permutation test (ties or zeros among at most 13 pairs), by
    enumerating every sign flip in one matrix product; None where SciPy does something
    else (no ties and no zeros: its exact distribution; more than 13 pairs: the normal
    approximation), so the caller asks SciPy.

    SciPy (1.11 and later) flips the signs of all n differences (2**n arrangements,
    zeros included, which change nothing) and counts arrangements whose signed-rank sum
    is at most / at least the observed one, within a relative tolerance of 100 machine
    epsilons; the same counts over the 2**m arrangements of the m non-zero differences
    give the same proportions. ``tests/test_participant_fast.py`` checks the equality
    on random paired accuracies.
    """
    from scipy.stats import rankdata

    d = np.asarray(diff, dtype=float)
    n = d.size
    nz = d[d != 0]
    m = nz.size
    if n > 13 or m == 0:
        return None
    ranks = rankdata(np.abs(nz), method="average")
    if m == n and np.unique(ranks).size == m:
        return None  # no ties, no zeros: SciPy's exact null distribution
    signs = _SIGNS.get(m)
    if signs is None:
        signs = ((np.arange(2**m)[:, None] >> np.arange(m)[None, :]) & 1).astype(float)
        _SIGNS[m] = signs
    null = signs @ ranks
    observed = float(ranks[nz > 0].sum())
    gamma = abs(np.finfo(float).eps * 100 * observed)
    less = np.count_nonzero(null <= observed + gamma) / null.size
    greater = np.count_nonzero(null >= observed - gamma) / null.size
    return float(min(max(min(less, greater) * 2, 0.0), 1.0))
