"""Per-cell tables of a factorial study: accuracy, information transfer, RT, error.

A cell is one (condition, n_targets, load) combination. Counting follows
:func:`tactorbelt.analysis.tables.tables.prepare_trials` (test blocks; ``done`` and
``timeout`` trials count, timeouts as incorrect; ``aborted`` left out).

Information transfer is estimated from each participant's confusion matrix of the
cell (rows: the n targets, columns: the response snapped to the nearest of those n
targets) by :func:`.transfer.estimate_transfer` (the estimator chosen by simulation,
:data:`.transfer.ESTIMATOR`, clamped to ``[0, log2 n]``), then averaged over
participants (``it_bits``), with a two-level bootstrap interval
(:func:`.transfer.cell_interval`: participants resampled, and each one's trials
resampled within each target; expanded percentile; ``it_bits_ci_low``,
``it_bits_ci_high``). Pooling every
participant's trials into one matrix would count the differences between
participants' response biases as transfer and give one number without a spread; the
pooled value is reported as well (``it_bits_pooled``) for comparison. Timeouts carry
no response and are left out of the matrices (they count in ``n`` and against
``accuracy``).

Trials of stores written before factorial designs have no ``n_targets`` or
``load`` column: they get the single target count (``n_targets`` argument, or
inferred as 360 / gcd of the target angles) and ``none``.

Pure: NumPy and pandas; never an I/O layer.
"""

from __future__ import annotations

import math
import zlib
from typing import Any, Final, cast

import numpy as np
import pandas as pd

from ...factors import BUILTIN, added_factors, after_builtin, factors
from ._json import finite_float as _num
from .tables import prepare_trials, with_cell_columns
from .transfer import ESTIMATOR, cell_interval, estimate_transfer, information_transfer

__all__ = [
    "CELL_COLUMNS",
    "CELL_KEYS",
    "IT_CI_LEVEL",
    "IT_CI_METHOD",
    "IT_N_BOOT",
    "PARTICIPANT_CELL_COLUMNS",
    "cell_summary",
    "cells_to_json",
    "is_factorial",
    "participant_cells",
]

#: The built-in factors' columns (:mod:`tactorbelt.factors`); :func:`cell_keys` adds the
#: factors declared beyond them.
CELL_KEYS: Final = [f.column for f in BUILTIN]
PARTICIPANT_CELL_COLUMNS: Final = [
    "participant", *CELL_KEYS, "n", "n_correct", "n_timeout", "accuracy", "it_bits",
    "it_bits_plain", "median_rt_s", "mean_abs_error_deg",
]
CELL_COLUMNS: Final = [
    *CELL_KEYS, "n_participants", "n", "n_correct", "n_timeout", "accuracy", "it_bits",
    "it_bits_sd", "it_bits_ci_low", "it_bits_ci_high", "it_bits_plain", "it_bits_pooled",
    "median_rt_s", "mean_abs_error_deg",
    "n_on_tactor", "accuracy_on_tactor", "n_between_tactor", "accuracy_between_tactor",
]

#: resamples and level of the cell interval of ``it_bits``
IT_N_BOOT: Final = 4000
IT_CI_LEVEL: Final = 0.95
#: summary.json's ``it_bits_ci_method``
IT_CI_METHOD: Final = (
    "95 % two-level bootstrap: participants resampled with replacement, and each drawn "
    "participant's trials resampled within each target (multinomial), the estimate "
    "recomputed and recentred on that participant's; expanded percentile interval "
    f"(Hesterberg 2015) of the {IT_N_BOOT} resampled means (plain percentile with one "
    "participant)")


def cell_keys() -> list[str]:
    """What makes a cell: every declared factor's column (condition, n_targets, load,
    then the factors declared beyond them)."""
    return [f.column for f in factors()]


def _added(columns: list[str]) -> list[str]:
    """``columns`` with the added factors' columns after the built-in ones."""
    return after_builtin(columns, [f.column for f in added_factors()])


def _prepared(trials: pd.DataFrame, n_targets: int | None) -> pd.DataFrame:
    tr = with_cell_columns(trials, n_targets)
    if "counted" not in tr.columns:
        tr = prepare_trials(tr)
    return tr.loc[tr["counted"]]


