#!/usr/bin/env python3
"""The perceptual calibration's closed loop with the model participant, end to end.

For ``--participants`` model participants: run the paper study (``tactorbelt study init``)
through the runner on the sim belt and a simulated clock, once as it is and once with
``[calibration] perceptual = true`` (the runner calibrates the same model observer
before training and renders the study for its profile), into one store, then print the
analysis' with/without table (``profile_effect.csv`` of ``tactorbelt analyze``) and the
fast-path measurement of ``scripts/calibration_effect.py`` (individual observers, the
felt bias of quarter points).

docs/calibration-perceptual.md shows the output of

    python scripts/perceptual_loop.py

The numbers follow from the model's assumptions; they are no evidence about people.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=6)
    ap.add_argument("--fast-participants", type=int, default=12)
    args = ap.parse_args()

    from calibration_effect import calibration_effect, summarise  # beside this script

    from tactorbelt.analysis.tables.profiles import profile_table
    from tactorbelt.clock import SimClock
    from tactorbelt.devices.sim import SimBelt
    from tactorbelt.experiment.runner import run_session
    from tactorbelt.experiment.store import open_store
    from tactorbelt.experiment.study import Study, template_toml
    from tactorbelt.inputs.model import make_model_cursor

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as d:
        db = Path(d) / "loop.sqlite"
        for perceptual in (False, True):
            text = template_toml("paper") + ("\n[calibration]\nperceptual = true\n"
                                             if perceptual else "")
            study = Study.from_toml(text)
            with open_store(db) as store:
                for i in range(args.participants):
                    clock = SimClock()
                    who = f"M{i + 1:02d}{'-cal' if perceptual else ''}"
                    with SimBelt(layout=study.layout_obj(), clock=clock) as belt:
                        cursor = make_model_cursor(belt, clock, seed=100 + i)
                        run_session(study, who, belt, cursor, store, clock, study_toml=text)
        table = profile_table([db])
    assert table is not None
    print(f"## Runner: the paper study, {args.participants} model participants "
          "(typical observer), with and without its profile\n")
    print("| " + " | ".join(table.columns) + " |")
    print("|" + "---|" * len(table.columns))
    for row in table.itertuples(index=False):
        print("| " + " | ".join(f"{v:.3f}" if isinstance(v, float) else str(v)
                                 for v in row) + " |")
    print(f"\n## Fast path: {args.fast_participants} individual observers, quarter-point "
          "targets and all between-tactor targets\n")
    print("| condition | profile | felt bias (deg) | answer bias (deg) | mean abs error (deg) "
          "| accuracy |\n|---|---|---|---|---|---|")
    for r in summarise(calibration_effect(args.fast_participants)):
        print(f"| {r['condition']} | {'with' if r['profile'] else 'without'} | "
              f"{r['felt_bias_deg']:+.2f} | {r['answer_bias_deg']:+.2f} | "
              f"{r['mean_abs_error_deg']:.2f} | {r['accuracy']:.3f} |")
    print(f"\n({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
