"""The store contract: what every store implementation must do (run over BACKENDS).

Schema on first use, refusing a newer schema, one transaction per trial, resume of
exactly the missing trials, provenance round trip, read-only opening, bulk reads equal
to what was written, and (file stores) nothing left on disk but the store after close.
"""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import pytest

from support.stores import (
    SCHEDULE,
    URLS,
    make_result,
    make_schema_2,
    make_session,
    set_schema_version,
    store_params,
)
from tactorbelt import StoreError
from tactorbelt.experiment.store import (
    RATING_COLUMNS,
    SAMPLE_COLUMNS,
    TASK_EVENT_COLUMNS,
    Store,
    open_store,
)
from tactorbelt.tasks import TLX_ITEMS
from tactorbelt.tasks.schedule import TaskEvent

REQUIRED = {
    "sessions": {"session_id", "participant", "study_name", "study_sha256", "study_toml",
                 "seed", "condition_order", "belt", "firmware_version", "package_version",
                 "started_at", "ended_at", "status"},
    "trials": {"trial_id", "session_id", "block", "condition", "repetition", "trial_index",
               "target_deg", "on_tactor", "response_deg", "response_target_deg", "correct",
               "rt_s", "onset_ns", "status"},
    "samples": set(SAMPLE_COLUMNS),
}


@pytest.fixture(params=store_params())
def backend(request: pytest.FixtureRequest, tmp_path: Path) -> tuple[str, str]:
    scheme = request.param
    url = URLS[scheme][0](tmp_path)
    if url is None:
        pytest.skip(f"no {scheme} server to test against")
    return scheme, url


def test_schema_is_created_on_first_use(backend: tuple[str, str]) -> None:
    _, url = backend
    with open_store(url) as store:
        assert store.sessions() == []
        for table, cols in REQUIRED.items():
            assert cols <= set(store.table_columns(table)), table
    with open_store(url, create=False, readonly=True) as reader:
        assert reader.sessions() == [] and reader.trials() == []


def test_a_store_of_a_newer_schema_is_refused(backend: tuple[str, str]) -> None:
    scheme, url = backend
    open_store(url).close()
    set_schema_version(scheme, url, 99)
    with pytest.raises(StoreError, match="newer tactorbelt"):
        open_store(url)


def test_a_failure_mid_trial_leaves_no_partial_trial(backend: tuple[str, str]) -> None:
    _, url = backend
    with open_store(url) as store:
        sid = make_session(store)
        store.write_trial(sid, make_result(0))
        broken = make_result(1, n=5)
        del broken.sample_x[3:]  # the samples fail part-way through the write
        with pytest.raises((StoreError, ValueError)):
            store.write_trial(sid, broken)
        assert [t["trial_index"] for t in store.trials(sid)] == [0]
        trial_ids = [t["trial_id"] for t in store.trials()]
        assert len(store.samples_of([*trial_ids, trial_ids[0] + 1])) == 3
        store.write_trial(sid, make_result(1, n=5))  # and the trial can be written after
        assert store.finished_indices(sid) == {0, 1}


def test_resume_returns_exactly_the_missing_trials(backend: tuple[str, str]) -> None:
    _, url = backend
    with open_store(url) as store:
        sid = make_session(store)
        for i in (0, 1, 3):
            store.write_trial(sid, make_result(i))
        store.write_trial(sid, make_result(2, status="aborted"))
        store.write_trial(sid, make_result(4, status="timeout", n=0))
        store.set_status(sid, "interrupted")
    with open_store(url) as store:
        resumable = store.find_resumable("P01")
        assert resumable is not None and resumable["session_id"] == sid
        done = store.finished_indices(sid)
        assert done == {0, 1, 3, 4}
        assert [t.trial_index for t in store.schedule(sid) if t.trial_index not in done][:3] \
            == [2, 5, 6]
        store.mark_resumed(sid)
        again = store.write_trial(sid, make_result(2))  # replaces the aborted row
        rows = {t["trial_index"]: t for t in store.trials(sid)}
        assert rows[2]["trial_id"] == again and rows[2]["attempts"] == 2
        assert rows[2]["status"] == "done"
        with pytest.raises(StoreError, match="already recorded"):
            store.write_trial(sid, make_result(0))
        store.set_status(sid, "complete")
        assert store.find_resumable("P01") is None
        assert store.session(sid)["resumed"] == 1


