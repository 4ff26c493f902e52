"""Export: tidy CSV files and a BIDS-style dataset that describe every column."""

from __future__ import annotations

import csv
import gzip
import itertools
import json
from pathlib import Path

import pytest

from support.studies import study_toml
from tactorbelt import ConfigError, StoreError
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.experiment.export import (
    BEH_COLUMNS,
    CURSOR_COLUMNS,
    bids_label,
    export_bids,
    export_csv,
)
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.schedule import make_schedule
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import Study
from tactorbelt.inputs.scripted import ScriptedCursor, ScriptedResponse

STUDY = study_toml(minimal=True, name="export", tactors=6, targets=6, timeout_s=1.0,
                   training=0, repetitions=1)


@pytest.fixture(scope="module")
def db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("export") / "s.sqlite"
    study = Study.from_toml(STUDY)
    clock = SimClock()
    with Store.open(path) as store, open_belt("sim", clock=clock) as belt:
        for pid in ("P-01", "P-02"):
            answers = {t.trial_index: t.target_deg for t in make_schedule(study, pid)}
            # trial 3 times out
            cursor = ScriptedCursor({3: ScriptedResponse(None)}, answers=answers)
            run_session(study, pid, belt, cursor, store, clock)
    return path


def _read(path: Path, delimiter: str = ",") -> list[dict[str, str]]:
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh, delimiter=delimiter))


def test_csv_export(db: Path, tmp_path: Path) -> None:
    files = export_csv(db, tmp_path / "out")
    assert [f.name for f in files] == ["sessions.csv", "trials.csv", "samples.csv"]
    sessions = _read(files[0])
    trials = _read(files[1])
    samples = _read(files[2])
    assert [s["participant"] for s in sessions] == ["P-01", "P-02"]
    assert len(trials) == 24
    assert {t["participant"] for t in trials} == {"P-01", "P-02"}
    t3 = [t for t in trials if t["trial_index"] == "3"]
    assert {t["status"] for t in t3} == {"timeout"}
    assert {t["rt_s"] for t in t3} == {""}
    with Store.open(db, readonly=True) as store:
        n = store.conn.execute("SELECT COUNT(*) FROM samples").fetchone()[0]
    assert len(samples) == n
    assert sum(int(t["n_samples"]) for t in trials) == n
    assert set(samples[0]) == {"participant", "session_id", "trial_index", "t_s", "x", "y",
                               "buttons"}


def test_bids_export(db: Path, tmp_path: Path) -> None:
    out = tmp_path / "bids"
    export_bids(db, out)
    desc = json.loads((out / "dataset_description.json").read_text())
    assert desc["BIDSVersion"] and desc["Name"]
    parts = _read(out / "participants.tsv", "\t")
    assert [p["participant_id"] for p in parts] == ["sub-P01", "sub-P02"]
    beh = out / "sub-P01" / "ses-1" / "beh" / "sub-P01_ses-1_task-betweentactor_beh.tsv"
    rows = _read(beh, "\t")
    assert list(rows[0]) == list(BEH_COLUMNS)
    assert len(rows) == 12
    assert rows[3]["rt_s"] == "n/a" and rows[3]["status"] == "timeout"
    sidecar = json.loads(beh.with_suffix(".json").read_text())
    for col in rows[0]:
        assert sidecar[col]["Description"]
    assert sidecar["tactorbelt"]["study_name"] == "export"
    # the cursor samples: a BIDS continuous recording of the beh data type, gzipped and
    # headerless, its columns named by the sidecar's Columns and each described there
    stem = "sub-P01_ses-1_task-betweentactor_recording-cursor_physio"
    assert not (out / "sub-P01" / "ses-1" / "motion").exists()
    meta = json.loads((beh.parent / f"{stem}.json").read_text())
    assert meta["Columns"] == list(CURSOR_COLUMNS) == ["trial_index", "t", "t_trial", "x",
                                                         "y", "buttons"]
    for col in meta["Columns"]:
        assert meta[col]["Description"]
    assert meta["SamplingFrequency"] == 100.0
    with gzip.open(beh.parent / f"{stem}.tsv.gz", "rt") as fh:
        samples = [line.rstrip("\n").split("\t") for line in fh]
    assert all(len(r) == len(meta["Columns"]) for r in samples)
    with Store.open(db, readonly=True) as store:
        sid = next(s["session_id"] for s in store.sessions() if s["participant"] == "P-01")
        stored = list(store.iter_samples(sid))
    # every sample, as stored: trial, time within the trial, x, y, buttons
    assert [(int(r[0]), float(r[2]), float(r[3]), float(r[4]), int(r[5])) for r in samples] \
        == [(i, t_s, x, y, b) for _sid, i, t_s, x, y, b in stored]
    # t: seconds from the first trial's onset (the origin of the events' onset), never
    # restarting at a trial; the recording pauses between trials, so each row says its time
    t = [float(r[1]) for r in samples]
    trial = [int(r[0]) for r in samples]
    assert meta["StartTime"] == t[0] == 0.0 and all(b > a for a, b in itertools.pairwise(t))
    assert all(len(r[1].split(".")[1]) == 6 for r in samples)
    onsets = {int(r["trial_index"]): float(r["onset_s"]) for r in rows}
    first = {k: t[trial.index(k)] for k in sorted(set(trial))}
    for k in first:  # a trial's first sample sits at its onset after the first trial's
        assert first[k] == pytest.approx(onsets[k] - onsets[0], abs=1e-6)
    assert "between trials" in meta["t"]["Description"]
    again = tmp_path / "again"
    export_bids(db, again)  # the gzip header holds no name or time: the same bytes
    rel = Path("sub-P01", "ses-1", "beh", f"{stem}.tsv.gz")
    assert (again / rel).read_bytes() == (out / rel).read_bytes()


