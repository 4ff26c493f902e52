"""Benchmark: the PostgreSQL store over a local Unix socket.

- ``push_trials_per_s``: ``tactorbelt sync`` (the runner's background push) of a local
  SQLite session with 150 cursor samples per trial (1.5 s at 100 Hz) into PostgreSQL,
  each trial one transaction; and ``write_trials_per_s``: the same trials written
  straight to PostgreSQL with ``write_trial``.
- ``analyze_<N>_pg_s`` / ``analyze_<N>_sqlite_s``: ``analyze()`` end to end of N
  synthetic participants (tests/support/synthetic.py, 240 trials each with their
  100 Hz samples) read from PostgreSQL and from SQLite; ``pg_over_sqlite`` is the ratio
  (target: at most 2).

The server is a throwaway one started like the tests' (tests/support/pgserver.py;
initdb and pg_ctl must be installed; fsync off, as in the tests). Prints one JSON object.

Usage: python benchmarks/bench_postgresql.py [--participants 100] [--trials 500]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "tests"))  # support.synthetic


def _server_url() -> str:
    """A fresh database on a throwaway server (tests/support/pgserver.py)."""
    sys.path.insert(0, str(HERE.parent / "tests"))
    from support import pgserver

    srv = pgserver.server()
    if srv is None:
        raise SystemExit(f"no PostgreSQL server: {pgserver.skip_reason()}")
    return str(srv.new_database())


def _local_session(path: Path, n_trials: int) -> None:
    """A local store with one session of ``n_trials`` trials, 150 samples each."""
    import hashlib

    from tactorbelt.experiment.schedule import make_schedule
    from tactorbelt.experiment.store import open_store
    from tactorbelt.experiment.study import paper_study
    from tactorbelt.experiment.trial import TrialResult

    study = paper_study()
    schedule = make_schedule(study, "P01")
    while len(schedule) < n_trials:
        schedule = schedule + [dataclasses.replace(t, trial_index=t.trial_index + len(schedule))
                               for t in schedule]
    schedule = schedule[:n_trials]
    text = study.to_toml()
    with open_store(path) as store:
        sid = store.create_session(
            participant="P01", study_name=study.name, study_toml=text,
            study_sha256=hashlib.sha256(text.encode()).hexdigest(), seed=1,
            condition_order=["static", "dynamic"], schedule=schedule, belt="sim",
            site="bench")
        for t in schedule:
            r = TrialResult(t, status="done", onset_ns=1_000_000_000)
            r.acquired_ns, r.rt_s, r.correct = 2_500_000_000, 1.5, True
            r.response_deg = r.response_target_deg = t.target_deg
            for k in range(150):
                r.sample_t_ns.append(1_000_000_000 + k * 10_000_000)
                r.sample_x.append(0.005 * k)
                r.sample_y.append(0.003 * k)
                r.sample_buttons.append(0)
            store.write_trial(sid, r)


def _copy_to_pg(src_path: Path, url: str) -> None:
    """Copy a synthetic (bare) SQLite store into PostgreSQL with bulk_insert, filling the
    columns a full store requires."""
    from support.synthetic import bulk_insert
    from tactorbelt.experiment.store import open_store

    with open_store(src_path, create=False, readonly=True, verify=False) as src, \
            open_store(url) as dst:
        scols = src.table_columns("sessions")
        sessions = [dict(zip(scols, r, strict=True)) for r in src.read_table("sessions", scols)]
        for s in sessions:
            s.update(session_number=1, schedule_json="[]", n_trials=240, site="bench",
                     resumed=0)
            s.setdefault("status", "complete")
        tcols = src.table_columns("trials")
        trials = [dict(zip(tcols, r, strict=True)) for r in src.read_table("trials", tcols)]
        for t in trials:
            t.update(block_index=0, block_name=t["block"], n_samples=0,
                     recorded_at="2026-01-01T00:00:00", attempts=1,
                     repetition=t.get("repetition") or 0,
                     trial_index=t.get("trial_index") or 0)
        bulk_insert(dst, sessions=sessions, trials=trials)
        ids = [int(t["trial_id"]) for t in trials]
        for start in range(0, len(ids), 5000):
            bulk_insert(dst, samples=src.samples_of(ids[start:start + 5000]))


def main() -> int:
    os.environ.setdefault("MPLBACKEND", "Agg")
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=100)
    ap.add_argument("--trials", type=int, default=500)
    args = ap.parse_args()

    from support.synthetic import synthesize_store
    from tactorbelt.analysis.report.analyze import analyze
    from tactorbelt.experiment.store import open_store
    from tactorbelt.experiment.sync import sync_stores

    tmp = Path(tempfile.mkdtemp(prefix="bench-pg-"))
    result: dict[str, float | int | str] = {}
    try:
        url = _server_url()
        local = tmp / "local.sqlite"
        _local_session(local, args.trials)
        t0 = time.perf_counter()
        rep = sync_stores(local, url)
        dt = time.perf_counter() - t0
        result["push_trials"] = rep.trials
        result["push_trials_per_s"] = round(rep.trials / dt, 1)
        result["push_samples_per_s"] = round(rep.samples / dt)
        with open_store(local, create=False, readonly=True) as src, \
                open_store(_server_url()) as dst:
            from tactorbelt.experiment.schedule import schedule_from_json
            from tactorbelt.experiment.trial import TrialResult

            row = src.sessions()[0]
            sched = schedule_from_json(row["schedule_json"])
            sid = dst.create_session(
                participant="W01", study_name=row["study_name"], study_toml=row["study_toml"],
                study_sha256=row["study_sha256"], seed=1, condition_order=["static"],
                schedule=sched, site="bench")
            results = []
            for t in sched:
                r = TrialResult(t, status="done", onset_ns=1)
                for k in range(150):
                    r.sample_t_ns.append(1 + k * 10_000_000)
                    r.sample_x.append(0.1)
                    r.sample_y.append(0.2)
                    r.sample_buttons.append(0)
                results.append(r)
            t0 = time.perf_counter()
            for r in results:
                dst.write_trial(sid, r)
            result["write_trials_per_s"] = round(len(results) / (time.perf_counter() - t0), 1)

        warm = tmp / "warm.sqlite"  # imports and first-call costs out of the timings
        synthesize_store(warm, 2, seed=0)
        analyze([str(warm)], tmp / "out-warm", seed=0)
        db = tmp / "synthetic.sqlite"
        synthesize_store(db, args.participants, seed=0)
        pg = _server_url()
        t0 = time.perf_counter()
        _copy_to_pg(db, pg)
        result["copy_synthetic_to_pg_s"] = round(time.perf_counter() - t0, 2)
        for name, store in (("sqlite", str(db)), ("pg", pg)):
            out = tmp / f"out-{name}"
            t0 = time.perf_counter()
            summary = analyze([store], out, seed=0)
            result[f"analyze_{args.participants}_{name}_s"] = round(time.perf_counter() - t0, 2)
            result[f"trials_{name}"] = summary.counts["trials"]
        result["pg_over_sqlite"] = round(
            float(result[f"analyze_{args.participants}_pg_s"])
            / float(result[f"analyze_{args.participants}_sqlite_s"]), 2)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
