"""Results with and without a wearer profile (the perceptual calibration), across
participants: ``profile_effect.csv`` of ``tactorbelt analyze``.

A session ran *with* a profile when the store recorded one for it
(:meth:`~tactorbelt.experiment.store.Store.session_profile`, written by the runner for
studies with ``[calibration] perceptual = true``). For each (profile, condition): the
participants, their between-tactor test trials, accuracy, mean absolute error (answered
target minus target, degrees) and mean signed error away from the nearer tactor (the
bias the calibration corrects: negative = felt too near the tactor; midpoints, which
have no nearer tactor, left out). Participants are
averaged with equal weight.

Reads stores (through the Store interface) and pandas; writes nothing itself.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from ..._errors import TactorbeltError
from ...geometry import Layout, wrap

__all__ = ["COLUMNS", "profile_table"]

COLUMNS = ("profile", "condition", "n_participants", "n", "accuracy", "mean_abs_error_deg",
           "mean_error_from_near_deg")


def _layout(study_toml: str) -> Layout:
    """The session's layout; a study text that no longer parses gives the default one."""
    from ...experiment.study import Study

    try:
        return Study.from_toml(study_toml).layout_obj()
    except TactorbeltError:
        return Layout.even(6)


def _has_profiles(path: str | Path) -> bool:
    from ...experiment.store import open_store

    with open_store(path, create=False, readonly=True) as store:
        return any(store.session_profile(int(s["session_id"])) is not None
                   for s in store.sessions())


def _rows(paths: Sequence[str | Path]) -> pd.DataFrame:
    from ...experiment.store import open_store

    if not any(_has_profiles(p) for p in paths):
        return pd.DataFrame()  # no session ran with a profile: nothing to compare
    frames = []
    for path in paths:
        with open_store(path, create=False, readonly=True) as store:
            for s in store.sessions():
                sid = int(s["session_id"])
                trials = pd.DataFrame(store.trials(sid))
                if trials.empty:
                    continue
                keep = ((trials["block"] == "test") & (trials["status"] == "done")
                        & ~trials["on_tactor"].astype(bool))
                t = trials.loc[keep]
                if t.empty:
                    continue
                layout = _layout(s["study_toml"])
                tgt = t["target_deg"].to_numpy(float)
                err = np.asarray(wrap(t["response_target_deg"].to_numpy(float) - tgt), float)
                # signed away from the nearer tactor (none at a midpoint: NaN, left out)
                d = np.asarray(wrap(tgt[:, None] - layout.angles[None, :]), float)
                ad = np.sort(np.abs(d), axis=1)
                near = d[np.arange(len(tgt)), np.argmin(np.abs(d), axis=1)]
                near = np.where(ad[:, 1] - ad[:, 0] < 1e-6, np.nan, near)
                frames.append(pd.DataFrame({
                    "participant": s["participant"], "condition": t["condition"].to_numpy(),
                    "profile": store.session_profile(sid) is not None,
                    "correct": t["correct"].astype(bool).to_numpy(),
                    "abs_error": np.abs(err), "from_near": err * np.sign(near)}))
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()


def profile_table(paths: Sequence[str | Path]) -> pd.DataFrame | None:
    """The with/without table, or None when no session ran with a profile."""
    rows = _rows(paths)
    if rows.empty or not rows["profile"].any():
        return None
    per = rows.groupby(["profile", "condition", "participant"]).agg(
        n=("correct", "size"), accuracy=("correct", "mean"),
        mean_abs_error_deg=("abs_error", "mean"),
        mean_error_from_near_deg=("from_near", "mean")).reset_index()
    out = per.groupby(["profile", "condition"]).agg(
        n_participants=("participant", "nunique"), n=("n", "sum"),
        accuracy=("accuracy", "mean"), mean_abs_error_deg=("mean_abs_error_deg", "mean"),
        mean_error_from_near_deg=("mean_error_from_near_deg", "mean")).reset_index()
    out["profile"] = out["profile"].map({True: "with", False: "without"})
    return out.loc[:, list(COLUMNS)]
