"""Inferential statistics of static versus dynamic between-tactor rendering, and the Summary.

Tests (docs/analysis.md), each with an effect size and a 95 % bootstrap CI (percentile,
seeded :class:`numpy.random.Generator`, vectorised):

- One participant: Fisher's exact test (two-sided) of between-tactor accuracy, effect
  size risk difference (dynamic - static; odds ratio alongside), CI of the accuracy
  difference; Mann-Whitney U (two-sided) of between-tactor RT, effect size
  rank-biserial correlation, CI of the difference of median RTs.
- Several participants: Wilcoxon signed-rank tests (two-sided) on per-participant
  between-tactor accuracy and median RT, effect size matched-pairs rank-biserial
  correlation, CI of the mean paired difference.
- From 3 participants: a binomial mixed model ``correct ~ condition + on_tactor`` with a
  random intercept per participant (statsmodels BinomialBayesMixedGLM, fit_vb; above
  :data:`VB_MAX_PARTICIPANTS` participants a GEE with exchangeable correlation instead,
  because the variational fit grows too slow).

A test that cannot be computed carries ``computed=False`` and a ``reason`` in words.

Pure: imports NumPy, pandas, SciPy, statsmodels and the pure analysis modules; never
an I/O layer. Randomness comes from the ``seed`` argument only.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Final

import numpy as np

from .cells import cell_summary, cells_to_json, participant_cells
from .design import StudyDesign, parse_design
from .tables import (
    CONDITIONS,
    condition_summary,
    confusion_matrices,
    direction_summary,
    per_participant,
    per_target,
    prepare_trials,
    training_summary,
)

if TYPE_CHECKING:
    import pandas as pd

    from .dataset import StoreData

__all__ = [
    "DEFAULT_N_BOOT",
    "VB_MAX_PARTICIPANTS",
    "Summary",
    "TestResult",
    "fisher_accuracy",
    "mann_whitney_rt",
    "matched_pairs_rank_biserial",
    "mixed_model",
    "summarize",
    "wilcoxon_paired",
]

DEFAULT_N_BOOT: Final = 2000
#: Above this many participants the mixed model is a GEE (fit_vb grows ~quadratically).
VB_MAX_PARTICIPANTS: Final = 60
COMPLETE_STATUSES: Final = frozenset({"complete", "completed", "done", "finished"})


def _num(x: Any) -> float | None:
    """A finite float, or None."""
    if x is None:
        return None
    try:
        v = float(x)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


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
        out: dict[str, Any] = {}
        for k, v in self.__dict__.items():
            if isinstance(v, float | np.floating):
                out[k] = _num(v)
            elif isinstance(v, dict):
                out[k] = {kk: (_num(vv) if isinstance(vv, float | np.floating) else vv)
                          for kk, vv in v.items()}
            else:
                out[k] = v
        if out.get("ci_low") is not None:
            out["ci95"] = [out["ci_low"], out["ci_high"]]
        return out


def _not_computed(key: str, test: str, question: str, reason: str, **n: int) -> TestResult:
    return TestResult(key=key, test=test, question=question, computed=False, reason=reason,
                      n=dict(n))


def _percentile_ci(boot: np.ndarray) -> tuple[float, float]:
    lo, hi = np.percentile(boot, [2.5, 97.5])
    return float(lo), float(hi)


# -- one participant -------------------------------------------------------------------

def fisher_accuracy(correct_static: int, n_static: int, correct_dynamic: int, n_dynamic: int,
                    rng: np.random.Generator, n_boot: int = DEFAULT_N_BOOT,
                    key: str = "between_accuracy") -> TestResult:
    """Fisher's exact test (two-sided) of static vs dynamic accuracy.

    Effect size: risk difference ``acc_dynamic - acc_static``; its 95 % CI is the
    percentile bootstrap of resampling trials with replacement within each condition,
    drawn exactly (and vectorised) as binomial counts. The sample odds ratio
    ``(a d) / (b c)`` is in ``details`` (None when a cell is zero).
    """
    from scipy.stats import fisher_exact

    test, question = "Fisher's exact test", "between-tactor accuracy, dynamic vs static"
    if n_static == 0 or n_dynamic == 0:
        missing = "static" if n_static == 0 else "dynamic"
        return _not_computed(key, test, question,
                             f"no {missing} between-tactor test trials; the test needs both "
                             "conditions", static=n_static, dynamic=n_dynamic)
    table = np.array([[correct_dynamic, n_dynamic - correct_dynamic],
                      [correct_static, n_static - correct_static]])
    res = fisher_exact(table, alternative="two-sided")
    p_s, p_d = correct_static / n_static, correct_dynamic / n_dynamic
    boot = (rng.binomial(n_dynamic, p_d, n_boot) / n_dynamic
            - rng.binomial(n_static, p_s, n_boot) / n_static)
    lo, hi = _percentile_ci(boot)
    a, b, c, d = (int(v) for v in table.ravel())
    odds = (a * d) / (b * c) if b * c > 0 else None
    return TestResult(
        key=key, test=test, question=question, statistic=_num(res.statistic),
        statistic_name="odds ratio (scipy)", p_value=float(res.pvalue),
        effect_name="risk difference (dynamic - static accuracy)", effect=p_d - p_s,
        ci_name="accuracy difference (bootstrap)", ci_low=lo, ci_high=hi,
        n={"static": int(n_static), "dynamic": int(n_dynamic)},
        details={"accuracy_static": p_s, "accuracy_dynamic": p_d, "odds_ratio": odds,
                 "odds_ratio_note": None if odds is not None else
                 "odds ratio undefined: a cell of the 2x2 table is zero",
                 "table": [[a, b], [c, d]], "n_boot": n_boot},
    )


def mann_whitney_rt(rt_static: np.ndarray, rt_dynamic: np.ndarray, rng: np.random.Generator,
                    n_boot: int = DEFAULT_N_BOOT, key: str = "between_rt") -> TestResult:
    """Mann-Whitney U test (two-sided) of static vs dynamic response times.

    Effect size: rank-biserial correlation ``2 U_dynamic / (n_d n_s) - 1`` (positive:
    dynamic RTs tend to be longer). CI: percentile bootstrap of the difference of
    median RTs (dynamic - static), trials resampled within each condition.
    """
    from scipy.stats import mannwhitneyu

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
    res = mannwhitneyu(d, s, alternative="two-sided")
    r = 2.0 * float(res.statistic) / (d.size * s.size) - 1.0
    bd = np.median(d[rng.integers(0, d.size, (n_boot, d.size))], axis=1)
    bs = np.median(s[rng.integers(0, s.size, (n_boot, s.size))], axis=1)
    lo, hi = _percentile_ci(bd - bs)
    return TestResult(
        key=key, test=test, question=question, statistic=float(res.statistic),
        statistic_name="U (dynamic)", p_value=float(res.pvalue),
        effect_name="rank-biserial correlation (+: dynamic slower)", effect=r,
        ci_name="median RT difference, dynamic - static, s (bootstrap)", ci_low=lo, ci_high=hi,
        n={"static": int(s.size), "dynamic": int(d.size)},
        details={"median_rt_static_s": float(np.median(s)),
                 "median_rt_dynamic_s": float(np.median(d)), "n_boot": n_boot},
    )


# -- several participants --------------------------------------------------------------

def matched_pairs_rank_biserial(diff: np.ndarray) -> float:
    """Matched-pairs rank-biserial correlation ``(T+ - T-) / (T+ + T-)``.

    Ranks of ``|diff|`` among the non-zero differences (average ranks for ties), as in
    the Wilcoxon signed-rank test with ``zero_method="wilcox"``.
    """
    from scipy.stats import rankdata

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

    Effect size: matched-pairs rank-biserial correlation of ``dynamic - static``. CI:
    percentile bootstrap (participants resampled) of the mean paired difference.
    """
    from scipy.stats import wilcoxon

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
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = wilcoxon(d, s, alternative="two-sided")
    boot = diff[rng.integers(0, diff.size, (n_boot, diff.size))].mean(axis=1)
    lo, hi = _percentile_ci(boot)
    return TestResult(
        key=key, test=test, question=question, statistic=float(res.statistic),
        statistic_name="W (smaller rank sum)", p_value=float(res.pvalue),
        effect_name="matched-pairs rank-biserial correlation (+: dynamic higher)",
        effect=matched_pairs_rank_biserial(diff),
        ci_name=f"mean paired difference, dynamic - static{unit} (bootstrap)",
        ci_low=lo, ci_high=hi, n={"pairs": int(s.size), "zero_differences":
                                  int((diff == 0).sum())},
        details={"mean_difference": float(diff.mean()),
                 "mean_static": float(s.mean()), "mean_dynamic": float(d.mean()),
                 "n_boot": n_boot},
    )


