"""Descriptive tables of a study: accuracy, response time and circular error.

Counting rules (docs/analysis.md):

- Only test-block trials count (training is summarised separately).
- ``done`` trials count; ``timeout`` trials count as incorrect, with no response time
  and no response direction; ``aborted`` trials are left out.
- The signed error of a response is ``wrap(response_target_deg - target_deg)`` in
  (-180, 180] (clockwise positive), using the selected target, or the raw cursor
  direction ``response_deg`` when no target was recorded.
- Circular statistics treat errors as angles: the circular mean is wrapped to
  (-180, 180]; the circular SD is ``sqrt(-2 ln R)`` in degrees (scipy's circstd).

Everything is a pandas ``groupby``; there is no per-trial Python loop.

Pure: imports NumPy, pandas, SciPy and tactorbelt.geometry; never an I/O layer.
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np
import pandas as pd
from scipy.stats import circmean, circstd

from ...factors import CONDITION, added_factors
from ...geometry import wrap

__all__ = [
    "CONDITIONS",
    "KINDS",
    "PER_TARGET_COLUMNS",
    "circ_stats",
    "condition_summary",
    "confusion_matrices",
    "direction_summary",
    "per_participant",
    "per_site",
    "per_target",
    "prepare_trials",
    "training_summary",
]

CONDITIONS: Final = tuple(CONDITION.levels)
#: Target kinds, by the ``on_tactor`` flag of the trial.
KINDS: Final = ("on_tactor", "between_tactor")
KIND_LABELS: Final = {"on_tactor": "on-tactor", "between_tactor": "between-tactor"}
PER_TARGET_COLUMNS: Final = [
    "participant", "condition", "n_targets", "load", "target_deg", "on_tactor", "n",
    "accuracy", "median_rt_s", "mean_signed_error_deg",
]
NO_RESPONSE: Final = "no response"


def prepare_trials(trials: pd.DataFrame) -> pd.DataFrame:
    """Add the derived columns every table uses.

    Adds ``counted`` (test block, status done or timeout, condition static or
    dynamic), ``responded`` (done with a response direction), ``is_correct`` (bool;
    False for timeouts), ``error_deg`` (signed, NaN without a response), ``rt``
    (``rt_s`` of done trials, NaN otherwise), ``kind`` (``on_tactor`` or
    ``between_tactor``) and ``err_sin``/``err_cos`` (for circular means).
    """
    tr = trials.copy()
    status = tr["status"].astype("string").fillna("aborted")
    done = (status == "done").to_numpy(dtype=bool)
    timeout = (status == "timeout").to_numpy(dtype=bool)
    test = (tr["block"].astype("string") == "test").fillna(False).to_numpy(dtype=bool)
    known = tr["condition"].isin(CONDITIONS).to_numpy(dtype=bool)
    tr["counted"] = test & known & (done | timeout)
    resp = tr["response_target_deg"].to_numpy(dtype=float)
    resp = np.where(np.isnan(resp), tr["response_deg"].to_numpy(dtype=float), resp)
    target = tr["target_deg"].to_numpy(dtype=float)
    responded = done & ~np.isnan(resp)
    tr["responded"] = responded
    tr["no_response"] = ~responded
    err = np.where(responded, wrap(np.where(responded, resp, 0.0) - target), np.nan)
    tr["error_deg"] = err
    stored = tr["correct"].to_numpy(dtype=float)
    derived = responded & (np.abs(np.nan_to_num(err)) < 1e-6)
    tr["is_correct"] = done & np.where(np.isnan(stored), derived, stored != 0)
    tr["rt"] = np.where(done, tr["rt_s"].to_numpy(dtype=float), np.nan)
    tr["kind"] = pd.Categorical(
        np.where(tr["on_tactor"].to_numpy(dtype=bool), "on_tactor", "between_tactor"),
        categories=list(KINDS))
    rad = np.deg2rad(err)
    tr["err_sin"] = np.sin(rad)
    tr["err_cos"] = np.cos(rad)
    return tr


def _circ_from_sums(s: np.ndarray, c: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Circular mean (wrapped to (-180, 180]) and SD in degrees from sums of sin and cos."""
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(n > 0, wrap(np.rad2deg(np.arctan2(s, c))), np.nan)
        r = np.clip(np.hypot(s, c) / n, 0.0, 1.0)
        sd = np.where(n > 0, np.rad2deg(np.sqrt(np.maximum(-2.0 * np.log(r), 0.0))) + 0.0,
                      np.nan)
    return mean, sd


def circ_stats(errors_deg: np.ndarray) -> tuple[float, float]:
    """Circular mean (wrapped to (-180, 180]) and circular SD of errors, by SciPy.

    Returns NaNs for no errors; callers say why in words.
    """
    e = np.asarray(errors_deg, dtype=float)
    e = e[~np.isnan(e)]
    if e.size == 0:
        return float("nan"), float("nan")
    m = float(wrap(circmean(e, high=180.0, low=-180.0)))
    sd = float(circstd(e, high=180.0, low=-180.0)) + 0.0
    return m, sd


