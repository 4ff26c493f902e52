"""Reliability of the session store: a run killed anywhere, a full or read-only disk, and
corrupted or truncated files.

- ``tactorbelt run`` killed with SIGKILL at 20 seeded random moments (start-up, store
  creation, mid-trial, mid-write) and resumed each time: the store opens cleanly after
  every kill, never holds a trial twice or samples without their trial, and after the
  last ``--resume`` holds every scheduled trial exactly once;
- the disk full (SQLite's own SQLITE_FULL, made real with ``PRAGMA max_page_count``, which
  works as root where chmod does not) or the store turning read-only in the middle of a
  session: a clear error, the trial in flight not half-written, the motors off, and the
  session resumable once there is room again;
- a corrupted or truncated store given to ``run``, ``analyze`` and ``export``: ``error:``
  naming the file, exit 2, no traceback.
"""

from __future__ import annotations

import os
import random
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from support.studies import study_toml
from tactorbelt import StoreError
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.devices.sim import SimBelt
from tactorbelt.experiment.listeners import NullObserver
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.schedule import make_schedule
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.store.sqlite import SQLiteStore
from tactorbelt.experiment.study import Study
from tactorbelt.experiment.trial import TrialState
from tactorbelt.inputs.scripted import ScriptedCursor

STUDY = study_toml(minimal=True, name="store-reliability", tactors=6, targets=12,
                   iti_s=0.2, break_every=0, training=1, training_conditions=["static"],
                   repetitions=8)  # 12 training + 192 test = 204 trials


def _tactorbelt(*args: str) -> list[str]:
    return [str(Path(sys.executable).with_name("tactorbelt")), *args]


def check_store(db: Path, study: Study, participant: str, complete: bool) -> int:
    """Open the store as a reader and check what must hold after any crash.

    Returns the number of trials with a final outcome.
    """
    if not _has_sessions_table(db):  # killed before the schema was committed
        assert not complete
        Store.open(db).close()  # a writer opens it cleanly
        return 0
    with Store.open(db, readonly=True) as store:
        assert store.conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        sessions = store.sessions(participant)
        assert len(sessions) <= 1
        if not sessions:
            assert not complete
            return 0
        (sess,) = sessions
        sched = store.schedule(sess["session_id"])
        assert sched == make_schedule(study, participant, 1)
        rows = store.trials(sess["session_id"])
        idx = [r["trial_index"] for r in rows]
        assert len(idx) == len(set(idx)), "a trial stored twice"
        # stored in schedule order, a prefix of the schedule (only final outcomes here,
        # since a SIGKILL leaves no time to store an aborted row)
        assert sorted(idx) == idx == list(range(len(idx)))
        for r in rows:
            assert r["status"] in ("done", "timeout")
        orphans = store.conn.execute("SELECT COUNT(*) FROM samples WHERE trial_id NOT IN "
                                     "(SELECT trial_id FROM trials)").fetchone()[0]
        assert orphans == 0
        per_trial = dict(store.conn.execute(
            "SELECT trial_id, COUNT(*) FROM samples GROUP BY trial_id").fetchall())
        for r in rows:
            assert per_trial.get(r["trial_id"], 0) == r["n_samples"] > 0
        if complete:
            assert sess["status"] == "complete"
            assert idx == [t.trial_index for t in sched]
        return len(idx)


def test_sigkill_at_20_random_moments_then_resume_holds_every_trial_once(tmp_path: Path
                                                                         ) -> None:
    study_file = tmp_path / "study.toml"
    study_file.write_text(STUDY)
    study = Study.from_toml(STUDY)
    db = tmp_path / "s.sqlite"
    base = ("run", str(study_file), "--participant", "P05", "--headless", "--input",
            "scripted", "--db", str(db))
    env = dict(os.environ, TACTORBELT_TEST_SLOW_TRIAL_S="0.04")
    rng = random.Random(20240607)
    done_after: list[int] = []
    for _ in range(20):
        has_session = db.exists() and _has_sessions_table(db) and _n_sessions(db) > 0
        args = _tactorbelt(*base, *(["--resume"] if has_session else []))
        proc = subprocess.Popen(args, env=env, stdout=subprocess.DEVNULL,
                                stderr=subprocess.PIPE)
        # time the kill from when this run has opened the store (its pid is in the lock
        # file; a killed run leaves its own behind), not from the start of the process:
        # start-up time depends on the machine's load
        lock = db.with_name(db.name + ".lock")
        give_up = time.monotonic() + 30.0
        while (proc.poll() is None and time.monotonic() < give_up
               and not _holds_lock(lock, proc.pid)):
            time.sleep(0.005)
        time.sleep(rng.uniform(0.0, 0.6))
        proc.send_signal(signal.SIGKILL)
        _, err = proc.communicate()
        assert proc.returncode in (-signal.SIGKILL, 0), err
        assert b"Traceback" not in err
        if db.exists():
            done_after.append(check_store(db, study, "P05", complete=False))
    print(f"trials stored after each kill: {done_after}")
    assert len(set(done_after)) > 5  # the kills landed at many different points
    assert done_after[-1] < study.n_trials()  # the last kill left work to resume
    out = subprocess.run(_tactorbelt(*base, "--resume"), capture_output=True, text=True,
                         check=False)
    assert out.returncode == 0, out.stderr
    assert check_store(db, study, "P05", complete=True) == study.n_trials()


