"""Benchmark: ``tactorbelt validate onsets`` on the sim belt, 6 tactors x 20 pulses.

Runs :func:`tactorbelt.validation.run.run_onsets` (what the command runs, minus the
process start) on ``sim`` (the wall clock: the pulses take real time) with 20 pulses of
each of the 6 tactors at level 1 and the default timing (on 0.3 s, each tactor resting
0.3 s, 0.05 s between pulses of different tactors: the model senses each tactor apart),
and prints one JSON object:

- ``validate_sim_s``: its wall time, belt opened to figure written (goal: under 60 s);
- ``validate_sim_schedule_s``: the baseline, the time the pulses themselves take: the
  lead-in, 120 pulses on, the pauses between them, and the last tactor's rest;
- ``validate_sim_overhead_s``: the rest (``validate_sim_s`` minus the schedule): opening,
  the sleeps' overshoot, the figure and the files;
- ``validate_virtual_s``: the same validation on ``sim:virtual`` (nothing waits): the
  work done besides waiting, commands, model queries and measurement of 120 pulses;
- ``validate_figure_s``: drawing and writing the PNG alone;
- ``validate_latency_error_pct``: the measured latency against the model's analytic 10 %
  point, in % (a check that the fast schedule still measures right).

Run alone: ``.venv/bin/python benchmarks/bench_validate.py [--pulses 20]``.
"""

from __future__ import annotations

import argparse
import json
import math
import tempfile
import time
from pathlib import Path


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pulses", type=int, default=20)
    args = ap.parse_args()

    from tactorbelt.devices import open_belt
    from tactorbelt.devices.erm import ErmParams
    from tactorbelt.validation import OnsetSettings, open_sensor, run_onsets, validate_onsets
    from tactorbelt.validation.run import GAP_S, onset_figure

    settings = OnsetSettings(pulses=args.pulses)
    with tempfile.TemporaryDirectory(prefix="tactorbelt-bench-validate-") as tmp:
        t0 = time.perf_counter()
        result, _ = run_onsets("sim", Path(tmp) / "sim", settings=settings)
        wall = time.perf_counter() - t0
        n = args.pulses * len(settings.levels) * 6
        schedule = settings.lead_s + n * settings.on_s + (n - 1) * GAP_S + settings.off_s
        t0 = time.perf_counter()
        with open_belt("sim:virtual") as belt, open_sensor(None, belt) as sensor:
            virtual = validate_onsets(belt, sensor, settings)
        virtual_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        onset_figure(virtual, Path(tmp) / "again.png")
        figure_s = time.perf_counter() - t0
    tau = ErmParams().rise_tau_s
    analytic_ms = -tau * math.log(1 - math.sqrt(0.1)) * 1e3
    latency = [t.to_dict()["latency_ms"] for t in result.tactors]
    error = max(abs(v - analytic_ms) for v in latency) / analytic_ms * 100
    print(json.dumps({
        "validate_sim_s": round(wall, 2),
        "validate_sim_schedule_s": round(schedule, 2),
        "validate_sim_overhead_s": round(wall - schedule, 2),
        "validate_virtual_s": round(virtual_s, 3),
        "validate_figure_s": round(figure_s, 3),
        "validate_latency_error_pct": round(error, 2),
        "validate_pulses": n,
    }))


if __name__ == "__main__":
    main()
