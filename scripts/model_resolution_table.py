#!/usr/bin/env python3
"""Print what the model participant predicts across target resolutions (a Markdown table).

For 12, 18, 24, 36 and 48 targets on 6 evenly spaced tactors (the paper's belt and
stimulus: paper law T = 15, period 1 s, transit 0.1 s), static and dynamic, it
simulates test trials on the fast path (:mod:`tactorbelt.participant.simulate`, the
``sim`` belt's vibration): the typical observer answering every target ``--reps``
times, and ``--participants`` individual observers (drawn around it) answering every
target ``--per-participant`` times, as a study would. Columns: accuracy (all targets,
on-tactor, between-tactor), mean absolute angular error, median RT, and information
transfer (bits): of the typical observer's pooled matrix (many trials: its bias is
negligible) and the mean over the individual observers of each one's Miller-Madow
estimate (what the analysis reports per cell).

docs/participant-model.md ("Across resolutions") shows the output of

    python scripts/model_resolution_table.py

The numbers follow from the model's assumptions; they are predictions to test, not
evidence about people.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from tactorbelt.analysis.tables.transfer import information_transfer
from tactorbelt.geometry import Layout, TargetSet, wrap
from tactorbelt.inputs.model import sim_vibrator
from tactorbelt.participant import ModelParams, Protocol, draw_participant, stimulus_cues
from tactorbelt.participant.simulate import TrialTable, simulate_participant

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from support.it_estimators import miller_madow_transfer

COUNTS = (12, 18, 24, 36, 48)


def _matrix(t: TrialTable, cond: str, n: int) -> np.ndarray:
    sel = t.condition == cond
    row = np.round(t.target_deg[sel] * n / 360).astype(int) % n
    col = np.round(t.response_deg[sel] * n / 360).astype(int) % n
    m = np.zeros((n, n))
    np.add.at(m, (row, col), 1)
    return m


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--reps", type=int, default=200, help="typical observer: trials per target")
    ap.add_argument("--participants", type=int, default=12)
    ap.add_argument("--per-participant", type=int, default=3,
                    help="individual observers: trials per target")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    layout = Layout.even(6)
    base = ModelParams()
    print("| targets | spacing | condition | accuracy | on-tactor | between-tactor | "
          "mean abs error (deg) | median RT (s) | IT typical (bits) | IT per participant "
          "(bits, MM) | log2(targets) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for n in COUNTS:
        blocks = (("static", args.reps), ("dynamic", args.reps))
        proto = Protocol(layout, TargetSet.even(n), "paper", 15.0, 1.0, 0.1, blocks)
        cues = stimulus_cues(proto, sim_vibrator(layout), base)
        rng = np.random.default_rng([args.seed, n])
        typical = simulate_participant(proto, cues, base, rng)
        few = Protocol(layout, TargetSet.even(n), "paper", 15.0, 1.0, 0.1,
                       (("static", args.per_participant), ("dynamic", args.per_participant)))
        people = [simulate_participant(few, cues, draw_participant(rng, base), rng)
                  for _ in range(args.participants)]
        for cond in ("static", "dynamic"):
            sel = typical.condition == cond
            ok = typical.correct[sel]
            on = typical.on_tactor[sel]
            err = np.abs(wrap(typical.response_deg[sel] - typical.target_deg[sel]))
            on_acc = f"{ok[on].mean():.2f}" if on.any() else "none"
            it_people = np.mean([miller_madow_transfer(_matrix(p, cond, n)) for p in people])
            print(f"| {n} | {360 / n:g}° | {cond} | {ok.mean():.2f} | {on_acc} | "
                  f"{ok[~on].mean():.2f} | {err.mean():.1f} | "
                  f"{np.median(typical.rt_s[sel]):.2f} | "
                  f"{information_transfer(_matrix(typical, cond, n)):.2f} | "
                  f"{it_people:.2f} | {np.log2(n):.2f} |")


if __name__ == "__main__":
    main()
