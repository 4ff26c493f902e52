"""Benchmark of the perceptual calibration: the whole procedure (intensity matching and
phantom location, about 230 QUEST+ trials) with the model participant answering, on the
sim belt and a simulated clock (goal: under 2 s).

Prints one JSON object (key -> number) as its last line.

- ``perceptual_calibration_s``: wall time of one calibration of the model participant.
- ``perceptual_trial_ms``: per trial (QUEST+'s update and choice dominate: ~5 ms).
"""

from __future__ import annotations

import json
import time


def main() -> None:
    from tactorbelt.calibration.perceptual import run_perceptual_calibration
    from tactorbelt.clock import SimClock
    from tactorbelt.devices.sim import SimBelt
    from tactorbelt.geometry import Layout
    from tactorbelt.inputs.model import make_model_respondent

    best = float("inf")
    n = 0
    for rep in range(3):
        clock = SimClock()
        t0 = time.perf_counter()
        with SimBelt(layout=Layout.even(6), clock=clock) as belt:
            res = run_perceptual_calibration(belt, clock, make_model_respondent(belt, rep),
                                             participant="M01", seed=rep)
        best = min(best, time.perf_counter() - t0)
        n = res.n_trials
    print(json.dumps({"perceptual_calibration_s": round(best, 3),
                      "perceptual_trial_ms": round(1000 * best / n, 3)}))


if __name__ == "__main__":
    main()
