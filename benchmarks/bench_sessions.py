"""Whole sessions with the model participant: one session, many participants, a long one.

- ``session_s``: the paper's session (48 training + 240 test trials) with the model
  participant on the simulated clock and the sim belt, headless, stored: the fast path
  (nothing real involved, so the store commits in batches; provenance.commit_mode).
  Median of 3. Goal: under 2 s.
- ``session_per_trial_s``: baseline, same run, same seeds: the same sessions with one
  commit (and fsync: WAL, synchronous=FULL) per trial, as with a person or a real belt.
  ``session_batch_speedup`` is the ratio.
- ``sessions_<N>_s``: N such participants on the fast path, one store per worker process
  (2 workers, as many as this machine has cores), wall time; ``sessions_per_s`` the
  participants per second, and ``sessions_1000_est_s`` what 1,000 take at that rate
  (``make bench`` runs 30; ``make bench-full`` runs 1,000 and reports
  ``sessions_1000_s``).
- ``session_after_s``, ``machine_drift``: the sessions of ``session_s`` again after the
  many, and the ratio: how far this machine's speed moved during the run (1.0: not at
  all; a shared machine moves by 10-30 % within minutes, so a figure within that of its
  goal is not met or missed by one run).
- ``sessions_linearity``: mean time of the last 10 % of sessions over the first 10 %
  (at least 3 a worker);
  1.0 means the cost per participant does not grow with the number already stored.
- ``session_fastest_tenth_s``, ``session_slowest_tenth_s``: the run cut into ten
  consecutive parts (each worker's sessions in order), the mean session time of the
  fastest and of the slowest part. ``sessions_tenths_spread`` is their ratio: a slow
  spell in the middle of the run, which ``machine_drift`` (the ends only) misses.
  ``sessions_1000_steady_s``: the run's wall time at its fastest part's pace (the
  code's cost when the machine's other load lets it run; not a goal figure).
- ``session_cpu_s``: CPU seconds (user + system) the workers took per session, and
  ``sessions_core_use`` those seconds over wall time times workers (1.0: both cores
  busy throughout; less: waiting, for the disk or an unbalanced split).
- ``long_session_trials``, ``long_session_rss_mb``, ``long_session_rss_growth_mb``: one
  session of ~10,000 test trials (the resolution template, 42 repetitions; ``make bench``:
  8 repetitions, 1,920), in its own process: resident memory at the end, and its growth
  from the later of 20 % of the trials and trial 1,100 (the runner keeps the samples of
  the last 1,000 trials in memory) to the end (goal: flat, under 20 MB), also per trial.

Prints one JSON object as its last line.
Usage: python benchmarks/bench_sessions.py [--participants 1000] [--long-repetitions 42]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import resource
import statistics
import tempfile
import time
from pathlib import Path


def _sessions(args: tuple[Path, list[int], bool]) -> list[float]:
    """Run one model session per participant number into one store; their wall times.
    ``per_trial``: the model is declared a person, so the store commits every trial."""
    from tactorbelt import open_belt
    from tactorbelt.clock import SimClock
    from tactorbelt.experiment.runner import run_session
    from tactorbelt.experiment.store import Store
    from tactorbelt.experiment.study import paper_study
    from tactorbelt.inputs.model import make_model_cursor

    db, numbers, per_trial = args
    study = paper_study()
    times = []
    with Store.open(db) as store:
        for n in numbers:
            t0 = time.perf_counter()
            clock = SimClock()
            with open_belt("sim", clock=clock, layout=study.layout_obj()) as belt:
                cursor = make_model_cursor(belt, clock, seed=n)
                if per_trial:
                    cursor.person = True  # type: ignore[misc]
                res = run_session(study, f"model-{n:04d}", belt, cursor, store, clock, seed=n)
            assert res.status == "complete", res.status
            times.append(time.perf_counter() - t0)
    return times


def _tenths(per_worker: list[list[float]]) -> list[float]:
    """Mean session time of each tenth of the run: each worker's sessions, in order, cut
    into ten consecutive parts (fewer when a worker ran fewer than ten sessions)."""
    parts = min(10, min(len(t) for t in per_worker))
    out = []
    for k in range(parts):
        part = [x for t in per_worker
                for x in t[k * len(t) // parts : (k + 1) * len(t) // parts]]
        out.append(statistics.mean(part))
    return out


def _children_cpu_s() -> float:
    """User plus system CPU seconds of this process's finished, joined children."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _rss_mb() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20


