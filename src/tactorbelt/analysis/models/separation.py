"""Separation in the accuracy model: design cells at 0 or 100 %, and the fixed effects
whose maximum-likelihood estimates are infinite because of them.

Localisation studies put cells at the ceiling as a rule (a static target on a tactor is
answered right every time). A logistic model's likelihood then keeps rising as some
coefficients go to plus or minus infinity: any finite number an optimiser stops at
(glmer's or ours) has no meaning, and its Wald SE and z have none either. This module
says which, as R's ``detectseparation`` (Kosmidis and Schumacher; after Konis 2007,
``safeBinaryRegression``) does for a binomial GLM, here on the GLMM's fixed part over
the design cells (trials pooled over participants and targets: the random effects are
penalised, so they cannot absorb a whole design cell at 0 or 100 %).

The linear programs (SciPy's HiGHS). With ``x_i`` a design cell's row of the fixed
design, ``xbar`` holds ``+x_i`` for a cell with a success and ``-x_i`` for one with a
failure (both for a cell with both). A direction ``d`` with ``xbar d >= 0`` and
``xbar d != 0`` raises the likelihood without bound (a separating direction).

1. The separated cells: maximise ``sum t_i`` subject to ``0 <= t_i <= 1``,
   ``t_i <= xbar_i d``, ``xbar d >= 0`` (``d`` free; the directions form a cone, so
   every row that some direction makes positive reaches 1).
2. Each coefficient: the largest and smallest ``d_j`` over those directions within
   ``-1 <= d <= 1``; a coefficient is infinite (not estimable) when either is not 0,
   ``+inf`` or ``-inf`` by the sign of the direction that Konis's program finds
   (maximise ``sum xbar d`` in the same box), as ``detect_separation`` reports them.

Pure: NumPy, pandas, SciPy; no I/O.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any, Final

import numpy as np
import pandas as pd
from scipy.optimize import linprog

from .glmm import ModelSpec, fixed_design, term_column

__all__ = ["Separation", "detect_separation", "not_estimable_text"]

#: A coefficient of a direction below this is 0 (detectseparation's default tolerance).
TOLERANCE: Final = 1e-3
METHOD: Final = ("linear programming on the design cells (Konis 2007; the approach of R's "
                 "detectseparation), trials pooled over participants and targets")


@dataclass
class Separation:
    """What :func:`detect_separation` found.

    Attributes:
        cells: one dict per design cell at 0 or 100 %: the factor columns' levels,
            ``successes``, ``n``, ``accuracy`` (0.0 or 1.0) and ``label``.
        terms: the fixed effects (lme4's names) that are not estimable, in the model's
            order.
        direction: per such term, ``"+inf"`` or ``"-inf"``.
        because: per such term, the labels of the cells at 0 or 100 % that hold it.
    """

    cells: list[dict[str, Any]] = field(default_factory=list)
    terms: list[str] = field(default_factory=list)
    direction: dict[str, str] = field(default_factory=dict)
    because: dict[str, list[str]] = field(default_factory=dict)

    @property
    def found(self) -> bool:
        return bool(self.terms)

    def to_json(self) -> dict[str, Any]:
        return {**asdict(self), "method": METHOD}


def _cell_label(cols: list[str], key: tuple[Any, ...], k: int, n: int) -> str:
    parts = []
    for c, v in zip(cols, key, strict=True):
        v = v.item() if hasattr(v, "item") else v
        if isinstance(v, float) and v.is_integer():
            v = int(v)
        parts.append(f"{c} = {v}")
    return f"{', '.join(parts)}: {k}/{n} ({100 * k / n:.0f} %)"


def detect_separation(frame: pd.DataFrame, spec: ModelSpec,
                      names: list[str] | None = None) -> Separation:
    """The design cells at 0 or 100 % and the fixed effects they make infinite.

    Args:
        frame: the model frame (one row per trial, ``spec.response`` 0/1).
        spec: the model; its fixed terms define the cells.
        names: the fitted model's fixed-effect names (columns the fit dropped as linear
            combinations are left out too); default: the design's own.
    """
    out = Separation()
    cols = [term_column(t) for t in spec.fixed]
    y = frame[spec.response].to_numpy(dtype=float)
    if not cols:
        keys: list[tuple[Any, ...]] = [()]
        groups = [np.arange(len(frame))]
    else:
        g = frame.groupby(cols, sort=True, dropna=False).indices
        keys = [k if isinstance(k, tuple) else (k,) for k in g]
        groups = [np.asarray(v, dtype=np.int64) for v in g.values()]
    first = np.array([idx[0] for idx in groups], dtype=int)
    succ = np.array([y[idx].sum() for idx in groups])
    n = np.array([len(idx) for idx in groups], dtype=float)
    labels = [_cell_label(cols, k, int(s), int(m)) for k, s, m in zip(keys, succ, n,
                                                                       strict=True)]
    x_all, all_names, _ = fixed_design(frame, spec.fixed)
    if names is not None:
        keep = [all_names.index(nm) for nm in names if nm in all_names]
        x_all, all_names = x_all[:, keep], [all_names[j] for j in keep]
    x = x_all[first]
    at_bound: list[int] = []
    for i, (k, s, m) in enumerate(zip(keys, succ, n, strict=True)):
        if s == 0 or s == m:
            cell = {c: (v.item() if hasattr(v, "item") else v) for c, v in zip(cols, k,
                                                                                strict=True)}
            cell.update(successes=int(s), n=int(m), accuracy=float(s / m), label=labels[i])
            out.cells.append(cell)
            at_bound.append(i)
    if not out.cells:
        return out
    rows, owner = [], []
    for i in range(len(keys)):
        if succ[i] > 0:
            rows.append(x[i])
            owner.append(i)
        if succ[i] < n[i]:
            rows.append(-x[i])
            owner.append(i)
    xbar = np.asarray(rows)
    r, p = xbar.shape
    # 1. rows some separating direction makes positive
    c = np.r_[np.zeros(p), -np.ones(r)]
    a_ub = np.block([[-xbar, np.zeros((r, r))], [-xbar, np.eye(r)]])
    res = linprog(c, A_ub=a_ub, b_ub=np.zeros(2 * r),
                  bounds=[(None, None)] * p + [(0.0, 1.0)] * r, method="highs")
    if not res.success or -res.fun < 0.5:
        return out
    # 2. per coefficient, within the box
    box = [(-1.0, 1.0)] * p
    konis = linprog(-xbar.sum(axis=0), A_ub=-xbar, b_ub=np.zeros(r), bounds=box,
                    method="highs")
    sign = konis.x if konis.success else np.zeros(p)
    for j, nm in enumerate(all_names):
        e = np.zeros(p)
        e[j] = 1.0
        hi = linprog(-e, A_ub=-xbar, b_ub=np.zeros(r), bounds=box, method="highs")
        lo = linprog(e, A_ub=-xbar, b_ub=np.zeros(r), bounds=box, method="highs")
        top = -hi.fun if hi.success else 0.0
        bottom = lo.fun if lo.success else 0.0
        if max(top, -bottom) <= TOLERANCE:
            continue
        out.terms.append(nm)
        s_j = sign[j] if abs(sign[j]) > TOLERANCE else (top if top > -bottom else bottom)
        out.direction[nm] = "+inf" if s_j > 0 else "-inf"
        out.because[nm] = [labels[i] for i in at_bound if x[i, j] != 0]
    return out


def not_estimable_text(sep: Separation, term: str) -> str:
    """The report's words for a term :func:`detect_separation` found infinite."""
    cells = sep.because.get(term) or [c["label"] for c in sep.cells]
    which = "; ".join(cells[:3]) + (f"; and {len(cells) - 3} more" if len(cells) > 3 else "")
    return f"not estimable ({'cell' if len(cells) == 1 else 'cells'} {which})"
