"""Synthetic session stores with only the required columns, for tests and benchmarks
(the benchmarks put tests/ on sys.path and import ``support.synthetic``).

The analysis must not depend on the study runner to be tested, so this module writes
bare stores (:func:`create_bare_store`: exactly
the columns the analysis requires, docs/study.md "The store") through the store's bulk
insert. Two entry points:

- :func:`create_store`, :func:`insert_session`, :func:`insert_trials`,
  :func:`insert_samples`: hand-built datasets with known numbers (tests).
- :func:`synthesize_store`: many participants with 100 Hz cursor samples, bulk-inserted
  from NumPy arrays (benchmarks, examples).

The numbers it makes up are not a model of people; they only exercise the analysis.

I/O (writes store files through the store interface); imports NumPy,
tactorbelt.geometry and the store.
"""

from __future__ import annotations

import sqlite3
import uuid
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from tactorbelt._errors import StoreError
from tactorbelt.experiment.provenance import default_site
from tactorbelt.experiment.store import SAMPLE_COLUMNS, Store
from tactorbelt.experiment.store.schema import SQLITE, create_index, table
from tactorbelt.experiment.store.sqlite import SQLiteStore
from tactorbelt.geometry import Layout, TargetSet, normalize

__all__ = [
    "bulk_insert",
    "create_store",
    "insert_samples",
    "insert_session",
    "insert_trials",
    "paper_study_toml",
    "synthesize_store",
]

SESSION_COLUMNS = (
    "session_id", "participant", "study_name", "study_sha256", "study_toml", "seed",
    "condition_order", "belt", "firmware_version", "package_version", "started_at",
    "ended_at", "status",
)
TRIAL_COLUMNS = (
    "trial_id", "session_id", "block", "condition", "repetition", "trial_index",
    "target_deg", "on_tactor", "response_deg", "response_target_deg", "correct", "rt_s",
    "onset_ns", "status",
)


def bulk_insert(store: Store, *, sessions: Iterable[Mapping[str, Any]] = (),
                trials: Iterable[Mapping[str, Any]] = (),
                samples: Iterable[Sequence[Any]] = ()) -> list[int]:
    """Insert ready-made rows into an open store in one transaction; the new sessions' ids.

    Rows go in as given (explicit ids are kept, missing columns get the schema's
    defaults); for synthetic data, not for runs (``write_trial`` checks trials). In a
    store of several sites (PostgreSQL) a session without a ``session_uuid`` gets one and
    without a site the default one, its participant id is claimed for that site, the next
    generated ids follow the explicit ones, and samples get their ``sample_index`` after
    the trial's samples already stored (by COPY).
    """
    d = store.dialect
    multisite = d.has("multisite")
    ids: list[int] = []
    with store._transaction() as c:
        for given in sessions:
            row = dict(given)
            if multisite:
                row = {"session_uuid": str(uuid.uuid4())} | row | {
                    "site": row.get("site") or default_site()}
                store._claim(c, str(row["participant"]), str(row["site"]))
            ids.append(store._insert(c, "sessions", row, "session_id"))
        trial_rows = list(trials)
        if trial_rows:
            cols = sorted({k for r in trial_rows for k in r})
            c.executemany(d.insert("trials", cols), ([r.get(k) for k in cols] for r in trial_rows))
        if not d.has("order_columns"):
            c.executemany(d.insert("samples", SAMPLE_COLUMNS), samples)
            return ids
        for name, col in (("sessions", "session_id"), ("trials", "trial_id")):
            c.execute(f"SELECT setval(pg_get_serial_sequence('{d.table(name)}', '{col}'),"
                      f" MAX({col})) FROM {d.table(name)} HAVING MAX({col}) IS NOT NULL")
        sample_rows = [tuple(r) for r in samples]
        tids = sorted({int(r[0]) for r in sample_rows})
        nxt = {int(t): int(k) for t, k in c.execute(d.sql(
            "SELECT trial_id, MAX(sample_index) + 1 FROM samples WHERE trial_id = ANY(?)"
            " GROUP BY trial_id"), (tids,)).fetchall()}
        with c.copy(f"COPY {d.table('samples')}(trial_id, sample_index, t_s, x, y, buttons)"
                    " FROM STDIN") as copy:
            for r in sample_rows:
                k = nxt.get(int(r[0]), 0)
                copy.write_row((int(r[0]), k, *r[1:]))
                nxt[int(r[0])] = k + 1
    return ids