def _long_session(args: tuple[Path, int]) -> dict[str, float]:
    """One long factorial session; resident memory at 20 % of the trials and at the end."""
    from tactorbelt import open_belt
    from tactorbelt.clock import SimClock
    from tactorbelt.experiment.runner import RESULT_SAMPLES_KEPT, run_session
    from tactorbelt.experiment.store import Store
    from tactorbelt.experiment.study import Study, template_toml
    from tactorbelt.inputs.model import make_model_cursor

    db, reps = args
    study = Study.from_toml(template_toml("resolution")
                            .replace("repetitions = 2  ", f"repetitions = {reps}  ")
                            .replace("passes = 1  ", "passes = 0  "))
    n = study.n_trials()
    marks: dict[str, float] = {}

    # from when the runner's window of trials that keep their samples is full
    mark = max(n // 5, min(RESULT_SAMPLES_KEPT + 100, n // 2))

    def progress(done: int, total: int) -> None:
        if done == mark:
            marks["rss_mark"] = _rss_mb()

    clock = SimClock()
    t0 = time.perf_counter()
    with Store.open(db) as store, open_belt("sim", clock=clock,
                                             layout=study.layout_obj()) as belt:
        cursor = make_model_cursor(belt, clock, seed=1)
        res = run_session(study, "model-long", belt, cursor, store, clock, seed=1,
                          progress=progress)
        end = _rss_mb()
    assert res.status == "complete" and res.n_done == n
    return {"long_session_trials": float(n), "long_session_s": time.perf_counter() - t0,
            "long_session_rss_mb": end, "long_session_rss_growth_mb": end - marks["rss_mark"],
            "long_session_rss_growth_kb_per_trial": (end - marks["rss_mark"]) * 1024
            / (n - mark)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=1000)
    ap.add_argument("--workers", type=int, default=min(2, os.cpu_count() or 1))
    ap.add_argument("--long-repetitions", type=int, default=42)
    args = ap.parse_args()
    out: dict[str, float] = {}
    ctx = mp.get_context("spawn")
    with tempfile.TemporaryDirectory() as tmp:
        fast = _sessions((Path(tmp) / "fast.sqlite", [1, 2, 3], False))
        slow = _sessions((Path(tmp) / "slow.sqlite", [1, 2, 3], True))
        out["session_s"] = round(statistics.median(fast), 4)
        out["session_per_trial_s"] = round(statistics.median(slow), 4)
        out["session_batch_speedup"] = round(statistics.median(slow) / statistics.median(fast),
                                             3)
        numbers = list(range(1, args.participants + 1))
        chunks = [(Path(tmp) / f"w{w}.sqlite", numbers[w::args.workers], False)
                  for w in range(args.workers)]
        cpu0 = _children_cpu_s()
        t0 = time.perf_counter()
        with ctx.Pool(args.workers) as pool:
            per_worker = pool.map(_sessions, chunks)
        total = time.perf_counter() - t0
        cpu = _children_cpu_s() - cpu0  # the workers have been joined: theirs is counted
        # the first three sessions again: how far the machine's speed moved meanwhile
        after = _sessions((Path(tmp) / "after.sqlite", [1, 2, 3], False))
        out["session_after_s"] = round(statistics.median(after), 4)
        out["machine_drift"] = round(statistics.median(after) / statistics.median(fast), 3)
        with ctx.Pool(1) as pool:  # a fresh process: its memory is the session's
            out.update(pool.apply(_long_session,
                                  ((Path(tmp) / "long.sqlite", args.long_repetitions),)))
    # per worker, in the order its store grew
    # (at least 3 sessions a worker at each end: one session alone is noise)
    shortest = min(len(t) for t in per_worker)
    tenth = min(max(3, shortest // 10), max(1, shortest // 2))
    first = statistics.mean(x for t in per_worker for x in t[:tenth])
    last = statistics.mean(x for t in per_worker for x in t[-tenth:])
    out[f"sessions_{args.participants}_s"] = round(total, 2)
    out["sessions_per_s"] = round(args.participants / total, 3)
    out["sessions_1000_est_s"] = round(1000 * total / args.participants, 1)
    out["sessions_linearity"] = round(last / first, 3)
    tenths = _tenths(per_worker)
    mean = sum(map(sum, per_worker)) / args.participants
    out["session_fastest_tenth_s"] = round(min(tenths), 4)
    out["session_slowest_tenth_s"] = round(max(tenths), 4)
    out["sessions_tenths_spread"] = round(max(tenths) / min(tenths), 3)
    out["sessions_1000_steady_s"] = round(1000 * total / args.participants
                                          * min(tenths) / mean, 1)
    out["session_cpu_s"] = round(cpu / args.participants, 4)
    out["sessions_core_use"] = round(cpu / (total * args.workers), 3)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
