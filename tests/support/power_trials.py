"""A study's counted test trials as the power analysis draws them, and the named-effect
model without an effect, for the tests and scripts/false_positive_rates.py:
:meth:`tactorbelt.power.design.PowerDesign.trials`, or every test block whatever its
target count (the resolution study's model with ``factor(n_targets)``); :func:`no_effect`;
a simulated participant's between-tactor accuracy (:func:`between_accuracy`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from tactorbelt.participant.simulate import TrialTable
from tactorbelt.power.design import PowerDesign, TrialDesign
from tactorbelt.power.glmm import NamedEffect


def trials_of(study: Any, n_targets: int | None = None, *, all_counts: bool = False
              ) -> TrialDesign:
    """One participant's counted test trials of ``study``: those of ``n_targets`` targets
    (None: its one count), or with ``all_counts`` every test block (``n_targets`` is then
    the first count; ``counts`` holds each trial's)."""
    design = PowerDesign.from_study(study)
    counts = design.counts
    if not all_counts or len(counts) == 1:
        return design.trials(n_targets)
    parts = [design.trials(c) for c in counts]
    return TrialDesign(np.concatenate([p.condition for p in parts]),
                       np.concatenate([p.target_deg for p in parts]),
                       np.concatenate([p.on_tactor for p in parts]), int(counts[0]),
                       np.concatenate([np.full(p.n, p.n_targets) for p in parts]),
                       {k: np.concatenate([p.levels[k] for p in parts])
                        for k in parts[0].levels})


def no_effect(**sizes: float) -> NamedEffect:
    """The named-effect model with no condition effect (odds ratio 1, which a user may not
    name): the null, for false-positive rates."""
    eff = NamedEffect(2.0, **sizes)
    object.__setattr__(eff, "odds_ratio", 1.0)
    return eff


def between_accuracy(table: TrialTable, condition: str) -> float:
    """Share of correct between-tactor test trials in one condition (NaN if none)."""
    sel = (table.condition == condition) & ~table.on_tactor
    return float(table.correct[sel].mean()) if sel.any() else float("nan")
