"""The information-transfer estimators the analysis does not report, kept for the tests
and for the simulation that chose :data:`~tactorbelt.analysis.tables.transfer.ESTIMATOR`
(``scripts/it_estimators.py``, docs/analysis.md "Information transfer").

Beside the plug-in :func:`~tactorbelt.analysis.tables.transfer.information_transfer` and
the reported :func:`~tactorbelt.analysis.tables.transfer.chao_shen_transfer`:

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
- :func:`bootstrap_corrected_transfer`: ``2 I - mean(I*)`` over resamples of each row
  (the bootstrap bias correction, Efron & Tibshirani 1993, ch. 10).

Each is clamped to ``[0, H(S)]`` as the reported one (``clamp=False``: the raw value).
Also :func:`confusion_matrix` (counts of stimulus-response pairs), :func:`stimulus_entropy`
and :func:`dense` (a resampling plan's draws as full matrices).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Final

import numpy as np

from tactorbelt.analysis.tables.transfer import (
    LN2,
    Counts,
    _bound,
    _counts,
    _out,
    _Plan,
    _plugin_bits,
    _stimulus_entropy,
    _xlogx,
    chao_shen_transfer,
    information_transfer,
)


def _dec(x: np.ndarray) -> np.ndarray:
    """x ln x - (x - 1) ln(x - 1): what removing one count takes off x ln x (0 at x <= 1)."""
    return np.where(x > 1, _xlogx(x) - _xlogx(np.maximum(x - 1.0, 0.0)), 0.0)


def stimulus_entropy(counts: Counts) -> float | np.ndarray:
    """The entropy (bits) of the row totals: the most a matrix can transmit.

    ``log2 M`` for M targets answered equally often (rows with no trial do not count).
    """
    return _out(_stimulus_entropy(_counts(counts)))


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


def dense(plan: _Plan, c: np.ndarray) -> np.ndarray:
    """The full ``(b, s, r)`` matrices of ``plan.draw``'s counts."""
    b = len(c)
    s, r = plan.shape
    out = np.zeros((b, s, r))
    np.add.at(out, (np.arange(b)[:, None, None], np.arange(s)[None, :, None],
                    plan.cols[None, :, :]), c)
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
