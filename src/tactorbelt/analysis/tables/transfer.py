"""Information transfer (bits) from a confusion matrix: estimators, bounds, bootstrap.

The information transferred from stimulus to response is their mutual information

    IT = sum_ij p_ij log2( p_ij / (p_i. p_.j) ),   p_ij = n_ij / N,

estimated here from a matrix of counts ``n_ij`` (rows: the stimulus, columns: the
response). The plug-in (maximum-likelihood) estimate :func:`information_transfer` is
biased upwards for small N: with a few trials per target, chance coincidences look
like transfer. The analysis reports :func:`chao_shen_transfer`: ``H(R) - sum_s p_s
H(R|s)`` with each entropy from the coverage-adjusted (Horvitz-Thompson) estimator of
Chao & Shen (2003, Environ. Ecol. Stat. 10:429-443).

:data:`ESTIMATOR` names it (:func:`estimate_transfer`), chosen among five published
corrections by a simulation with known truth (``scripts/it_estimators.py``,
docs/analysis.md "Information transfer"; the other four, Miller-Madow, Panzeri-Treves,
the jackknife and the bootstrap, are in ``tests/support/it_estimators.py``).

**Bounds.** Every estimate here is clamped to ``[0, H(S)]`` after its correction, where
``H(S)`` is the entropy of the matrix's row totals (``log2 M`` for M targets answered
equally often, and never more): no channel transmits more than its stimulus entropy,
and no information is negative. A correction can cross either bound on its own (on a
perfect 12-target matrix Miller-Madow gives 3.92 bits with 2 trials per target and
3.81 with 3, the jackknife 3.84 and Chao-Shen 3.75 with 3, against log2 12 = 3.585).
``clamp=False`` returns the raw value (for simulations). Averages of clamped estimates
are biased upwards near 0 bits and downwards near ``H(S)``; docs/analysis.md compares
clamped and unclamped errors.

All estimators also take a stack of matrices (``(..., S, R)``, one value per matrix),
as the simulation draws them. :func:`cell_interval` is the interval of a cell's mean
over participants (a two-level bootstrap, :func:`bootstrap_draws` within each).

Pure: NumPy (SciPy's t and normal quantiles for the interval's levels).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Final

import numpy as np
from scipy.stats import norm
from scipy.stats import t as t_dist

__all__ = [
    "ESTIMATOR",
    "bootstrap_draws",
    "cell_interval",
    "chao_shen_transfer",
    "estimate_transfer",
    "expanded_levels",
    "information_transfer",
    "two_level_means",
]

LN2: Final = math.log(2.0)
Counts = np.ndarray | Sequence[Sequence[float]]


def _counts(counts: Counts) -> np.ndarray:
    m = np.asarray(counts, dtype=float)
    if m.ndim < 2:
        raise ValueError(f"a confusion matrix is 2-D (stimulus x response); got {m.ndim}-D")
    if not np.all(np.isfinite(m)) or np.any(m < 0):
        raise ValueError("confusion-matrix counts must be finite and >= 0")
    return m


def _xlogx(x: np.ndarray) -> np.ndarray:
    """x ln x with 0 ln 0 = 0."""
    safe = np.where(x > 0, x, 1.0)
    return np.where(x > 0, x * np.log(safe), 0.0)


def _out(v: np.ndarray) -> float | np.ndarray:
    return float(v) if v.ndim == 0 else v


def _entropy_rows_bits(totals: np.ndarray) -> np.ndarray:
    """Plug-in entropy (bits) of the distribution given by ``totals`` along the last axis."""
    n = totals.sum(axis=-1)
    safe = np.where(n > 0, n, 1.0)
    h = (_xlogx(safe) - _xlogx(totals).sum(axis=-1)) / safe / LN2
    return np.where(n > 0, np.maximum(h, 0.0), 0.0)


def _stimulus_entropy(m: np.ndarray) -> np.ndarray:
    rows = m.sum(axis=-1)
    k = np.count_nonzero(rows, axis=-1)
    top = rows.max(axis=-1)
    # rows answered equally often: exactly log2 of their number (the clamp's ceiling)
    equal = np.all((rows == 0) | (rows == top[..., None]), axis=-1)
    return np.where(equal, np.log2(np.maximum(k, 1)), _entropy_rows_bits(rows))


def _bound(it: np.ndarray, m: np.ndarray, clamp: bool) -> float | np.ndarray:
    n = m.sum(axis=(-2, -1))
    it = np.where(n > 0, it, 0.0)
    if clamp:
        it = np.clip(it, 0.0, _stimulus_entropy(m))
    return _out(it)


def _plugin_bits(m: np.ndarray) -> np.ndarray:
    n = m.sum(axis=(-2, -1))
    rows = m.sum(axis=-1)
    cols = m.sum(axis=-2)
    t = (_xlogx(m).sum(axis=(-2, -1)) - _xlogx(rows).sum(axis=-1) - _xlogx(cols).sum(axis=-1)
         + _xlogx(n))
    return np.where(n > 0, t / np.where(n > 0, n, 1.0) / LN2, 0.0)


def information_transfer(counts: Counts, *, clamp: bool = True) -> float | np.ndarray:
    """The plug-in (maximum-likelihood) information transfer in bits.

    Args:
        counts: stimulus x response counts (any non-negative numbers), or a stack of
            them (``(..., S, R)``: one value per matrix).
        clamp: keep the value in ``[0, H(S)]`` (it is there anyway up to rounding).

    Returns:
        Mutual information in bits; 0 for an empty matrix. An identity matrix of M
        equally frequent stimuli gives log2(M); independent rows give 0.
    """
    m = _counts(counts)
    return _bound(_plugin_bits(m), m, clamp)


def _chao_shen_nats(c: np.ndarray) -> np.ndarray:
    """Coverage-adjusted entropy (nats) of count vectors along the last axis."""
    n = c.sum(axis=-1, keepdims=True)
    safe = np.where(n > 0, n, 1.0)
    f1 = (c == 1).sum(axis=-1, keepdims=True).astype(float)
    f1 = np.where(f1 == n, n - 1.0, f1)            # all singletons: coverage not 0
    cov = 1.0 - f1 / safe
    pa = cov * c / safe
    la = 1.0 - (1.0 - pa) ** safe
    ok = c > 0
    term = np.where(ok, -pa * np.log(np.where(ok, pa, 1.0)) / np.where(ok, la, 1.0), 0.0)
    return np.where(n[..., 0] > 0, term.sum(axis=-1), 0.0)


def _chao_shen_bits(m: np.ndarray) -> np.ndarray:
    n = m.sum(axis=(-2, -1))
    rows = m.sum(axis=-1)
    h_r = _chao_shen_nats(m.sum(axis=-2))
    h_rs = (rows * _chao_shen_nats(m)).sum(axis=-1) / np.where(n > 0, n, 1.0)
    return (h_r - h_rs) / LN2


def chao_shen_transfer(counts: Counts, *, clamp: bool = True) -> float | np.ndarray:
    """Information transfer in bits, ``H(R) - sum_s p_s H(R|s)`` with Chao-Shen entropies."""
    m = _counts(counts)
    return _bound(_chao_shen_bits(m), m, clamp)


#: the estimator the analysis reports (docs/analysis.md: smallest RMSE in the simulation);
#: :func:`estimate_transfer` and :func:`bootstrap_draws` compute it
ESTIMATOR: Final = "Chao-Shen"


def estimate_transfer(counts: Counts) -> float | np.ndarray:
    """Information transfer in bits by :data:`ESTIMATOR`, clamped to ``[0, H(S)]``."""
    return chao_shen_transfer(counts)


class _Plan:
    """One matrix's resampling plan: each row's occupied cells and their proportions."""

    def __init__(self, m: np.ndarray) -> None:
        s, r = m.shape
        self.rows = m.sum(axis=1)
        support = [np.flatnonzero(m[i]) for i in range(s)]
        self.k = k = max([1, *(len(x) for x in support)])
        probs = np.zeros((s, k))
        #: the column of each row's j-th occupied cell (0 for padding, never drawn)
        self.cols = np.zeros((s, k), dtype=np.int64)
        for i, x in enumerate(support):
            if len(x):
                probs[i, :len(x)] = m[i, x] / self.rows[i]
                self.cols[i, :len(x)] = x
            else:
                probs[i, 0] = 1.0  # an empty row draws nothing
        # multinomial rows as categorical trials: a trial falls in the first cell whose
        # cumulative probability exceeds a uniform draw (the last is exactly 1, so the
        # padding is never reached)
        cum = np.cumsum(probs, axis=1)
        self.cum = (cum / cum[:, -1:])[:, :-1]
        t = self.rows.astype(np.int64)
        self.tmax = max(1, int(t.max()))
        self.live = np.arange(self.tmax)[None, :] < t[:, None]        # (s, tmax)
        self.shape = (s, r)

    def draw(self, b: int, rng: np.random.Generator) -> np.ndarray:
        """``b`` resamples as counts of each row's occupied cells, ``(b, s, k)``."""
        s, _ = self.shape
        u = rng.random((b, s, self.tmax))
        cell = (u[..., None] >= self.cum[None, :, None, :]).sum(axis=-1)   # (b, s, tmax)
        idx = (np.arange(b)[:, None, None] * s + np.arange(s)[None, :, None]) * self.k + cell
        c = np.bincount(idx[:, self.live].ravel(), minlength=b * s * self.k)
        return c.reshape(b, s, self.k).astype(float)

