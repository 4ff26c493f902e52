"""The mixed models of static versus dynamic between-tactor rendering (docs/analysis.md).

- Accuracy (from 3 participants): a binomial GLMM ``correct ~ condition * on_tactor
  [* factor(n_targets) * load] + (1 + condition | participant) + (1 | target)`` by maximum
  likelihood with the Laplace approximation (:mod:`.glmm`, agreeing with lme4's glmer; or
  glmer itself through Rscript), simplified by a stated rule while the fit is singular,
  with its tests of the condition (:mod:`.lrt`: Wald, likelihood ratio with chi-square and
  F references, parametric bootstrap) and the headline test the report names, and the
  contrasts per target count (:mod:`.contrasts`).
- Response time: a linear mixed model of log RT with the same structure (REML, as lmer),
  Satterthwaite t tests (:mod:`.satterthwaite`), timeouts counted per design cell.

:data:`DESIGN_FACTORS` are the trials-table columns that enter the fixed part.

Pure: imports NumPy, pandas, SciPy and the pure analysis modules; never an I/O layer,
except that ``engine="lme4"`` runs R through :mod:`.lme4` (temporary files and a
subprocess). SciPy loads inside the functions.
"""

from __future__ import annotations

import functools
import math
import warnings
from typing import Any, Final

import numpy as np
import pandas as pd
from scipy.stats import t as t_dist

from ...factors import CONDITION, LOAD, TARGETS, added_factors, factor
from ..tables._json import finite_float as _num
from ..tables._json import finite_json as _finite_json
from ..tables.classical import TestResult, _not_computed
from ..tables.tables import CONDITIONS
from .contrasts import condition_contrasts, contrast_matrix
from .glmm import Z95, FixefPrior, ModelSpec, RandomTerm, fit_glmm, fit_lmm, fit_simplified
from .lme4 import Lme4Unavailable, condition_tests_lme4, fit_lme4
from .lrt import (
    DEFAULT_PB_SIMS,
    condition_terms,
    likelihood_ratio,
    null_spec,
    parametric_bootstrap,
    wald_condition,
)
from .satterthwaite import satterthwaite
from .separation import detect_separation, not_estimable_text

__all__ = [
    "DESIGN_FACTORS",
    "ENGINES",
    "ENGINE_NAMES",
    "HEADLINE_TEST",
    "HEADLINE_WHY",
    "METHOD_WORDS",
    "PB_MAX_PARTICIPANTS",
    "TIMEOUT_NOTE_SHARE",
    "condition_tests",
    "design_factors",
    "fit_model",
    "mixed_model",
    "model_frame",
    "model_json",
    "model_spec",
    "rt_model",
    "rt_satterthwaite",
    "timeout_cells",
]

#: The trials-table columns of the fixed part, in this order (those that vary, crossed):
#: the built-in factors (:mod:`tactorbelt.factors`), with ``on_tactor`` (a property of
#: the target) after the condition; :func:`design_factors` adds the declared ones.
DESIGN_FACTORS: Final = (CONDITION.column, "on_tactor", TARGETS.column, LOAD.column)


def design_factors() -> tuple[str, ...]:
    """:data:`DESIGN_FACTORS`, then the column of each factor declared beyond the
    built-in ones."""
    return (*DESIGN_FACTORS, *(f.column for f in added_factors()))


def _term(column: str) -> str:
    """A design column's term in the formula (a factor's as declared: the target count
    is ``factor(n_targets)``, no straight line in log-odds across counts)."""
    return column if column == "on_tactor" else factor(column).model_term
#: A cell with more timeouts than this share gets a note beside the RT model.
TIMEOUT_NOTE_SHARE: Final = 0.05
ENGINES: Final = ("tactorbelt", "lme4")
ENGINE_NAMES: Final = {"tactorbelt": "tactorbelt-laplace", "lme4": "lme4"}