def paper_study_toml(name: str = "between-tactor-paper", tactors: int | Sequence[float] = 6,
                     targets: int = 24, law: str = "paper", falloff_deg: float = 15.0) -> str:
    """A small study TOML text with the sections the analysis reads."""
    if isinstance(tactors, int):
        layout = f"tactors = {tactors}"
    else:
        layout = "angles_deg = [" + ", ".join(f"{a:g}" for a in tactors) + "]"
    return (
        f'name = "{name}"\n\n[layout]\n{layout}\n\n[targets]\ncount = {targets}\n\n'
        f'[stimulus]\nlaw = "{law}"\nfalloff_deg = {falloff_deg}\n'
    )


def bare_statements(extra_columns: bool = False) -> list[str]:
    """SQLite statements of a bare store: the required columns alone, as a store written
    by another tool may have them (no meta, no constraints but the required values)."""
    out = []
    for name in ("sessions", "trials", "samples"):
        cols = [c for c in table(name).columns if c.required]
        defs = [f"{c.name} " + ("INTEGER PRIMARY KEY" if c.type == "id" else SQLITE.types[c.type]
                                + (" NOT NULL" if c.required == "value" else ""))
                for c in cols]
        out.append(f"CREATE TABLE {name}(\n    " + ",\n    ".join(defs) + "\n)")
    if extra_columns:  # columns the analysis must tolerate
        out += ["ALTER TABLE sessions ADD COLUMN input TEXT",
                "ALTER TABLE trials ADD COLUMN notes TEXT"]
    return out


def create_bare_store(path: str | Path, *, samples_index: bool = True,
                      extra_columns: bool = False, fast: bool = False) -> SQLiteStore:
    """Create a bare store (only the required columns) for synthetic data; open for writing.

    The analysis reads any store that has the required tables and columns; this one has
    no more (no meta table, no provenance), so tests can check that. Fill it with
    :func:`bulk_insert`.

    Args:
        path: the new file (must not exist).
        samples_index: create the index on ``samples(trial_id)`` now (else call
            :func:`index_samples` after loading).
        extra_columns: add columns the analysis must tolerate (``sessions.input``,
            ``trials.notes``).
        fast: no journal and no fsync (a benchmark's scratch file; not crash safe).
    """
    p = Path(path)
    if p.exists():
        raise StoreError(f"{p} exists; a synthetic store is written into a new file")
    try:
        conn = sqlite3.connect(str(p), isolation_level=None, check_same_thread=False)
        conn.row_factory = sqlite3.Row
        if fast:
            conn.execute("PRAGMA journal_mode = OFF")
            conn.execute("PRAGMA synchronous = OFF")
        conn.execute("BEGIN")
        for stmt in bare_statements(extra_columns):
            conn.execute(stmt)
        if samples_index:
            conn.execute(create_index(SQLITE, "samples_trial"))
        conn.execute("COMMIT")
    except sqlite3.Error as exc:
        raise StoreError(f"cannot create {p}: {exc}") from None
    return SQLiteStore(p, conn, None, readonly=False)


def index_samples(store: SQLiteStore) -> None:
    """Create the index on ``samples(trial_id)`` (after a bulk load without it)."""
    with store._transaction() as c:
        c.execute(create_index(SQLITE, "samples_trial"))


def create_store(path: str | Path, *, samples_index: bool = True,
                 extra_columns: bool = False) -> SQLiteStore:
    """Create an empty bare store and return it open for writing (close it when done).

    Args:
        path: the new file (must not exist).
        samples_index: create an index on ``samples(trial_id)``, as a real store has.
        extra_columns: add columns the analysis must tolerate (``input``, ``notes``).
    """
    return create_bare_store(path, samples_index=samples_index, extra_columns=extra_columns)


def insert_session(store: SQLiteStore, **fields: Any) -> int:
    """Insert one session; missing required fields get plausible defaults."""
    row: dict[str, Any] = {
        "participant": "P01",
        "study_name": "between-tactor-paper",
        "study_sha256": "0" * 64,
        "study_toml": paper_study_toml(),
        "seed": 1,
        "condition_order": "static,dynamic",
        "belt": "serial:/dev/ttyACM0",
        "firmware_version": "1.0.0",
        "package_version": "0.1.0",
        "started_at": "2026-01-01T10:00:00+00:00",
        "ended_at": "2026-01-01T10:30:00+00:00",
        "status": "complete",
    }
    row.update(fields)
    (session_id,) = bulk_insert(store, sessions=[row])
    return session_id