def test_provenance_round_trips(backend: tuple[str, str]) -> None:
    _, url = backend
    calibration = {"gains": [1.0, 0.9, 1.1, 1.0, 0.95, 1.05]}
    with open_store(url) as store:
        sid = make_session(store, firmware_version="1.2.3", calibration=calibration,
                           git_commit="abc123", host="lab-pc", input="joystick",
                           clock="wall", seed=2**63 - 1)
    with open_store(url, create=False, readonly=True) as reader:
        s = reader.session(sid)
        assert (s["participant"], s["session_number"], s["seed"]) == ("P01", 1, 2**63 - 1)
        assert (s["belt"], s["firmware_version"], s["package_version"]) == \
            ("sim", "1.2.3", "0.1.0")
        assert (s["git_commit"], s["host"], s["input"], s["clock"]) == \
            ("abc123", "lab-pc", "joystick", "wall")
        assert json.loads(s["calibration_json"]) == calibration
        assert json.loads(s["condition_order"]) == ["static", "dynamic"]
        assert s["status"] == "running" and s["started_at"] and s["ended_at"] is None
        assert s["n_trials"] == len(SCHEDULE)
        assert reader.schedule(sid) == SCHEDULE
        assert [x["session_id"] for x in reader.sessions("P01")] == [sid]


def test_a_read_only_store_cannot_be_written(backend: tuple[str, str]) -> None:
    _, url = backend
    with open_store(url) as store:
        sid = make_session(store)
        store.write_trial(sid, make_result(0))
    with open_store(url, create=False, readonly=True) as reader:
        assert reader.readonly
        with pytest.raises(StoreError):
            reader.write_trial(sid, make_result(1))
        with pytest.raises(StoreError):
            make_session(reader, "P02")
        with pytest.raises(StoreError):
            reader.set_status(sid, "complete")
        assert len(reader.trials()) == 1
    with pytest.raises(StoreError, match="no such store"):
        open_store(url + "-absent", create=False, readonly=True)


def test_bulk_reads_equal_what_was_written(backend: tuple[str, str]) -> None:
    _, url = backend
    with open_store(url) as store:
        a = make_session(store, "P01")
        b = make_session(store, "P02")
        for i in range(4):
            store.write_trial(a, make_result(i, n=i + 1))
            store.write_trial(b, make_result(i, n=2))
        store.write_trial(a, make_result(4, status="aborted", n=2))
    with open_store(url, create=False, readonly=True) as reader:
        trials = reader.trials()
        assert len(trials) == 9
        cols = ["trial_id", "session_id", "trial_index", "status", "rt_s", "target_deg"]
        rows = reader.read_table("trials", cols)
        expected = sorted((tuple(t[c] for c in cols) for t in trials), key=lambda r: (r[1], r[0]))
        assert rows == expected
        sess = reader.read_table("sessions", ["session_id", "participant", "seed"])
        assert sess == [(a, "P01", 1), (b, "P02", 1)]
        ids = [t["trial_id"] for t in trials]
        per_trial = {tid: reader.samples(tid) for tid in ids}
        assert reader.samples_of(ids) == [(tid, *s) for tid in sorted(ids)
                                          for s in per_trial[tid]]
        by_id = {t["trial_id"]: t for t in trials}
        streamed = list(reader.iter_samples())
        assert streamed == [(by_id[tid]["session_id"], by_id[tid]["trial_index"], *s)
                            for tid in sorted(ids, key=lambda t: (by_id[t]["session_id"], t))
                            for s in per_trial[tid]]
        assert list(reader.iter_samples(b)) == [r for r in streamed if r[0] == b]
        first = make_result(0, n=1)
        assert per_trial[ids[0]] == [(0.0, first.sample_x[0], 0.0, 0)]


