"""The classical tests of static against dynamic rendering (docs/analysis.md): each with an
effect size and a 95 % bootstrap interval (BCa by ``scipy.stats.bootstrap``, seeded,
vectorised).

- :func:`signed_rank_test`: Wilcoxon's signed-rank test, exact up to 50 differences
  (all sign flips of the mid-ranks), version-independent; Hodges-Lehmann estimates;
- one participant: :func:`fisher_accuracy` (Fisher's exact test of between-tactor
  accuracy, risk difference and odds ratio) and :func:`mann_whitney_rt` (Mann-Whitney U
  of between-tactor RT, rank-biserial correlation);
- several participants: :func:`wilcoxon_paired` (signed-rank tests of per-participant
  accuracy and median RT, matched-pairs rank-biserial correlation).

A test that cannot be computed carries ``computed=False`` and a ``reason`` in words.
The mixed models and the summary are in :mod:`.stats`.

Pure: NumPy and SciPy; randomness from the generator passed in.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any, Final

import numpy as np
from scipy.stats import bootstrap, fisher_exact, mannwhitneyu, norm, rankdata, ttest_1samp
from scipy.stats.contingency import odds_ratio

from ._json import finite_float as _num

__all__ = [
    "DEFAULT_N_BOOT",
    "SIGNED_RANK_EXACT_MAX",
    "TestResult",
    "bca_interval",
    "fisher_accuracy",
    "hodges_lehmann_paired",
    "hodges_lehmann_shift",
    "mann_whitney_rt",
    "matched_pairs_rank_biserial",
    "signed_rank_test",
    "wilcoxon_paired",
]


DEFAULT_N_BOOT: Final = 2000


@dataclass
class TestResult:
    """One statistical test, or the reason it could not be computed.

    Attributes:
        key: a stable identifier (``between_accuracy``, ``between_rt``, ``mixed_model``).
        test: the test's name (``Fisher's exact test``, ...).
        question: what it compares, in words.
        computed: False when it could not be computed; ``reason`` says why.
        statistic, statistic_name: the test statistic.
        p_value: two-sided p (None for the Bayesian model).
        effect_name, effect: the effect size.
        ci_name, ci_low, ci_high: the 95 % interval, and what it is an interval of.
        n: sample sizes.
        details: further numbers (odds ratio, medians, method, warnings).
    """

    key: str
    test: str
    question: str
    computed: bool = True
    reason: str | None = None
    statistic: float | None = None
    statistic_name: str | None = None
    p_value: float | None = None
    effect_name: str | None = None
    effect: float | None = None
    ci_name: str | None = None
    ci_low: float | None = None
    ci_high: float | None = None
    n: dict[str, int] = field(default_factory=dict)
    details: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: every number finite or None."""
        def num(v: Any) -> Any:
            return _num(v) if isinstance(v, float | np.floating) else v

        out = {k: ({kk: num(vv) for kk, vv in v.items()} if isinstance(v, dict) else num(v))
               for k, v in self.__dict__.items()}
        if out.get("ci_low") is not None:
            out["ci95"] = [out["ci_low"], out["ci_high"]]
        return out


def _not_computed(key: str, test: str, question: str, reason: str, **n: int) -> TestResult:
    return TestResult(key=key, test=test, question=question, computed=False, reason=reason,
                      n=dict(n))


def bca_interval(data: tuple[np.ndarray, ...], statistic: Any, rng: np.random.Generator,
                 n_boot: int = DEFAULT_N_BOOT) -> tuple[float, float, str]:
    """A 95 % bias-corrected and accelerated bootstrap interval (``scipy.stats.bootstrap``).

    ``statistic(*samples, axis)`` is vectorised; the samples are resampled
    independently (trials within a condition, or participants). When BCa is undefined
    (e.g. every resample equal) the percentile interval is returned, and the third
    value says which one it is.
    """
    for method in ("BCa", "percentile"):
        with warnings.catch_warnings(action="ignore"):
            try:
                res = bootstrap(data, statistic, n_resamples=n_boot, method=method, rng=rng,
                                vectorized=True, axis=-1)
            except (ValueError, FloatingPointError):
                continue
        lo, hi = float(res.confidence_interval.low), float(res.confidence_interval.high)
        if math.isfinite(lo) and math.isfinite(hi):
            return lo, hi, method
    v = float(statistic(*data, axis=-1))
    return v, v, "degenerate (every resample equal)"