def bootstrap_draws(counts: Counts, n: int, rng: np.random.Generator) -> np.ndarray:
    """:func:`estimate_transfer` of ``n`` resamples of one matrix (rows redrawn).

    Each row keeps its total and is redrawn (multinomial) from its own proportions:
    the trials of a participant's matrix resampled within each target. Counts must be
    integers. Returns an array of ``n`` values.

    A resampled row can only fill the cells its original filled, so the resamples are
    drawn and estimated on those cells alone (a few per row instead of M), the column
    totals gathered with ``bincount``: the same values as ``estimate_transfer`` of the
    full matrices (a test checks it), many times faster.
    """
    m = _counts(counts)
    if m.ndim != 2:
        raise ValueError("bootstrap_draws takes one matrix")
    total = float(m.sum())
    if total <= 0:
        return np.zeros(n)
    plan = _Plan(m)
    s, r = plan.shape
    ceiling = float(_stimulus_entropy(m))
    weight = plan.rows / total
    out = np.empty(n)
    chunk = max(1, 2_000_000 // (s * plan.tmax * plan.k + s * plan.k + r))
    for start in range(0, n, chunk):
        b = min(chunk, n - start)
        c = plan.draw(b, rng)
        flat = (np.arange(b)[:, None, None] * r + plan.cols[None, :, :]).ravel()
        col = np.bincount(flat, weights=c.ravel(), minlength=b * r).reshape(b, r)
        it = (_chao_shen_nats(col) - (_chao_shen_nats(c) * weight).sum(axis=1)) / LN2
        out[start:start + b] = np.clip(it, 0.0, ceiling)
    return out


def cell_interval(matrices: Sequence[Counts], *, rng: np.random.Generator,
                  n_boot: int = 4000, level: float = 0.95) -> tuple[float, float]:
    """Two-level bootstrap interval of the mean over participants of :func:`estimate_transfer`.

    Each of ``n_boot`` resamples draws the participants with replacement and, for each
    one drawn, a resample of that participant's trials (:func:`bootstrap_draws`: every
    row redrawn from its own proportions), recentred on the participant's estimate (a
    bias-corrected estimator's resamples scatter around the plug-in value, the truth of
    the resampled world, not around the estimate), clamped to ``[0, H(S)]``, and
    averages them. The interval takes the percentiles of these means at the expanded
    levels of Hesterberg (2015, The American Statistician 69:371-386, "expanded
    percentile interval"), ``Phi(+-sqrt(n / (n - 1)) t_(n-1, (1 + level) / 2))`` for n
    participants, which make up for the bootstrap's narrowness with few participants
    (with 4 the plain percentile interval covered 82-87 % instead of 95 %:
    docs/analysis.md); with one participant it is the plain percentile interval of the
    trial-level bootstrap. ``(nan, nan)`` without matrices.

    A participant contributes ``clip(ceil(n_boot / n), 50, n_boot)`` trial resamples,
    so the work grows with the participants only past ``n_boot / 50`` of them.
    """
    if len(matrices) == 0:
        return float("nan"), float("nan")
    vals = two_level_means(matrices, rng=rng, n_boot=n_boot)
    lo, hi = np.quantile(vals, expanded_levels(len(matrices), level))
    return float(lo), float(hi)


def two_level_means(matrices: Sequence[Counts], *, rng: np.random.Generator,
                    n_boot: int = 4000) -> np.ndarray:
    """The ``n_boot`` resampled means of :func:`cell_interval` (at least one matrix)."""
    mats = [_counts(m) for m in matrices]
    n = len(mats)
    est = np.array([float(estimate_transfer(m)) for m in mats])
    ceil = np.array([float(_stimulus_entropy(m)) for m in mats])
    per = int(np.clip(math.ceil(n_boot / n), 50, n_boot))
    noise = np.empty((n, per))
    for i, m in enumerate(mats):
        d = bootstrap_draws(m, per, rng)
        noise[i] = d - d.mean()
    who = rng.integers(n, size=(n_boot, n))
    which = rng.integers(per, size=(n_boot, n))
    return np.clip(est[who] + noise[who, which], 0.0, ceil[who]).mean(axis=1)


def expanded_levels(n: int, level: float = 0.95) -> tuple[float, float]:
    """The percentile levels of Hesterberg's expanded percentile interval for n observations.

    ``Phi(-+ sqrt(n / (n - 1)) t_(n-1, (1 + level) / 2))``; the plain ones
    ``((1 - level) / 2, (1 + level) / 2)`` for n < 2.
    """
    a = (1.0 - level) / 2.0
    if n < 2:
        return a, 1.0 - a
    z = math.sqrt(n / (n - 1.0)) * float(t_dist.ppf(1.0 - a, n - 1))
    lo = float(norm.cdf(-z))
    return lo, 1.0 - lo