def _matrix(c: pd.DataFrame, n: int) -> np.ndarray:
    """Target x response (snapped to the nearest of the n targets) counts; no timeouts."""
    r = c.loc[c["responded"]]
    step = 360.0 / n
    target = r["target_deg"].to_numpy(dtype=float)
    resp = target + r["error_deg"].to_numpy(dtype=float)
    row = np.mod(np.round(target / step), n).astype(int)
    col = np.mod(np.round(resp / step), n).astype(int)
    m = np.zeros((n, n), dtype=np.int64)
    np.add.at(m, (row, col), 1)
    return m


def _stats(c: pd.DataFrame) -> dict[str, float | int]:
    n = len(c)
    rt = c["rt"].dropna()
    err = c["error_deg"].dropna()
    return {
        "n": n,
        "n_correct": int(c["is_correct"].sum()),
        "n_timeout": int((~c["responded"]).sum()),
        "accuracy": float(c["is_correct"].mean()) if n else float("nan"),
        "median_rt_s": float(rt.median()) if len(rt) else float("nan"),
        "mean_abs_error_deg": float(err.abs().mean()) if len(err) else float("nan"),
    }


def participant_cells(trials: pd.DataFrame, n_targets: int | None = None) -> pd.DataFrame:
    """One row per (participant, condition, n_targets, load): :data:`PARTICIPANT_CELL_COLUMNS`.

    ``it_bits`` is :func:`~.transfer.estimate_transfer` of the participant's confusion
    matrix of the cell (clamped to ``[0, log2 n_targets]``), ``it_bits_plain`` the
    plug-in estimate.
    """
    c = _prepared(trials, n_targets)
    keys = cell_keys()
    rows = []
    for key, g in c.groupby(["participant", *keys], sort=True, observed=True, dropna=False):
        p, *levels = cast("tuple[Any, ...]", key)
        cell = dict(zip(keys, levels, strict=True))
        n = cell["n_targets"] = int(cell["n_targets"])
        m = _matrix(g, n)
        rows.append({"participant": p, **cell,
                     **_stats(g), "it_bits": float(estimate_transfer(m)),
                     "it_bits_plain": float(information_transfer(m))})
    return pd.DataFrame(rows, columns=_added(PARTICIPANT_CELL_COLUMNS))


def _cell_rng(seed: int, levels: list[Any]) -> np.random.Generator:
    """The cell's own generator: its interval does not depend on the other cells."""
    key = "|".join(str(v) for v in levels)
    return np.random.default_rng([seed, zlib.crc32(key.encode())])


def cell_summary(trials: pd.DataFrame, n_targets: int | None = None, *, seed: int = 0,
                 n_boot: int = IT_N_BOOT) -> pd.DataFrame:
    """One row per (condition, n_targets, load): :data:`CELL_COLUMNS`.

    Args:
        trials: the trials (as :func:`tactorbelt.analysis.tables.load.load_stores` gives them,
            with or without :func:`~tactorbelt.analysis.tables.tables.prepare_trials`).
        n_targets: the target count of trials without an ``n_targets`` value (old
            stores); None infers it from the angles.
        seed, n_boot: the bootstrap of the ``it_bits`` interval (each cell draws from
            its own generator, seeded by ``seed`` and the cell's keys).

    ``accuracy``, ``median_rt_s`` and ``mean_abs_error_deg`` pool the cell's trials;
    ``it_bits`` is the mean over participants of each one's estimate
    (:func:`~.transfer.estimate_transfer`; ``it_bits_sd`` their SD, NaN for one
    participant; ``it_bits_ci_low``/``it_bits_ci_high`` its 95 % interval,
    :func:`~.transfer.cell_interval`), ``it_bits_plain`` the mean plug-in estimate,
    ``it_bits_pooled`` the estimate of the pooled matrix.
    Rows are sorted by condition (static first), n_targets and load (``none`` first).
    """
    c = _prepared(trials, n_targets)
    per = participant_cells(c, n_targets)
    keys = cell_keys()
    rows = []
    for key, g in c.groupby(keys, sort=True, observed=True, dropna=False):
        levels = list(cast("tuple[Any, ...]", key))
        cell = dict(zip(keys, levels, strict=True))
        n = cell["n_targets"] = int(cell["n_targets"])
        mine = np.ones(len(per), dtype=bool)
        for k, v in cell.items():
            mine &= (per[k] == v).to_numpy() if v == v else per[k].isna().to_numpy()
        pp = per.loc[mine]
        on = g.loc[g["on_tactor"].astype(bool)]
        between = g.loc[~g["on_tactor"].astype(bool)]
        mats = [_matrix(gp, n) for _, gp in g.groupby("participant", sort=True,
                                                      observed=True)]
        lo, hi = cell_interval(mats, rng=_cell_rng(seed, [cell[k] for k in keys]),
                               n_boot=n_boot, level=IT_CI_LEVEL)
        rows.append({
            **cell,
            "n_participants": int(g["participant"].nunique()), **_stats(g),
            "it_bits": float(pp["it_bits"].mean()),
            "it_bits_sd": float(pp["it_bits"].std(ddof=1)) if len(pp) > 1 else float("nan"),
            "it_bits_ci_low": lo, "it_bits_ci_high": hi,
            "it_bits_plain": float(pp["it_bits_plain"].mean()),
            "it_bits_pooled": float(estimate_transfer(_matrix(g, n))),
            "n_on_tactor": len(on),
            "accuracy_on_tactor": float(on["is_correct"].mean()) if len(on) else float("nan"),
            "n_between_tactor": len(between),
            "accuracy_between_tactor": (float(between["is_correct"].mean()) if len(between)
                                        else float("nan")),
        })
    out = pd.DataFrame(rows, columns=_added(CELL_COLUMNS))
    order = {"static": 0, "dynamic": 1}

    out["_c"] = out["condition"].map(order)
    out["_l"] = out["load"].where(out["load"] != "none", "")  # no load first
    out = out.sort_values(["_c", "n_targets", "_l", *keys[len(CELL_KEYS):]],
                          kind="stable").drop(columns=["_c", "_l"])
    return out.reset_index(drop=True)