def mixed_model(tr: pd.DataFrame, *, vb_max_participants: int = VB_MAX_PARTICIPANTS) -> TestResult:
    """Binomial mixed model ``correct ~ condition + on_tactor + (1 | participant)``.

    ``condition`` is coded dynamic = 1, static = 0; the reported coefficient is its
    log-odds effect. Up to ``vb_max_participants`` participants: statsmodels
    BinomialBayesMixedGLM.fit_vb, interval = posterior mean +- 1.96 posterior SD (no
    p-value). Above: GEE (binomial, exchangeable within participant, robust SE), Wald
    interval and p-value; a population-averaged rather than subject-specific effect.

    Args:
        tr: prepared trials (:func:`~tactorbelt.analysis.tables.prepare_trials`),
            only the counted ones are used.
    """
    key, question = "mixed_model", "accuracy, dynamic vs static, all targets"
    c = tr.loc[tr["counted"]]
    parts = c["participant"].unique()
    n_p = int(parts.size)
    test = ("binomial mixed model (BinomialBayesMixedGLM, fit_vb)"
            if n_p <= vb_max_participants else "GEE, binomial, exchangeable (mixed-model stand-in)")
    if n_p < 3:
        return _not_computed(key, test, question,
                             f"needs at least 3 participants, found {n_p}", participants=n_p)
    conds = set(c["condition"].unique())
    if conds != set(CONDITIONS):
        only = ", ".join(sorted(conds)) or "none"
        return _not_computed(key, test, question,
                             f"needs both conditions; the data hold only {only}",
                             participants=n_p, trials=len(c))
    y = c["is_correct"].to_numpy(dtype=float)
    if np.all(y == y[0]):
        return _not_computed(key, test, question,
                             "every counted trial is " + ("correct" if y[0] else "incorrect")
                             + "; a logistic model has nothing to fit",
                             participants=n_p, trials=len(c))
    cond = (c["condition"] == "dynamic").to_numpy(dtype=float)
    on = c["on_tactor"].to_numpy(dtype=float)
    names = ["Intercept", "condition[dynamic]"]
    cols = [np.ones_like(y), cond]
    notes: list[str] = []
    if 0 < on.sum() < on.size:
        names.append("on_tactor")
        cols.append(on)
    else:
        notes.append("on_tactor dropped from the model: all targets are of one kind")
    x = np.column_stack(cols)
    group = np.unique(c["participant"].to_numpy(), return_inverse=True)[1]
    n = {"participants": n_p, "trials": len(c)}
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            if n_p <= vb_max_participants:
                from scipy import sparse
                from statsmodels.genmod.bayes_mixed_glm import BinomialBayesMixedGLM

                z = sparse.csr_array((np.ones(len(y)), (np.arange(len(y)), group)),
                                     shape=(len(y), n_p))
                model = BinomialBayesMixedGLM(y, x, z, np.zeros(n_p, dtype=int),
                                              fep_names=names, vcp_names=["participant"])
                fit = model.fit_vb()
                coef = float(fit.fe_mean[1])
                sd = float(fit.fe_sd[1])
                lo, hi = coef - 1.959964 * sd, coef + 1.959964 * sd
                p = None
                details: dict[str, Any] = {
                    "method": "variational Bayes (fit_vb); interval = mean +- 1.96 SD of the "
                              "approximate posterior; no p-value",
                    "posterior_sd": sd,
                    "random_intercept_sd": float(np.exp(fit.vcp_mean[0])),
                }
            else:
                import statsmodels.api as sm

                gee = sm.GEE(y, x, groups=group, family=sm.families.Binomial(),
                             cov_struct=sm.cov_struct.Exchangeable()).fit()
                coef = float(gee.params[1])
                se = float(gee.bse[1])
                lo, hi = coef - 1.959964 * se, coef + 1.959964 * se
                p = float(gee.pvalues[1])
                details = {
                    "method": f"GEE with exchangeable working correlation within participant "
                              f"(used instead of fit_vb above {vb_max_participants} "
                              "participants); robust SE, Wald interval and p-value",
                    "robust_se": se,
                    "within_participant_correlation": float(gee.cov_struct.dep_params),
                }
        msgs = sorted({str(w.message).splitlines()[0] for w in caught
                       if not issubclass(w.category, DeprecationWarning | FutureWarning)})
    except Exception as exc:  # statsmodels raises many kinds (LinAlgError, separation, ...)
        return _not_computed(key, test, question,
                             f"the model fit failed: {type(exc).__name__}: {exc}", **n)
    if not (math.isfinite(coef) and math.isfinite(lo) and math.isfinite(hi)):
        return _not_computed(key, test, question,
                             "the fit gave no finite coefficient (separation?)", **n)
    details["formula"] = "correct ~ condition + on_tactor + (1 | participant)"
    details["odds_ratio"] = math.exp(coef)
    details["odds_ratio_interval"] = [math.exp(lo), math.exp(hi)]
    if msgs:
        details["warnings"] = msgs
    if notes:
        details["notes"] = notes
    return TestResult(
        key=key, test=test, question=question, statistic=coef,
        statistic_name="condition[dynamic] coefficient (log-odds)", p_value=p,
        effect_name="condition[dynamic] log-odds ratio", effect=coef,
        ci_name="condition coefficient, 95 % " + ("posterior" if p is None else "Wald")
                + " interval (model-based, not bootstrap)",
        ci_low=lo, ci_high=hi, n=n, details=details,
    )