def _agg(tr: pd.DataFrame, keys: list[str]) -> pd.DataFrame:
    """n, n_correct, accuracy, n_rt, median_rt_s, n_error, circular error by ``keys``."""
    g = tr.groupby(keys, observed=True, sort=True)
    out = g.agg(
        n=("is_correct", "size"),
        n_correct=("is_correct", "sum"),
        n_timeout=("no_response", "sum"),
        n_rt=("rt", "count"),
        median_rt_s=("rt", "median"),
        n_error=("error_deg", "count"),
        s=("err_sin", "sum"),
        c=("err_cos", "sum"),
    )
    out["accuracy"] = out["n_correct"] / out["n"]
    mean, sd = _circ_from_sums(out["s"].to_numpy(), out["c"].to_numpy(),
                               out["n_error"].to_numpy())
    out["mean_signed_error_deg"] = mean
    out["circ_sd_error_deg"] = sd
    out["n_correct"] = out["n_correct"].astype(int)
    out["n_timeout"] = out["n_timeout"].astype(int)
    return out.drop(columns=["s", "c"]).reset_index()


def per_target(tr: pd.DataFrame) -> pd.DataFrame:
    """Per participant, condition, target count, load and target (``per_target.csv``).

    Columns exactly :data:`PER_TARGET_COLUMNS`. ``median_rt_s`` is empty (NaN) where
    every trial timed out; ``mean_signed_error_deg`` likewise where nothing was
    answered. Trials without ``n_targets``/``load`` (older stores) get the target
    count inferred from their angles and ``none``.
    """
    if "n_targets" not in tr.columns or "load" not in tr.columns:
        tr = with_cell_columns(tr)
    c = tr.loc[tr["counted"]]
    out = _agg(c, ["participant", "condition", "n_targets", "load", "target_deg",
                   "on_tactor"])
    cond_order = {k: i for i, k in enumerate(CONDITIONS)}
    out = out.sort_values(["participant", "condition", "n_targets", "load", "target_deg"],
                          key=lambda s: s.map(cond_order) if s.name == "condition" else s)
    return out[PER_TARGET_COLUMNS].reset_index(drop=True)


def condition_summary(tr: pd.DataFrame) -> pd.DataFrame:
    """Per condition and target kind, pooled over participants (SciPy circular stats).

    Columns: condition, kind, n, n_participants, n_correct, accuracy, n_timeout, n_rt,
    median_rt_s, n_error, circ_mean_error_deg, circ_sd_error_deg.
    """
    c = tr.loc[tr["counted"]]
    rows = []
    for cond in CONDITIONS:
        for kind in KINDS:
            sub = c.loc[(c["condition"] == cond) & (c["kind"] == kind)]
            m, sd = circ_stats(sub["error_deg"].to_numpy())
            n = len(sub)
            rows.append({
                "condition": cond, "kind": kind, "n": n,
                "n_participants": int(sub["participant"].nunique()),
                "n_correct": int(sub["is_correct"].sum()),
                "accuracy": float(sub["is_correct"].mean()) if n else float("nan"),
                "n_timeout": int((~sub["responded"]).sum()),
                "n_rt": int(sub["rt"].count()),
                "median_rt_s": float(sub["rt"].median()) if sub["rt"].count() else float("nan"),
                "n_error": int(sub["error_deg"].count()),
                "circ_mean_error_deg": m, "circ_sd_error_deg": sd,
            })
    return pd.DataFrame(rows)


def per_participant(tr: pd.DataFrame) -> pd.DataFrame:
    """Per participant, condition and target kind: n, accuracy, median RT.

    Every participant gets a row for every condition and kind; where they have no
    trial, ``n`` is 0 and the values are NaN (the report says so).
    """
    c = tr.loc[tr["counted"]]
    out = _agg(c, ["participant", "condition", "kind"])
    parts = sorted(tr["participant"].unique().tolist())
    full = pd.MultiIndex.from_product([parts, list(CONDITIONS), list(KINDS)],
                                      names=["participant", "condition", "kind"])
    out = out.set_index(["participant", "condition", "kind"]).reindex(full)
    out["n"] = out["n"].fillna(0).astype(int)
    return out.reset_index()[["participant", "condition", "kind", "n", "accuracy",
                              "median_rt_s", "mean_signed_error_deg"]]


def per_site(tr: pd.DataFrame, site_of: dict[str, str]) -> pd.DataFrame:
    """Per site (a participant's site, ``site_of``) and condition: participants, n,
    accuracy, median RT (multi-site studies)."""
    c = tr.loc[tr["counted"]].copy()
    c["site"] = c["participant"].map(site_of).fillna("(no site)")
    out = _agg(c, ["site", "condition"])
    parts = c.groupby(["site", "condition"], observed=True)["participant"].nunique()
    out = out.merge(parts.rename("participants").reset_index(), on=["site", "condition"])
    return out[["site", "condition", "participants", "n", "accuracy", "median_rt_s"]]


