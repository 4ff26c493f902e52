"""Loading stores and the descriptive tables, cross-checked on a store built by hand."""

from __future__ import annotations

import math
import sqlite3
from collections import defaultdict
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.stats import circmean, circstd

from support.analysis import HAND_TRIALS, _rows, hand_store
from support.synthetic import (
    create_store,
    insert_samples,
    insert_session,
    insert_trials,
    paper_study_toml,
)
from tactorbelt import StoreError
from tactorbelt.analysis.tables.design import parse_design
from tactorbelt.analysis.tables.load import load_samples, load_stores
from tactorbelt.analysis.tables.tables import (
    PER_TARGET_COLUMNS,
    condition_summary,
    confusion_matrices,
    per_target,
    prepare_trials,
)


@pytest.fixture
def hand(tmp_path: Path) -> Path:
    return hand_store(tmp_path / "hand.sqlite")


def test_load_reads_trials_with_participant_and_tolerates_extra_columns(hand: Path) -> None:
    data = load_stores([hand])
    assert len(data.sessions) == 1
    assert len(data.trials) == len(HAND_TRIALS)
    assert set(data.trials["participant"]) == {"P01"}
    assert data.trials["on_tactor"].dtype == bool
    assert "input" in data.sessions.columns


def test_per_target_hand_values(hand: Path) -> None:
    tr = prepare_trials(load_stores([hand]).trials)
    pt = per_target(tr)
    assert list(pt.columns) == PER_TARGET_COLUMNS
    row = pt.set_index(["condition", "target_deg"])
    # static, target 0: aborted and training trials left out -> 2 trials, 1 correct
    assert row.loc[("static", 0.0), "n"] == 2
    assert row.loc[("static", 0.0), "accuracy"] == 0.5
    assert row.loc[("static", 0.0), "median_rt_s"] == pytest.approx(1.1)
    assert row.loc[("static", 0.0), "mean_signed_error_deg"] == pytest.approx(7.5)
    # static, target 15: one timeout counts as incorrect, with no RT
    assert row.loc[("static", 15.0), "n"] == 2
    assert row.loc[("static", 15.0), "accuracy"] == 0.0
    assert row.loc[("static", 15.0), "median_rt_s"] == pytest.approx(1.4)
    assert row.loc[("static", 15.0), "mean_signed_error_deg"] == pytest.approx(-15.0)
    # error wraps across 0: 345 -> 0 is +15, not -345
    assert row.loc[("static", 345.0), "mean_signed_error_deg"] == pytest.approx(15.0)
    assert bool(row.loc[("static", 30.0), "on_tactor"]) is True


def test_per_target_recomputed_from_raw_trials(hand: Path, tmp_path: Path) -> None:
    # a second participant in a second store, with random numbers
    rng = np.random.default_rng(5)
    other = tmp_path / "other.sqlite"
    conn = create_store(other)
    sid = insert_session(conn, participant="P02", started_at="2026-01-02T09:00:00+00:00")
    trials = []
    for i in range(120):
        target = float(rng.integers(0, 24) * 15)
        status = "timeout" if rng.random() < 0.1 else "done"
        resp = None if status == "timeout" else float((target + rng.choice([-15, 0, 15, 30]))
                                                      % 360)
        trials.append(("test", "dynamic" if i % 2 else "static", target,
                       int(target % 60 == 30), resp,
                       None if resp is None else int(resp == target),
                       None if resp is None else float(rng.uniform(0.5, 3)), status))
    insert_trials(conn, _rows(sid, trials))
    conn.close()

    data = load_stores([hand, other])
    pt = per_target(prepare_trials(data.trials))

    # independent recomputation straight from SQL rows
    groups: dict[tuple, list[tuple]] = defaultdict(list)
    for path in (hand, other):
        con = sqlite3.connect(path)
        q = ("SELECT s.participant, t.condition, t.target_deg, t.on_tactor, t.correct, t.rt_s, "
             "t.response_target_deg, t.status FROM trials t JOIN sessions s USING(session_id) "
             "WHERE t.block = 'test' AND t.status IN ('done', 'timeout')")
        for p, c, tg, on, ok, rt, resp, st in con.execute(q):
            groups[(p, c, tg)].append((on, ok, rt, resp, st))
        con.close()
    assert len(pt) == len(groups)
    for r in pt.itertuples(index=False):
        g = groups[(r.participant, r.condition, r.target_deg)]
        assert r.n == len(g)
        assert r.accuracy == pytest.approx(sum(1 for x in g if x[4] == "done" and x[1]) / len(g))
        rts = [x[2] for x in g if x[4] == "done"]
        if rts:
            assert r.median_rt_s == pytest.approx(float(np.median(rts)))
        else:
            assert math.isnan(r.median_rt_s)
        errs = [((x[3] - r.target_deg + 180) % 360) - 180 for x in g if x[4] == "done"]
        if errs:
            expect = circmean(errs, high=180, low=-180)
            assert abs(((r.mean_signed_error_deg - expect + 180) % 360) - 180) < 1e-9
        assert bool(r.on_tactor) == bool(g[0][0])


