"""`tactorbelt export` as a researcher meets it: never a silent merge into an old export.

Exporting into a directory that is not empty used to merge: four ``sub-*`` folders next
to a ``participants.tsv`` listing one. Now the export refuses (exit 2, saying what to
do), or ``--force`` replaces an earlier export, and only that.
"""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from support.cli import model_store, tactorbelt


@pytest.fixture(scope="module")
def stores(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """Two stores: P01 and P02; then P03 alone."""
    return (model_store(tmp_path_factory.mktemp("two"), participants=("P01", "P02")),
            model_store(tmp_path_factory.mktemp("one"), participants=("P03",)))


def _subjects(out: Path) -> tuple[list[str], list[str]]:
    with (out / "participants.tsv").open(newline="") as fh:
        listed = [r["participant_id"] for r in csv.DictReader(fh, delimiter="\t")]
    return sorted(p.name for p in out.glob("sub-*")), listed


def test_export_into_an_earlier_export_is_refused(stores: tuple[Path, Path],
                                                  tmp_path: Path) -> None:
    two, one = stores
    out = tmp_path / "bids"
    assert tactorbelt("export", str(two), "-o", str(out), "--format", "bids").returncode == 0
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    proc = tactorbelt("export", str(one), "-o", str(out), "--format", "bids")
    assert proc.returncode == 2
    assert proc.stderr.startswith(f"error: {out} is not empty")
    assert "--force" in proc.stderr and "Traceback" not in proc.stderr
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before


def test_force_replaces_the_earlier_export(stores: tuple[Path, Path], tmp_path: Path) -> None:
    two, one = stores
    out = tmp_path / "bids"
    assert tactorbelt("export", str(two), "-o", str(out), "--format", "bids").returncode == 0
    assert _subjects(out) == (["sub-P01", "sub-P02"], ["sub-P01", "sub-P02"])
    proc = tactorbelt("export", str(one), "-o", str(out), "--format", "bids", "--force")
    assert proc.returncode == 0, proc.stderr
    assert _subjects(out) == (["sub-P03"], ["sub-P03"])


def test_force_never_deletes_what_an_export_did_not_write(stores: tuple[Path, Path],
                                                          tmp_path: Path) -> None:
    two, _ = stores
    out = tmp_path / "results"
    out.mkdir()
    (out / "notes.txt").write_text("my notes")
    (out / "sessions.csv").write_text("old")
    for fmt in ("csv", "bids"):
        proc = tactorbelt("export", str(two), "-o", str(out), "--format", fmt, "--force")
        assert proc.returncode == 2
        assert "not from a tactorbelt" in proc.stderr and "notes.txt" in proc.stderr
    assert (out / "notes.txt").read_text() == "my notes"
    assert (out / "sessions.csv").read_text() == "old"


def test_csv_export_refuses_and_replaces_the_same_way(stores: tuple[Path, Path],
                                                      tmp_path: Path) -> None:
    two, one = stores
    out = tmp_path / "csv"
    assert tactorbelt("export", str(two), "-o", str(out)).returncode == 0
    proc = tactorbelt("export", str(one), "-o", str(out))
    assert proc.returncode == 2 and "is not empty" in proc.stderr
    assert tactorbelt("export", str(one), "-o", str(out), "--force").returncode == 0
    with (out / "sessions.csv").open(newline="") as fh:
        assert [r["participant"] for r in csv.DictReader(fh)] == ["P03"]


def test_the_old_positional_output_still_works(stores: tuple[Path, Path],
                                               tmp_path: Path) -> None:
    two, _ = stores
    proc = tactorbelt("export", str(two), str(tmp_path / "csv"))
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "csv" / "trials.csv").exists()
    proc = tactorbelt("export", str(two))
    assert proc.returncode == 2 and "-o DIRECTORY" in proc.stderr
