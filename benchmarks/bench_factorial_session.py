"""A factorial session on the simulated clock: 4 target counts x 2 conditions x 3
repetitions (720 test trials, no training) with the model participant, stored.

The resolution template (12, 24, 36, 48 targets x static, dynamic) with
``repetitions = 3`` and ``training.passes = 0``, run by one model participant through
run_session on the sim belt and a SimClock into a temporary SQLite store (WAL,
synchronous=FULL, one transaction per trial). Baseline, in the same run: the paper's
session (48 training + 240 test trials) of the same model participant, per trial.

Prints one JSON object: factorial_session_s (median of 3), factorial_session_trials,
factorial_trial_ms, paper_model_trial_ms (the baseline per trial) and
factorial_vs_paper_per_trial (1.0: a factorial trial costs what a paper trial does).
"""

from __future__ import annotations

import json
import statistics
import tempfile
import time
from pathlib import Path

from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import Study, paper_study, template_toml
from tactorbelt.inputs.model import make_model_cursor


def factorial_study() -> Study:
    text = (template_toml("resolution")
            .replace("repetitions = 2  ", "repetitions = 3  ")
            .replace("passes = 1  ", "passes = 0  "))
    study = Study.from_toml(text)
    assert study.n_trials() == 720 and len(study.test) == 8
    return study


def one_session(study: Study, db: Path) -> float:
    clock = SimClock()
    t0 = time.perf_counter()
    with Store.open(db) as store, open_belt("sim", clock=clock,
                                             layout=study.layout_obj()) as belt:
        cursor = make_model_cursor(belt, clock, seed=1)
        res = run_session(study, "model-01", belt, cursor, store, clock, seed=1)
    wall = time.perf_counter() - t0
    assert res.status == "complete" and res.n_done == study.n_trials()
    return wall


def main() -> None:
    fac, paper = factorial_study(), paper_study()
    walls, base = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(3):
            walls.append(one_session(fac, Path(tmp) / f"f{i}.sqlite"))
            base.append(one_session(paper, Path(tmp) / f"p{i}.sqlite"))
    session_s = statistics.median(walls)
    trial_ms = 1000 * session_s / fac.n_trials()
    paper_ms = 1000 * statistics.median(base) / paper.n_trials()
    print(json.dumps({
        "factorial_session_s": round(session_s, 4),
        "factorial_session_trials": fac.n_trials(),
        "factorial_trial_ms": round(trial_ms, 4),
        "paper_model_trial_ms": round(paper_ms, 4),
        "factorial_vs_paper_per_trial": round(trial_ms / paper_ms, 4),
    }))


if __name__ == "__main__":
    main()