# -- the whole summary -----------------------------------------------------------------

@dataclass
class Summary:
    """Everything the report shows, as plain values and DataFrames.

    Attributes:
        counts: participants, sessions, trials, and how many were counted/left out.
        conditions: :func:`~tactorbelt.analysis.tables.condition_summary`.
        per_target: the ``per_target.csv`` table.
        per_participant: per participant, condition and kind.
        directions: per condition and target, pooled (for the figures).
        confusion: per condition, target by response counts.
        training: training-block accuracy per condition.
        tests: every test, computed or not (with the reason).
        between_accuracy_test: the primary test (Fisher with one participant,
            Wilcoxon with several).
        design: layout, targets and law used for the amplitude figure.
        sessions: the sessions table (provenance).
        incomplete_sessions, timeouts, aborted: rows the report names.
        simulated_sessions: keys of sessions whose data come from a simulated model.
        notes: what was noticed, assumed or could not be computed, in words.
        trials: the prepared trials table (derived columns added).
        seed, n_boot: bootstrap settings.
    """

    counts: dict[str, int]
    conditions: pd.DataFrame
    per_target: pd.DataFrame
    per_participant: pd.DataFrame
    directions: pd.DataFrame
    confusion: dict[str, pd.DataFrame]
    training: pd.DataFrame
    tests: list[TestResult]
    between_accuracy_test: TestResult
    design: StudyDesign
    sessions: pd.DataFrame
    incomplete_sessions: pd.DataFrame
    timeouts: pd.DataFrame
    aborted: pd.DataFrame
    simulated_sessions: list[str]
    notes: list[str]
    trials: pd.DataFrame
    paths: list[str]
    seed: int = 0
    n_boot: int = DEFAULT_N_BOOT
    #: per (condition, n_targets, load): :func:`~tactorbelt.analysis.cells.cell_summary`
    cells: pd.DataFrame | None = None
    #: per (participant, condition, n_targets, load): ``participant_cells``
    participant_cells: pd.DataFrame | None = None

    @property
    def simulated(self) -> bool:
        """True when every session's data come from a simulated model participant."""
        return bool(self.simulated_sessions) and len(self.simulated_sessions) == len(self.sessions)

    def test(self, key: str) -> TestResult | None:
        """The test with this key, if it was run or considered."""
        return next((t for t in self.tests if t.key == key), None)

    def condition_value(self, condition: str, kind: str, column: str) -> float | None:
        """One value of :attr:`conditions` (None when missing or not finite)."""
        sel = self.conditions.loc[(self.conditions["condition"] == condition)
                                  & (self.conditions["kind"] == kind), column]
        return _num(sel.iloc[0]) if len(sel) else None

    def provenance(self) -> dict[str, Any]:
        """Study names and hashes, package and firmware versions, belts, seeds."""
        s = self.sessions

        def uniq(col: str) -> list[Any]:
            vals = s[col].dropna().unique().tolist() if col in s else []
            return sorted((v.item() if hasattr(v, "item") else v) for v in vals)

        studies = (s[["study_name", "study_sha256"]].drop_duplicates().fillna("")
                   .astype(str).to_dict("records"))
        return {
            "stores": self.paths,
            "studies": studies,
            "package_versions": uniq("package_version"),
            "belts": uniq("belt"),
            "firmware_versions": uniq("firmware_version"),
            "inputs": uniq("input"),
            "session_seeds": [int(v) for v in pd_numeric(s["seed"]).dropna().unique()],
            "analysis_seed": self.seed,
            "bootstrap_resamples": self.n_boot,
        }

    def to_json(self) -> dict[str, Any]:
        """The ``summary.json`` content (every number finite or null)."""
        conditions: dict[str, Any] = {}
        for cond in CONDITIONS:
            entry: dict[str, Any] = {}
            for kind in ("on_tactor", "between_tactor"):
                row = self.conditions.loc[(self.conditions["condition"] == cond)
                                          & (self.conditions["kind"] == kind)]
                if row.empty:
                    entry[kind] = {"n": 0}
                    continue
                r = row.iloc[0]
                entry[kind] = {
                    "n": int(r["n"]), "n_participants": int(r["n_participants"]),
                    "n_correct": int(r["n_correct"]), "n_timeout": int(r["n_timeout"]),
                    "accuracy": _num(r["accuracy"]), "median_rt_s": _num(r["median_rt_s"]),
                    "circ_mean_error_deg": _num(r["circ_mean_error_deg"]),
                    "circ_sd_error_deg": _num(r["circ_sd_error_deg"]),
                }
                if int(r["n"]) == 0:
                    entry[kind]["note"] = "no counted test trials"
                elif int(r["n_rt"]) == 0:
                    entry[kind]["note"] = ("every counted trial timed out: no response time "
                                           "and no error")
            conditions[cond] = entry
        return {
            "tactorbelt_analysis": 1,
            "simulated_model_data": self.simulated,
            "simulated_sessions": len(self.simulated_sessions),
            "counts": dict(self.counts),
            "conditions": conditions,
            "cells": cells_to_json(self.cells),
            "between_accuracy_test": self.between_accuracy_test.to_dict(),
            "tests": [t.to_dict() for t in self.tests],
            "counting": COUNTING_RULES,
            "study": {
                "layout_deg": self.design.layout.to_list(),
                "targets_deg": list(self.design.targets.angles_deg),
                "law": self.design.law, "falloff_deg": self.design.falloff_deg,
                "fallbacks": list(self.design.fallbacks),
            },
            "provenance": self.provenance(),
            "notes": list(self.notes),
        }


