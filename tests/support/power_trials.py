"""A study's counted test trials as the power analysis draws them, for the tests and
scripts/false_positive_rates.py: :meth:`tactorbelt.power.design.PowerDesign.trials`, or
every test block whatever its target count (the resolution study's model with
``factor(n_targets)``)."""

from __future__ import annotations

from typing import Any

import numpy as np

from tactorbelt.power.design import PowerDesign, TrialDesign


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