def direction_summary(tr: pd.DataFrame) -> pd.DataFrame:
    """Per condition and target, pooled over participants, for the figures.

    Columns: condition, target_deg, on_tactor, n, accuracy, median_rt_s,
    mean_signed_error_deg, circ_sd_error_deg, n_participants, accuracy_se (standard
    error of per-participant accuracies; NaN with one participant).
    """
    c = tr.loc[tr["counted"]]
    out = _agg(c, ["condition", "target_deg", "on_tactor"])
    pp = _agg(c, ["condition", "target_deg", "participant"])
    se = pp.groupby(["condition", "target_deg"])["accuracy"].agg(["sem", "size"])
    out = out.merge(se.rename(columns={"sem": "accuracy_se", "size": "n_participants"}),
                    left_on=["condition", "target_deg"], right_index=True, how="left")
    return out


def confusion_matrices(tr: pd.DataFrame, targets: np.ndarray) -> dict[str, pd.DataFrame]:
    """Target (rows) by selected response target (columns) counts, per condition.

    Responses that were not one of ``targets`` are put on the nearest target;
    timeouts go to the last column, ``no response``.
    """
    c = tr.loc[tr["counted"]]
    tg = np.unique(np.round(np.concatenate([np.asarray(targets, dtype=float),
                                            c["target_deg"].to_numpy(dtype=float)]), 6))
    resp = np.where(c["responded"].to_numpy(),
                    np.mod(c["target_deg"].to_numpy() + np.nan_to_num(c["error_deg"].to_numpy()),
                           360.0), np.nan)
    d = np.abs(wrap(np.subtract.outer(np.nan_to_num(resp), tg)))
    col = np.where(np.isnan(resp), len(tg), d.argmin(axis=1)) if len(tg) else np.zeros(0)
    row = np.searchsorted(tg, np.round(c["target_deg"].to_numpy(dtype=float), 6))
    labels = [*[float(t) for t in tg], NO_RESPONSE]
    out: dict[str, pd.DataFrame] = {}
    cond = c["condition"].to_numpy()
    for name in CONDITIONS:
        sel = cond == name
        m = np.zeros((len(tg), len(tg) + 1), dtype=int)
        np.add.at(m, (row[sel], col[sel].astype(int)), 1)
        out[name] = pd.DataFrame(m, index=pd.Index([float(t) for t in tg], name="target_deg"),
                                 columns=labels)
    return out


def training_summary(tr: pd.DataFrame) -> pd.DataFrame:
    """Training-block trials per condition: n and accuracy (same counting rules)."""
    t = tr.loc[(tr["block"] == "training") & tr["status"].isin(["done", "timeout"])]
    if t.empty:
        return pd.DataFrame(columns=["condition", "n", "accuracy"])
    g = t.groupby("condition", sort=True)["is_correct"]
    out = g.agg(n="size", accuracy="mean").reset_index()
    order = {k: i for i, k in enumerate(CONDITIONS)}
    return out.sort_values("condition", key=lambda c: c.map(order).fillna(len(order)))


def infer_n_targets(target_deg: np.ndarray) -> int:
    """The target count of angles at k*360/n: 360 / gcd(angles, 360) (in micro-degrees)."""
    micro = np.round(np.mod(np.asarray(target_deg, dtype=float), 360.0) * 1e6).astype(np.int64)
    return max(1, round(360_000_000 / math.gcd(360_000_000, *np.unique(micro).tolist())))


def with_cell_columns(trials: pd.DataFrame, n_targets: int | None = None) -> pd.DataFrame:
    """``trials`` with ``n_targets``, ``load`` and the added factors' columns
    (:mod:`tactorbelt.factors`) filled in for old stores.

    Missing (or null) ``n_targets`` become ``n_targets`` if given, else the count
    inferred from the test trials' angles; missing ``load`` becomes ``none``.
    """
    tr = trials.copy()
    if "n_targets" not in tr.columns:
        tr["n_targets"] = np.nan
    if tr["n_targets"].isna().any():
        if n_targets is None:
            n_targets = infer_n_targets(tr["target_deg"].dropna().to_numpy(dtype=float))
        tr["n_targets"] = tr["n_targets"].fillna(n_targets)
    tr["n_targets"] = tr["n_targets"].astype(int)
    if "load" not in tr.columns:
        tr["load"] = "none"
    tr["load"] = tr["load"].fillna("none").astype(str)
    for f in added_factors():  # declared beyond the built-in ones: a store from before
        if f.column not in tr.columns:  # has no column, and old rows are NULL
            tr[f.column] = f.default
        elif f.default is not None:
            tr[f.column] = tr[f.column].fillna(f.default)
    return tr
