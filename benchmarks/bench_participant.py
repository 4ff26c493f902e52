"""Benchmark of the model participant: a whole paper session in the runner on a
simulated clock (goal: under 5 s), the fast path, and the power analysis' cost.

Prints one JSON object (key -> number) as its last line.

- ``model_session_s``: one paper session (48 training + 240 test trials) of a model
  participant through run_session on the sim belt and a SimClock, with the SQLite store.
- ``model_decide_ms``: the model's own share per trial of that session (sensing the
  sim belt's vibration, perceiving it, planning the movement).
- ``fast_participants_per_s``: participants per second simulated on the fast path.
- ``power_default_estimate_s``: estimated single-process time of ``tactorbelt power``
  with its defaults (500 studies at 4, 8, 12 and 16 participants), from 10 studies
  per size; divide by --jobs.
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path


def main() -> None:
    import numpy as np

    from tactorbelt import open_belt
    from tactorbelt.clock import SimClock
    from tactorbelt.experiment.runner import run_session
    from tactorbelt.experiment.store import Store
    from tactorbelt.experiment.study import paper_study
    from tactorbelt.inputs.model import ModelCursor, make_model_cursor, sim_vibrator
    from tactorbelt.participant import ModelParams, simulate_participant, stimulus_cues
    from tactorbelt.participant.factorial import FactorialProtocol
    from tactorbelt.power.design import PowerDesign
    from tactorbelt.power.effects import Effect
    from tactorbelt.power.simulation import analysis_paired_test, simulate_factorial_studies

    study = paper_study()
    out: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as d:
        clock = SimClock()
        with Store.open(Path(d) / "s.sqlite") as store, open_belt("sim", clock=clock) as belt:
            cursor = make_model_cursor(belt, clock, seed=1)
            assert isinstance(cursor, ModelCursor)
            decide = cursor._decide
            spent = [0.0]

            def timed(now_ns: int) -> None:
                t = time.perf_counter()
                decide(now_ns)
                spent[0] += time.perf_counter() - t

            cursor._decide = timed  # type: ignore[method-assign]
            t0 = time.perf_counter()
            run_session(study, "model-01", belt, cursor, store, clock, seed=1)
            out["model_session_s"] = time.perf_counter() - t0
            out["model_decide_ms"] = 1000 * spent[0] / study.n_trials()

    protocol = PowerDesign.from_study(study).protocol()
    cues = stimulus_cues(protocol, sim_vibrator(protocol.layout))
    rng = np.random.default_rng(0)
    t0 = time.perf_counter()
    for _ in range(200):
        simulate_participant(protocol, cues, ModelParams(), rng)
    out["fast_participants_per_s"] = 200 / (time.perf_counter() - t0)

    total = 0.0
    for n in (4, 8, 12, 16):
        t0 = time.perf_counter()
        simulate_factorial_studies(FactorialProtocol((protocol,)), (cues,), Effect("condition"),
                                   n, range(10), 1, analysis_paired_test)
        total += (time.perf_counter() - t0) / 10 * 500
    out["power_default_estimate_s"] = total
    print(json.dumps({k: round(v, 4) for k, v in out.items()}))


if __name__ == "__main__":
    main()
