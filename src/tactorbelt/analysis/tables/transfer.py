"""Information transfer (bits) from a confusion matrix: estimators, bounds, bootstrap.

The information transferred from stimulus to response is their mutual information

    IT = sum_ij p_ij log2( p_ij / (p_i. p_.j) ),   p_ij = n_ij / N,

estimated here from a matrix of counts ``n_ij`` (rows: the stimulus, columns: the
response). The plug-in (maximum-likelihood) estimate :func:`information_transfer` is
biased upwards for small N: with a few trials per target, chance coincidences look
like transfer. Five published corrections are implemented, all from the counts alone:

- :func:`miller_madow_transfer`: the first-order bias of ``IT = H(R) - H(R|S)``
  subtracted, ``(sum_s (R_s - 1) - (R - 1)) / (2 N ln 2)`` with ``R_s`` the non-empty
  cells of row s and ``R`` the non-empty columns (Miller 1955; Panzeri & Treves 1996,
  Network 7:87-107, with naive bin counting).
- :func:`panzeri_treves_transfer`: the same formula with ``R_s`` and ``R`` from the
  Bayesian bin counting of Panzeri & Treves (1996), which adds the bins a row
  probably has but did not show in its few trials.
- :func:`jackknife_transfer`: the delete-one-trial jackknife (Quenouille 1956;
  Efron & Stein 1981; Strong et al. 1998 for information), ``N I - (N - 1) mean(I_-k)``,
  in closed form (no loop over trials).
- :func:`chao_shen_transfer`: ``H(R) - sum_s p_s H(R|s)`` with each entropy from the
  coverage-adjusted (Horvitz-Thompson) estimator of Chao & Shen (2003, Environ. Ecol.
  Stat. 10:429-443).
- :func:`bootstrap_corrected_transfer`: ``2 I - mean(I*)`` over resamples of each row
  (the bootstrap bias correction, Efron & Tibshirani 1993, ch. 10).

:data:`ESTIMATOR` names the one the analysis reports (:func:`estimate_transfer`),
chosen by a simulation with known truth (``scripts/it_estimators.py``,
docs/analysis.md "Information transfer").

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
from collections.abc import Callable, Sequence
from typing import Final

import numpy as np

__all__ = [
    "ESTIMATOR",
    "ESTIMATORS",
    "bootstrap_corrected_transfer",
    "bootstrap_draws",
    "cell_interval",
    "chao_shen_transfer",
    "confusion_matrix",
    "estimate_transfer",
    "expanded_levels",
    "information_transfer",
    "jackknife_transfer",
    "miller_madow_bias",
    "miller_madow_transfer",
    "panzeri_treves_transfer",
    "stimulus_entropy",
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


def _dec(x: np.ndarray) -> np.ndarray:
    """x ln x - (x - 1) ln(x - 1): what removing one count takes off x ln x (0 at x <= 1)."""
    return np.where(x > 1, _xlogx(x) - _xlogx(np.maximum(x - 1.0, 0.0)), 0.0)


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


def stimulus_entropy(counts: Counts) -> float | np.ndarray:
    """The entropy (bits) of the row totals: the most a matrix can transmit.

    ``log2 M`` for M targets answered equally often (rows with no trial do not count).
    """
    return _out(_stimulus_entropy(_counts(counts)))


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


def _mm_bias(m: np.ndarray) -> np.ndarray:
    n = m.sum(axis=(-2, -1))
    rows = m.sum(axis=-1)
    per_row = np.count_nonzero(m, axis=-1)
    occupied_rows = np.count_nonzero(rows, axis=-1)
    cols = np.count_nonzero(m.sum(axis=-2), axis=-1)
    num = (per_row.sum(axis=-1) - occupied_rows) - (cols - 1)
    return np.where(n > 0, num / (2.0 * np.where(n > 0, n, 1.0) * LN2), 0.0)


def miller_madow_bias(counts: Counts) -> float | np.ndarray:
    """The first-order bias of the plug-in estimate in bits (see the module docstring).

    ``(sum_s (R_s - 1) - (R - 1)) / (2 N ln 2)`` with R_s the non-empty cells of row s
    (over the non-empty rows) and R the non-empty columns; 0 for an empty matrix.
    """
    return _out(_mm_bias(_counts(counts)))


def miller_madow_transfer(counts: Counts, *, clamp: bool = True) -> float | np.ndarray:
    """Information transfer in bits with the Miller-Madow bias correction."""
    m = _counts(counts)
    return _bound(_plugin_bits(m) - _mm_bias(m), m, clamp)


def _pt_bins(c: np.ndarray) -> np.ndarray:
    """Panzeri & Treves' (1996) Bayesian estimate of the relevant bins of each count vector.

    ``c``: (K, D) counts of K distributions over D bins. With Nt trials and R~ occupied
    bins, x unseen bins are supposed to share gamma = x (1 - (Nt / (Nt + R~))^(1/Nt)) of
    the probability, the seen ones (1 - gamma)(n_k + 1) / (Nt + R~); x runs up from 0
    while the expected number of occupied bins in Nt trials gets closer to R~, and the
    estimate is R~ + x at the first minimum of that distance (D at most).
    """
    k, d = c.shape
    chunk = max(1, 2_000_000 // ((d + 1) * d))
    if k > chunk:  # bound the (rows, candidates, bins) temporaries
        return np.concatenate([_pt_bins(c[i:i + chunk]) for i in range(0, k, chunk)])
    nt = c.sum(axis=1)
    occ = c > 0
    rn = occ.sum(axis=1).astype(float)
    out = rn.copy()
    todo = (rn < d) & (nt > 0)
    if not todo.any():
        return out
    c, nt, occ, rn = c[todo], nt[todo][:, None], occ[todo], rn[todo][:, None]
    p = c / nt
    xs = np.arange(d + 1, dtype=float)[None, :]                       # (1, X)
    # x = 0: the naive frequencies
    e0 = (occ * (1.0 - (1.0 - p) ** nt)).sum(axis=1, keepdims=True)
    step = 1.0 - (nt / (nt + rn)) ** (1.0 / nt)                      # (K, 1)
    gamma = xs * step                                                  # (K, X)
    q = ((1.0 - gamma)[:, :, None] * (c[:, None, :] + 1.0) / (nt + rn)[:, :, None])
    seen = (occ[:, None, :] * (1.0 - (1.0 - q) ** nt[:, :, None])).sum(axis=2)
    unseen = xs * (1.0 - (1.0 - step) ** nt)
    e = np.where(xs == 0, e0, seen + unseen)
    delta = np.abs(rn - e)
    delta = np.where((rn + xs > d) | (gamma > 1.0), np.inf, delta)
    stop = np.append(delta[:, 1:] >= delta[:, :-1], np.ones((len(delta), 1), bool), axis=1)
    x = np.argmax(stop, axis=1).astype(float)
    out[todo] = rn[:, 0] + x
    return out


def _pt_bias(m: np.ndarray) -> np.ndarray:
    shape = m.shape[:-2]
    s, r = m.shape[-2:]
    flat = m.reshape(-1, s, r)
    n = flat.sum(axis=(1, 2))
    rows = flat.sum(axis=2)
    rs = _pt_bins(flat.reshape(-1, r)).reshape(-1, s)
    rs = np.where(rows > 0, rs - 1.0, 0.0).sum(axis=1)
    rr = _pt_bins(flat.sum(axis=1)) - 1.0
    bias = np.where(n > 0, (rs - rr) / (2.0 * np.where(n > 0, n, 1.0) * LN2), 0.0)
    return bias.reshape(shape)


def panzeri_treves_transfer(counts: Counts, *, clamp: bool = True) -> float | np.ndarray:
    """Information transfer in bits with the Panzeri-Treves (1996) correction.

    The Miller-Madow formula with Bayesian bin counting: each row's relevant responses
    (and the response marginal's) are the occupied ones plus those its few trials
    probably missed (:func:`_pt_bins`).
    """
    m = _counts(counts)
    return _bound(_plugin_bits(m) - _pt_bias(m), m, clamp)


def _jackknife_bits(m: np.ndarray) -> np.ndarray:
    # I_J = N I - (N-1) mean_k I_(-k). With T = sum f(n_ij) - sum f(n_i.) - sum f(n_.j)
    # + f(N) (f = x ln x, I = T / N), deleting one trial of cell ij turns T into
    # T - d(n_ij) + d(n_i.) + d(n_.j) - d(N) (d = _dec); averaging over the N trials
    # gives I_J = [sum n_ij d(n_ij) - sum n_i. d(n_i.) - sum n_.j d(n_.j) + N d(N)] / N.
    n = m.sum(axis=(-2, -1))
    rows = m.sum(axis=-1)
    cols = m.sum(axis=-2)
    t = ((m * _dec(m)).sum(axis=(-2, -1)) - (rows * _dec(rows)).sum(axis=-1)
         - (cols * _dec(cols)).sum(axis=-1) + n * _dec(n))
    ok = n >= 2
    return np.where(ok, t / np.where(ok, n, 1.0) / LN2, _plugin_bits(m))


def jackknife_transfer(counts: Counts, *, clamp: bool = True) -> float | np.ndarray:
    """Information transfer in bits, delete-one-trial jackknife bias-corrected.

    ``N I - (N - 1) mean_k I_(-k)`` over the N trials (the plug-in value for N < 2).
    """
    m = _counts(counts)
    return _bound(_jackknife_bits(m), m, clamp)


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


def _resample_rows(m: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` resamples of one matrix, each row redrawn (multinomial) from its proportions."""
    rows = m.sum(axis=1)
    p = np.where(rows[:, None] > 0, m / np.where(rows > 0, rows, 1.0)[:, None], 1.0 / m.shape[1])
    return rng.multinomial(rows.astype(np.int64), p, size=(n, m.shape[0])).astype(float)


def bootstrap_corrected_transfer(counts: Counts, *, n_boot: int = 200,
                                 rng: np.random.Generator | int = 0,
                                 clamp: bool = True) -> float | np.ndarray:
    """Information transfer in bits, bootstrap bias-corrected: ``2 I - mean(I*)``.

    ``I*`` is the plug-in value of ``n_boot`` resamples in which every row (stimulus) is
    redrawn from its own proportions with its own total (the design fixes the trials
    per target). Counts must be integers. A stack of matrices is corrected one by one.
    """
    m = _counts(counts)
    gen = np.random.default_rng(rng)
    flat = m.reshape(-1, *m.shape[-2:])
    out = np.empty(len(flat))
    for i, one in enumerate(flat):
        star = _plugin_bits(_resample_rows(one, n_boot, gen))
        out[i] = 2.0 * _plugin_bits(one) - star.mean()
    return _bound(out.reshape(m.shape[:-2]), m, clamp)


Estimator = Callable[..., "float | np.ndarray"]

#: every estimator by name (the names of summary.json's ``it_bits_method`` and the docs)
ESTIMATORS: Final[dict[str, Estimator]] = {
    "plug-in": information_transfer,
    "Miller-Madow": miller_madow_transfer,
    "Panzeri-Treves": panzeri_treves_transfer,
    "jackknife": jackknife_transfer,
    "Chao-Shen": chao_shen_transfer,
    "bootstrap": bootstrap_corrected_transfer,
}

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

    def dense(self, c: np.ndarray) -> np.ndarray:
        """The full ``(b, s, r)`` matrices of :meth:`draw`'s counts."""
        b = len(c)
        s, r = self.shape
        out = np.zeros((b, s, r))
        np.add.at(out, (np.arange(b)[:, None, None], np.arange(s)[None, :, None],
                        self.cols[None, :, :]), c)
        return out


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


def confusion_matrix(
    stimulus: Sequence[float] | np.ndarray,
    response: Sequence[float] | np.ndarray,
    categories: Sequence[float] | np.ndarray,
    *,
    decimals: int = 6,
) -> np.ndarray:
    """Counts of (stimulus, response) pairs over ``categories`` (e.g. target angles).

    Values are matched after rounding to ``decimals``; a pair whose stimulus or
    response is not a category (or is NaN, e.g. a timeout) is not counted.
    """
    cats = np.round(np.asarray(categories, dtype=float), decimals)
    index = {float(c): i for i, c in enumerate(cats)}
    out = np.zeros((len(cats), len(cats)), dtype=np.int64)
    s = np.round(np.asarray(stimulus, dtype=float), decimals)
    r = np.round(np.asarray(response, dtype=float), decimals)
    for a, b in zip(s.tolist(), r.tolist(), strict=True):
        i = index.get(a)
        j = index.get(b)
        if i is not None and j is not None:
            out[i, j] += 1
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
    from scipy.stats import norm
    from scipy.stats import t as t_dist

    z = math.sqrt(n / (n - 1.0)) * float(t_dist.ppf(1.0 - a, n - 1))
    lo = float(norm.cdf(-z))
    return lo, 1.0 - lo
