"""Satterthwaite t tests of a linear mixed model's fixed effects, as lmerTest computes them.

lmerTest (Kuznetsova, Brockhoff & Christensen 2017, J. Stat. Softw. 82(13)) gives each
fixed effect ``b_j`` of an ``lmer`` fit a t statistic ``b_j / se_j`` on

    df_j = 2 V_jj^2 / (g_j' A g_j)

degrees of freedom, where ``V = sigma^2 (R_X' R_X)^-1`` is the fixed effects' covariance
as a function of the variance parameters ``varpar = (theta, sigma)``, ``g_j`` the
gradient of ``V_jj`` over ``varpar`` (the Jacobian of ``V``) and ``A = 2 H^-1`` the
asymptotic covariance of ``varpar``, ``H`` the Hessian of the (REML) deviance as a
function of ``varpar`` (lmerTest's ``devfun_vp``: ``log det(L L') + pwrss / sigma^2 +
n log(2 pi sigma^2)``, plus ``log det(R_X' R_X) - p log(2 pi sigma^2)`` for REML). As
lmerTest, ``H^-1`` is taken over the eigenvectors with eigenvalues above 1e-8 (a
boundary fit), and p is two-sided from t(df).

lmerTest differentiates numerically with numDeriv (Richardson extrapolation); so does
this module (central differences at 4 step sizes, halved each time, extrapolated;
steps ``0.1 |x| + 1e-4`` for the Hessian as numDeriv's ``hessian``, ``1e-4 |x| + 1e-4``
for the Jacobian as its ``jacobian``).

Pure: NumPy, SciPy and :class:`~tactorbelt.analysis.models.glmm.LmmData`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
import pandas as pd
from scipy.stats import t as t_dist

from .glmm import Z95, LmmData, MixedModelFit, one_blas_thread

__all__ = ["richardson_hessian", "richardson_jacobian", "satterthwaite"]


def _extrapolate(a: list[np.ndarray]) -> np.ndarray:
    """Richardson extrapolation of central differences at steps h, h/2, h/4, ..."""
    for m in range(1, len(a)):
        f = 4.0**m
        a = [(a[k + 1] * f - a[k]) / (f - 1.0) for k in range(len(a) - 1)]
    return a[0]


def richardson_jacobian(f: Callable[[np.ndarray], np.ndarray], x: np.ndarray, *,
                        d: float = 1e-4, eps: float = 1e-4, r: int = 4) -> np.ndarray:
    """``(len(f(x)), len(x))`` Jacobian by extrapolated central differences (numDeriv)."""
    x = np.asarray(x, dtype=float)
    h0 = np.where(np.abs(x) < 1e-6, eps, d * np.abs(x))
    cols = []
    for i in range(x.size):
        est = []
        for k in range(r):
            h = h0[i] / 2.0**k
            e = np.zeros(x.size)
            e[i] = h
            est.append((np.asarray(f(x + e)) - np.asarray(f(x - e))) / (2.0 * h))
        cols.append(_extrapolate(est))
    return np.column_stack(cols)


def richardson_hessian(f: Callable[[np.ndarray], float], x: np.ndarray, *,
                       d: float = 0.1, eps: float = 1e-4, r: int = 4) -> np.ndarray:
    """Hessian by extrapolated central second differences (numDeriv's ``hessian``)."""
    x = np.asarray(x, dtype=float)
    k = x.size
    h0 = np.where(np.abs(x) < 1e-6, eps, d * np.abs(x))
    f0 = f(x)
    hess = np.zeros((k, k))
    for i in range(k):
        est = []
        for m in range(r):
            h = h0[i] / 2.0**m
            e = np.zeros(k)
            e[i] = h
            est.append(np.array((f(x + e) - 2.0 * f0 + f(x - e)) / h**2))
        hess[i, i] = float(_extrapolate(est))
    for i in range(k):
        for j in range(i):
            est = []
            for m in range(r):
                hi, hj = h0[i] / 2.0**m, h0[j] / 2.0**m
                ei = np.zeros(k)
                ej = np.zeros(k)
                ei[i], ej[j] = hi, hj
                est.append(np.array((f(x + ei + ej) - f(x + ei - ej) - f(x - ei + ej)
                                     + f(x - ei - ej)) / (4.0 * hi * hj)))
            hess[i, j] = hess[j, i] = float(_extrapolate(est))
    return hess


@one_blas_thread
def satterthwaite(frame: pd.DataFrame, fit: MixedModelFit,
                  tol: float = 1e-8) -> dict[str, dict[str, Any]]:
    """Satterthwaite ``df``, ``t`` and two-sided ``p`` of each fixed effect (lmerTest).

    Args:
        frame: the data ``fit`` was fitted to (answered trials).
        fit: an LMM by REML (:func:`~tactorbelt.analysis.models.glmm.fit_lmm`, or lmer's).

    Returns:
        Per fixed effect: ``df``, ``t``, ``p``, and ``ci_low``/``ci_high`` (the 95 % t
        interval on ``df``); and under the key ``"_"`` the notes (negative or zero
        eigenvalues of the Hessian, as lmerTest warns).
    """
    data = LmmData(frame, fit.spec)
    sigma = float(fit.random_effects["Residual"]["sd"]["(Intercept)"])
    varpar = np.r_[fit.theta, sigma]
    n, p = data.n, data.p

    def dev_vp(vp: np.ndarray) -> float:
        st = data.state(vp[:-1])
        s2 = vp[-1] ** 2
        dev = st["ldl2"] + st["pwrss"] / s2 + n * math.log(2.0 * math.pi * s2)
        dev += st["ldx"] - p * math.log(2.0 * math.pi * s2)  # REML
        return float(dev)

    def covbeta(vp: np.ndarray) -> np.ndarray:
        st = data.state(vp[:-1])
        return np.asarray(vp[-1] ** 2 * np.linalg.inv(st["sbb"])).ravel()

    hess = richardson_hessian(dev_vp, varpar)
    evals, evecs = np.linalg.eigh((hess + hess.T) / 2.0)
    notes = []
    if np.any(evals < -tol):
        notes.append(f"the Hessian of the deviance has {int((evals < -tol).sum())} negative "
                     "eigenvalue(s): the model may not have converged")
    if np.any(np.abs(evals) <= tol):
        notes.append(f"the Hessian of the deviance has {int((np.abs(evals) <= tol).sum())} "
                     "eigenvalue(s) near zero (a boundary fit)")
    pos = evals > tol
    a = 2.0 * (evecs[:, pos] / evals[pos]) @ evecs[:, pos].T
    jac = richardson_jacobian(covbeta, varpar)  # (p*p, k)
    vcov = np.asarray(fit.vcov)
    out: dict[str, dict[str, Any]] = {}
    for j, name in enumerate(fit.fixed_effects):
        fe = fit.fixed_effects[name]
        var = vcov[j, j]
        grad = jac[j * p + j, :]
        denom = float(grad @ a @ grad)
        df = 2.0 * var**2 / denom if denom > 0 else math.inf
        tval = fe.estimate / fe.se if fe.se > 0 else math.nan
        pval = float(2.0 * t_dist.sf(abs(tval), df)) if math.isfinite(tval) else math.nan
        q = float(t_dist.ppf(0.975, df)) if math.isfinite(df) else Z95
        out[name] = {"df": float(df), "t": float(tval), "p": pval,
                     "ci_low": fe.estimate - q * fe.se, "ci_high": fe.estimate + q * fe.se}
    out["_"] = {"notes": notes}
    return out
