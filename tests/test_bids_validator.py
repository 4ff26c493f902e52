"""`tactorbelt export --format bids` passes the official BIDS validator.

The researcher's path: run a session, export it as BIDS with the CLI, run
``bids-validator`` (npm ``bids-validator@1.15.0``, installed by ``.ci/run``) on it: no
error and no warning of ours. Skipped, saying why, when the validator is not installed.
"""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import pytest

from support.cli import model_store, tactorbelt

VALIDATOR = shutil.which("bids-validator")

#: Warnings that are the validator's, not the export's. The legacy (1.x) validator reads
#: the first data row of a headerless ``_motion.tsv`` as column names and asks for their
#: description, although the BIDS motion spec says these files have no header (their
#: columns are the rows of ``_channels.tsv``): bids-standard/legacy-validator#1627, #1889.
NOT_OURS = {"CUSTOM_COLUMN_WITHOUT_DESCRIPTION": "_motion.tsv"}

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


def _ours(warnings: list[dict]) -> list[dict]:
    def theirs(w: dict) -> bool:
        suffix = NOT_OURS.get(w["key"])
        files = [f["file"]["relativePath"] for f in w["files"] if f.get("file")]
        return suffix is not None and bool(files) and all(f.endswith(suffix) for f in files)

    return [w for w in warnings if not theirs(w)]


def _summary(issues: list[dict]) -> str:
    return "; ".join(f"{i['key']}: {i.get('reason')} "
                     f"{[f.get('evidence') for f in i['files']][:2]}" for i in issues)


def test_the_bids_export_passes_the_validator(store: Path, tmp_path: Path) -> None:
    out = tmp_path / "bids"
    proc = tactorbelt("export", str(store), "-o", str(out), "--format", "bids",
                      "--authors", "Ada Lovelace, Alan Turing")
    assert proc.returncode == 0, proc.stderr
    errors, warnings = _validate(out)
    assert errors == [], _summary(errors)
    assert _ours(warnings) == [], _summary(_ours(warnings))
    desc = json.loads((out / "dataset_description.json").read_text())
    assert desc["Name"] == "first-use"
    assert desc["Authors"] == ["Ada Lovelace", "Alan Turing"]
    readme = (out / "README.md").read_text()
    for words in ("first-use", "Task", "rt_s", "latency", "LATENCY", "discontinuous"):
        assert words in readme


def test_without_authors_the_export_says_what_the_validator_will(store: Path,
                                                                 tmp_path: Path) -> None:
    out = tmp_path / "bids"
    proc = tactorbelt("export", str(store), "-o", str(out), "--format", "bids")
    assert proc.returncode == 0, proc.stderr
    assert "no --authors" in proc.stderr and "NO_AUTHORS" in proc.stderr
    errors, warnings = _validate(out)
    assert errors == [], _summary(errors)
    assert [w["key"] for w in _ours(warnings)] == ["NO_AUTHORS"]


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
    errors, warnings = _validate(out)
    assert errors == [] and _ours(warnings) == [], _summary(errors + _ours(warnings))
