"""The SQLite store: schema, durability settings, one row per trial, and clear errors."""

from __future__ import annotations

import hashlib
import os
import sqlite3
from pathlib import Path

import pytest

from support.studies import study_toml
from tactorbelt import StoreError
from tactorbelt.experiment.schedule import make_schedule
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import paper_study
from tactorbelt.experiment.trial import TrialResult

DESIGN_COLUMNS = {
    "sessions": {"session_id", "participant", "study_name", "study_sha256", "study_toml",
                 "seed", "condition_order", "belt", "firmware_version", "package_version",
                 "started_at", "ended_at", "status"},
    "trials": {"trial_id", "session_id", "block", "condition", "repetition", "trial_index",
               "target_deg", "on_tactor", "response_deg", "response_target_deg", "correct",
               "rt_s", "onset_ns", "status"},
    "samples": {"trial_id", "t_s", "x", "y", "buttons"},
}


def _session(store: Store, participant: str = "P01") -> int:
    study = paper_study()
    text = study.to_toml()
    return store.create_session(
        participant=participant, study_name=study.name, study_toml=text,
        study_sha256=hashlib.sha256(text.encode()).hexdigest(), seed=1,
        condition_order=["static", "dynamic"], schedule=make_schedule(study, participant),
        belt="sim", package_version="0.1.0")


def _result(index: int = 0, status: str = "done", n: int = 3) -> TrialResult:
    t = make_schedule(paper_study(), "P01")[index]
    r = TrialResult(t, status=status, onset_ns=1_000_000_000)
    if status == "done":
        r.acquired_ns = 1_500_000_000
        r.rt_s = 0.5
        r.response_deg = t.target_deg
        r.response_target_deg = t.target_deg
        r.correct = True
    for k in range(n):
        r.sample_t_ns.append(1_000_000_000 + k * 10_000_000)
        r.sample_x.append(0.1 * k)
        r.sample_y.append(0.2 * k)
        r.sample_buttons.append(0)
    return r


def test_schema_has_designs_columns_and_indexes(tmp_path: Path) -> None:
    with Store.open(tmp_path / "s.sqlite") as store:
        for table, cols in DESIGN_COLUMNS.items():
            have = {r[1] for r in store.conn.execute(f"PRAGMA table_info({table})")}
            assert cols <= have, (table, cols - have)
        idx = {r[0]: r[1] for r in store.conn.execute(
            "SELECT name, sql FROM sqlite_master WHERE type='index' AND sql IS NOT NULL")}
        assert any("trials(session_id)" in s for s in idx.values())
        assert any("samples(trial_id)" in s for s in idx.values())
        assert store.conn.execute("PRAGMA synchronous").fetchone()[0] == 2  # FULL
        assert store.conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"  # while open
    # a clean close leaves the file in rollback mode, alone in its folder
    conn = sqlite3.connect(tmp_path / "s.sqlite")
    assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "delete"
    conn.close()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.sqlite"]


def test_session_provenance_and_trials_round_trip(tmp_path: Path) -> None:
    with Store.open(tmp_path / "s.sqlite") as store:
        sid = _session(store)
        tid = store.write_trial(sid, _result(0))
        store.set_status(sid, "complete")
    with Store.open(tmp_path / "s.sqlite", create=False) as store:
        s = store.session(sid)
        assert s["status"] == "complete" and s["ended_at"] is not None
        assert s["session_number"] == 1
        assert store.schedule(sid) == make_schedule(paper_study(), "P01")
        (row,) = store.trials(sid)
        assert row["trial_id"] == tid and row["status"] == "done" and row["correct"] == 1
        assert row["block"] == "training" and row["onset_ns"] == 1_000_000_000
        assert store.samples(tid) == [(0.0, 0.0, 0.0, 0), (0.01, 0.1, 0.2, 0),
                                      (0.02, 0.2, 0.4, 0)]
        assert store.finished_indices(sid) == {0}
        # a second session of the same participant is session number 2
        assert store.session(_session(store))["session_number"] == 2


@pytest.mark.parametrize("n", [1, 99, 100, 101, 250])
@pytest.mark.parametrize("pressed", [None, 0, -1])
def test_samples_round_trip_in_order_across_statements(tmp_path: Path, n: int,
                                                        pressed: int | None) -> None:
    """Every sample comes back in order with its values and types, whether a trial has
    fewer rows than one INSERT takes or spans several, with or without a button held
    (``pressed``: the sample holding buttons 5, none when None)."""
    r = _result(3, n=n)
    if pressed is not None:
        r.sample_buttons[pressed] = 5
    with Store.open(tmp_path / "s.sqlite") as store:
        sid = _session(store)
        tid = store.write_trial(sid, r)
        other = store.write_trial(sid, _result(4, n=2))  # a trial after it: its own rows
        got = store.samples(tid)
        assert got == list(zip(r.sample_times_s(), r.sample_x, r.sample_y, r.sample_buttons,
                               strict=True))
        assert [type(v) for row in got for v in row] == [float, float, float, int] * n
        assert len(store.samples(other)) == 2


