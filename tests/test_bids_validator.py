"""`tactorbelt export --format bids` passes the official BIDS validator.

The researcher's path: run a session, export it as BIDS with the CLI, run
``bids-validator`` (npm ``bids-validator@1.15.0``, installed by ``.ci/run``) on it: no
error and no warning. Skipped, saying why, when the validator is not installed.

Three studies as a researcher meets them: the demo (the paper's protocol), a resolution
study and a load study (secondary-task events and NASA-TLX ratings), each from its
template (``study init --template``) run by ``tactorbelt demo --study``: 0 errors and 0
warnings on each, the cursor samples included (``beh/*_recording-cursor_physio.tsv.gz``
with its ``_physio.json``).
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from support.cli import model_store, tactorbelt

VALIDATOR = shutil.which("bids-validator")

pytestmark = pytest.mark.skipif(
    VALIDATOR is None,
    reason="bids-validator is not installed (npm install -g bids-validator@1.15.0)")


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return model_store(tmp_path_factory.mktemp("bids"), participants=("P01", "P-02"))


def _validate(dataset: Path) -> tuple[list[dict], list[dict]]:
    assert VALIDATOR is not None
    proc = subprocess.run([VALIDATOR, str(dataset), "--json"], capture_output=True, text=True,
                          timeout=300)
    report = json.loads(proc.stdout)
    return report["issues"]["errors"], report["issues"]["warnings"]


def _summary(issues: list[dict]) -> str:
    return "; ".join(f"{i['key']}: {i.get('reason')} "
                     f"{[f.get('evidence') for f in i['files']][:2]}" for i in issues)


def _clean(out: Path) -> None:
    """0 errors and 0 warnings, and every session's cursor samples were among the files
    checked (a beh continuous recording with its sidecar, no motion directory)."""
    errors, warnings = _validate(out)
    assert errors == [], _summary(errors)
    assert warnings == [], _summary(warnings)
    sessions = sorted(out.glob("sub-*/ses-*"))
    recordings = sorted(out.glob("sub-*/ses-*/beh/*_task-betweentactor_recording-cursor_"
                                 "physio.tsv.gz"))
    assert sessions and len(recordings) == len(sessions)
    for rec in recordings:
        assert rec.with_name(rec.name.replace(".tsv.gz", ".json")).is_file()
    assert not list(out.glob("sub-*/ses-*/motion"))


def test_the_bids_export_passes_the_validator(store: Path, tmp_path: Path) -> None:
    out = tmp_path / "bids"
    proc = tactorbelt("export", str(store), "-o", str(out), "--format", "bids",
                      "--authors", "Ada Lovelace, Alan Turing")
    assert proc.returncode == 0, proc.stderr
    _clean(out)
    desc = json.loads((out / "dataset_description.json").read_text())
    assert desc["Name"] == "first-use"
    assert desc["Authors"] == ["Ada Lovelace", "Alan Turing"]
    readme = (out / "README.md").read_text()
    for words in ("first-use", "Task", "rt_s", "_recording-cursor_physio.tsv.gz", "`t`",
                  "pauses between trials"):
        assert words in readme


def test_without_authors_the_export_says_what_the_validator_will(store: Path,
                                                                 tmp_path: Path) -> None:
    out = tmp_path / "bids"
    proc = tactorbelt("export", str(store), "-o", str(out), "--format", "bids")
    assert proc.returncode == 0, proc.stderr
    assert "no --authors" in proc.stderr and "NO_AUTHORS" in proc.stderr
    errors, warnings = _validate(out)
    assert errors == [], _summary(errors)
    assert [w["key"] for w in warnings] == ["NO_AUTHORS"]


def test_a_readme_of_ones_own_is_copied(store: Path, tmp_path: Path) -> None:
    mine = tmp_path / "README.txt"
    mine.write_text("Belt localisation, lab 3, spring cohort.\n\n" + "Participants felt a "
                    "direction on a six-motor belt and pointed to it with a joystick; "
                    "static and dynamic rendering of directions between two motors.\n" * 3)
    out = tmp_path / "bids"
    proc = tactorbelt("export", str(store), "-o", str(out), "--format", "bids",
                      "--readme", str(mine), "--authors", "A. Author, B. Author")
    assert proc.returncode == 0, proc.stderr
    assert (out / "README.txt").read_text() == mine.read_text()
    assert not (out / "README.md").exists()
    _clean(out)


# -- the demo, a resolution study and a load study, as `study init` writes them -------------------
def _demo(directory: Path, template: str | None = None, authors: str | None = None,
          participants: int = 1) -> Path:
    """``tactorbelt demo`` of the paper's protocol, or of a template made smaller (one
    repetition per block) and with ``authors`` at the top; returns the store."""
    args = ["demo", "-o", str(directory / "demo"), "--participants", str(participants)]
    if template is not None:
        study = directory / f"{template}.toml"
        proc = tactorbelt("study", "init", "--template", template, str(study))
        assert proc.returncode == 0, proc.stderr
        text, n = re.subn(r"(?m)^repetitions = 2\b", "repetitions = 1", study.read_text())
        assert n == 1
        if authors is not None:
            text = re.sub(r"(?m)^(name = .*)$", rf"\1\nauthors = {authors}", text, count=1)
        study.write_text(text)
        args += ["--study", str(study)]
    proc = tactorbelt(*args)
    assert proc.returncode == 0, proc.stderr
    return directory / "demo" / "study.sqlite"


@pytest.mark.slow
def test_the_demo_exports_with_authors_from_the_command_line(tmp_path: Path) -> None:
    db = _demo(tmp_path)
    out = tmp_path / "bids"
    proc = tactorbelt("export", str(db), "-o", str(out), "--format", "bids", "--authors",
                      "Ada Lovelace, Alan Turing")
    assert proc.returncode == 0, proc.stderr
    assert "  Authors: Ada Lovelace, Alan Turing (from --authors)" in proc.stdout
    assert "validator" not in proc.stderr.lower()  # no note: nothing it warns about
    _clean(out)


@pytest.mark.slow
def test_a_resolution_study_exports_cleanly(tmp_path: Path) -> None:
    db = _demo(tmp_path, "resolution", authors='["Ada Lovelace", "Grace Hopper"]')
    out = tmp_path / "bids"
    proc = tactorbelt("export", str(db), "-o", str(out), "--format", "bids")
    assert proc.returncode == 0, proc.stderr
    assert ("  Authors: Ada Lovelace, Grace Hopper (from the study file's authors; --authors "
            "'A, B' replaces them)") in proc.stdout
    _clean(out)
    beh = next(out.glob("sub-*/ses-1/beh/*_task-betweentactor_beh.tsv"))
    counts = {line.split("\t")[7] for line in beh.read_text().splitlines()[1:]}
    assert counts == {"12", "24", "36", "48"}  # n_targets: every cell of the design


@pytest.mark.slow
def test_a_load_study_exports_its_task_events_and_ratings_cleanly(tmp_path: Path) -> None:
    db = _demo(tmp_path, "load", authors='["Ada Lovelace", "Alan Turing"]', participants=2)
    out = tmp_path / "bids"
    proc = tactorbelt("export", str(db), "-o", str(out), "--format", "bids")
    assert proc.returncode == 0, proc.stderr
    assert "  events: 2 file(s) *_events.tsv" in proc.stdout
    assert "  ratings: 2 file(s) *_task-nasatlx_beh.tsv" in proc.stdout
    desc = json.loads((out / "dataset_description.json").read_text())
    assert desc["Authors"] == ["Ada Lovelace", "Alan Turing"]
    _clean(out)
    events = sorted(out.glob("sub-*/ses-1/beh/*_task-betweentactor_events.tsv"))
    ratings = sorted(out.glob("sub-*/ses-1/beh/*_task-nasatlx_beh.tsv"))
    assert len(events) == len(ratings) == 2
    rows = [line.split("\t") for line in events[0].read_text().splitlines()]
    assert rows[0][:3] == ["onset", "duration", "trial_type"]
    assert {r[2] for r in rows[1:]} <= {"go", "nogo", "extra_press"}
    assert {r[4] for r in rows[1:]} == {"practice", "baseline", "dual"}
    tlx = [line.split("\t") for line in ratings[0].read_text().splitlines()]
    assert len(tlx) == 1 + 4  # a row per test block
