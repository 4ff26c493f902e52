"""Inferential statistics of static versus dynamic between-tactor rendering, and the Summary.

Tests (docs/analysis.md), each with an effect size and a 95 % bootstrap CI (BCa by
``scipy.stats.bootstrap``, seeded :class:`numpy.random.Generator`, vectorised):

- One participant: Fisher's exact test (two-sided) of between-tactor accuracy, effect
  size risk difference (dynamic - static; odds ratio alongside), CI of the accuracy
  difference; Mann-Whitney U (two-sided) of between-tactor RT, effect size
  rank-biserial correlation, CI of the difference of median RTs.
- Several participants: Wilcoxon signed-rank tests (two-sided) on per-participant
  between-tactor accuracy and median RT, effect size matched-pairs rank-biserial
  correlation, CI of the mean paired difference.
- From 3 participants: a binomial GLMM ``correct ~ condition * on_tactor +
  (1 + condition | participant) + (1 | target)`` by maximum likelihood with the Laplace
  approximation (:mod:`.glmm`, agreeing with lme4's glmer; or glmer itself through
  Rscript), simplified by a stated rule while the fit is singular; and a linear mixed
  model of log RT with the same structure (REML, as lmer), timeouts counted per cell.

A test that cannot be computed carries ``computed=False`` and a ``reason`` in words.

Pure: imports NumPy, pandas, SciPy and the pure analysis modules; never an I/O layer,
except that ``engine="lme4"`` runs R through :mod:`.lme4` (temporary files and a
subprocess). Randomness comes from the ``seed`` argument only.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Final

import numpy as np

from .cells import cell_summary, cells_to_json, participant_cells
from .classical import (
    DEFAULT_N_BOOT,
    TestResult,
    _not_computed,
    _num,
    fisher_accuracy,
    mann_whitney_rt,
    matched_pairs_rank_biserial,
    wilcoxon_paired,
)
from .design import StudyDesign, parse_design
from .lrt import DEFAULT_PB_SIMS
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
    "DEFAULT_PB_SIMS",
    "HEADLINE_TEST",
    "PB_MAX_PARTICIPANTS",
    "RT_FROM",
    "Summary",
    "TestResult",
    "condition_tests",
    "fisher_accuracy",
    "headline_method",
    "mann_whitney_rt",
    "matched_pairs_rank_biserial",
    "mixed_model",
    "rt_from_choice",
    "summarize",
    "wilcoxon_paired",
]

Z95: Final = 1.959963984540054
COMPLETE_STATUSES: Final = frozenset({"complete", "completed", "done", "finished"})
#: Where a response time is counted from (``tactorbelt analyze --rt-from``).
RT_FROM: Final = ("skin", "command")


DESIGN_FACTORS: Final = ("condition", "on_tactor", "n_targets", "load")
#: A cell with more timeouts than this share gets a note beside the RT model.
TIMEOUT_NOTE_SHARE: Final = 0.05
ENGINES: Final = ("tactorbelt", "lme4")
ENGINE_NAMES: Final = {"tactorbelt": "tactorbelt-laplace", "lme4": "lme4"}


def model_frame(tr: pd.DataFrame) -> pd.DataFrame:
    """The counted trials in the columns the mixed models use (the trials table's names).

    ``correct`` 0/1 (timeouts 0), ``condition`` text, ``on_tactor`` 0/1 integer (so
    lme4 names its coefficient ``on_tactor``, not ``on_tactorTRUE``), ``n_targets`` and
    ``load`` when present, ``participant`` text, ``target`` (``target_deg`` as text, a
    factor), ``rt_s`` (NaN for timeouts) and ``status``.
    """
    import pandas as pd

    c = tr.loc[tr["counted"]]
    out = pd.DataFrame({
        "correct": c["is_correct"].to_numpy(dtype=int),
        "condition": c["condition"].astype(str).to_numpy(),
        "on_tactor": c["on_tactor"].to_numpy(dtype=bool).astype(int),
        "participant": c["participant"].astype(str).to_numpy(),
        "target": [f"{v:g}" for v in c["target_deg"].to_numpy(dtype=float)],
        "rt_s": c["rt"].to_numpy(dtype=float),
        "status": c["status"].astype(str).to_numpy(),
    })
    if "n_targets" in c:
        out["n_targets"] = pd.to_numeric(c["n_targets"], errors="coerce").to_numpy()
    if "load" in c:
        out["load"] = c["load"].astype("string").fillna("none").astype(str).to_numpy()
    return out


def model_spec(frame: pd.DataFrame, response: str = "correct",
               transform: str | None = None) -> tuple[Any, list[str]]:
    """The maximal model the data support, and notes on what was left out.

    Fixed: every :data:`DESIGN_FACTORS` column that varies, fully crossed. Random: a
    per-participant intercept and condition slope (from 2 participants; the slope only
    when some participant has both conditions) and a per-target intercept (from 2
    targets).
    """
    from .glmm import ModelSpec, RandomTerm

    notes: list[str] = []
    fixed = []
    for col in DESIGN_FACTORS:
        if col not in frame:
            continue
        if frame[col].nunique(dropna=True) > 1:
            # the target count is a factor: no straight line in log-odds across counts
            fixed.append("factor(n_targets)" if col == "n_targets" else col)
        elif col == "on_tactor":
            notes.append("on_tactor left out of the model: all targets are of one kind")
    random = []
    if frame["participant"].nunique() > 1:
        both = frame.groupby("participant")["condition"].nunique().max() > 1
        random.append(RandomTerm("participant", ("condition",) if both else ()))
    if frame["target"].nunique() > 1:
        random.append(RandomTerm("target"))
    return ModelSpec(response, tuple(fixed), tuple(random), transform), notes


def _fitter(engine: str, family: str, keep_slopes: bool = False) -> Any:
    if engine == "lme4":
        from .lme4 import fit_lme4

        return lambda df, spec: fit_lme4(df, spec, family=family)
    from .glmm import fit_glmm, fit_lmm

    last: list[Any] = [None]  # each simplification step starts from the previous fit

    def fit(df: pd.DataFrame, spec: Any) -> Any:
        if family == "binomial":  # no Hessian for a fit the simplification replaces
            last[0] = fit_glmm(df, spec, skip_se_if_simplified=True, start=last[0],
                               keep_slopes=keep_slopes)
        else:
            last[0] = fit_lmm(df, spec, start=last[0])
        return last[0]

    return fit


def model_json(fit: Any, steps: list[dict[str, Any]], engine: str,
               notes: list[str], satt: dict[str, dict[str, Any]] | None = None
               ) -> dict[str, Any]:
    """The ``summary.json`` object of one fitted model (docs/conventions.md).

    ``satt``: lmerTest's Satterthwaite ``df``, ``t``, ``p`` (and t intervals) per fixed
    effect of an LMM; they replace the Wald p and interval.
    """
    binomial = fit.family == "binomial"
    fixed = {k: v.to_dict() for k, v in fit.fixed_effects.items()}
    p_method, ci_method = "Wald z, two-sided, normal reference", "Wald"
    if satt is not None:
        for k, v in fixed.items():
            sv = satt.get(k)
            if sv is None:
                continue
            v["df"] = _num(sv["df"])
            v["t"] = _num(sv["t"])
            v["p"] = _num(sv["p"])
            if "ci_low" in sv:
                v["ci_low"], v["ci_high"] = _num(sv["ci_low"]), _num(sv["ci_high"])
        p_method = ("t = estimate / SE on Satterthwaite's degrees of freedom, two-sided, as "
                    "lmerTest's summary (z: the same ratio)")
        ci_method = "t on the Satterthwaite df"
    return {
        "engine": ENGINE_NAMES[engine],
        "family": "binomial (logit link)" if binomial else "gaussian (identity link)",
        "criterion": ("maximum likelihood, Laplace approximation (glmer's nAGQ = 1)"
                      if binomial else "REML (lmer's default)"),
        "formula": fit.spec.formula(),
        "scale": "log-odds" if binomial else "log(seconds)",
        "fixed_effects": fixed,
        "ci_method": ci_method,
        "p_method": p_method,
        "vcov_method": fit.vcov_method,
        "random_effects": fit.random_effects,
        "singular": bool(fit.singular),
        "simplification": steps,
        "converged": bool(fit.converged),
        "convergence": list(fit.messages) or ["converged"],
        "n": {"observations": int(fit.n_obs), **{f"{g}s": int(n) for g, n in
                                                  fit.groups.items()}},
        "coding": "treatment coding, alphabetically first level the reference "
                  "(condition: dynamic); on_tactor numeric 0/1 (1 = on a tactor); "
                  "factor(n_targets): the target count as a factor, the smallest the "
                  "reference",
        "notes": notes,
    }


def fit_model(frame: pd.DataFrame, *, engine: str = "tactorbelt", rt: bool = False,
              keep_slopes: bool = False) -> tuple[Any, dict[str, Any]]:
    """Fit the accuracy GLMM (or, ``rt=True``, the log-RT LMM) with the simplification rule.

    Returns:
        ``(fit, json)``; see :func:`model_json`.
    """
    from .glmm import fit_simplified

    if engine not in ENGINES:
        raise ValueError(f"unknown engine {engine!r}; choose {', '.join(ENGINES)}")
    data = frame.loc[frame["status"] == "done"] if rt else frame
    spec, notes = model_spec(data, "rt_s" if rt else "correct", "log" if rt else None)
    fit, steps = fit_simplified(data, spec, _fitter(engine, "gaussian" if rt else "binomial",
                                                    keep_slopes), keep_slopes=keep_slopes)
    satt = None
    if rt:
        satt = rt_satterthwaite(data, fit)
        notes = notes + list(satt.pop("_", {}).get("notes", []))
    return fit, model_json(fit, steps, engine, notes, satt)


def rt_satterthwaite(data: pd.DataFrame, fit: Any) -> dict[str, dict[str, Any]]:
    """lmerTest's Satterthwaite df, t and p of an LMM's fixed effects: R's own numbers
    for a fit by R with lmerTest, else :func:`.satterthwaite.satterthwaite` (which also
    takes R's fit)."""
    from scipy.stats import t as t_dist

    from .satterthwaite import satterthwaite

    if getattr(fit, "satterthwaite", None):
        out: dict[str, dict[str, Any]] = {}
        for k, v in fit.satterthwaite.items():
            fe = fit.fixed_effects[k]
            q = float(t_dist.ppf(0.975, v["df"]))
            out[k] = {**v, "ci_low": fe.estimate - q * fe.se, "ci_high": fe.estimate + q * fe.se}
        return out
    return satterthwaite(data, fit)


def timeout_cells(frame: pd.DataFrame) -> list[dict[str, Any]]:
    """Timeouts per design cell (condition x kind [x n_targets x load])."""
    keys = ["condition", "on_tactor"] + [c for c in ("n_targets", "load") if c in frame]
    g = frame.assign(timeout=frame["status"] == "timeout").groupby(keys, dropna=False)
    out = []
    for key, sub in g:
        vals = dict(zip(keys, key if isinstance(key, tuple) else (key,), strict=True))
        n = len(sub)
        k = int(sub["timeout"].sum())
        out.append({**{kk: (v.item() if hasattr(v, "item") else v) for kk, v in vals.items()},
                    "n": n, "timeouts": k, "share": k / n if n else None})
    return out


#: Up to this many participants the parametric bootstrap of the likelihood ratio is
#: computed beside the headline (above, it would cost minutes and the chi-square p of
#: the ratio is near its level; docs/analysis.md "Tests of the condition").
PB_MAX_PARTICIPANTS: Final = 16
#: The report's headline test of the condition (every study size): the likelihood ratio
#: referred to F(k, participants - 1) (:func:`.lrt.f_reference`).
HEADLINE_TEST: Final = "LRT, F(k, participants - 1)"


def headline_method(n_participants: int) -> str:
    """The report's headline test of the condition for a study of this size: the
    likelihood ratio referred to ``F(k, n_participants - 1)`` at every size measured
    (4, 8 and 16 participants: the only test of those computed that holds its level
    there; docs/analysis.md, "Tests of the condition")."""
    return HEADLINE_TEST


HEADLINE_WHY: Final = (
    "The likelihood ratio of every condition term ({k} df) is referred to F({k}, {df2}): "
    "the {n} participants, minus one, are the denominator degrees of freedom, because the "
    "condition effect is replicated over participants, not over trials. In simulated "
    "studies without a condition effect (docs/analysis.md, 'Tests of the condition') it "
    "found one in 0.3 %, 2.0 % and 4.0 % of studies of 4, 8 and 16 participants (nominal "
    "5 %), where the same ratio's chi-square p did in 15 %, 11 % and 7.3 %, the Wald tests "
    "about as often, and the parametric bootstrap in 11 % at 4 and 8: with few "
    "participants the spread of the condition effect across them (the random slope) is "
    "often estimated at 0, and a test that trusts the fitted random effects, the "
    "bootstrap from the fitted null model included, then counts trials as independent "
    "evidence. The F reference is conservative with 4 participants.")
METHOD_WORDS: Final = {
    "Wald": "Wald chi-square over every condition term",
    "LRT": "likelihood-ratio test (chi-square)",
    HEADLINE_TEST: "likelihood-ratio test referred to F(k, participants - 1)",
    "parametric bootstrap": "parametric bootstrap of the likelihood ratio",
}


def _average_contrast(fit: Any, frame: pd.DataFrame) -> tuple[float, float]:
    """Static minus dynamic log-odds at between-tactor targets, averaged over the target
    counts and loads (emmeans' ``pairs(emmeans(m, ~ condition, at = list(on_tactor =
    0)))``, reversed): ``(estimate, se)``."""
    from .contrasts import contrast_matrix

    _, xd, xs = contrast_matrix(fit, frame)
    lvec = (xs - xd).mean(axis=0)
    beta = np.array([fe.estimate for fe in fit.fixed_effects.values()])
    return float(lvec @ beta), float(math.sqrt(max(float(lvec @ fit.vcov @ lvec), 0.0)))


def condition_tests(frame: pd.DataFrame, fit: Any, *, engine: str = "tactorbelt",
                    pb_sims: int | None = DEFAULT_PB_SIMS, seed: int = 0,
                    progress: Any = None) -> tuple[list[dict[str, Any]], Any]:
    """The Wald, likelihood-ratio (chi-square and F references) and (for a study of up
    to :data:`PB_MAX_PARTICIPANTS` participants) parametric-bootstrap tests of the
    condition (:mod:`.lrt`), as ``summary.json`` objects, and the null fit.

    Args:
        pb_sims: the bootstrap's simulations (0: not computed; None: the default).
        seed: seeds the bootstrap.
        progress: ``progress(done, total)`` as the bootstrap refits.
    """
    from .lrt import likelihood_ratio, null_spec, parametric_bootstrap, wald_condition

    n_sim = DEFAULT_PB_SIMS if pb_sims is None else int(pb_sims)
    n_p = int(frame["participant"].nunique())
    spec0 = null_spec(fit.spec)
    tests: list[dict[str, Any]] = [wald_condition(fit)]
    fit0 = None
    if engine == "lme4":
        from .lme4 import fit_lme4

        fit0 = fit_lme4(frame, spec0)
    else:
        from .glmm import fit_glmm

        fit0 = fit_glmm(frame, spec0, se=False)
    lr = likelihood_ratio(fit, fit0)
    tests.append(lr)
    pb: dict[str, Any] = {"term": "condition", "method": "parametric bootstrap",
                          "n_sim": n_sim, "p": None}
    if n_p > PB_MAX_PARTICIPANTS:
        pb.update(computed=False, reason=f"not computed with more than "
                  f"{PB_MAX_PARTICIPANTS} participants (minutes of refits; the likelihood "
                  "ratio's chi-square p is near its level there)")
    elif n_sim <= 0:
        pb.update(computed=False, reason="not computed: --bootstrap-sims 0")
    elif engine == "lme4":
        from .lme4 import condition_tests_lme4

        r = condition_tests_lme4(frame, fit.spec, spec0, n_sim=n_sim, seed=seed)
        pb.update(computed=True, statistic=lr["statistic"], df=lr["df"], p=r["pb_p"],
                  n_sim=int(r["pb_nsim"]), n_positive=int(r["pb_npos"]), seed=seed,
                  description="pbkrtest's PBmodcomp(m, m0, nsim) in R, set.seed(seed)")
    else:
        res = parametric_bootstrap(frame, fit, fit0, n_sim=n_sim, seed=seed,
                                   progress=progress)
        pb = {**res.to_dict(), "computed": True}
        if res.notes:
            pb["notes"] = res.notes
    tests.append(pb)
    return [_finite_json(t) for t in tests], fit0


def mixed_model(tr: pd.DataFrame, *, engine: str = "tactorbelt",
                pb_sims: int | None = DEFAULT_PB_SIMS, seed: int = 0,
                progress: Any = None) -> TestResult:
    """Binomial GLMM of accuracy: ``correct ~ condition * on_tactor [* factor(n_targets) *
    load] + (1 + condition | participant) + (1 | target)``, simplified while singular,
    with its tests of the condition and the contrasts per target count.

    Maximum likelihood with the Laplace approximation (:mod:`.glmm`, or lme4's glmer
    with ``engine="lme4"``). The test reported is the headline test of the condition
    (:func:`headline_method`): the likelihood ratio of every condition term against
    none, referred to ``F(k, participants - 1)``; the Wald, chi-square and (up to
    :data:`PB_MAX_PARTICIPANTS` participants) bootstrap tests are beside it. The
    effect is the static minus dynamic log-odds at between-tactor targets (averaged
    over target counts and loads). ``details["model"]`` is the ``summary.json``
    ``mixed_model`` object (with ``tests``), ``details["contrasts"]`` the per-count
    contrasts (:func:`.contrasts.condition_contrasts`).

    Args:
        tr: prepared trials (:func:`~tactorbelt.analysis.tables.prepare_trials`),
            only the counted ones are used.
        engine: ``tactorbelt`` (this package) or ``lme4`` (R, through Rscript).
        pb_sims: the parametric bootstrap's simulations (0: not computed).
        seed: seeds the bootstrap.
        progress: ``progress(done, total)`` as the bootstrap refits.
    """
    from .contrasts import condition_contrasts

    key, question = "mixed_model", "accuracy, dynamic vs static (every condition term)"
    frame = model_frame(tr)
    n_p = int(frame["participant"].nunique())
    test = f"binomial GLMM, Laplace ML ({ENGINE_NAMES.get(engine, engine)})"
    if n_p < 3:
        return _not_computed(key, test, question,
                             f"needs at least 3 participants, found {n_p}", participants=n_p)
    conds = set(frame["condition"].unique())
    if conds != set(CONDITIONS):
        only = ", ".join(sorted(conds)) or "none"
        return _not_computed(key, test, question,
                             f"needs both conditions; the data hold only {only}",
                             participants=n_p, trials=len(frame))
    y = frame["correct"].to_numpy()
    if np.all(y == y[0]):
        return _not_computed(key, test, question,
                             "every counted trial is " + ("correct" if y[0] else "incorrect")
                             + "; a logistic model has nothing to fit",
                             participants=n_p, trials=len(frame))
    n = {"participants": n_p, "trials": len(frame)}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fit, js = fit_model(frame, engine=engine)
            fe = fit.fixed_effects.get("conditionstatic")
            if fe is None or not (math.isfinite(fe.estimate) and math.isfinite(fe.se)):
                return _not_computed(key, test, question, "the fit gave no finite condition "
                                     "coefficient (separation?)", **n)
            tests, _ = condition_tests(frame, fit, engine=engine, pb_sims=pb_sims, seed=seed,
                                       progress=progress)
            contrasts = condition_contrasts(fit, frame)
    except Exception as exc:  # an engine may raise many kinds (LinAlgError, R errors, ...)
        from .lme4 import Lme4Unavailable

        if isinstance(exc, Lme4Unavailable):
            raise
        return _not_computed(key, test, question,
                             f"the model fit failed: {type(exc).__name__}: {exc}", **n)
    method = headline_method(n_p)
    by = {t["method"]: t for t in tests}
    lrt = by["LRT"]
    fref = lrt.get("f_reference") or {}
    why = HEADLINE_WHY.format(k=lrt["df"], df2=fref.get("df2"), n=n_p)
    js["tests"] = tests
    js["headline_test"] = {"method": "LRT", "reference": f"F({lrt['df']}, {fref.get('df2')})",
                           "statistic": fref.get("statistic"), "p": fref.get("p"),
                           "why": why}
    est, se = _average_contrast(fit, frame)
    lo, hi = est - Z95 * se, est + Z95 * se
    several = "factor(n_targets)" in fit.spec.fixed or "load" in fit.spec.fixed
    details: dict[str, Any] = {
        "method": f"{js['criterion']}; {js['formula']}; {METHOD_WORDS[method]}",
        "formula": js["formula"], "model": js, "contrasts": contrasts,
        "headline_test": method, "why": why,
        "tests": tests, "lrt_chi_square_p": lrt.get("p"),
        "odds_ratio": math.exp(est),
        "odds_ratio_interval": [math.exp(lo), math.exp(hi)],
        "wald_z_conditionstatic": {"z": fe.z, "p": fe.p},
        "p_method": (f"likelihood ratio / {lrt['df']} referred to F({lrt['df']}, "
                     f"{fref.get('df2')}) (participants - 1 denominator df)"),
    }
    if js["notes"]:
        details["notes"] = list(js["notes"])
    if fit.singular or not fit.converged:
        details["warnings"] = list(fit.messages)
    return TestResult(
        key=key, test=f"{test}: {METHOD_WORDS[method]}", question=question,
        statistic=lrt.get("statistic"),
        statistic_name=f"likelihood ratio chi-square, {lrt['df']} df (p from F)",
        p_value=fref.get("p"),
        effect_name=("log-odds, static - dynamic, between-tactor targets"
                     + (" (averaged over target counts and loads)" if several else "")),
        effect=est,
        ci_name="static - dynamic log-odds, 95 % Wald interval (model-based, not bootstrap)",
        ci_low=lo, ci_high=hi, n=n, details=details,
    )


def rt_model(tr: pd.DataFrame, *, engine: str = "tactorbelt") -> dict[str, Any]:
    """The log-RT linear mixed model (REML) as a ``summary.json`` object, with timeouts.

    Same fixed and random structure as :func:`mixed_model`, over answered (``done``)
    trials; timeouts have no RT and are counted per cell beside the model.
    """
    frame = model_frame(tr)
    cells = timeout_cells(frame)
    out: dict[str, Any] = {"timeouts_by_cell": cells}
    high = [c for c in cells if c["share"] is not None and c["share"] > TIMEOUT_NOTE_SHARE]
    if high:
        out["timeout_note"] = (
            f"{len(high)} cell(s) have more than {TIMEOUT_NOTE_SHARE:.0%} timeouts; the RT "
            "model sees only answered trials, so its estimates there describe the faster "
            "answers")
    done = frame.loc[frame["status"] == "done"]
    n_p = int(done["participant"].nunique())
    if n_p < 3 or done["condition"].nunique() < 2 or not (done["rt_s"] > 0).all():
        out["computed"] = False
        out["reason"] = ("needs at least 3 participants with answered trials in both "
                         "conditions and positive response times")
        return out
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            _, js = fit_model(frame, engine=engine, rt=True)
    except Exception as exc:  # reported, not raised
        from .lme4 import Lme4Unavailable

        if isinstance(exc, Lme4Unavailable):
            raise
        out["computed"] = False
        out["reason"] = f"the model fit failed: {type(exc).__name__}: {exc}"
        return out
    return {"computed": True, **js, **out}


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
        simulated_sessions: keys of sessions whose answers come from a model participant
            (or a scripted cursor), not from a person.
        simulated_belt_sessions: keys of sessions played on the simulated belt (no motor
            vibrated, whoever answered).
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
    simulated_belt_sessions: list[str]
    notes: list[str]
    trials: pd.DataFrame
    paths: list[str]
    seed: int = 0
    n_boot: int = DEFAULT_N_BOOT
    #: the ``rt_mixed_model`` object of summary.json (None without counted trials).
    rt_model: dict[str, Any] | None = None
    #: per (condition, n_targets, load): :func:`~tactorbelt.analysis.cells.cell_summary`
    cells: pd.DataFrame | None = None
    #: per (participant, condition, n_targets, load): ``participant_cells``
    participant_cells: pd.DataFrame | None = None
    #: ``summary.json["secondary_tasks"]`` (:func:`.tasks.secondary_tasks_json`), None
    #: without task events
    secondary_tasks: dict[str, Any] | None = None
    #: ``summary.json["tlx"]`` (:func:`.tasks.tlx_summary`), None without ratings
    tlx: dict[str, Any] | None = None
    #: where the response times count from (:func:`rt_from_choice`): ``skin`` or
    #: ``command``, and why
    rt_from: str = "command"
    rt_from_reason: str = ""

    @property
    def mixed_model(self) -> dict[str, Any] | None:
        """The ``mixed_model`` object of summary.json, when the GLMM was fitted."""
        t = self.test("mixed_model")
        return t.details.get("model") if t is not None and t.computed else None

    @property
    def contrasts(self) -> list[dict[str, Any]]:
        """``summary.json["contrasts"]``: dynamic - static per target count at
        between-tactor targets, Holm-adjusted (empty without the accuracy model)."""
        t = self.test("mixed_model")
        return list(t.details.get("contrasts", [])) if t is not None and t.computed else []

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
            "rt_from": self.rt_from,
            "rt_from_reason": self.rt_from_reason,
            "simulated_model_data": self.simulated,
            "simulated_sessions": len(self.simulated_sessions),
            "simulated_belt_sessions": len(self.simulated_belt_sessions),
            "counts": dict(self.counts),
            "conditions": conditions,
            "cells": cells_to_json(self.cells),
            "between_accuracy_test": self.between_accuracy_test.to_dict(),
            "tests": [t.to_dict() for t in self.tests],
            "mixed_model": self.mixed_model,
            "contrasts": _finite_json(self.contrasts),
            "rt_mixed_model": self.rt_model,
            "secondary_tasks": _finite_json(self.secondary_tasks),
            "tlx": _finite_json(self.tlx),
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


def _finite_json(v: Any) -> Any:
    """``v`` with every non-finite float replaced by None (summary.json has no NaN)."""
    if isinstance(v, dict):
        return {k: _finite_json(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_finite_json(x) for x in v]
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


COUNTING_RULES: Final = (
    "Only test-block trials count. Trials with status 'done' count; 'timeout' trials count "
    "as incorrect, with no response time and no response direction; 'aborted' trials are "
    "left out. Training trials are summarised separately."
)


def pd_numeric(s: pd.Series) -> pd.Series:
    """``pd.to_numeric(errors="coerce")`` (imported lazily)."""
    import pandas as pd

    return pd.to_numeric(s, errors="coerce")


def _is_model(sessions: pd.DataFrame) -> pd.Series:
    """Sessions answered by the model participant or a scripted cursor, not a person:
    the stored input; a store without it (older versions) by a ``model...`` participant."""
    inp = sessions["input"].astype("string").str.lower()
    by_name = sessions["participant"].astype(str).str.lower().str.startswith("model")
    return inp.isin(["model", "scripted"]).fillna(False) | (inp.isna() & by_name)


def _on_simulated_belt(sessions: pd.DataFrame) -> pd.Series:
    """Sessions played on the simulated belt (``sim`` URLs): no motor vibrated."""
    scheme = sessions["belt"].astype("string").str.lower().fillna("").str.split(":").str[0]
    return scheme.str.strip().eq("sim")


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


def rt_from_choice(trials: pd.DataFrame, rt_from: str | None = None
                   ) -> tuple[pd.DataFrame, str, str]:
    """Where the response times count from: ``(trials, used, reason)``.

    The analysed trials are those with a response time (done). ``skin``: each RT less
    the trial's ``skin_offset_s`` (``(skin_onset_ns - onset_ns) / 1e9``, the measured
    latency of the tactors that start the stimulus), so it counts from when the skin
    felt the stimulus; ``trials`` then keeps the stored RT as ``rt_command_s``.
    ``command``: the stored RTs, from the stored onset. ``rt_from`` None chooses
    ``skin`` when every analysed trial has a skin onset, else ``command``.

    Raises:
        ConfigError: ``skin`` asked for while some analysed trial has no skin onset, or
            an unknown ``rt_from``.
    """
    from .._errors import ConfigError

    if rt_from is not None and rt_from not in RT_FROM:
        raise ConfigError(f"--rt-from must be one of {', '.join(RT_FROM)}, got {rt_from!r}")
    rt = pd_numeric(trials["rt_s"]).to_numpy(dtype=float)
    status = trials["status"].astype("string").fillna("")
    analysed = (status == "done").to_numpy(dtype=bool) & ~np.isnan(rt)
    offset = (pd_numeric(trials["skin_offset_s"]).to_numpy(dtype=float)
              if "skin_offset_s" in trials.columns else np.full(len(trials), np.nan))
    n = int(analysed.sum())
    lacking = int((analysed & np.isnan(offset)).sum())
    how = ("the skin onset is the stored onset plus the measured latency of the tactors "
           "that start the stimulus (the belt's calibration, 'tactorbelt validate onsets')")
    if rt_from == "skin" and lacking:
        raise ConfigError(
            f"--rt-from skin: {lacking} of the {n} analysed trials have no skin onset (their "
            "belt's calibration had no measured latency when they ran: measure it with "
            "'tactorbelt validate onsets --calibration FILE'); use --rt-from command")
    if rt_from == "command":
        used, reason = "command", "asked for (--rt-from command): RTs from the stored onset"
    elif rt_from == "skin":
        used, reason = "skin", f"asked for (--rt-from skin); {how}"
    elif n and not lacking:
        used, reason = "skin", f"every analysed trial ({n}) has a skin onset; {how}"
    elif not n:
        used, reason = "command", "no trial has a response time"
    elif lacking == n:
        used, reason = "command", ("no analysed trial has a skin onset (no measured "
                                   "latency in the belt's calibration): RTs from the "
                                   "stored onset")
    else:
        used, reason = "command", (f"{lacking} of the {n} analysed trials have no skin "
                                   "onset (no measured latency): RTs from the stored "
                                   "onset for all")
    if used == "skin":
        trials = trials.copy()
        trials["rt_command_s"] = rt
        trials["rt_s"] = np.where(analysed, rt - offset, rt)
    return trials, used, reason


def summarize(data: StoreData, *, seed: int = 0, n_boot: int = DEFAULT_N_BOOT,
              engine: str = "tactorbelt", pb_sims: int | None = DEFAULT_PB_SIMS,
              progress: Any = None, rt_from: str | None = None) -> Summary:
    """Compute every table and test from loaded stores. Pure: no files, no clock.

    Args:
        data: what :func:`tactorbelt.analysis.load.load_stores` returned.
        seed: seeds the bootstrap (a :class:`numpy.random.Generator`).
        n_boot: bootstrap resamples per interval.
        engine: who fits the mixed models: ``tactorbelt`` (:mod:`.glmm`) or ``lme4``
            (R through Rscript; raises :class:`~tactorbelt.analysis.lme4.Lme4Unavailable`
            without it).
        pb_sims: simulations of the accuracy model's parametric bootstrap (computed up to
            :data:`PB_MAX_PARTICIPANTS` participants; 0: never), seeded by
            ``seed``.
        progress: ``progress(done, total)`` as the bootstrap refits.
        rt_from: ``skin``, ``command`` or None (the default: skin where every analysed
            trial has a skin onset), see :func:`rt_from_choice`.
    """
    rng = np.random.default_rng(seed)
    notes = list(data.notes)
    sessions = data.sessions.copy()
    sessions["simulated"] = _is_model(sessions).to_numpy(dtype=bool)
    sessions["simulated_belt"] = _on_simulated_belt(sessions).to_numpy(dtype=bool)
    design = _design_for(sessions, notes)
    trials, rt_used, rt_reason = rt_from_choice(data.trials, rt_from)
    tr = prepare_trials(trials)

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
    rt_json: dict[str, Any] | None = None
    if len(counted):
        tests.append(mixed_model(tr, engine=engine, pb_sims=pb_sims, seed=seed,
                                 progress=progress))
        rt_json = rt_model(tr, engine=engine)
        if rt_json.get("timeout_note"):
            notes.append("RT model: " + rt_json["timeout_note"])
    primary = next(t for t in tests if t.key == "between_accuracy")
    for t in tests:
        if not t.computed:
            notes.append(f"not computed: {t.test} ({t.question}): {t.reason}")
    for cond in CONDITIONS:
        if not (counted["condition"] == cond).any() and len(counted):
            notes.append(f"no {cond} test trials: its accuracy and RT are not reported")

    from .tasks import secondary_tasks_json, tlx_rows, tlx_summary

    secondary = secondary_tasks_json(data.task_events)
    tlx = tlx_summary(tlx_rows(data.ratings)) if data.ratings else None
    if tlx is not None and tlx["test"] is not None and not tlx["test"]["computed"]:
        notes.append(f"not computed: the NASA-TLX test across load: {tlx['test']['reason']}")
    return Summary(
        counts=counts, conditions=cond_table, per_target=pt, per_participant=pp,
        directions=directions, confusion=confusion, training=training, tests=tests,
        between_accuracy_test=primary, design=design, sessions=sessions,
        incomplete_sessions=incomplete.reset_index(drop=True), timeouts=timeouts,
        aborted=aborted,
        simulated_sessions=sessions.loc[sessions["simulated"], "session_key"].tolist(),
        simulated_belt_sessions=sessions.loc[sessions["simulated_belt"],
                                             "session_key"].tolist(),
        notes=notes, trials=tr, paths=[str(p) for p in data.paths], seed=seed, n_boot=n_boot,
        rt_model=rt_json,
        cells=cell_summary(tr, seed=seed), participant_cells=participant_cells(tr),
        secondary_tasks=secondary, tlx=tlx, rt_from=rt_used, rt_from_reason=rt_reason,
    )