COUNTING_RULES: Final = (
    "Only test-block trials count. Trials with status 'done' count; 'timeout' trials count "
    "as incorrect, with no response time and no response direction; 'aborted' trials are "
    "left out. Training trials are summarised separately."
)


def pd_numeric(s: pd.Series) -> pd.Series:
    """``pd.to_numeric(errors="coerce")`` (imported lazily)."""
    import pandas as pd

    return pd.to_numeric(s, errors="coerce")


def _is_simulated(sessions: pd.DataFrame) -> pd.Series:
    part = sessions["participant"].astype(str).str.lower().str.startswith("model")
    belt = sessions["belt"].astype("string").str.lower().fillna("")
    sim_belt = belt.str.startswith("sim") | belt.str.startswith("model")
    inp = sessions["input"].astype("string").str.lower().fillna("") == "model"
    return part | sim_belt | inp


def _design_for(sessions: pd.DataFrame, notes: list[str]) -> StudyDesign:
    """Parse the study of most sessions; say when studies differ or defaults were used."""
    texts = sessions["study_toml"].fillna("").astype(str)
    counts = texts.value_counts()
    text = str(counts.index[0]) if len(counts) else ""
    design = parse_design(text or None)
    if len(counts) > 1:
        parsed = {(d.layout.angles_deg, d.targets.angles_deg, d.law, d.falloff_deg)
                  for d in (parse_design(t or None) for t in counts.index)}
        if len(parsed) > 1:
            notes.append(
                f"the sessions ran {len(parsed)} different study designs; the amplitude figure "
                f"shows the one used by most sessions ({int(counts.iloc[0])} of {len(texts)})"
            )
    if design.fallbacks:
        notes.append(
            "study design: " + "; ".join(design.fallbacks) + " - fell back to the paper's "
            "defaults where needed (6 even tactors, 24 targets, paper law T = 15)"
        )
    return design