def insert_trials(store: SQLiteStore, rows: Iterable[Mapping[str, Any]]) -> None:
    """Insert trial rows (dicts keyed by trial column name; missing ones are NULL)."""
    bulk_insert(store, trials=rows)


def insert_samples(store: SQLiteStore, trial_id: int, t_s: Sequence[float],
                   x: Sequence[float], y: Sequence[float]) -> None:
    """Insert one trial's cursor samples (buttons 0)."""
    bulk_insert(store, samples=[(trial_id, float(t), float(a), float(b), 0)
                               for t, a, b in zip(t_s, x, y, strict=True)])


def synthesize_store(
    path: str | Path,
    participants: int,
    *,
    repetitions: int = 5,
    tactors: int = 6,
    targets: int | Sequence[int] = 24,
    seed: int = 0,
    samples: bool = True,
    sample_rate_hz: float = 100.0,
    timeout_rate: float = 0.01,
    participant_prefix: str = "P",
    belt: str = "serial:/dev/ttyACM0",
    chunk: int = 50,
    participant_sd: float = 0.0,
    slope_sd: float = 0.0,
    target_sd: float = 0.0,
) -> dict[str, int]:
    """Write a store of made-up sessions: ``participants * 2 * repetitions * targets`` test trials.

    Each participant has one complete session with a static and a dynamic test block.
    On-tactor targets are found 90 % of the time; between-tactor ones 50 % (static) or
    75 % (dynamic); misses land on a neighbouring target. RTs are log-normal around
    1.2 s (static) and 1.4 s (dynamic). A cursor path from the centre to the response is
    sampled at ``sample_rate_hz`` until the response time (about 150 samples a trial).

    ``participant_sd``, ``slope_sd`` and ``target_sd`` (log-odds; default 0, every
    participant and target alike) add what people and targets do in a real study: a
    per-participant intercept and dynamic-condition slope and a per-target intercept
    on the logit of those accuracies (drawn from the same generator, after the trials'
    other draws, so the default data are unchanged).

    ``targets`` a list of counts (``[12, 24, 36, 48]``): a resolution study, each
    participant one session per count, an hour apart (its study text names the count,
    so the analysis reads each trial's ``n_targets`` from it); the first count's data
    are those of ``targets=count``.

    Returns:
        Counts written: ``sessions``, ``trials``, ``samples``.
    """

    count_list = [int(targets)] if isinstance(targets, int) else [int(c) for c in targets]
    rng = np.random.default_rng(seed)
    varied = participant_sd > 0 or slope_sd > 0 or target_sd > 0
    rng_re = np.random.default_rng([seed, 1])
    u_p = rng_re.normal(0.0, participant_sd, participants)
    v_p = rng_re.normal(0.0, slope_sd, participants)
    w_ts = [rng_re.normal(0.0, target_sd, c) for c in count_list]
    layout = Layout.even(tactors)
    store = create_bare_store(path, samples_index=False, fast=True)
    counts = {"sessions": 0, "trials": 0, "samples": 0}
    trial_id = 0
    for ci, targets in enumerate(count_list):
        w_t = w_ts[ci]
        first_session = ci * participants
        hour = f"{10 + ci:02d}"
        tset = TargetSet.even(targets)
        tgt = tset.angles
        on = tset.on_tactor(layout)
        step = 360.0 / targets
        toml = paper_study_toml(tactors=tactors, targets=targets)
        n_per = 2 * repetitions * targets
        trial_id = _synthesize_block(
            store, counts, rng, trial_id, participants=participants, chunk=chunk,
            first_session=first_session, hour=hour, toml=toml, seed=seed, belt=belt,
            participant_prefix=participant_prefix, repetitions=repetitions,
            targets=targets, tgt=tgt, on=on, step=step, n_per=n_per, varied=varied,
            u_p=u_p, v_p=v_p, w_t=w_t, timeout_rate=timeout_rate, samples=samples,
            sample_rate_hz=sample_rate_hz)
    if samples:
        index_samples(store)
    store.close()
    return counts