def test_bulk_insert_round_trips(backend: tuple[str, str]) -> None:
    """The synthetic stores' bulk insert (tests/support) writes into every store."""
    from support.synthetic import bulk_insert

    _, url = backend
    with open_store(url) as store:
        sid = make_session(store)
        store.write_trial(sid, make_result(0))
        (tid,) = [t["trial_id"] for t in store.trials()]
        bulk_insert(store, samples=[(tid, 9.0, 0.5, 0.25, 1)])
        assert store.samples(tid)[-1] == (9.0, 0.5, 0.25, 1)


def test_a_clean_close_leaves_only_the_store(backend: tuple[str, str], tmp_path: Path) -> None:
    _, url = backend
    store = open_store(url)
    if not store.capabilities.file:
        store.close()
        pytest.skip("not a file store")
    assert store.path is not None
    sid = make_session(store)
    store.write_trial(sid, make_result(0))
    with open_store(url, readonly=True) as reader:  # a reader meanwhile
        assert len(reader.trials()) == 1
    store.close()
    store.close()  # twice is fine
    assert sorted(p.name for p in store.path.parent.iterdir()) == [store.path.name]
    with open_store(url, readonly=True) as reader:
        assert len(reader.trials()) == 1
    assert sorted(p.name for p in store.path.parent.iterdir()) == [store.path.name]


def test_one_writer_at_a_time(backend: tuple[str, str]) -> None:
    _, url = backend
    with open_store(url) as store:
        if not store.capabilities.exclusive_writer:
            pytest.skip("several writers allowed")
        with pytest.raises(StoreError, match="another run is using the store"):
            open_store(url)
    open_store(url).close()  # released on close


def test_unknown_schemes() -> None:
    with pytest.raises(StoreError, match="unknown store URL scheme"):
        open_store("mysql://localhost/x")
    assert Store.open is not None


def _events(block: int, phase: str) -> list[TaskEvent]:
    return [TaskEvent(block, "nb2", phase, 0, 10_000_000_000, "tone3", False, "", True, None),
            TaskEvent(block, "nb2", phase, 1, 12_500_000_000, "K", True, "press", True, 0.4321),
            TaskEvent(block, "nb2", phase, -1, 13_000_000_000, None, False, "press", False,
                      None)]


def test_task_events_and_ratings_round_trip(backend: tuple[str, str]) -> None:
    _, url = backend
    tlx = dict(zip(TLX_ITEMS, (70.0, 5.0, 42.5, 20.0, 65.0, 30.0), strict=True))
    with open_store(url) as store:
        a, b = make_session(store), make_session(store, "P02")
        assert store.task_events(a) == [] and store.ratings(a) == []
        store.write_task_events(a, _events(3, "practice"))
        store.write_task_events(b, _events(1, "dual"))
        store.write_task_events(a, _events(3, "dual"))
        store.write_ratings(a, 3, "nasa_tlx", tlx)
        store.write_ratings(a, 3, "nasa_tlx", {**tlx, "effort": 80.0})  # asked again
        store.write_ratings(a, 5, "nasa_tlx", tlx)
        store.write_ratings(b, 1, "nasa_tlx", tlx)
    with open_store(url, create=False, readonly=True) as reader:
        rows = reader.task_events(a)
        assert [tuple(r) for r in rows] == [TASK_EVENT_COLUMNS] * 6
        want = [{"session_id": a, **asdict(e)} for e in _events(3, "practice") + _events(3, "dual")]
        assert rows == want  # in the order written, booleans as booleans
        assert len(reader.task_events()) == 9
        ratings = reader.ratings(a)
        assert [tuple(r) for r in ratings] == [RATING_COLUMNS] * 12
        assert [(r["block_index"], r["item"], r["value"]) for r in ratings] == [
            (3, k, 80.0 if k == "effort" else v) for k, v in tlx.items()] + [
            (5, k, v) for k, v in tlx.items()]
        assert {r["session_id"] for r in reader.ratings()} == {a, b}
        with pytest.raises(StoreError, match="read-only"):
            reader.write_task_events(a, _events(3, "dual"))