def summarize(data: StoreData, *, seed: int = 0, n_boot: int = DEFAULT_N_BOOT,
              vb_max_participants: int = VB_MAX_PARTICIPANTS) -> Summary:
    """Compute every table and test from loaded stores. Pure: no files, no clock.

    Args:
        data: what :func:`tactorbelt.analysis.load.load_stores` returned.
        seed: seeds the bootstrap (a :class:`numpy.random.Generator`).
        n_boot: bootstrap resamples per interval.
        vb_max_participants: above this, the mixed model is a GEE.
    """
    rng = np.random.default_rng(seed)
    notes = list(data.notes)
    sessions = data.sessions.copy()
    sessions["simulated"] = _is_simulated(sessions).to_numpy(dtype=bool)
    design = _design_for(sessions, notes)
    tr = prepare_trials(data.trials)

    unknown_cond = tr["block"].eq("test") & ~tr["condition"].isin(CONDITIONS)
    if unknown_cond.any():
        vals = sorted(tr.loc[unknown_cond, "condition"].fillna("<null>").unique().tolist())
        notes.append(f"{int(unknown_cond.sum())} test trial(s) with condition "
                     f"{', '.join(vals)} were left out (allowed: static, dynamic)")
    status = tr["status"]
    test = tr["block"] == "test"
    counted = tr.loc[tr["counted"]]
    status_s = sessions["status"].astype("string").str.lower().fillna("")
    incomplete = sessions.loc[~status_s.isin(COMPLETE_STATUSES) | sessions["ended_at"].isna(),
                              ["session_key", "participant", "status", "started_at",
                               "ended_at"]]
    trial_cols = ["session_key", "participant", "block", "condition", "trial_index",
                  "target_deg"]
    timeouts = tr.loc[status == "timeout", trial_cols].reset_index(drop=True)
    aborted = tr.loc[status == "aborted", trial_cols].reset_index(drop=True)
    counts = {
        "stores": len(data.paths),
        "participants": int(sessions["participant"].nunique()),
        "participants_with_test_trials": int(counted["participant"].nunique()),
        "sessions": len(sessions),
        "sessions_incomplete": len(incomplete),
        "trials": len(tr),
        "test_trials": int(test.sum()),
        "counted_trials": len(counted),
        "done": int((test & (status == "done")).sum()),
        "timeout": int((test & (status == "timeout")).sum()),
        "aborted": int((test & (status == "aborted")).sum()),
        "training_trials": int((tr["block"] == "training").sum()),
        "training_timeout": int(((tr["block"] == "training") & (status == "timeout")).sum()),
        "training_aborted": int(((tr["block"] == "training") & (status == "aborted")).sum()),
    }

    cond_table = condition_summary(tr)
    pt = per_target(tr)
    pp = per_participant(tr)
    directions = direction_summary(tr)
    confusion = confusion_matrices(tr, design.targets.angles)
    training = training_summary(tr)

    tests: list[TestResult] = []
    n_part = counts["participants_with_test_trials"]
    between = counted.loc[counted["kind"] == "between_tactor"]
    if len(counted) == 0:
        reason = ("no test-block trial was done or timed out" if len(tr) else
                  "the stores hold no trials")
        tests.append(_not_computed("between_accuracy", "Fisher's exact test",
                                   "between-tactor accuracy, dynamic vs static", reason))
        tests.append(_not_computed("between_rt", "Mann-Whitney U test",
                                   "between-tactor response time, dynamic vs static", reason))
        notes.append(f"no statistics: {reason}")
    elif n_part == 1:
        by = {c: between.loc[between["condition"] == c] for c in CONDITIONS}
        if between.empty:
            reason = "no between-tactor test trials (every target is on a tactor)"
            tests.append(_not_computed("between_accuracy", "Fisher's exact test",
                                       "between-tactor accuracy, dynamic vs static", reason))
            tests.append(_not_computed("between_rt", "Mann-Whitney U test",
                                       "between-tactor response time, dynamic vs static", reason))
        else:
            tests.append(fisher_accuracy(
                int(by["static"]["is_correct"].sum()), len(by["static"]),
                int(by["dynamic"]["is_correct"].sum()), len(by["dynamic"]), rng, n_boot))
            tests.append(mann_whitney_rt(by["static"]["rt"].to_numpy(),
                                         by["dynamic"]["rt"].to_numpy(), rng, n_boot))
    else:
        b = pp.loc[pp["kind"] == "between_tactor"].pivot(
            index="participant", columns="condition", values=["accuracy", "median_rt_s"])
        if between.empty:
            reason = "no between-tactor test trials (every target is on a tactor)"
            tests.append(_not_computed("between_accuracy", "Wilcoxon signed-rank test",
                                       "per-participant between-tactor accuracy, dynamic vs "
                                       "static", reason))
            tests.append(_not_computed("between_rt", "Wilcoxon signed-rank test",
                                       "per-participant between-tactor median RT, dynamic vs "
                                       "static", reason))
        else:
            acc_s, acc_d = b[("accuracy", "static")], b[("accuracy", "dynamic")]
            lacking = b.index[acc_s.isna() | acc_d.isna()].tolist()
            if lacking:
                notes.append(
                    f"{len(lacking)} participant(s) lack between-tactor trials in a condition "
                    "and are left out of the paired tests: " + ", ".join(map(str, lacking[:20]))
                    + (" ..." if len(lacking) > 20 else ""))
            tests.append(wilcoxon_paired(acc_s.to_numpy(), acc_d.to_numpy(), rng, n_boot,
                                         key="between_accuracy", what="accuracy"))
            tests.append(wilcoxon_paired(
                b[("median_rt_s", "static")].to_numpy(), b[("median_rt_s", "dynamic")].to_numpy(),
                rng, n_boot, key="between_rt", what="median RT", unit=", s"))
    if len(counted):
        tests.append(mixed_model(tr, vb_max_participants=vb_max_participants))
    primary = next(t for t in tests if t.key == "between_accuracy")
    for t in tests:
        if not t.computed:
            notes.append(f"not computed: {t.test} ({t.question}): {t.reason}")
    for cond in CONDITIONS:
        if not (counted["condition"] == cond).any() and len(counted):
            notes.append(f"no {cond} test trials: its accuracy and RT are not reported")

    return Summary(
        counts=counts, conditions=cond_table, per_target=pt, per_participant=pp,
        directions=directions, confusion=confusion, training=training, tests=tests,
        between_accuracy_test=primary, design=design, sessions=sessions,
        incomplete_sessions=incomplete.reset_index(drop=True), timeouts=timeouts,
        aborted=aborted,
        simulated_sessions=sessions.loc[sessions["simulated"], "session_key"].tolist(),
        notes=notes, trials=tr, paths=[str(p) for p in data.paths], seed=seed, n_boot=n_boot,
        cells=cell_summary(tr), participant_cells=participant_cells(tr),
    )