def test_bids_label() -> None:
    assert bids_label("P-01") == "P01"
    with pytest.raises(ConfigError):
        bids_label("--")


def test_export_of_a_missing_or_foreign_file(tmp_path: Path) -> None:
    with pytest.raises(StoreError, match="no such store"):
        export_csv(tmp_path / "nope.sqlite", tmp_path / "out")
    assert not (tmp_path / "out").exists()
    bad = tmp_path / "bad.sqlite"
    bad.write_text("hello")
    with pytest.raises(StoreError, match="not an SQLite"):
        export_bids(bad, tmp_path / "out")


def test_export_into_a_file_is_refused(db: Path, tmp_path: Path) -> None:
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(ConfigError, match="not a directory"):
        export_csv(db, f)


# -- BIDS under cognitive load: task events, ratings, authors ------------------------------------
@pytest.fixture(scope="module")
def load_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Two model participants with a 2-back (in the first block, so its practice comes
    before the first trial) and the NASA-TLX; the study file names two authors."""
    from support.cli import tactorbelt
    from support.studies import write_study

    d = tmp_path_factory.mktemp("load")
    study = write_study(
        d, name="load", tactors=4, targets=8, iti_s=0.5, break_every=0, training=0,
        timeout_s=3.0, max_presentation_s=2.0,
        blocks=[{"name": "busy", "condition": "dynamic", "repetitions": 1, "load": "nb2"},
                {"name": "calm", "condition": "static", "repetitions": 1}],
        tasks={"nb2": {"kind": "nback", "n": 2, "interval_s": 1.0, "practice": 6}},
        questionnaire={"tlx": True})
    study.write_text(study.read_text().replace(
        'name = "load"\n', 'name = "load"\nauthors = ["Ada Lovelace", " Alan Turing "]\n', 1))
    for pid in ("P01", "P02"):
        proc = tactorbelt("run", str(study), "-p", pid, "--headless", "--input", "model",
                          "--db", str(d / "s.sqlite"))
        assert proc.returncode == 0, proc.stderr
    return d / "s.sqlite"


def test_bids_task_events_and_ratings_with_every_column_described(load_db: Path,
                                                                   tmp_path: Path) -> None:
    from tactorbelt.experiment.export import EVENT_COLUMNS, TLX_COLUMNS

    out = tmp_path / "bids"
    files = export_bids(load_db, out)
    desc = json.loads((out / "dataset_description.json").read_text())
    assert desc["Authors"] == ["Ada Lovelace", "Alan Turing"]  # from the study file
    beh = out / "sub-P01" / "ses-1" / "beh"
    ev = beh / "sub-P01_ses-1_task-betweentactor_events.tsv"
    tlx = beh / "sub-P01_ses-1_task-nasatlx_beh.tsv"
    assert {ev, ev.with_suffix(".json"), tlx, tlx.with_suffix(".json")} <= set(files)
    # every column of every table is described in its sidecar
    for tsv in out.glob("sub-*/ses-*/beh/*.tsv"):
        header = tsv.read_text().splitlines()[0].split("\t")
        sidecar = json.loads(tsv.with_suffix(".json").read_text())
        assert all(sidecar[c]["Description"] for c in header), tsv
    events = _read(ev, "\t")
    assert list(events[0]) == list(EVENT_COLUMNS)
    with Store.open(load_db, readonly=True) as store:
        (sess,) = store.sessions("P01")
        stored = store.task_events(sess["session_id"])
        trials = store.trials(sess["session_id"])
        ratings = store.ratings(sess["session_id"])
    assert len(events) == len(stored)
    onsets = [float(e["onset"]) for e in events]
    assert onsets == sorted(onsets) and onsets[0] < 0  # practice before the first trial
    first = min(t["onset_ns"] for t in trials)
    by_item = {(e["phase"], e["item_index"]): e for e in stored}
    for e in events:
        s = by_item[(e["phase"], int(e["item_index"]))]
        assert float(e["onset"]) == pytest.approx((s["t_ns"] - first) / 1e9, abs=1e-6)
        assert e["trial_type"] == ("extra_press" if s["item_index"] < 0 else
                                   "go" if s["target"] else "nogo")
        assert e["response"] == (s["response"] or "n/a")
        assert e["response_time"] == ("n/a" if s["rt_s"] is None else repr(s["rt_s"]))
        assert e["duration"] in ("0.5", "0.0")
    # the ratings: one row per rated block, the six items and their mean
    rows = _read(tlx, "\t")
    assert list(rows[0]) == list(TLX_COLUMNS)
    assert [r["block_name"] for r in rows] == ["busy", "calm"]
    for r in rows:
        mine = {x["item"]: x["value"] for x in ratings if x["block_index"] == int(r["block_index"])}
        assert {k: float(r[k]) for k in mine} == mine
        assert float(r["raw_tlx"]) == pytest.approx(sum(mine.values()) / 6, abs=1e-3)
    readme = (out / "README.md").read_text()
    assert "## Secondary-task events" in readme and "## Workload ratings" in readme


def test_bids_authors_given_replace_the_study_files(load_db: Path, tmp_path: Path) -> None:
    export_bids(load_db, tmp_path / "a", authors=["Grace Hopper"])
    desc = json.loads((tmp_path / "a" / "dataset_description.json").read_text())
    assert desc["Authors"] == ["Grace Hopper"]
    export_bids(load_db, tmp_path / "b", authors=[])
    assert "Authors" not in json.loads((tmp_path / "b" / "dataset_description.json")
                                       .read_text())


def test_the_export_command_says_where_the_authors_came_from(load_db: Path,
                                                              tmp_path: Path) -> None:
    from support.cli import tactorbelt

    proc = tactorbelt("export", str(load_db), "-o", str(tmp_path / "a"), "--format", "bids",
                      "--authors", "Grace Hopper")
    assert proc.returncode == 0, proc.stderr
    assert "  Authors: Grace Hopper (from --authors)" in proc.stdout
    assert "note: one author (Grace Hopper): the BIDS validator warns TOO_FEW_AUTHORS" in \
        proc.stderr
    proc = tactorbelt("export", str(load_db), "-o", str(tmp_path / "b"), "--format", "bids",
                      "--authors", " , ")
    assert proc.returncode == 2
    assert "Invalid value for '--authors': name at least one author" in proc.stderr


def test_a_study_file_author_must_be_a_name() -> None:
    from tactorbelt import StudyFileError

    text = STUDY.replace('name = "export"\n', 'name = "export"\nauthors = ["A", " "]\n', 1)
    with pytest.raises(StudyFileError, match="authors"):
        Study.from_toml(text)
    assert Study.from_toml(STUDY).authors == []