def test_a_failed_event_write_writes_none_of_them(backend: tuple[str, str]) -> None:
    _, url = backend
    with open_store(url) as store:
        sid = make_session(store)
        bad = [*_events(0, "dual"), TaskEvent(0, "nb2", "rest", 2, 1, "x", False, "", True,
                                              None)]
        with pytest.raises(StoreError):
            store.write_task_events(sid, bad)  # 'rest' is no phase
        with pytest.raises(StoreError, match="finite"):
            store.write_ratings(sid, 0, "nasa_tlx", {"mental": float("nan")})
        assert store.task_events(sid) == [] and store.ratings(sid) == []


def test_a_store_of_schema_2_gains_the_task_tables(backend: tuple[str, str]) -> None:
    scheme, url = backend
    with open_store(url) as store:
        sid = make_session(store)
        store.write_trial(sid, make_result(0))
    make_schema_2(scheme, url)
    with open_store(url, create=False, readonly=True) as reader:  # readers change nothing
        assert reader.task_events() == [] and reader.ratings() == []
        assert reader.table_columns("task_events") == []
    with open_store(url) as store:  # a writer migrates it
        assert len(store.trials(sid)) == 1
        assert set(TASK_EVENT_COLUMNS) <= set(store.table_columns("task_events"))
        assert set(RATING_COLUMNS) <= set(store.table_columns("ratings"))
        store.write_task_events(sid, _events(0, "dual"))
        store.write_ratings(sid, 0, "nasa_tlx", {"mental": 12.5})
    with open_store(url, create=False, readonly=True) as reader:
        assert len(reader.task_events(sid)) == 3 and reader.ratings(sid)[0]["value"] == 12.5


def test_skin_onsets_round_trip_and_older_stores_gain_the_columns(
        backend: tuple[str, str]) -> None:
    from support import pgserver

    scheme, url = backend
    with open_store(url) as store:
        sid = make_session(store)
        store.write_trial(sid, make_result(0))  # no skin onset: NULL
        store.write_trial(sid, make_result(1), skin_onset_ns=1_015_184_001,
                          skin_onset_sd_ns=250_000)
        rows = store.trials(sid)
    assert [(t["skin_onset_ns"], t["skin_onset_sd_ns"]) for t in rows] == [
        (None, None), (1_015_184_001, 250_000)]
    # a store written before the columns existed (same schema version): a writer adds
    # them, the old rows NULL
    drop = "ALTER TABLE {}trials DROP COLUMN {}"
    if scheme == "sqlite":
        import sqlite3

        conn = sqlite3.connect(url.removeprefix("sqlite://"))
        for col in ("skin_onset_ns", "skin_onset_sd_ns"):
            conn.execute(drop.format("", col))
        conn.commit()
        conn.close()
    else:
        pgserver.run_sql(url, *(drop.format("tactorbelt.", c)
                                for c in ("skin_onset_ns", "skin_onset_sd_ns")))
    with open_store(url, create=False, readonly=True) as reader:  # readers change nothing
        assert "skin_onset_ns" not in reader.table_columns("trials")
    with open_store(url) as store:
        store.write_trial(sid, make_result(2), skin_onset_ns=7, skin_onset_sd_ns=0)
        rows = store.trials(sid)
    assert [(t["skin_onset_ns"], t["skin_onset_sd_ns"]) for t in rows] == [
        (None, None), (None, None), (7, 0)]
