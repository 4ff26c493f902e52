"""A factorial study run end to end: model participants through the runner, the store's
n_targets and load columns, and the per-cell analysis recomputed from the raw trials.

Also: a store written before factorial designs (no n_targets / load columns) still
analyses, and a writer opening it migrates its schema.
"""

from __future__ import annotations

import csv
import json
import math
import sqlite3
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from support.studies import make_study
from tactorbelt.analysis.report.analyze import analyze
from tactorbelt.analysis.summary import summarize
from tactorbelt.analysis.tables.load import load_stores
from tactorbelt.analysis.tables.transfer import estimate_transfer
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.experiment.export import export_csv
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.store import open_store
from tactorbelt.experiment.store.base import SCHEMA_VERSION
from tactorbelt.experiment.study import Study
from tactorbelt.geometry import wrap
from tactorbelt.inputs.model import make_model_cursor

COUNTS = (12, 24)


def _study() -> Study:
    return make_study(design={"targets": list(COUNTS), "condition": ["static", "dynamic"],
                              "repetitions": 2, "order": "williams"},
                      training=1, training_conditions=["static"], iti_s=0.2,
                      break_every=0)


def _run(study: Study, db: Path, participants: tuple[str, ...]) -> None:
    with open_store(db) as store:
        for i, pid in enumerate(participants):
            clock = SimClock()
            with open_belt("sim", clock=clock, layout=study.layout_obj()) as belt:
                cursor = make_model_cursor(belt, clock, seed=10 + i)
                res = run_session(study, pid, belt, cursor, store, clock, seed=3,
                                  input_name="model")
            assert res.status == "complete"


@pytest.fixture(scope="module")
def factorial_db(tmp_path_factory: pytest.TempPathFactory) -> tuple[Study, Path]:
    study = _study()
    db = tmp_path_factory.mktemp("factorial") / "study.sqlite"
    _run(study, db, ("model-01", "model-02"))
    return study, db


def _raw(db: Path) -> list[dict[str, Any]]:
    conn = sqlite3.connect(db)
    conn.row_factory = sqlite3.Row
    rows = [dict(r) for r in conn.execute(
        "SELECT s.participant, t.* FROM trials t JOIN sessions s USING (session_id)")]
    conn.close()
    return rows


def test_every_trial_stores_its_blocks_target_count_and_load(factorial_db: tuple[Study, Path]
                                                              ) -> None:
    study, db = factorial_db
    rows = _raw(db)
    assert len(rows) == 2 * study.n_trials()
    assert {r["load"] for r in rows} == {"none"}
    blocks = {b.label: study.block_n_targets(b) for b in study.test}
    for r in rows:
        n = r["n_targets"]
        if r["block"] == "test":
            assert n == blocks[r["block_name"]]
        assert n in COUNTS
        step = 360.0 / n
        # the target and the answer are both of the block's target set
        assert abs(wrap(r["target_deg"] - step * round(r["target_deg"] / step))) < 1e-6
        if r["status"] == "done":
            chosen = r["response_target_deg"]
            assert abs(wrap(chosen - step * round(chosen / step))) < 1e-6
            # the snapped answer is the block's target nearest the cursor's direction
            assert abs(wrap(r["response_deg"] - chosen)) <= step / 2 + 1e-6
    # training covers both counts; each test block has its count's trials
    training = [r for r in rows if r["block"] == "training"]
    assert {r["n_targets"] for r in training} == set(COUNTS)
    per_block: dict[tuple[str, str], int] = defaultdict(int)
    for r in rows:
        if r["block"] == "test":
            per_block[(r["participant"], r["block_name"])] += 1
    assert set(per_block.values()) == {2 * 12, 2 * 24}