def _signed_rank_null(ranks2: np.ndarray) -> np.ndarray:
    """Exact null distribution of ``2 T+`` over all sign flips of the (doubled) ranks."""
    total = int(ranks2.sum())
    dist = np.zeros(total + 1)
    dist[0] = 1.0
    for r in ranks2.astype(int):
        shifted = np.zeros_like(dist)
        shifted[r:] = dist[: total + 1 - r]
        dist = dist + shifted
    return dist / dist.sum()


#: Up to this many non-zero differences the signed-rank p is exact (all sign flips).
SIGNED_RANK_EXACT_MAX: Final = 50


def signed_rank_test(diff: np.ndarray) -> tuple[float, float, str]:
    """Wilcoxon signed-rank test (two-sided) of paired differences, version-independent.

    Zero differences are dropped (``zero_method="wilcox"``), tied ``|diff|`` get mid-ranks.
    Up to :data:`SIGNED_RANK_EXACT_MAX` non-zero differences the p is exact: the
    distribution of ``T+`` over all ``2^n`` sign flips of the observed (mid-)ranks, by
    dynamic programming (equal to SciPy's ``method="exact"`` without ties and to its
    exhaustive permutation with ties); above, the normal approximation with the tie
    correction of the variance and no continuity correction (SciPy's
    ``"asymptotic"``).

    Returns:
        ``(W, p, method)``: W the smaller of ``T+`` and ``T-``.
    """
    d = np.asarray(diff, dtype=float)
    d = d[d != 0]
    n = d.size
    ranks = rankdata(np.abs(d))
    t_plus = float(ranks[d > 0].sum())
    total = float(ranks.sum())
    w = min(t_plus, total - t_plus)
    if n <= SIGNED_RANK_EXACT_MAX:
        dist = _signed_rank_null(np.round(2 * ranks).astype(int))
        k = round(2 * w)
        p = min(1.0, 2.0 * float(dist[: k + 1].sum()))
        ties = np.unique(ranks).size < n
        return w, p, ("exact (all sign flips of the mid-ranks)" if ties else "exact")
    _, counts = np.unique(np.abs(d), return_counts=True)
    var = n * (n + 1) * (2 * n + 1) / 24.0 - float((counts**3 - counts).sum()) / 48.0
    z = (w - n * (n + 1) / 4.0) / math.sqrt(var)
    return w, min(1.0, float(2.0 * norm.cdf(z))), "normal approximation, tie-corrected"


def _untied_signed_rank_cut(n: int) -> int:
    """c with ``P(T <= c) <= 0.025`` maximal (untied, exact up to 50, normal above)."""
    if n <= SIGNED_RANK_EXACT_MAX:
        cdf = np.cumsum(_signed_rank_null(2 * np.arange(1, n + 1)))[::2]
        ok = np.flatnonzero(cdf <= 0.025)
        return int(ok[-1]) if ok.size else -1
    big_n = n * (n + 1) / 2
    return math.floor(big_n / 2 - 0.5 - norm.ppf(0.975) * math.sqrt(
        n * (n + 1) * (2 * n + 1) / 24.0))


def hodges_lehmann_paired(diff: np.ndarray) -> tuple[float, float, float, str]:
    """Hodges-Lehmann estimate (median of the Walsh averages) and its 95 % interval.

    The interval is ``[W_(c+1), W_(N-c)]`` of the sorted Walsh averages, ``c`` from the
    signed-rank distribution (exact up to 50 pairs, untied; normal above), as R's
    ``wilcox.test(conf.int = TRUE)``. Zero differences are kept.
    """
    d = np.asarray(diff, dtype=float)
    n = d.size
    i, j = np.triu_indices(n)
    walsh = np.sort((d[i] + d[j]) / 2.0)
    c = _untied_signed_rank_cut(n)
    est = float(np.median(walsh))
    if c < 0:
        return est, float("nan"), float("nan"), f"too few pairs ({n}) for a 95 % interval"
    method = "exact" if n <= SIGNED_RANK_EXACT_MAX else "normal approximation"
    return est, float(walsh[c]), float(walsh[walsh.size - 1 - c]), method