def is_factorial(cells: pd.DataFrame | None) -> bool:
    """True when the cells span more than one target count, a load other than ``none``
    or several levels of a declared factor (the report then shows the per-cell section
    and figures)."""
    if cells is None or cells.empty:
        return False
    added = [f.column for f in added_factors() if f.column in cells]
    return bool(cells["n_targets"].nunique() > 1 or (cells["load"] != "none").any()
                or any(cells[k].nunique() > 1 for k in added))


def _level(v: Any) -> Any:
    """An added factor's level as JSON (NaN, a missing level: null)."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return None
    return v.item() if isinstance(v, np.generic) else v


def cells_to_json(cells: pd.DataFrame | None) -> list[dict[str, Any]]:
    """The ``cells`` list of ``summary.json``: one object per (condition, n_targets, load).

    Keys: condition, n_targets, load, n_participants, n, n_correct, n_timeout,
    accuracy, it_bits (mean over participants of each one's estimate), it_bits_sd,
    it_bits_ci_low, it_bits_ci_high (its 95 % interval), it_bits_method (the estimator,
    :data:`.transfer.ESTIMATOR`), it_bits_ci_method (:data:`IT_CI_METHOD`),
    it_bits_plain, it_bits_pooled, median_rt_s, mean_abs_error_deg, and ``on_tactor``
    / ``between_tactor`` objects with ``n`` and ``accuracy``. Numbers that cannot be
    computed are null.
    """
    if cells is None:
        return []
    out = []
    added = [f.column for f in added_factors() if f.column in cells]
    for r in cells.to_dict("records"):
        out.append({
            "condition": str(r["condition"]), "n_targets": int(r["n_targets"]),
            "load": str(r["load"]), **{k: _level(r[k]) for k in added},
            **{k: int(r[k]) for k in ("n_participants", "n", "n_correct", "n_timeout")},
            **{k: _num(r[k]) for k in ("accuracy", "it_bits", "it_bits_sd", "it_bits_ci_low",
                                       "it_bits_ci_high")},
            "it_bits_method": f"{ESTIMATOR}, clamped to [0, log2 n_targets]",
            "it_bits_ci_method": IT_CI_METHOD,
            **{k: _num(r[k]) for k in ("it_bits_plain", "it_bits_pooled", "median_rt_s",
                                       "mean_abs_error_deg")},
            "on_tactor": {"n": int(r["n_on_tactor"]),
                          "accuracy": _num(r["accuracy_on_tactor"])},
            "between_tactor": {"n": int(r["n_between_tactor"]),
                               "accuracy": _num(r["accuracy_between_tactor"])},
        })
    return out