def _holds_lock(lock: Path, pid: int) -> bool:
    try:
        return lock.read_text().strip() == f"pid {pid}"
    except OSError:
        return False


def _has_sessions_table(db: Path) -> bool:
    with sqlite3.connect(db) as conn:
        return conn.execute("SELECT COUNT(*) FROM sqlite_master WHERE name='sessions'"
                            ).fetchone()[0] == 1


def _n_sessions(db: Path) -> int:
    with Store.open(db, readonly=True) as store:
        return len(store.sessions())


# -- a full disk or a read-only store mid-session --------------------------------------------


class FillDiskAt(NullObserver):
    """Caps the store's size at what it holds when trial ``at`` starts: SQLITE_FULL."""

    def __init__(self, store: Store, at: int) -> None:
        self.store = store
        self.at = at

    def on_trial_state(self, trial: Any, state: TrialState, now_ns: int) -> None:
        if trial.trial_index == self.at and state is TrialState.WAIT_HOME:
            pages = self.store.conn.execute("PRAGMA page_count").fetchone()[0]
            self.store.conn.execute(f"PRAGMA max_page_count = {pages}")


def _cursor(study: Study, participant: str = "P01") -> ScriptedCursor:
    return ScriptedCursor(answers={t.trial_index: t.target_deg
                                   for t in make_schedule(study, participant)})


def _trial_rows_without_all_samples(store: Store) -> int:
    return int(store.conn.execute(
        "SELECT COUNT(*) FROM trials t WHERE n_samples != "
        "(SELECT COUNT(*) FROM samples s WHERE s.trial_id = t.trial_id)").fetchone()[0])


def test_disk_full_mid_session_stops_cleanly_and_resumes(tmp_path: Path) -> None:
    study = Study.from_toml(STUDY)
    db = tmp_path / "s.sqlite"
    clock = SimClock()
    with Store.open(db) as store, open_belt("sim", clock=clock) as belt:
        assert isinstance(belt, SimBelt)
        with pytest.raises(StoreError) as info:
            run_session(study, "P01", belt, _cursor(study), store, clock,
                        observer=FillDiskAt(store, at=20))
        msg = str(info.value)
        assert "database or disk is full" in msg and str(db) in msg
        assert not belt.levels.any()  # motors off
        rows = store.trials()
        failed = len(rows)
        assert 20 <= failed < study.n_trials()
        assert [r["trial_index"] for r in rows] == list(range(failed))
        assert _trial_rows_without_all_samples(store) == 0
        assert store.conn.execute("SELECT COUNT(*) FROM samples WHERE trial_id NOT IN "
                                  "(SELECT trial_id FROM trials)").fetchone()[0] == 0
    # room again (a new connection has no page cap): the session resumes and completes
    with Store.open(db) as store, open_belt("sim", clock=clock) as belt:
        res = run_session(study, "P01", belt, _cursor(study), store, clock, resume=True)
        assert res.status == "complete"
        assert res.results[0].trial.trial_index == failed
        rows = store.trials()
        assert sorted(r["trial_index"] for r in rows) == list(range(study.n_trials()))
        assert _trial_rows_without_all_samples(store) == 0


class _FailingConn:
    """A connection whose INSERT into ``samples`` fails: the trial row went in first, so
    the transaction must be rolled back as a whole."""

    def __init__(self, conn: sqlite3.Connection, message: str, after: int) -> None:
        self._conn = conn
        self._message = message
        self._after = after
        self.trials = 0

    def _check(self, sql: str) -> None:
        head = sql.lstrip().upper()
        if head.startswith("INSERT INTO TRIALS"):
            self.trials += 1
        elif head.startswith("INSERT INTO SAMPLES") and self.trials > self._after:
            raise sqlite3.OperationalError(self._message)

    def execute(self, sql: str, *args: Any) -> Any:
        self._check(sql)
        return self._conn.execute(sql, *args)

    def executemany(self, sql: str, rows: Any) -> Any:
        self._check(sql)
        return self._conn.executemany(sql, rows)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._conn, name)


@pytest.mark.parametrize("message", ["attempt to write a readonly database",
                                     "database or disk is full", "disk I/O error"])
def test_store_failing_mid_transaction_leaves_no_half_written_trial(tmp_path: Path,
                                                                    message: str) -> None:
    study = Study.from_toml(STUDY)
    db = tmp_path / "s.sqlite"
    clock = SimClock()
    with Store.open(db) as store, open_belt("sim", clock=clock) as belt:
        assert isinstance(belt, SimBelt)
        real = store.conn
        store.conn = _FailingConn(real, message, after=7)  # type: ignore[assignment]
        with pytest.raises(StoreError, match=f"cannot write trial 7 to .*{message}"):
            run_session(study, "P01", belt, _cursor(study), store, clock)
        assert not belt.levels.any()
        store.conn = real
        rows = store.trials()
        assert [r["trial_index"] for r in rows] == list(range(7))  # trial 7: nothing
        assert _trial_rows_without_all_samples(store) == 0
        assert store.find_resumable("P01") is not None