def hodges_lehmann_shift(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float, str]:
    """Hodges-Lehmann shift ``x - y`` (median of all pairwise differences), 95 % interval.

    ``[D_(c+1), D_(nm-c)]`` with ``c`` from the Mann-Whitney U distribution: exact (by
    recursion) when ``n m <= 2500``, else its normal approximation with continuity
    correction (no tie correction).
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    n, m = x.size, y.size
    diffs = np.sort((x[:, None] - y[None, :]).ravel())
    est = float(np.median(diffs))
    nm = n * m
    if nm <= 2500:
        # c(i, j, u) = c(i-1, j, u-j) + c(i, j-1, u): the largest value is an x (above all
        # j y-values) or a y; rolled over i
        f = np.zeros((m + 1, nm + 1))
        f[:, 0] = 1.0
        for _ in range(n):
            g = np.zeros((m + 1, nm + 1))
            g[0, 0] = 1.0
            for j in range(1, m + 1):
                g[j, j:] = f[j, : nm + 1 - j]
                g[j] += g[j - 1]
            f = g
        dist = f[m] / f[m].sum()
        cdf = np.cumsum(dist)
        ok = np.flatnonzero(cdf <= 0.025)
        c = int(ok[-1]) if ok.size else -1
        method = "exact"
    else:
        c = math.floor(nm / 2 - 0.5 - norm.ppf(0.975) * math.sqrt(nm * (n + m + 1) / 12.0))
        method = "normal approximation"
    if c < 0:
        return est, float("nan"), float("nan"), "too few trials for a 95 % interval"
    return est, float(diffs[c]), float(diffs[nm - 1 - c]), method


# -- one participant -------------------------------------------------------------------

def fisher_accuracy(correct_static: int, n_static: int, correct_dynamic: int, n_dynamic: int,
                    rng: np.random.Generator, n_boot: int = DEFAULT_N_BOOT,
                    key: str = "between_accuracy") -> TestResult:
    """Fisher's exact test (two-sided) of static vs dynamic accuracy.

    Statistic: the conditional maximum-likelihood odds ratio (dynamic vs static) with
    its exact 95 % interval (``scipy.stats.contingency.odds_ratio``, as R's
    ``fisher.test``). Effect size: risk difference ``acc_dynamic - acc_static``, with a
    BCa bootstrap interval (trials resampled within each condition). The sample odds
    ratio ``(a d) / (b c)`` is in ``details`` as ``sample_odds_ratio``.
    """
    test, question = "Fisher's exact test", "between-tactor accuracy, dynamic vs static"
    if n_static == 0 or n_dynamic == 0:
        missing = "static" if n_static == 0 else "dynamic"
        return _not_computed(key, test, question,
                             f"no {missing} between-tactor test trials; the test needs both "
                             "conditions", static=n_static, dynamic=n_dynamic)
    table = np.array([[correct_dynamic, n_dynamic - correct_dynamic],
                      [correct_static, n_static - correct_static]])
    res = fisher_exact(table, alternative="two-sided")
    cond = odds_ratio(table, kind="conditional")
    ci = cond.confidence_interval(confidence_level=0.95)
    p_s, p_d = correct_static / n_static, correct_dynamic / n_dynamic
    ys = np.r_[np.ones(correct_static), np.zeros(n_static - correct_static)]
    yd = np.r_[np.ones(correct_dynamic), np.zeros(n_dynamic - correct_dynamic)]
    lo, hi, how = bca_interval((yd, ys), lambda a, b, axis: a.mean(axis) - b.mean(axis),
                               rng, n_boot)
    a, b, c, d = (int(v) for v in table.ravel())
    sample = (a * d) / (b * c) if b * c > 0 else None
    cmle = _num(cond.statistic)
    zero_cell = min(a, b, c, d) == 0
    return TestResult(
        key=key, test=test, question=question, statistic=cmle,
        statistic_name="odds ratio, dynamic vs static (conditional MLE)",
        p_value=float(res.pvalue),
        effect_name="risk difference (dynamic - static accuracy)", effect=p_d - p_s,
        ci_name=f"accuracy difference ({how} bootstrap)", ci_low=lo, ci_high=hi,
        n={"static": int(n_static), "dynamic": int(n_dynamic)},
        details={"accuracy_static": p_s, "accuracy_dynamic": p_d,
                 "odds_ratio": None if zero_cell else cmle,
                 "odds_ratio_method": "conditional maximum likelihood (as R's fisher.test)",
                 "odds_ratio_ci95": [_num(ci.low), _num(ci.high)],
                 "odds_ratio_ci_method": "exact conditional (non-central hypergeometric)",
                 "odds_ratio_note": None if not zero_cell else
                 "odds ratio undefined (0 or infinite): a cell of the 2x2 table is zero",
                 "sample_odds_ratio": sample,
                 "p_method": "exact (Fisher, two-sided: tables no more likely than observed)",
                 "table": [[a, b], [c, d]], "n_boot": n_boot, "bootstrap": how},
    )


def mann_whitney_rt(rt_static: np.ndarray, rt_dynamic: np.ndarray, rng: np.random.Generator,
                    n_boot: int = DEFAULT_N_BOOT, key: str = "between_rt") -> TestResult:
    """Mann-Whitney U test (two-sided) of static vs dynamic response times.

    Effect size: rank-biserial correlation ``2 U_dynamic / (n_d n_s) - 1`` (positive:
    dynamic RTs tend to be longer). CI: BCa bootstrap of the difference of median RTs
    (dynamic - static), trials resampled within each condition. Beside it, the
    Hodges-Lehmann shift with its distribution-free interval. The p is exact when a
    sample has at most 8 trials and there are no ties, else the tie-corrected normal
    approximation with continuity correction (SciPy's rule, chosen explicitly).
    """
    test, question = "Mann-Whitney U test", "between-tactor response time, dynamic vs static"
    s = np.asarray(rt_static, dtype=float)
    d = np.asarray(rt_dynamic, dtype=float)
    s, d = s[~np.isnan(s)], d[~np.isnan(d)]
    if s.size == 0 or d.size == 0:
        missing = "static" if s.size == 0 else "dynamic"
        return _not_computed(key, test, question,
                             f"no {missing} between-tactor response time (no answered trial); "
                             "the test needs both conditions", static=int(s.size),
                             dynamic=int(d.size))
    if np.all(np.concatenate([s, d]) == s[0]):
        return _not_computed(key, test, question, "all response times are equal; no ranks to "
                             "compare", static=int(s.size), dynamic=int(d.size))
    both = np.concatenate([s, d])
    ties = np.unique(both).size < both.size
    method = "exact" if (min(s.size, d.size) <= 8 and not ties) else "asymptotic"
    res = mannwhitneyu(d, s, alternative="two-sided", method=method)
    r = 2.0 * float(res.statistic) / (d.size * s.size) - 1.0
    lo, hi, how = bca_interval(
        (d, s), lambda a, b, axis: np.median(a, axis=axis) - np.median(b, axis=axis),
        rng, n_boot)
    hl, hl_lo, hl_hi, hl_how = hodges_lehmann_shift(d, s)
    return TestResult(
        key=key, test=test, question=question, statistic=float(res.statistic),
        statistic_name="U (dynamic)", p_value=float(res.pvalue),
        effect_name="rank-biserial correlation (+: dynamic slower)", effect=r,
        ci_name=f"median RT difference, dynamic - static, s ({how} bootstrap)", ci_low=lo,
        ci_high=hi, n={"static": int(s.size), "dynamic": int(d.size)},
        details={"median_rt_static_s": float(np.median(s)),
                 "median_rt_dynamic_s": float(np.median(d)), "n_boot": n_boot,
                 "bootstrap": how,
                 "p_method": ("exact" if method == "exact" else
                              "normal approximation, tie-corrected, continuity-corrected"),
                 "hodges_lehmann_s": hl, "hodges_lehmann_ci95": [_num(hl_lo), _num(hl_hi)],
                 "hodges_lehmann_method": f"shift dynamic - static; interval {hl_how}"},
    )


# -- several participants --------------------------------------------------------------

def matched_pairs_rank_biserial(diff: np.ndarray) -> float:
    """Matched-pairs rank-biserial correlation ``(T+ - T-) / (T+ + T-)``.

    Ranks of ``|diff|`` among the non-zero differences (average ranks for ties), as in
    the Wilcoxon signed-rank test with ``zero_method="wilcox"``.
    """
    d = np.asarray(diff, dtype=float)
    d = d[d != 0]
    if d.size == 0:
        return float("nan")
    ranks = rankdata(np.abs(d))
    t_plus = ranks[d > 0].sum()
    t_minus = ranks[d < 0].sum()
    return float((t_plus - t_minus) / (t_plus + t_minus))


def wilcoxon_paired(static: np.ndarray, dynamic: np.ndarray, rng: np.random.Generator,
                    n_boot: int = DEFAULT_N_BOOT, *, key: str, what: str,
                    unit: str = "") -> TestResult:
    """Wilcoxon signed-rank test (two-sided) of paired per-participant values.

    p: :func:`signed_rank_test` (exact up to 50 pairs, also with ties). Effect size:
    matched-pairs rank-biserial correlation of ``dynamic - static``. CI: BCa bootstrap
    (participants resampled) of the mean paired difference; the t interval and the
    Hodges-Lehmann estimate with its interval are in ``details``.
    """
    test = "Wilcoxon signed-rank test"
    question = f"per-participant between-tactor {what}, dynamic vs static"
    s = np.asarray(static, dtype=float)
    d = np.asarray(dynamic, dtype=float)
    ok = ~(np.isnan(s) | np.isnan(d))
    s, d = s[ok], d[ok]
    if s.size < 2:
        return _not_computed(key, test, question,
                             f"needs at least 2 participants with between-tactor {what} in both "
                             f"conditions, found {s.size}", pairs=int(s.size))
    diff = d - s
    if np.all(diff == 0):
        return _not_computed(key, test, question,
                             f"all {s.size} paired differences are zero (every participant has "
                             f"the same {what} in both conditions)", pairs=int(s.size))
    w, p, p_how = signed_rank_test(diff)
    lo, hi, how = bca_interval((diff,), lambda a, axis: a.mean(axis), rng, n_boot)
    with warnings.catch_warnings(action="ignore"):
        tci = ttest_1samp(diff, 0.0).confidence_interval(0.95)
    hl, hl_lo, hl_hi, hl_how = hodges_lehmann_paired(diff)
    return TestResult(
        key=key, test=test, question=question, statistic=w,
        statistic_name="W (smaller rank sum)", p_value=p,
        effect_name="matched-pairs rank-biserial correlation (+: dynamic higher)",
        effect=matched_pairs_rank_biserial(diff),
        ci_name=f"mean paired difference, dynamic - static{unit} ({how} bootstrap)",
        ci_low=lo, ci_high=hi, n={"pairs": int(s.size), "zero_differences":
                                  int((diff == 0).sum())},
        details={"mean_difference": float(diff.mean()),
                 "mean_static": float(s.mean()), "mean_dynamic": float(d.mean()),
                 "n_boot": n_boot, "bootstrap": how, "p_method": p_how,
                 "t_interval_ci95": [_num(tci.low), _num(tci.high)],
                 "hodges_lehmann": hl, "hodges_lehmann_ci95": [_num(hl_lo), _num(hl_hi)],
                 "hodges_lehmann_method": f"median of Walsh averages; interval {hl_how}"},
    )