def test_condition_summary_matches_scipy_circular_stats(hand: Path) -> None:
    tr = prepare_trials(load_stores([hand]).trials)
    cs = condition_summary(tr).set_index(["condition", "kind"])
    sb = cs.loc[("static", "between_tactor")]
    assert sb["n"] == 5 and sb["n_correct"] == 1 and sb["n_timeout"] == 1
    assert sb["accuracy"] == pytest.approx(0.2)
    assert sb["median_rt_s"] == pytest.approx(np.median([1.0, 1.2, 1.4, 1.1]))
    errs = np.array([0.0, 15.0, -15.0, 15.0])
    assert sb["circ_mean_error_deg"] == pytest.approx(circmean(errs, high=180, low=-180))
    assert sb["circ_sd_error_deg"] == pytest.approx(circstd(errs, high=180, low=-180))
    db = cs.loc[("dynamic", "between_tactor")]
    assert db["n"] == 6 and db["accuracy"] == pytest.approx(4 / 6)


def test_confusion_counts_targets_by_response_and_timeouts(hand: Path) -> None:
    tr = prepare_trials(load_stores([hand]).trials)
    cm = confusion_matrices(tr, parse_design(None).targets.angles)
    static = cm["static"]
    assert static.shape == (24, 25)
    assert static.loc[0.0, 0.0] == 1 and static.loc[0.0, 15.0] == 1
    assert static.loc[15.0, "no response"] == 1
    assert static.to_numpy().sum() == 7
    assert cm["dynamic"].loc[345.0, 330.0] == 1


def test_load_samples_fetches_only_requested_trials(tmp_path: Path) -> None:
    path = tmp_path / "s.sqlite"
    conn = create_store(path)
    sid = insert_session(conn)
    insert_trials(conn, _rows(sid, HAND_TRIALS[:3]))
    for tid in (1, 2, 3):
        t = np.arange(5) / 100
        insert_samples(conn, tid, t, t * tid, t)
    conn.close()
    data = load_stores([path])
    want = data.trials.loc[data.trials["trial_id"].isin([2])]
    s = load_samples(data, want)
    assert set(s["trial_id"]) == {2}
    assert len(s) == 5
    assert s["x"].iloc[-1] == pytest.approx(0.08)


def test_study_design_from_toml_and_fallback() -> None:
    d = parse_design(paper_study_toml(tactors=[0, 90, 180, 270], targets=8, law="linear"))
    assert d.layout.angles_deg == (0.0, 90.0, 180.0, 270.0)
    assert d.targets.m == 8 and d.law == "linear" and not d.fallbacks
    bad = parse_design("this is [not toml")
    assert bad.layout.n == 6 and bad.targets.m == 24 and bad.falloff_deg == 15.0
    assert bad.fallbacks and "not valid TOML" in bad.fallbacks[0]
    partial = parse_design('name = "x"\n[targets]\ncount = 12\n')
    assert partial.targets.m == 12 and partial.layout.n == 6
    assert any("layout" in f for f in partial.fallbacks)


# -- bad stores -------------------------------------------------------------------------

def test_not_sqlite_is_a_store_error(tmp_path: Path) -> None:
    p = tmp_path / "notes.sqlite"
    p.write_text("hello, I am a text file\n")
    with pytest.raises(StoreError, match="not an SQLite database"):
        load_stores([p])


def test_missing_file_is_a_store_error(tmp_path: Path) -> None:
    with pytest.raises(StoreError, match="no such file"):
        load_stores([tmp_path / "nope.sqlite"])


def test_sqlite_without_tables_is_a_store_error(tmp_path: Path) -> None:
    p = tmp_path / "other.sqlite"
    con = sqlite3.connect(p)
    con.execute("CREATE TABLE things(a)")
    con.commit()
    con.close()
    with pytest.raises(StoreError, match=r"not a tactorbelt store.*sessions, trials, samples"):
        load_stores([p])


def test_missing_column_is_named(tmp_path: Path) -> None:
    p = tmp_path / "old.sqlite"
    create_store(p).close()
    con = sqlite3.connect(p)
    con.execute("ALTER TABLE trials RENAME COLUMN rt_s TO rt")
    con.commit()
    con.close()
    with pytest.raises(StoreError, match=r"trials lacks column.*rt_s"):
        load_stores([p])


def test_empty_store_is_a_store_error(tmp_path: Path) -> None:
    p = tmp_path / "empty.sqlite"
    create_store(p).close()
    with pytest.raises(StoreError, match="empty store"):
        load_stores([p])


def test_same_session_in_two_stores_counted_once(hand: Path, tmp_path: Path) -> None:
    copy = tmp_path / "copy.sqlite"
    copy.write_bytes(hand.read_bytes())
    data = load_stores([hand, copy])
    assert len(data.sessions) == 1
    assert len(data.trials) == len(HAND_TRIALS)
    assert any("more than one store" in n for n in data.notes)


def test_per_target_of_empty_selection_has_the_columns() -> None:
    empty = pd.DataFrame({c: pd.Series(dtype=float) for c in (
        "block", "condition", "status", "target_deg", "on_tactor", "response_deg",
        "response_target_deg", "correct", "rt_s", "participant")})
    empty["on_tactor"] = empty["on_tactor"].astype(bool)
    pt = per_target(prepare_trials(empty))
    assert list(pt.columns) == PER_TARGET_COLUMNS and pt.empty