def model_frame(tr: pd.DataFrame) -> pd.DataFrame:
    """The counted trials in the columns the mixed models use (the trials table's names).

    ``correct`` 0/1 (timeouts 0), ``condition`` text, ``on_tactor`` 0/1 integer (so
    lme4 names its coefficient ``on_tactor``, not ``on_tactorTRUE``), ``n_targets`` and
    ``load`` when present (and each declared factor's column), ``participant`` text,
    ``target`` (``target_deg`` as text, a factor), ``rt_s`` (NaN for timeouts) and
    ``status``.
    """
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
    for f in added_factors():
        if f.column in c:
            col = c[f.column]
            out[f.column] = (pd.to_numeric(col, errors="coerce").to_numpy() if f.type == "int"
                             else col.astype("string").fillna(str(f.default)).astype(str)
                             .to_numpy())
    return out


def model_spec(frame: pd.DataFrame, response: str = "correct",
               transform: str | None = None) -> tuple[Any, list[str]]:
    """The maximal model the data support, and notes on what was left out.

    Fixed: every :func:`design_factors` column that varies, fully crossed. Random: a
    per-participant intercept and condition slope (from 2 participants; the slope only
    when some participant has both conditions) and a per-target intercept (from 2
    targets).
    """
    notes: list[str] = []
    fixed = []
    for col in design_factors():
        if col not in frame:
            continue
        if frame[col].nunique(dropna=True) > 1:
            fixed.append(_term(col))
        elif col == "on_tactor":
            notes.append("on_tactor left out of the model: all targets are of one kind")
    random = []
    if frame["participant"].nunique() > 1:
        both = frame.groupby("participant")["condition"].nunique().max() > 1
        random.append(RandomTerm("participant", ("condition",) if both else ()))
    if frame["target"].nunique() > 1:
        random.append(RandomTerm("target"))
    return ModelSpec(response, tuple(fixed), tuple(random), transform), notes


