"""Exports people open in their own tools (docs/export.md): Parquet, the tidy table for
R (lme4) and JASP, and PsychoPy's trial-by-trial CSV files, made through the command."""

from __future__ import annotations

import csv
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from support.cli import model_store, tactorbelt
from support.studies import write_study
from tactorbelt.experiment.export_formats import (
    DTYPES,
    PSYCHOPY_COLUMNS,
    TIDY_COLUMNS,
    psychopy_date,
    read_table,
    tables,
)


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return model_store(tmp_path_factory.mktemp("formats"), participants=("P01", "P02", "P03"))


@pytest.fixture(scope="module")
def load_store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A model participant's session with a 2-back task and the NASA-TLX."""
    d = tmp_path_factory.mktemp("load")
    study = write_study(
        d, name="load", tactors=4, targets=8, iti_s=0.5, break_every=0, training=0,
        timeout_s=3.0, max_presentation_s=2.0,
        blocks=[{"name": "calm", "condition": "static", "repetitions": 1},
                {"name": "busy", "condition": "dynamic", "repetitions": 1, "load": "nb2"}],
        tasks={"nb2": {"kind": "nback", "n": 2, "interval_s": 1.0, "practice": 6}},
        questionnaire={"tlx": True})
    proc = tactorbelt("run", str(study), "-p", "P01", "--headless", "--input", "model",
                      "--db", str(d / "s.sqlite"))
    assert proc.returncode == 0, proc.stderr
    return d / "s.sqlite"


def _export(db: Path, out: Path, fmt: str, *extra: str) -> subprocess.CompletedProcess[str]:
    return tactorbelt("export", str(db), "-o", str(out), "--format", fmt, *extra)


def test_parquet_and_csv_read_back_as_the_same_dataframes(store: Path, tmp_path: Path) -> None:
    pytest.importorskip("pyarrow")
    for fmt in ("csv", "parquet"):
        proc = _export(store, tmp_path / fmt, fmt)
        assert proc.returncode == 0, proc.stderr
    frames = tables(store)
    for name in ("sessions", "trials", "samples"):
        from_csv = read_table(tmp_path / "csv" / f"{name}.csv")
        from_parquet = read_table(tmp_path / "parquet" / f"{name}.parquet")
        pd.testing.assert_frame_equal(from_csv, from_parquet)
        pd.testing.assert_frame_equal(from_parquet, frames[name])
        # what pandas reads from the Parquet file needs no help: it is typed
        raw = pd.read_parquet(tmp_path / "parquet" / f"{name}.parquet")
        assert {c: str(t) for c, t in raw.dtypes.items()} == DTYPES[name]
    trials = frames["trials"]
    assert len(trials) == 3 * 18 and trials["correct"].dtype == "boolean"
    assert trials["rt_s"].notna().all()  # model participants answer every trial
    assert len(frames["samples"]) == int(trials["n_samples"].sum())


def test_task_events_and_ratings_round_trip_too(load_store: Path, tmp_path: Path) -> None:
    pytest.importorskip("pyarrow")
    for fmt in ("csv", "parquet"):
        proc = _export(load_store, tmp_path / fmt, fmt)
        assert proc.returncode == 0, proc.stderr
    frames = tables(load_store)
    assert set(frames) == set(DTYPES)
    for name in DTYPES:
        pd.testing.assert_frame_equal(read_table(tmp_path / "csv" / f"{name}.csv"),
                                      read_table(tmp_path / "parquet" / f"{name}.parquet"))
    events = frames["task_events"]
    assert set(events["phase"]) == {"practice", "dual"} and events["target"].dtype == "boolean"
    # nothing pressed: an empty response, missing in both files
    assert events["response"].isna().any() and not (events["response"] == "").any()
    assert len(frames["ratings"]) == 2 * 6  # NASA-TLX after each test block


