"""Whole sessions with the model participant: one session, and 1,000 participants.

- ``session_s``: the paper's session (48 training + 240 test trials) with the model
  participant on the simulated clock and the sim belt, headless, stored (SQLite, WAL,
  synchronous=FULL, a transaction per trial): median of 3. Goal: under 2 s.
- ``sessions_1000_s``: 1,000 such participants, one store per worker process (2 workers,
  as many as this machine has cores), wall time.
- ``sessions_linearity``: mean time of the last 10 % of sessions over the first 10 %;
  1.0 means the cost per participant does not grow with the number already stored.

Prints one JSON object as its last line. ``--participants N`` for a shorter run.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import statistics
import tempfile
import time
from pathlib import Path


def _sessions(args: tuple[Path, list[int]]) -> list[float]:
    """Run one model session per participant number into one store; their wall times."""
    from tactorbelt import open_belt
    from tactorbelt.clock import SimClock
    from tactorbelt.experiment.runner import run_session
    from tactorbelt.experiment.store import Store
    from tactorbelt.experiment.study import paper_study
    from tactorbelt.inputs.model import make_model_cursor

    db, numbers = args
    study = paper_study()
    times = []
    with Store.open(db) as store:
        for n in numbers:
            t0 = time.perf_counter()
            clock = SimClock()
            with open_belt("sim", clock=clock, layout=study.layout_obj()) as belt:
                cursor = make_model_cursor(belt, clock, seed=n)
                res = run_session(study, f"model-{n:04d}", belt, cursor, store, clock, seed=n)
            assert res.status == "complete", res.status
            times.append(time.perf_counter() - t0)
    return times


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=1000)
    ap.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        single = _sessions((Path(tmp) / "one.sqlite", [1, 2, 3]))
        numbers = list(range(1, args.participants + 1))
        chunks = [(Path(tmp) / f"w{w}.sqlite", numbers[w::args.workers])
                  for w in range(args.workers)]
        t0 = time.perf_counter()
        with mp.get_context("spawn").Pool(args.workers) as pool:
            per_worker = pool.map(_sessions, chunks)
        total = time.perf_counter() - t0
    # per worker, in the order its store grew
    tenth = max(1, min(len(t) for t in per_worker) // 10)
    first = statistics.mean(x for t in per_worker for x in t[:tenth])
    last = statistics.mean(x for t in per_worker for x in t[-tenth:])
    key = "sessions_1000_s" if args.participants == 1000 else f"sessions_{args.participants}_s"
    print(json.dumps({
        "session_s": round(statistics.median(single), 4),
        key: round(total, 2),
        "sessions_per_s": round(args.participants / total, 3),
        "sessions_linearity": round(last / first, 3),
    }))


if __name__ == "__main__":
    main()
