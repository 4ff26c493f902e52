"""Export: tidy CSV files and a BIDS-style dataset that describe every column."""

from __future__ import annotations

import csv
import itertools
import json
from pathlib import Path

import pytest

from support.studies import study_toml
from tactorbelt import ConfigError, StoreError
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.experiment.export import BEH_COLUMNS, bids_label, export_bids, export_csv
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
    motion_dir = out / "sub-P01" / "ses-1" / "motion"
    stem = "sub-P01_ses-1_task-betweentactor_tracksys-cursor"
    channels = _read(motion_dir / f"{stem}_channels.tsv", "\t")
    assert [c["name"] for c in channels] == ["trial", "latency", "x", "y", "buttons"]
    assert [c["type"] for c in channels][1] == "LATENCY"
    motion = (motion_dir / f"{stem}_motion.tsv").read_text().splitlines()
    assert all(len(line.split("\t")) == len(channels) for line in motion)
    assert sum(int(r["trial_index"] != "") for r in rows) == 12
    meta = json.loads((motion_dir / f"{stem}_motion.json").read_text())
    assert meta["SamplingFrequency"] == 100.0
    # BIDS motion: LATENCY is seconds from recording onset (the first trial's onset), so
    # it never restarts at a trial; trials differ in length, so the recording is
    # discontinuous rather than epoched (no EpochLength)
    assert meta["RecordingType"] == "discontinuous" and "EpochLength" not in meta
    latency = [float(line.split("\t")[1]) for line in motion]
    trial = [int(line.split("\t")[0]) for line in motion]
    assert latency[0] == 0.0 and all(b > a for a, b in itertools.pairwise(latency))
    assert all(len(line.split("\t")[1].split(".")[1]) == 6 for line in motion)
    onsets = {int(r["trial_index"]): float(r["onset_s"]) for r in rows}
    first = {k: latency[trial.index(k)] for k in sorted(set(trial))}
    for k in first:  # a trial's first sample sits at its onset after the first trial's
        assert first[k] == pytest.approx(onsets[k] - onsets[0], abs=1e-6)


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