def test_per_cell_numbers_recomputed_from_the_raw_trials(factorial_db: tuple[Study, Path],
                                                         tmp_path: Path) -> None:
    _, db = factorial_db
    analyze([db], tmp_path / "out", n_boot=20)
    doc = json.loads((tmp_path / "out" / "summary.json").read_text())
    cells = {(c["condition"], c["n_targets"], c["load"]): c for c in doc["cells"]}
    assert set(cells) == {(c, n, "none") for c in ("static", "dynamic") for n in COUNTS}

    groups: dict[tuple[str, int, str], list[dict[str, Any]]] = defaultdict(list)
    for r in _raw(db):
        if r["block"] == "test" and r["status"] in ("done", "timeout"):
            groups[(r["condition"], r["n_targets"], r["load"])].append(r)
    for key, trials in groups.items():
        c = cells[key]
        n = key[1]
        done = [t for t in trials if t["status"] == "done"]
        assert c["n"] == len(trials)
        assert c["n_participants"] == 2
        assert c["accuracy"] == pytest.approx(sum(t["correct"] == 1 for t in trials) / len(trials))
        assert c["median_rt_s"] == pytest.approx(float(np.median([t["rt_s"] for t in done])))
        err = [abs(wrap(t["response_target_deg"] - t["target_deg"])) for t in done]
        assert c["mean_abs_error_deg"] == pytest.approx(float(np.mean(err)))
        between = [t for t in trials if not t["on_tactor"]]
        assert c["between_tactor"]["n"] == len(between)
        assert c["between_tactor"]["accuracy"] == pytest.approx(
            sum(t["correct"] == 1 for t in between) / len(between))
        # information transfer: each participant's matrix of the cell, then the mean
        bits = []
        for pid in ("model-01", "model-02"):
            m = np.zeros((n, n))
            for t in done:
                if t["participant"] == pid:
                    m[round(t["target_deg"] * n / 360) % n,
                      round(t["response_target_deg"] * n / 360) % n] += 1
            bits.append(float(estimate_transfer(m)))
        assert c["it_bits"] == pytest.approx(float(np.mean(bits)))
        assert 0 < c["it_bits"] <= math.log2(n)  # never above what the channel can carry

    # per_target.csv has the cell columns; the report shows the cells and their figures
    with (tmp_path / "out" / "per_target.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert {(r["n_targets"], r["load"]) for r in rows} == {(str(n), "none") for n in COUNTS}
    html = (tmp_path / "out" / "report.html").read_text()
    assert "Results by cell" in html
    for name in ("resolution.png", *(f"fig1b-{n}.png" for n in COUNTS)):
        assert (tmp_path / "out" / name).is_file(), name
        assert name in html


def _drop_cell_columns(db: Path) -> None:
    """Make ``db`` a schema-1 store: no trials.n_targets / trials.load."""
    conn = sqlite3.connect(db)
    conn.execute("ALTER TABLE trials DROP COLUMN n_targets")
    conn.execute("ALTER TABLE trials DROP COLUMN load")
    conn.execute("UPDATE meta SET value='1' WHERE key='schema_version'")
    conn.commit()
    conn.close()


def test_a_store_without_the_cell_columns_still_analyses(tmp_path: Path) -> None:
    study = make_study(targets=12, repetitions=1, training=0, iti_s=0.2, break_every=0)
    db = tmp_path / "old.sqlite"
    _run(study, db, ("model-01",))
    before = summarize(load_stores([db]), n_boot=10)
    _drop_cell_columns(db)
    data = load_stores([db])
    assert set(data.trials["n_targets"]) == {12} and set(data.trials["load"]) == {"none"}
    after = summarize(data, n_boot=10)
    assert after.to_json()["cells"] == before.to_json()["cells"]
    assert [(c["n_targets"], c["load"]) for c in after.to_json()["cells"]] == \
        [(12, "none"), (12, "none")]
    # export fills them in too
    export_csv(db, tmp_path / "csv")
    with (tmp_path / "csv" / "trials.csv").open() as fh:
        exported = list(csv.DictReader(fh))
    assert {(r["n_targets"], r["load"]) for r in exported} == {("12", "none")}
    # a paper-style study is not factorial: no cell section, no cell figures
    analyze([db], tmp_path / "out", n_boot=10)
    assert not (tmp_path / "out" / "resolution.png").exists()
    assert "Results by cell" not in (tmp_path / "out" / "report.html").read_text()


def test_a_writer_migrates_a_schema_1_store_and_resume_still_works(tmp_path: Path) -> None:
    study = make_study(targets=12, repetitions=1, training=0, iti_s=0.2, break_every=0)
    db = tmp_path / "old.sqlite"
    with open_store(db) as store:
        clock = SimClock()
        with open_belt("sim", clock=clock, layout=study.layout_obj()) as belt:
            res = run_session(study, "P01", belt, make_model_cursor(belt, clock, seed=1),
                              store, clock, limit=5)
        assert res.status == "interrupted"
    _drop_cell_columns(db)
    # an old schedule (stored before factorial designs) lacks n_targets and load too
    conn = sqlite3.connect(db)
    (text,) = conn.execute("SELECT schedule_json FROM sessions").fetchone()
    old = [{k: v for k, v in t.items() if k not in ("n_targets", "load")}
           for t in json.loads(text)]
    conn.execute("UPDATE sessions SET schedule_json=?", (json.dumps(old),))
    conn.commit()
    conn.close()
    with open_store(db) as store:
        assert {"n_targets", "load"} <= set(store.table_columns("trials"))
        clock = SimClock()
        with open_belt("sim", clock=clock, layout=study.layout_obj()) as belt:
            res = run_session(study, "P01", belt, make_model_cursor(belt, clock, seed=1),
                              store, clock, resume=True)
        assert res.status == "complete"
    conn = sqlite3.connect(db)
    version = conn.execute("SELECT value FROM meta WHERE key='schema_version'").fetchone()
    rows = conn.execute("SELECT n_targets, load FROM trials ORDER BY trial_index").fetchall()
    conn.close()
    assert int(version[0]) == SCHEMA_VERSION == 3
    assert rows[:5] == [(None, None)] * 5  # written before the migration
    assert set(rows[5:]) == {(12, "none")}
    data = load_stores([db])
    assert set(data.trials["n_targets"]) == {12} and set(data.trials["load"]) == {"none"}