def test_the_tidy_table_loads_into_r_and_lme4_with_the_documented_types(
        store: Path, tmp_path: Path) -> None:
    out = tmp_path / "tidy"
    proc = _export(store, out, "tidy")
    assert proc.returncode == 0, proc.stderr
    with (out / "codebook.csv").open() as fh:
        book = list(csv.DictReader(fh))
    assert [r["column"] for r in book] == [c[0] for c in TIDY_COLUMNS]
    head = (out / "trials_tidy.csv").read_text().splitlines()[0].split(",")
    assert head == [c[0] for c in TIDY_COLUMNS]
    if shutil.which("Rscript") is None:
        pytest.skip("Rscript is not installed")
    script = f"""
d <- read.csv("{out / 'trials_tidy.csv'}", stringsAsFactors = TRUE)
cat(paste(names(d), sapply(d, function(x) class(x)[1]), sep = "="), sep = "\\n")
cat("rows=", nrow(d), "\\n", sep = "")
if (requireNamespace("lme4", quietly = TRUE)) {{
  m <- suppressMessages(suppressWarnings(lme4::glmer(
    correct ~ condition + (1 | participant), data = d, family = binomial)))
  cat("lme4=", paste(names(lme4::fixef(m)), collapse = ","), "\\n", sep = "")
}}
"""
    r = subprocess.run(["Rscript", "-e", script], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    got = dict(line.split("=", 1) for line in r.stdout.splitlines() if "=" in line)
    for name, _type, r_type, _jasp, _desc in TIDY_COLUMNS:
        want = r_type
        if name in ("response_deg", "response_target_deg", "target_deg", "signed_error_deg"):
            # whole degrees only (6 targets, model responses snap): R may read integers
            assert got[name] in ("numeric", "integer"), name
            continue
        if name == "participant":
            want = "factor"
        assert got[name] == want, (name, got[name])
    assert got["rows"] == str(3 * 18)
    if "lme4" in got:
        assert got["lme4"].split(",") == ["(Intercept)", "conditionstatic"]


def test_psychopy_export_has_one_wide_file_per_session_with_loop_counters(
        store: Path, tmp_path: Path) -> None:
    out = tmp_path / "psychopy"
    proc = _export(store, out, "psychopy")
    assert proc.returncode == 0, proc.stderr
    files = sorted(out.glob("*.csv"))
    assert [f.name.split("_")[0] for f in files] == ["P01", "P02", "P03"]
    sessions = tables(store)["sessions"]
    for f, (_, s) in zip(files, sessions.iterrows(), strict=True):
        date = psychopy_date(s["started_at"])
        assert f.name == f"{s['participant']}_first-use_{date}.csv"
        d = pd.read_csv(f)
        # PsychoPy ends every line with a delimiter: pandas names that column "Unnamed"
        assert list(d.columns) == [*PSYCHOPY_COLUMNS, f"Unnamed: {len(PSYCHOPY_COLUMNS)}"]
        assert len(d) == 18  # one row per trial
        assert (d["participant"] == s["participant"]).all() and (d["session"] == 1).all()
        assert (d["date"] == date).all() and (d["expName"] == "first-use").all()
        for _, block in d.groupby("blocks.thisN"):
            assert list(block["trials.thisN"]) == list(range(len(block)))
            assert block["trials.thisRepN"].nunique() == 1  # one repetition per block
            assert sorted(block["trials.thisIndex"]) == list(range(6))
        assert list(d["blocks.thisN"].drop_duplicates()) == [0, 1, 2]
        assert set(d["response.corr"]) <= {0, 1} and d["stimulus.started"].iloc[0] == 0.0


PSYCHOPY_REFERENCE = """
import sys
from psychopy import data
rows, out = {rows!r}, sys.argv[1]
info = dict(participant="P01", session=1, date=data.getDateStr(), expName="first-use",
            psychopyVersion="", frameRate="", tactorbeltVersion="0")
exp = data.ExperimentHandler(name="first-use", extraInfo=info, dataFileName=out)
blocks = data.TrialHandler(rows["blocks"], nReps=1, method="sequential", name="blocks")
exp.addLoop(blocks)
for _ in blocks:
    trials = data.TrialHandler(rows["targets"], nReps=1, method="sequential", name="trials")
    exp.addLoop(trials)
    for _ in trials:
        for name in rows["data"]:
            exp.addData(name, 1)
        exp.nextEntry()
exp.saveAsWideText(out + ".csv", delim="auto")
exp.abort()
"""


def test_psychopy_export_has_the_header_psychopy_itself_writes(store: Path,
                                                                tmp_path: Path) -> None:
    proc = subprocess.run([sys.executable, "-c", "import psychopy.data"], capture_output=True,
                          timeout=120)
    if proc.returncode != 0:
        pytest.skip("PsychoPy is not installed (pip install psychopy)")
    cols = PSYCHOPY_COLUMNS
    rows = {"blocks": [dict.fromkeys(cols[:cols.index("target_deg")], "x")],
            "targets": [dict.fromkeys(cols[cols.index("target_deg"):cols.index("on_tactor") + 1],
                                      1.0)],
            "data": cols[cols.index("stimulus.started"):cols.index("participant")]}
    ref = tmp_path / "ref"
    proc = subprocess.run([sys.executable, "-c", PSYCHOPY_REFERENCE.format(rows=rows),
                           str(ref)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    want = (tmp_path / "ref.csv").read_bytes().splitlines()[0]
    out = tmp_path / "psychopy"
    assert _export(store, out, "psychopy").returncode == 0
    got = sorted(out.glob("*.csv"))[0].read_bytes().splitlines()[0]
    assert got == want  # byte-order mark, column order, the trailing delimiter


def test_psychopy_date_is_getdatestr_format() -> None:
    assert psychopy_date("2024-01-31T14:05:23.123456") == "2024-01-31_14h05.23.123"
    assert psychopy_date(None) == ""


@pytest.mark.parametrize("fmt, names", [
    ("parquet", ["sessions.parquet"]), ("tidy", ["trials_tidy.csv"]),
    ("psychopy", ["P01_first-use_2026-01-01_10h00.00.000.csv"]),
])
def test_exports_refuse_existing_files_unless_force(store: Path, tmp_path: Path, fmt: str,
                                                    names: list[str]) -> None:
    if fmt == "parquet":
        pytest.importorskip("pyarrow")
    out = tmp_path / "out"
    out.mkdir()
    for n in names:
        (out / n).write_text("earlier\n")
    proc = _export(store, out, fmt)
    assert proc.returncode == 2 and "is not empty" in proc.stderr and "--force" in proc.stderr
    assert (out / names[0]).read_text() == "earlier\n"
    proc = _export(store, out, fmt, "--force")
    assert proc.returncode == 0, proc.stderr
    assert not (out / names[0]).exists() or (out / names[0]).read_bytes() != b"earlier\n"
    # --force replaces an earlier export only, never someone's other files
    (out / "notes.txt").write_text("mine\n")
    proc = _export(store, out, fmt, "--force")
    assert proc.returncode == 2 and "notes.txt" in proc.stderr
    assert (out / "notes.txt").read_text() == "mine\n"


def test_parquet_without_pyarrow_says_how_to_install_it(store: Path, tmp_path: Path) -> None:
    fake = tmp_path / "fake" / "pyarrow"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text("raise ImportError('No module named pyarrow')\n")
    import os

    env = dict(os.environ, PYTHONPATH=str(tmp_path / "fake"))
    proc = subprocess.run([sys.executable, "-m", "tactorbelt", "export", str(store), "-o",
                           str(tmp_path / "out"), "--format", "parquet"],
                          capture_output=True, text=True, env=env, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: Parquet files need the pyarrow package; install it "
                                  "with: pip install 'tactorbelt[parquet]'"), proc.stderr
    assert not (tmp_path / "out").exists()
