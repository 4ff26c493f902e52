"""Information transfer (bits) from a confusion matrix: plug-in and Miller-Madow estimates.

The information transferred from stimulus to response is their mutual information

    IT = sum_ij p_ij log2( p_ij / (p_i. p_.j) ),   p_ij = n_ij / N,

estimated here from a matrix of counts ``n_ij`` (rows: the stimulus, columns: the
response). The plug-in (maximum-likelihood) estimate :func:`information_transfer`
is biased upwards for small N (it is positive on average even when stimulus and
response are independent). :func:`miller_madow_transfer` subtracts the first-order
bias of ``IT = H(R) - H(R|S)``, the Miller-Madow correction applied to each entropy
(Miller 1955; Panzeri & Treves 1996, "Analytical estimates of limited sampling biases
in different information measures", Network 7:87-107, Eq. 8 with naive bin counting):

    bias = ( sum_s (R_s - 1) - (R - 1) ) / (2 N ln 2)   bits,

where R_s counts the non-empty cells of stimulus row s and R the non-empty response
columns. When every cell is non-empty this is ``(rows - 1)(cols - 1) / (2 N ln 2)``,
the textbook form; counting only the cells that occur keeps the correction from
overshooting on sparse matrices (a participant who confuses only neighbours), where
the textbook form can subtract more bits than the matrix holds. The corrected value
may be slightly negative; it is not clipped, so averages over participants stay
unbiased.

Pure: NumPy only.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = [
    "confusion_matrix",
    "information_transfer",
    "miller_madow_bias",
    "miller_madow_transfer",
]


def _counts(counts: np.ndarray | Sequence[Sequence[float]]) -> np.ndarray:
    m = np.asarray(counts, dtype=float)
    if m.ndim != 2:
        raise ValueError(f"a confusion matrix is 2-D (stimulus x response); got {m.ndim}-D")
    if not np.all(np.isfinite(m)) or np.any(m < 0):
        raise ValueError("confusion-matrix counts must be finite and >= 0")
    return m


def information_transfer(counts: np.ndarray | Sequence[Sequence[float]]) -> float:
    """The plug-in (maximum-likelihood) information transfer in bits.

    Args:
        counts: stimulus x response counts (any non-negative numbers).

    Returns:
        Mutual information in bits; 0 for an empty matrix. An identity matrix of M
        equally frequent stimuli gives log2(M); independent rows give 0.
    """
    m = _counts(counts)
    n = m.sum()
    if n <= 0:
        return 0.0
    p = m / n
    pr = p.sum(axis=1, keepdims=True)
    pc = p.sum(axis=0, keepdims=True)
    nz = p > 0
    ratio = p[nz] / (pr @ pc)[nz]
    return max(0.0, float(np.sum(p[nz] * np.log2(ratio))))


def miller_madow_bias(counts: np.ndarray | Sequence[Sequence[float]]) -> float:
    """The first-order bias of the plug-in estimate in bits (see the module docstring).

    ``(sum_s (R_s - 1) - (R - 1)) / (2 N ln 2)`` with R_s the non-empty cells of row s
    (over the non-empty rows) and R the non-empty columns; 0 for an empty matrix.
    """
    m = _counts(counts)
    n = m.sum()
    if n <= 0:
        return 0.0
    rows = m[m.sum(axis=1) > 0]
    per_row = np.count_nonzero(rows, axis=1)
    cols = int(np.count_nonzero(m.sum(axis=0)))
    return float(np.sum(per_row - 1) - (cols - 1)) / (2.0 * n * math.log(2.0))


def miller_madow_transfer(counts: np.ndarray | Sequence[Sequence[float]]) -> float:
    """Information transfer in bits with the Miller-Madow bias correction (may be < 0)."""
    return information_transfer(counts) - miller_madow_bias(counts)


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
