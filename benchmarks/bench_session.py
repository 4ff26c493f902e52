"""A whole paper session on the simulated clock: training + 240 test trials, stored.

Runs the paper's study (48 training + 240 test trials) with a scripted cursor on a
SimClock and the sim belt, storing every trial and its samples to a temporary SQLite
file (WAL, synchronous=FULL, one transaction per trial). Repeats 3 times.

Prints one JSON object: scripted_session_s (median wall time of a session, store included),
session_cpu_s (median CPU time), session_nosync_s (the same with the store's
fsyncs off, to show what the disk costs), trials_per_s, samples_per_session.
(The goal session_s, with the model participant, is in bench_sessions.py.)
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
from tactorbelt.experiment.schedule import make_schedule
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import paper_study
from tactorbelt.inputs.scripted import ScriptedCursor


def one_session(db: Path, sync: bool = True) -> tuple[float, float, int]:
    study = paper_study()
    clock = SimClock()
    cursor = ScriptedCursor(answers={t.trial_index: t.target_deg
                                     for t in make_schedule(study, "P01")})
    t0, c0 = time.perf_counter(), time.process_time()
    with Store.open(db) as store, open_belt("sim", clock=clock,
                                             layout=study.layout_obj()) as belt:
        if not sync:
            store.conn.execute("PRAGMA synchronous = OFF")
        res = run_session(study, "P01", belt, cursor, store, clock)
        n_samples = store.conn.execute("SELECT COUNT(*) FROM samples").fetchone()[0]
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    assert res.status == "complete" and res.n_done == 288
    return wall, cpu, int(n_samples)


def main() -> None:
    walls, cpus, nosync = [], [], []
    n_samples = 0
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(3):
            w, c, n_samples = one_session(Path(tmp) / f"s{i}.sqlite")
            walls.append(w)
            cpus.append(c)
            nosync.append(one_session(Path(tmp) / f"n{i}.sqlite", sync=False)[0])
    session_s = statistics.median(walls)
    print(json.dumps({
        "scripted_session_s": round(session_s, 4),
        "session_cpu_s": round(statistics.median(cpus), 4),
        "session_nosync_s": round(statistics.median(nosync), 4),
        "trials_per_s": round(288 / session_s, 1),
        "samples_per_session": n_samples,
    }))


if __name__ == "__main__":
    main()