def test_samples_of_any_count_take_a_few_statement_shapes(tmp_path: Path) -> None:
    """Trials of 1 to 260 samples are written with 8 INSERT texts at most (100 rows, then
    64, 32, ..., 1): SQLite prepares every statement again after each batched session
    (PRAGMA foreign_keys), so one text per sample count would be parsed ~100 times a
    session. Every sample still comes back in order."""
    texts: set[str] = set()
    with Store.open(tmp_path / "s.sqlite") as store:
        sid = _session(store)
        store.conn.set_trace_callback(
            lambda sql: texts.add(sql) if sql.startswith("INSERT INTO samples") else None)
        written = {}
        for i, n in enumerate([*range(1, 200, 7), 255, 256, 260]):
            r = _result(i, n=n)
            written[store.write_trial(sid, r)] = r
        store.conn.set_trace_callback(None)
        for tid, r in written.items():
            assert store.samples(tid) == r.sample_rows()
    # the trace shows each statement with its values: count the shapes (rows per INSERT)
    assert len({t.count("),(") for t in texts}) <= 8


def test_a_final_trial_is_never_written_twice(tmp_path: Path) -> None:
    with Store.open(tmp_path / "s.sqlite") as store:
        sid = _session(store)
        store.write_trial(sid, _result(5, "timeout"))
        with pytest.raises(StoreError, match="already recorded"):
            store.write_trial(sid, _result(5, "done"))
        assert len(store.trials(sid)) == 1


def test_an_aborted_trial_is_replaced_with_its_samples(tmp_path: Path) -> None:
    with Store.open(tmp_path / "s.sqlite") as store:
        sid = _session(store)
        old = store.write_trial(sid, _result(7, "aborted", n=5))
        new = store.write_trial(sid, _result(7, "done", n=2))
        (row,) = store.trials(sid)
        assert row["trial_id"] == new != old
        assert row["attempts"] == 2 and row["status"] == "done"
        assert store.samples(old) == []
        assert len(store.samples(new)) == 2
        assert store.conn.execute("SELECT COUNT(*) FROM samples").fetchone()[0] == 2


def test_find_resumable(tmp_path: Path) -> None:
    with Store.open(tmp_path / "s.sqlite") as store:
        assert store.find_resumable("P01") is None
        sid = _session(store)
        assert store.find_resumable("P01")["session_id"] == sid  # type: ignore[index]
        store.set_status(sid, "complete")
        assert store.find_resumable("P01") is None
        sid2 = _session(store)
        store.set_status(sid2, "interrupted")
        assert store.find_resumable("P01")["session_id"] == sid2  # type: ignore[index]
        assert store.find_resumable("P02") is None


# -- bad stores: a clear error before anything is written -------------------------------

def _snapshot(p: Path) -> tuple[bytes, list[str]]:
    return p.read_bytes(), sorted(os.listdir(p.parent))


def test_not_sqlite(tmp_path: Path) -> None:
    p = tmp_path / "notes.sqlite"
    p.write_text("participant,answer\nP01,3\n")
    before = _snapshot(p)
    with pytest.raises(StoreError, match="not an SQLite database"):
        Store.open(p)
    assert _snapshot(p) == before


def test_read_only(tmp_path: Path) -> None:
    p = tmp_path / "ro.sqlite"
    with Store.open(p) as store:
        _session(store)
    p.chmod(0o444)
    try:
        before = _snapshot(p)
        with pytest.raises(StoreError, match="read-only"):
            Store.open(p)
        assert _snapshot(p) == before
    finally:
        p.chmod(0o644)


def test_locked_by_another_run(tmp_path: Path) -> None:
    p = tmp_path / "busy.sqlite"
    with Store.open(p) as first:
        _session(first)
        before = p.read_bytes()
        with pytest.raises(StoreError, match="another run is using the store"):
            Store.open(p)
        assert p.read_bytes() == before
    # released on close
    Store.open(p).close()