def test_cli_reports_a_full_disk_and_turns_the_motors_off(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from tactorbelt import devices
    from tactorbelt.cli import main

    study_file = tmp_path / "study.toml"
    study_file.write_text(STUDY)
    db = tmp_path / "s.sqlite"
    belts: list[Any] = []
    real_open = devices.open_belt

    def recording_open(url: str, **options: Any) -> Any:
        belt = real_open(url, **options)
        belts.append(belt)
        return belt

    real_write = SQLiteStore.write_trial

    def write_then_fill(self: SQLiteStore, session_id: int, result: Any) -> int:
        if result.trial.trial_index == 10:
            pages = self.conn.execute("PRAGMA page_count").fetchone()[0]
            self.conn.execute(f"PRAGMA max_page_count = {pages}")
        return real_write(self, session_id, result)

    monkeypatch.setattr(devices, "open_belt", recording_open)
    monkeypatch.setattr(SQLiteStore, "write_trial", write_then_fill)
    with pytest.raises(SystemExit) as exit_info:
        main(["run", str(study_file), "-p", "P01", "--headless", "--input", "scripted",
              "--db", str(db)])
    err = capsys.readouterr().err
    assert exit_info.value.code == 2, err
    assert "Traceback" not in err
    assert err.startswith("error: cannot write trial ") and "database or disk is full" in err
    assert str(db) in err
    (belt,) = belts
    assert belt.closed and not belt.levels.any()


# -- corrupted and truncated stores ----------------------------------------------------------


@pytest.fixture(scope="module")
def good_store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    study = Study.from_toml(STUDY)
    db = tmp_path_factory.mktemp("store") / "good.sqlite"
    clock = SimClock()
    with Store.open(db) as store, open_belt("sim", clock=clock) as belt:
        run_session(study, "P01", belt, _cursor(study), store, clock)
    with sqlite3.connect(db) as conn:  # fold the WAL in: the file alone is the store
        conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    return db


def _corrupt(good: Path, dest: Path, how: str) -> Path:
    data = bytearray(good.read_bytes())
    rng = np.random.default_rng(5)
    if how == "truncated-half":
        data = data[: len(data) // 2]
    elif how == "truncated-odd":
        data = data[: 4096 * 3 + 1234]
    elif how == "header":
        data[:100] = rng.integers(0, 256, 100, dtype=np.uint8).tobytes()
    elif how == "pages":  # garbage over every page's b-tree header but the first
        for off in range(4096, len(data), 4096):
            data[off : off + 64] = rng.integers(0, 256, 64, dtype=np.uint8).tobytes()
    elif how == "empty":
        data = bytearray()
    elif how == "text":
        data = bytearray(b"name = 'not a database'\n" * 50)
    else:  # pragma: no cover
        raise AssertionError(how)
    dest.write_bytes(bytes(data))
    return dest


CORRUPTIONS = ["truncated-half", "truncated-odd", "header", "pages", "text"]


@pytest.mark.parametrize("how", CORRUPTIONS)
@pytest.mark.parametrize("command", ["run", "analyze", "export"])
def test_corrupted_store_gives_a_clear_error(
    good_store: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], how: str,
    command: str
) -> None:
    from tactorbelt.cli import main

    bad = _corrupt(good_store, tmp_path / "bad.sqlite", how)
    before = bad.read_bytes()
    study_file = tmp_path / "study.toml"
    study_file.write_text(STUDY)
    argv = {
        "run": ["run", str(study_file), "-p", "P02", "--headless", "--input", "scripted",
                "--db", str(bad)],
        "analyze": ["analyze", str(bad), "--out", str(tmp_path / "report")],
        "export": ["export", str(bad), str(tmp_path / "export")],
    }[command]
    with pytest.raises(SystemExit) as exit_info:
        main(argv)
    err = capsys.readouterr().err
    assert exit_info.value.code == 2, err
    assert err.startswith("error: ") and "Traceback" not in err
    assert str(bad) in err
    assert any(w in err for w in ("corrupted", "truncated", "not an SQLite", "malformed",
                                  "not a tactorbelt store")), err
    assert bad.read_bytes() == before  # nothing was written to it
    assert not (tmp_path / "export").exists()


def test_an_empty_file_is_not_taken_for_a_store_by_readers(
    good_store: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from tactorbelt.cli import main

    bad = _corrupt(good_store, tmp_path / "empty.sqlite", "empty")
    for argv in (["analyze", str(bad), "--out", str(tmp_path / "r")],
                 ["export", str(bad), str(tmp_path / "e")]):
        with pytest.raises(SystemExit) as exit_info:
            main(argv)
        err = capsys.readouterr().err
        assert exit_info.value.code == 2 and err.startswith("error: ") and str(bad) in err