def _synthesize_block(store: SQLiteStore, counts: dict[str, int], rng: np.random.Generator,
                      trial_id: int, *, participants: int, chunk: int, first_session: int,
                      hour: str, toml: str, seed: int, belt: str, participant_prefix: str,
                      repetitions: int, targets: int, tgt: np.ndarray, on: np.ndarray,
                      step: float, n_per: int, varied: bool, u_p: np.ndarray,
                      v_p: np.ndarray, w_t: np.ndarray, timeout_rate: float, samples: bool,
                      sample_rate_hz: float) -> int:
    """Write every participant's session of one target count; returns the last trial id."""
    for start in range(0, participants, chunk):
        stop = min(participants, start + chunk)
        sess_rows = []
        for p in range(start, stop):
            order = "static,dynamic" if p % 2 == 0 else "dynamic,static"
            sess_rows.append((first_session + p + 1, f"{participant_prefix}{p + 1:04d}",
                              "synthetic", "0" * 64, toml, seed, order, belt, "1.0.0", "0.1.0",
                              f"2026-01-01T{hour}:00:00+00:00",
                              f"2026-01-01T{hour}:30:00+00:00", "complete"))
        bulk_insert(store, sessions=(dict(zip(SESSION_COLUMNS, r, strict=True))
                                     for r in sess_rows))
        k = stop - start
        n = k * n_per
        sess = np.repeat(first_session + np.arange(start, stop) + 1, n_per)
        cond_dyn = np.tile(np.repeat([False, True], repetitions * targets), k)
        tidx = np.tile(np.arange(targets), 2 * repetitions * k)
        target = tgt[tidx]
        on_t = on[tidx]
        rep = np.tile(np.repeat(np.arange(repetitions), targets), 2 * k)
        p_ok = np.where(on_t, 0.9, np.where(cond_dyn, 0.75, 0.5))
        if varied:
            pidx = np.repeat(np.arange(start, stop), n_per)
            eta = (np.log(p_ok / (1 - p_ok)) + u_p[pidx] + v_p[pidx] * cond_dyn
                   + w_t[tidx])
            p_ok = 1.0 / (1.0 + np.exp(-eta))
        ok = rng.random(n) < p_ok
        off = rng.choice([-1.0, 1.0], n) * np.where(rng.random(n) < 0.85, 1.0, 2.0)
        resp_t = np.asarray(normalize(target + np.where(ok, 0.0, off * step)))
        resp = np.asarray(normalize(resp_t + rng.uniform(-step / 3, step / 3, n)))
        rt = np.exp(rng.normal(np.log(np.where(cond_dyn, 1.4, 1.2)), 0.2))
        timeout = rng.random(n) < timeout_rate
        status = np.where(timeout, "timeout", "done")
        ids = np.arange(trial_id + 1, trial_id + n + 1)
        trial_id += n
        cond = np.where(cond_dyn, "dynamic", "static")
        rows = zip(
            ids.tolist(), sess.tolist(), ["test"] * n, cond.tolist(), rep.tolist(),
            (np.arange(n) % n_per).tolist(), target.tolist(), on_t.astype(int).tolist(),
            [None if t else v for t, v in zip(timeout.tolist(), resp.tolist(), strict=True)],
            [None if t else v for t, v in zip(timeout.tolist(), resp_t.tolist(), strict=True)],
            (ok & ~timeout).astype(int).tolist(),
            [None if t else v for t, v in zip(timeout.tolist(), rt.tolist(), strict=True)],
            (np.arange(n, dtype=np.int64) * 3_000_000_000).tolist(), status.tolist(),
            strict=True,
        )
        bulk_insert(store, trials=(dict(zip(TRIAL_COLUMNS, r, strict=True)) for r in rows))
        counts["sessions"] += k
        counts["trials"] += n
        if samples:
            dur = np.where(timeout, 10.0, rt)
            ns = np.ceil(dur * sample_rate_hz).astype(np.int64) + 1
            tid = np.repeat(ids, ns)
            first = np.repeat(np.cumsum(ns) - ns, ns)
            i = np.arange(int(ns.sum())) - first
            t = i / sample_rate_hz
            frac = np.clip(t / np.repeat(dur, ns), 0.0, 1.0)
            r = frac * frac * (3 - 2 * frac)  # smooth start and stop
            a = np.deg2rad(np.repeat(resp, ns)) + 0.05 * np.sin(6 * frac)
            x = r * np.sin(a)
            y = r * np.cos(a)
            bulk_insert(store, samples=zip(tid.tolist(), t.tolist(), x.tolist(), y.tolist(),
                                           [0] * len(tid), strict=True))
            counts["samples"] += int(ns.sum())
    return trial_id
