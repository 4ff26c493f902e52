"""Dynamic against static at each target count: the accuracy model's contrasts.

What ``emmeans`` computes in R for a fitted ``glmer``::

    em <- emmeans(m, ~ condition | n_targets, at = list(on_tactor = 0))
    test(pairs(em), adjust = "holm", by = NULL)             # log-odds
    test(pairs(regrid(em)), adjust = "holm", by = NULL)     # probability

The reference grid is every combination of the model's factor levels with
``on_tactor`` held at 0 (between-tactor targets); a factor the contrast is not about
(``load``) is averaged with equal weights, on the log-odds scale, as emmeans does. Each
contrast is ``L beta`` with ``L`` the difference of the two conditions' grid rows, its
SE ``sqrt(L V L')`` with ``V`` the model's ``vcov``, z and two-sided p from the normal
distribution (emmeans' asymptotic ``df = Inf`` for a GLMM). On the probability scale
the estimate is ``expit(eta_dynamic) - expit(eta_static)`` with a delta-method SE
(emmeans' ``regrid``). p-values are Holm-adjusted across the target counts (the whole
family: ``by = NULL``), by ``statsmodels.stats.multitest.multipletests``.

Pure: NumPy, pandas, SciPy, statsmodels.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from typing import Any, Final

import numpy as np
import pandas as pd
from scipy.special import expit
from scipy.stats import norm

from ..tables._json import finite_float as _num
from .glmm import MixedModelFit, fixed_design, term_column, term_levels

__all__ = ["CONTRAST", "condition_contrasts", "contrast_matrix"]

CONTRAST: Final = "dynamic - static"
ADJUST: Final = "holm"


def _grid(frame: pd.DataFrame, terms: tuple[str, ...]) -> tuple[pd.DataFrame, list[Any]]:
    """The reference grid: condition x n_targets x (other factor levels), on_tactor = 0.

    Returns the grid and the target counts (one ``None`` when the data have none)."""
    columns: dict[str, list[Any]] = {"condition": ["dynamic", "static"]}
    counts: list[Any] = [None]
    for t in terms:
        col = term_column(t)
        if col in ("condition", "on_tactor"):
            continue
        lv = term_levels(frame, t)
        if lv is None:  # a numeric covariate: at its mean, as emmeans
            columns[col] = [float(frame[col].mean())]
        else:
            columns[col] = list(lv)
        if col == "n_targets":
            counts = list(columns[col])
    if "n_targets" not in columns and "n_targets" in frame:
        vals = frame["n_targets"].dropna().unique()
        if len(vals) == 1:
            counts = [vals[0]]
    keys = list(columns)
    rows = [dict(zip(keys, combo, strict=True)) for combo in itertools.product(
        *(columns[k] for k in keys))]
    grid = pd.DataFrame(rows)
    grid["on_tactor"] = 0
    return grid, counts


def contrast_matrix(fit: MixedModelFit, frame: pd.DataFrame
                    ) -> tuple[list[Any], np.ndarray, np.ndarray]:
    """The grid rows of each condition at each target count, averaged over the other
    factors: ``(counts, X_dynamic, X_static)``, each ``(len(counts), p)`` over the fit's
    fixed effects."""
    terms = fit.spec.fixed
    grid, counts = _grid(frame, terms)
    levels = {t: term_levels(frame, t) for t in terms}
    x, names, _ = fixed_design(grid, terms, levels=levels, check_rank=False)
    idx = [names.index(nm) for nm in fit.fixed_effects]
    x = x[:, idx]
    xd = np.zeros((len(counts), len(idx)))
    xs = np.zeros_like(xd)
    for i, k in enumerate(counts):
        at = np.ones(len(grid), dtype=bool)
        if k is not None and "n_targets" in grid:
            at = grid["n_targets"].to_numpy() == k
        xd[i] = x[at & (grid["condition"] == "dynamic").to_numpy()].mean(axis=0)
        xs[i] = x[at & (grid["condition"] == "static").to_numpy()].mean(axis=0)
    return counts, xd, xs


def condition_contrasts(fit: MixedModelFit, frame: pd.DataFrame,
                        not_estimable: Sequence[str] = ()) -> list[dict[str, Any]]:
    """Dynamic minus static at between-tactor targets, per target count (see the module).

    Args:
        fit: the accuracy GLMM (a ``condition`` factor with levels dynamic and static).
        frame: the data it was fitted to (for the factor levels).
        not_estimable: fixed effects whose estimates are infinite (separation); a
            contrast that weighs any of them gets ``"estimable": false``.

    Returns:
        One object per target count, in count order: ``contrast``, ``by``
        (``n_targets``, ``on_tactor``), ``scale`` ``"log-odds"``, ``estimate``, ``se``,
        ``z``, ``p``, ``p_adjusted``, ``adjust`` ``"holm"``, ``n_family``, and
        ``probability`` (the same on the probability scale, with each condition's
        estimated accuracy), ``estimable``. Empty when the model has no condition or no finite vcov.
    """
    from statsmodels.stats.multitest import multipletests

    if "condition" not in fit.spec.fixed:
        return []
    beta = np.array([fe.estimate for fe in fit.fixed_effects.values()])
    vcov = np.asarray(fit.vcov, dtype=float)
    if not (np.all(np.isfinite(beta)) and np.all(np.isfinite(vcov))):
        return []
    counts, xd, xs = contrast_matrix(fit, frame)
    lmat = xd - xs
    est = lmat @ beta
    se = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", lmat, vcov, lmat), 0.0))
    z = est / se
    p = 2.0 * norm.sf(np.abs(z))
    eta_d, eta_s = xd @ beta, xs @ beta
    pd_, ps_ = expit(eta_d), expit(eta_s)
    gmat = (pd_ * (1 - pd_))[:, None] * xd - (ps_ * (1 - ps_))[:, None] * xs
    pest = pd_ - ps_
    pse = np.sqrt(np.maximum(np.einsum("ij,jk,ik->i", gmat, vcov, gmat), 0.0))
    pz = pest / pse
    pp = 2.0 * norm.sf(np.abs(pz))
    names = list(fit.fixed_effects)
    bad = [names.index(t) for t in not_estimable if t in names]
    estimable = ~np.any(np.abs(lmat[:, bad]) > 1e-12, axis=1) if bad else np.ones(len(est), bool)
    padj = multipletests(p, method=ADJUST)[1]
    ppadj = multipletests(pp, method=ADJUST)[1]
    out = []
    for i, k in enumerate(counts):
        by: dict[str, Any] = {}
        if k is not None:
            by["n_targets"] = int(k) if float(k).is_integer() else float(k)
        by["on_tactor"] = 0
        out.append({
            "contrast": CONTRAST, "by": by, "scale": "log-odds",
            "estimate": _num(est[i]), "se": _num(se[i]), "z": _num(z[i]), "p": _num(p[i]),
            "p_adjusted": _num(padj[i]), "adjust": ADJUST, "n_family": len(counts),
            "probability": {
                "scale": "probability", "estimate": _num(pest[i]), "se": _num(pse[i]),
                "z": _num(pz[i]), "p": _num(pp[i]), "p_adjusted": _num(ppadj[i]),
                "adjust": ADJUST, "dynamic": _num(pd_[i]), "static": _num(ps_[i]),
                "method": "delta method on the back-transformed estimates (emmeans' regrid)",
            },
            "estimable": bool(estimable[i]),
        })
    return out