def _fitter(engine: str, family: str, keep_slopes: bool = False,
            fixef_prior: Any = None) -> Any:
    if engine == "lme4":
        return lambda df, spec: fit_lme4(df, spec, family=family, fixef_prior=fixef_prior)
    last: list[Any] = [None]  # each simplification step starts from the previous fit

    def fit(df: pd.DataFrame, spec: Any) -> Any:
        if family == "binomial":  # no Hessian for a fit the simplification replaces
            last[0] = fit_glmm(df, spec, skip_se_if_simplified=True, start=last[0],
                               keep_slopes=keep_slopes, fixef_prior=fixef_prior)
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
    prior = fit.fixef_prior
    fixed = {k: v.to_dict() for k, v in fit.fixed_effects.items()}
    p_method, ci_method = "Wald z, two-sided, normal reference", "Wald"
    if satt is not None:
        for k, v in fixed.items():
            sv = satt.get(k, {})
            v.update({c: _num(sv[c]) for c in ("df", "t", "p", "ci_low", "ci_high") if c in sv})
        p_method = ("t = estimate / SE on Satterthwaite's degrees of freedom, two-sided, as "
                    "lmerTest's summary (z: the same ratio)")
        ci_method = "t on the Satterthwaite df"
    criterion = ("maximum likelihood, Laplace approximation (glmer's nAGQ = 1)"
                 if binomial else "REML (lmer's default)")
    if prior is not None:
        criterion = (f"penalised maximum likelihood (posterior mode), Laplace approximation, "
                     f"as {prior.call()}")
    out = {
        "engine": (ENGINE_NAMES[engine] if prior is None
                   else "blme" if engine == "lme4" else "tactorbelt-laplace (penalised)"),
        "family": "binomial (logit link)" if binomial else "gaussian (identity link)",
        "criterion": criterion,
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
    if prior is not None:
        out["fixef_prior"] = prior.to_json()
    return out


def fit_model(frame: pd.DataFrame, *, engine: str = "tactorbelt", rt: bool = False,
              keep_slopes: bool = False, fixef_prior: Any = None
              ) -> tuple[Any, dict[str, Any]]:
    """Fit the accuracy GLMM (or, ``rt=True``, the log-RT LMM) with the simplification rule.

    ``fixef_prior``: a :class:`~tactorbelt.analysis.models.glmm.FixefPrior` for the accuracy
    model (blme's bglmer); ignored for the RT model.

    Returns:
        ``(fit, json)``; see :func:`model_json`.
    """
    if engine not in ENGINES:
        raise ValueError(f"unknown engine {engine!r}; choose {', '.join(ENGINES)}")
    data = frame.loc[frame["status"] == "done"] if rt else frame
    spec, notes = model_spec(data, "rt_s" if rt else "correct", "log" if rt else None)
    fit, steps = fit_simplified(data, spec, _fitter(engine, "gaussian" if rt else "binomial",
                                                    keep_slopes, None if rt else fixef_prior),
                                keep_slopes=keep_slopes)
    satt = None
    if rt:
        satt = rt_satterthwaite(data, fit)
        notes = notes + list(satt.pop("_", {}).get("notes", []))
    return fit, model_json(fit, steps, engine, notes, satt)


def rt_satterthwaite(data: pd.DataFrame, fit: Any) -> dict[str, dict[str, Any]]:
    """lmerTest's Satterthwaite df, t and p of an LMM's fixed effects: R's own numbers
    for a fit by R with lmerTest, else :func:`.satterthwaite.satterthwaite` (which also
    takes R's fit)."""
    if fit.satterthwaite:
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
#: The report's headline test of the condition at every study size: the likelihood ratio
#: referred to F(k, participants - 1) (:func:`.lrt.f_reference`), at 4, 8 and 16
#: participants the only test of those computed that holds its level (docs/analysis.md,
#: "Tests of the condition").
HEADLINE_TEST: Final = "LRT, F(k, participants - 1)"


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


def _average_weights(fit: Any, frame: pd.DataFrame) -> np.ndarray:
    """The weights of :func:`_average_contrast` on the fit's fixed effects."""
    _, xd, xs = contrast_matrix(fit, frame)
    return np.asarray((xs - xd).mean(axis=0))


def _average_contrast(fit: Any, frame: pd.DataFrame) -> tuple[float, float]:
    """Static minus dynamic log-odds at between-tactor targets, averaged over the target
    counts and loads (emmeans' ``pairs(emmeans(m, ~ condition, at = list(on_tactor =
    0)))``, reversed): ``(estimate, se)``."""
    lvec = _average_weights(fit, frame)
    beta = np.array([fe.estimate for fe in fit.fixed_effects.values()])
    return float(lvec @ beta), float(math.sqrt(max(float(lvec @ fit.vcov @ lvec), 0.0)))


def condition_tests(frame: pd.DataFrame, fit: Any, *, engine: str = "tactorbelt",
                    pb_sims: int | None = DEFAULT_PB_SIMS, seed: int = 0,
                    progress: Any = None, not_estimable: Any = ()
                    ) -> tuple[list[dict[str, Any]], Any]:
    """The Wald, likelihood-ratio (chi-square and F references) and (for a study of up
    to :data:`PB_MAX_PARTICIPANTS` participants) parametric-bootstrap tests of the
    condition (:mod:`.lrt`), as ``summary.json`` objects, and the null fit.

    Args:
        pb_sims: the bootstrap's simulations (0: not computed; None: the default).
        seed: seeds the bootstrap.
        progress: ``progress(done, total)`` as the bootstrap refits.
        not_estimable: fixed effects made infinite by separation
            (:func:`.separation.detect_separation`): a Wald test over any of them is
            marked not valid (its SE means nothing), the likelihood ratio stays valid.
    """
    n_sim = DEFAULT_PB_SIMS if pb_sims is None else int(pb_sims)
    n_p = int(frame["participant"].nunique())
    spec0 = null_spec(fit.spec)
    prior = fit.fixef_prior
    wald = wald_condition(fit)
    bad = [t for t in condition_terms(list(fit.fixed_effects)) if t in set(not_estimable)]
    if bad:
        wald.update(valid=False, why=(
            "not valid: separation makes " + ", ".join(bad) + " infinite, so their estimates "
            "and SEs (and this statistic) are where the optimiser stopped; the likelihood "
            "ratio stays finite and valid"))
    tests: list[dict[str, Any]] = [wald]
    fit0 = (fit_lme4(frame, spec0, fixef_prior=prior) if engine == "lme4"
            else fit_glmm(frame, spec0, se=False, fixef_prior=prior))
    lr = likelihood_ratio(fit, fit0)
    if bad:
        lr["valid"] = True
    if prior is not None:
        lr["description"] += ("; both fits penalised by the prior, the ratio of their "
                              "likelihoods at the posterior modes")
    tests.append(lr)
    pb: dict[str, Any] = {"term": "condition", "method": "parametric bootstrap",
                          "n_sim": n_sim, "p": None}
    if n_p > PB_MAX_PARTICIPANTS:
        pb.update(computed=False, reason=f"not computed with more than "
                  f"{PB_MAX_PARTICIPANTS} participants (minutes of refits; the likelihood "
                  "ratio's chi-square p is near its level there)")
    elif n_sim <= 0:
        pb.update(computed=False, reason="not computed: --bootstrap-sims 0")
    elif prior is not None:
        pb.update(computed=False, reason="not computed for a penalised fit (--fixef-prior)")
    elif engine == "lme4":
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


def _separation(frame: pd.DataFrame, fit: Any, js: dict[str, Any]) -> Any:
    """Detect separation on the fitted model's design (:mod:`.separation`), put it in
    ``js["separation"]`` and mark each infinite fixed effect ``"estimable": false``
    with the cells that make it so (not for a penalised fit, whose estimates are
    finite by its prior)."""
    sep = detect_separation(frame, fit.spec, list(fit.fixed_effects))
    js["separation"] = sep.to_json()
    if fit.fixef_prior is None:
        for term in sep.terms:
            fe = js["fixed_effects"].get(term)
            if fe is not None:
                fe["estimable"] = False
                fe["note"] = not_estimable_text(sep, term)
    return sep


def _sensitivity(frame: pd.DataFrame, engine: str) -> dict[str, Any]:
    """The penalised fit (bglmer's default prior, normal(sd = c(10, 2.5))) beside a
    maximum-likelihood fit with separation: its fixed effects and condition effect."""
    prior = FixefPrior()
    out: dict[str, Any] = {"fixef_prior": prior.to_json(),
                           "why": "separation: a weakly informative prior on the fixed "
                                  "effects keeps every estimate finite (Gelman et al. "
                                  "2008); compare its condition effect with the ML fit's"}
    try:
        fit, js = fit_model(frame, engine=engine, fixef_prior=prior)
        est, se = _average_contrast(fit, frame)
    except Exception as exc:  # reported beside the ML fit, never fatal (R without blme)
        return {**out, "computed": False, "reason": f"{type(exc).__name__}: {exc}"}
    return {**out, "computed": True, "engine": js["engine"], "formula": js["formula"],
            "fixed_effects": js["fixed_effects"], "converged": js["converged"],
            "convergence": js["convergence"],
            "condition_effect": _finite_json({
                "contrast": "static - dynamic", "scale": "log-odds",
                "at": "between-tactor targets", "estimate": est, "se": se,
                "ci_low": est - Z95 * se, "ci_high": est + Z95 * se})}


def mixed_model(tr: pd.DataFrame, *, engine: str = "tactorbelt",
                pb_sims: int | None = DEFAULT_PB_SIMS, seed: int = 0,
                progress: Any = None, fixef_prior: Any = None) -> TestResult:
    """Binomial GLMM of accuracy: ``correct ~ condition * on_tactor [* factor(n_targets) *
    load] + (1 + condition | participant) + (1 | target)``, simplified while singular,
    with its tests of the condition and the contrasts per target count.

    Maximum likelihood with the Laplace approximation (:mod:`.glmm`, or lme4's glmer
    with ``engine="lme4"``). The test reported is the headline test of the condition
    (:data:`HEADLINE_TEST`): the likelihood ratio of every condition term against
    none, referred to ``F(k, participants - 1)``; the Wald, chi-square and (up to
    :data:`PB_MAX_PARTICIPANTS` participants) bootstrap tests are beside it. The
    effect is the static minus dynamic log-odds at between-tactor targets (averaged
    over target counts and loads). ``details["model"]`` is the ``summary.json``
    ``mixed_model`` object (with ``tests``), ``details["contrasts"]`` the per-count
    contrasts (:func:`.contrasts.condition_contrasts`).

    Args:
        tr: prepared trials (:func:`~tactorbelt.analysis.tables.tables.prepare_trials`),
            only the counted ones are used.
        engine: ``tactorbelt`` (this package) or ``lme4`` (R, through Rscript).
        pb_sims: the parametric bootstrap's simulations (0: not computed).
        seed: seeds the bootstrap.
        progress: ``progress(done, total)`` as the bootstrap refits.
        fixef_prior: fit with this prior (:class:`~tactorbelt.analysis.models.glmm.FixefPrior`,
            ``analyze --fixef-prior``), as ``blme::bglmer``; the model object names it.

    Where a design cell is at 0 or 100 %, ``model["separation"]`` names the cells and
    the fixed effects they make infinite (marked not estimable, the Wald test not
    valid), and (without a prior) ``model["sensitivity"]`` holds the penalised fit
    with bglmer's default prior.
    """
    key, question = "mixed_model", "accuracy, dynamic vs static (every condition term)"
    frame = model_frame(tr)
    n_p = int(frame["participant"].nunique())
    test = f"binomial GLMM, Laplace ML ({ENGINE_NAMES.get(engine, engine)})"
    if fixef_prior is not None:
        test = (f"binomial GLMM, penalised ML, fixef.prior = {fixef_prior.blme()} "
                f"({'blme' if engine == 'lme4' else ENGINE_NAMES.get(engine, engine)})")
    skip = functools.partial(_not_computed, key, test, question)
    if n_p < 3:
        return skip(f"needs at least 3 participants, found {n_p}", participants=n_p)
    n = {"participants": n_p, "trials": len(frame)}
    conds = set(frame["condition"].unique())
    if conds != set(CONDITIONS):
        return skip("needs both conditions; the data hold only "
                    + (", ".join(sorted(conds)) or "none"), **n)
    y = frame["correct"].to_numpy()
    if np.all(y == y[0]):
        return skip("every counted trial is " + ("correct" if y[0] else "incorrect")
                    + "; a logistic model has nothing to fit", **n)
    try:
        with warnings.catch_warnings(action="ignore"):
            fit, js = fit_model(frame, engine=engine, fixef_prior=fixef_prior)
            sep = _separation(frame, fit, js)
            inf_terms = [] if fit.fixef_prior is not None else sep.terms
            fe = fit.fixed_effects.get("conditionstatic")
            if fe is None or not (math.isfinite(fe.estimate) and math.isfinite(fe.se)):
                return skip("the fit gave no finite condition coefficient (separation?)", **n)
            tests, _ = condition_tests(frame, fit, engine=engine, pb_sims=pb_sims, seed=seed,
                                       progress=progress, not_estimable=inf_terms)
            contrasts = condition_contrasts(fit, frame, inf_terms)
            if sep.found and fixef_prior is None:
                js["sensitivity"] = _sensitivity(frame, engine)
    except Lme4Unavailable:
        raise
    except Exception as exc:  # an engine may raise many kinds (LinAlgError, R errors, ...)
        return skip(f"the model fit failed: {type(exc).__name__}: {exc}", **n)
    method = HEADLINE_TEST
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
        "wald_z_conditionstatic": (
            {"z": None, "p": None, "valid": False,
             "why": "separation makes the coefficient infinite (its standard error is 0 "
                    "at the boundary): no Wald test"}
            if "conditionstatic" in inf_terms else {"z": fe.z, "p": fe.p}),
        "p_method": (f"likelihood ratio / {lrt['df']} referred to F({lrt['df']}, "
                     f"{fref.get('df2')}) (participants - 1 denominator df)"),
    }
    if js["notes"]:
        details["notes"] = list(js["notes"])
    if fit.singular or not fit.converged:
        details["warnings"] = list(fit.messages)
    if inf_terms:
        lvec = _average_weights(fit, frame)
        names = list(fit.fixed_effects)
        if any(abs(lvec[names.index(t)]) > 1e-12 for t in inf_terms if t in names):
            details["effect_estimable"] = False
            details["effect_note"] = ("not estimable: the effect weighs fixed effects that "
                                      "separation makes infinite (see the model's "
                                      "separation and its penalised sensitivity fit)")
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
        with warnings.catch_warnings(action="ignore"):
            _, js = fit_model(frame, engine=engine, rt=True)
    except Lme4Unavailable:
        raise
    except Exception as exc:  # reported, not raised
        out["computed"] = False
        out["reason"] = f"the model fit failed: {type(exc).__name__}: {exc}"
        return out
    return {"computed": True, **js, **out}
