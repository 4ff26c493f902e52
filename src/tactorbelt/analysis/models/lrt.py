"""Tests of the condition in the accuracy GLMM: Wald, likelihood ratio, parametric bootstrap.

All three test the same hypothesis: *the condition has no effect anywhere in the
model*, i.e. every fixed-effect term containing ``condition`` is 0
(``conditionstatic``, ``conditionstatic:on_tactor``, and with several target counts
or loads their interactions with those factors too).

- **Wald**: the Wald chi-square ``b' V^-1 b`` over those terms (``V`` their block of
  the model's ``vcov``), on ``k`` degrees of freedom (k terms).
- **LRT**: the model against the same model without those terms (the same random
  effects), both by maximum likelihood (Laplace, as glmer; an LMM by ML), as R's
  ``anova(m0, m)``: ``2 (log L - log L0)`` on ``k`` df, p from chi-square; and
  ``LRT / k`` referred to ``F(k, participants - 1)`` (:func:`f_reference`: the
  report's headline, the one of these that holds its level with 4 to 16
  participants).
- **Parametric bootstrap**, as pbkrtest's ``PBmodcomp(m, m0)``: ``n_sim`` responses are
  simulated from the null fit (new random effects each time, as ``simulate(m0)``),
  both models are refitted to each, and ``p = (1 + #{LRT* > LRT}) / (1 + #{LRT* > 0})``
  (pbkrtest 0.5: simulated statistics at or below 0, from a refit that did not
  improve on the null, are left out of both counts; ``n_positive`` says how many
  remain).

Refits start from the observed fits (the null model) and from the null refit with
the condition terms at 0 (the full model), so a refit's ``LRT*`` is never below 0 by
more than the optimiser's tolerance. Each refit computes no standard errors.

Pure: NumPy, SciPy and the GLMM engine; the randomness comes from the ``seed``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Final

import numpy as np
import pandas as pd
from scipy.stats import chi2
from scipy.stats import f as f_dist

from .glmm import GlmmData, MixedModelFit, ModelSpec, glmm_fit, one_blas_thread

__all__ = [
    "DEFAULT_PB_SIMS",
    "PBResult",
    "condition_terms",
    "f_reference",
    "likelihood_ratio",
    "null_spec",
    "parametric_bootstrap",
    "pb_p_value",
    "wald_condition",
]

#: simulations of the report's parametric bootstrap (docs/analysis.md).
DEFAULT_PB_SIMS: Final = 100
TERM: Final = "condition"


def condition_terms(names: list[str]) -> list[str]:
    """The fixed-effect names that contain the condition (``conditionstatic``,
    ``conditionstatic:on_tactor``, ``conditionstatic:factor(n_targets)24``, ...)."""
    return [nm for nm in names if any(part.startswith(TERM) for part in nm.split(":"))]


def null_spec(spec: ModelSpec) -> ModelSpec:
    """The model without every fixed-effect term containing the condition: the other
    factors still fully crossed, the random effects unchanged (a random condition slope
    stays)."""
    return replace(spec, fixed=tuple(f for f in spec.fixed if f != TERM))


def wald_condition(fit: MixedModelFit) -> dict[str, Any]:
    """The Wald chi-square of every condition term at once."""
    names = list(fit.fixed_effects)
    terms = condition_terms(names)
    idx = [names.index(t) for t in terms]
    b = np.array([fit.fixed_effects[t].estimate for t in terms])
    v = np.asarray(fit.vcov)[np.ix_(idx, idx)]
    out: dict[str, Any] = {"term": TERM, "method": "Wald", "df": len(terms),
                           "terms": terms,
                           "description": "Wald chi-square b' V^-1 b over every fixed-effect "
                                          "term containing condition (V: their block of "
                                          "the model's vcov)"}
    if not terms or not (np.all(np.isfinite(b)) and np.all(np.isfinite(v))):
        return {**out, "statistic": None, "p": None}
    try:
        stat = float(b @ np.linalg.solve(v, b))
    except np.linalg.LinAlgError:
        return {**out, "statistic": None, "p": None}
    return {**out, "statistic": stat, "p": float(chi2.sf(stat, len(terms)))}


def likelihood_ratio(fit: MixedModelFit, fit0: MixedModelFit) -> dict[str, Any]:
    """``anova(m0, m)``: ``2 (log L - log L0)``, its df and chi-square p; and the same
    ratio referred to ``F(df, participants - 1)`` (``f_reference``, see
    :func:`f_reference`)."""
    df = len(fit.fixed_effects) - len(fit0.fixed_effects)
    # -2 log L of each (a penalised fit's deviance also holds its prior)
    stat = float(2.0 * (fit.loglik - fit0.loglik))
    p = float(chi2.sf(max(stat, 0.0), df)) if df > 0 and math.isfinite(stat) else math.nan
    out = {"term": TERM, "method": "LRT", "statistic": stat, "df": df, "p": p,
           "description": f"likelihood ratio of {fit.spec.formula()} against "
                          f"{fit0.spec.formula()}, both by maximum likelihood "
                          f"({fit.criterion}); chi-square on {df} df, as anova(m0, m)"}
    n_p = fit.groups.get("participant", 0)
    if n_p >= 2 and df > 0:
        out["f_reference"] = f_reference(stat, df, n_p)
    return out


def f_reference(lrt: float, df: int, n_participants: int) -> dict[str, Any]:
    """The likelihood ratio per df referred to ``F(df, n_participants - 1)``.

    The participants are the units over which the condition effect is replicated (each
    has both conditions): ``n_participants - 1`` is the df of a paired test of
    participant means, and of the participant x condition term the condition is
    contained in (SAS's containment and between-within methods; Li & Redden 2015,
    BMC Med Res Methodol 15:38, for binary GLMMs with few clusters). The chi-square
    reference assumes the random effects are known; with a handful of participants
    their variances are estimated poorly (the condition slope's often at 0) and the
    chi-square p finds effects that are not there (docs/analysis.md, "Tests of the
    condition").
    """
    df2 = int(n_participants) - 1
    fstat = max(float(lrt), 0.0) / df
    return {"statistic": fstat, "df1": int(df), "df2": df2,
            "p": float(f_dist.sf(fstat, df, df2)) if df2 > 0 else math.nan,
            "description": f"LRT / {df} referred to F({df}, {df2}): the participants, "
                           "minus one, are the denominator df"}


def pb_p_value(observed: float, ref: np.ndarray) -> tuple[float, int, int]:
    """pbkrtest's p: ``(1 + #{ref > observed, ref > 0}) / (1 + #{ref > 0})``.

    Returns:
        ``(p, n_positive, n_extreme)``.
    """
    ref = np.asarray(ref, dtype=float)
    pos = ref[np.isfinite(ref) & (ref > 0)]
    extreme = int((pos > observed).sum())
    return (1 + extreme) / (1 + pos.size), int(pos.size), extreme


@dataclass
class PBResult:
    """A parametric bootstrap of the likelihood ratio.

    Attributes:
        statistic: the observed LRT; df: its chi-square df (for reference).
        p: pbkrtest's p (:func:`pb_p_value`); n_sim: simulations; n_positive: those
            with a positive LRT*; n_extreme: those above the observed.
        ref: the simulated LRT* (``n_sim``; NaN where a refit failed).
        seed: the seed of the simulations.
    """

    statistic: float
    df: int
    p: float
    n_sim: int
    n_positive: int
    n_extreme: int
    ref: np.ndarray
    seed: Any
    failed: int = 0
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        se = math.sqrt(self.p * (1 - self.p) / self.n_positive) if self.n_positive else math.nan
        return {"term": TERM, "method": "parametric bootstrap", "statistic": self.statistic,
                "p_mc_ci95": [max(0.0, self.p - 1.96 * se), min(1.0, self.p + 1.96 * se)],
                "df": self.df, "p": self.p, "n_sim": self.n_sim,
                "n_positive": self.n_positive, "n_extreme": self.n_extreme,
                "failed_refits": self.failed, "seed": self.seed,
                "description": "parametric bootstrap of the likelihood ratio, as pbkrtest's "
                               "PBmodcomp: responses simulated from the null fit, both models "
                               "refitted, p = (1 + #{LRT* > LRT}) / (1 + #{LRT* > 0})"}


def _par(fit: MixedModelFit, data: GlmmData) -> np.ndarray:
    """``(theta, beta)`` of ``fit`` in ``data``'s order; fixed effects ``fit`` lacks at 0."""
    th = dict(zip(fit.theta_names, fit.theta, strict=True))
    beta = [fit.fixed_effects[nm].estimate if nm in fit.fixed_effects else 0.0
            for nm in data.names]
    return np.array([th[nm] for nm in data.theta_names] + beta, dtype=float)


@one_blas_thread
def parametric_bootstrap(frame: pd.DataFrame, fit: MixedModelFit, fit0: MixedModelFit,
                         n_sim: int = DEFAULT_PB_SIMS, seed: int | Sequence[int] = 0,
                         responses: np.ndarray | None = None,
                         progress: Callable[[int, int], None] | None = None) -> PBResult:
    """pbkrtest's ``PBmodcomp(m, m0, nsim = n_sim)`` with this package's GLMM engine.

    Args:
        frame: the data both models were fitted to.
        fit, fit0: the model and the null model (:func:`null_spec`), binomial.
        n_sim: simulated responses.
        seed: seeds the simulations (``numpy.random.default_rng(seed)``; an int or a
            sequence of ints).
        responses: ``(n_sim, N)`` 0/1 responses to use instead of simulating (to refit
            the very responses R refits, in the tests).
        progress: called with ``(done, n_sim)``.
    """
    data = GlmmData(frame, fit.spec)
    data0 = GlmmData(frame, fit0.spec)
    if responses is None:
        responses = data0.simulate(fit0, np.random.default_rng(seed), n_sim)
    n_sim = int(responses.shape[0])
    start0 = _par(fit0, data0)
    ref = np.full(n_sim, np.nan)
    failed = 0
    for i, y in enumerate(responses):
        try:
            r0 = glmm_fit(data0, y, start_par=start0, se=False)
            r1 = glmm_fit(data, y, start_par=_par(r0, data), se=False)
            ref[i] = r0.deviance - r1.deviance
        except (ValueError, np.linalg.LinAlgError, FloatingPointError):
            failed += 1
        if progress is not None:
            progress(i + 1, n_sim)
    observed = float(fit0.deviance - fit.deviance)
    p, npos, extreme = pb_p_value(observed, ref)
    notes = [f"{failed} refit(s) failed and are left out"] if failed else []
    return PBResult(observed, len(fit.fixed_effects) - len(fit0.fixed_effects), p, n_sim,
                    npos, extreme, ref, seed, failed, notes)