def test_truncated(tmp_path: Path) -> None:
    p = tmp_path / "t.sqlite"
    with Store.open(p) as store:
        sid = _session(store)
        for i in range(40):
            store.write_trial(sid, _result(i, n=50))
        store.conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    data = p.read_bytes()
    p.write_bytes(data[: len(data) // 2])
    with pytest.raises(StoreError, match="corrupted or truncated"):
        Store.open(p)


def test_corrupted_pages(tmp_path: Path) -> None:
    p = tmp_path / "c.sqlite"
    with Store.open(p) as store:
        sid = _session(store)
        for i in range(40):
            store.write_trial(sid, _result(i, n=50))
        store.conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    data = bytearray(p.read_bytes())
    page = 4096
    for off in range(2 * page, len(data), page):  # garble every page header after the first
        data[off:off + 8] = b"\xff" * 8
    p.write_bytes(bytes(data))
    with pytest.raises(StoreError, match="corrupted or truncated"):
        Store.open(p)


def test_sqlite_but_not_a_store(tmp_path: Path) -> None:
    p = tmp_path / "other.sqlite"
    conn = sqlite3.connect(p)
    conn.execute("CREATE TABLE people(name TEXT)")
    conn.commit()
    conn.close()
    with pytest.raises(StoreError, match="not a tactorbelt store"):
        Store.open(p)


def test_directory_and_missing(tmp_path: Path) -> None:
    with pytest.raises(StoreError, match="is a directory"):
        Store.open(tmp_path)
    with pytest.raises(StoreError, match="no such store"):
        Store.open(tmp_path / "absent.sqlite", create=False)
    with pytest.raises(StoreError, match="does not exist"):
        Store.open(tmp_path / "nodir" / "s.sqlite")


def test_read_only_open_does_not_lock(tmp_path: Path) -> None:
    p = tmp_path / "s.sqlite"
    with Store.open(p) as writer:
        sid = _session(writer)
        writer.write_trial(sid, _result(0))
        with Store.open(p, readonly=True) as reader:
            assert len(reader.trials()) == 1
            with pytest.raises(StoreError, match="read-only"):
                reader.write_trial(sid, _result(1))


def test_a_reader_that_outlives_the_writer(tmp_path: Path) -> None:
    # export/analysis reading while a run ends must leave the store readable
    p = tmp_path / "s.sqlite"
    writer = Store.open(p)
    sid = _session(writer)
    writer.write_trial(sid, _result(0))
    reader = Store.open(p, readonly=True)
    assert len(reader.trials()) == 1
    writer.write_trial(sid, _result(1))
    writer.close()
    assert len(reader.trials()) == 2
    reader.close()
    with Store.open(p, readonly=True) as again:
        assert len(again.trials()) == 2
    with Store.open(p) as w2:
        assert w2.finished_indices(sid) == {0, 1}


SMALL_STUDY = study_toml(minimal=True, name="store-files", tactors=6, targets=12,
                         break_every=0, training=0, conditions=["static"], repetitions=1)


def test_run_and_resume_leave_only_the_store_file(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    from tactorbelt.cli import main

    study = tmp_path / "study.toml"
    study.write_text(SMALL_STUDY)
    db = tmp_path / "runs" / "s.sqlite"
    db.parent.mkdir()
    base = ["run", str(study), "--participant", "P01", "--headless", "--input", "scripted",
            "--db", str(db)]
    for argv in ([*base, "--limit", "5"], [*base, "--resume"]):
        code = 0
        try:
            main(argv)
        except SystemExit as exc:
            code = exc.code or 0
        assert code == 0, capsys.readouterr().err
        assert sorted(p.name for p in db.parent.iterdir()) == ["s.sqlite"]
    with Store.open(db, readonly=True) as store:
        assert len(store.trials()) == 12
    assert sorted(p.name for p in db.parent.iterdir()) == ["s.sqlite"]


def test_a_failed_write_in_a_batch_undoes_itself_alone(tmp_path: Path) -> None:
    """Inside a batch each write is a savepoint (kept in memory): a trial that fails half
    written leaves no row and no samples, and the batch's other trials are stored."""
    with Store.open(tmp_path / "s.sqlite") as store:
        sid = _session(store)
        store.begin_batch(sid, 64)
        store.write_trial(sid, _result(0, n=150))
        bad = _result(1, n=150)
        bad.sample_y.pop()  # fails after the trial row is inserted
        with pytest.raises(StoreError, match="unequal length"):
            store.write_trial(sid, bad)
        store.write_trial(sid, _result(2, n=150))
        store.end_batch()
        assert [r["trial_index"] for r in store.trials(sid)] == [0, 2]
        assert store.conn.execute("SELECT count(*) FROM samples").fetchone()[0] == 300
        bad.sample_y.append(0.3)  # mended, it can be written now
        store.write_trial(sid, bad)
        assert [r["trial_index"] for r in store.trials(sid)] == [0, 2, 1]
