"""A study factor declared in one place reaches everything that handles factors.

The test declares ``posture`` (recorded, it changes nothing a session plays) with
:func:`tactorbelt.factors.registered` and nothing else: the study file crosses it in
``[design]``, the schedule carries it, the store keeps it in its own column (a store
opened before the declaration gains the column), every export writes and describes it,
the LSL markers carry it, the cells and the mixed model take it as a factor, and the
power analysis crosses it. What the test touches is the declaration and this file
(docs/architecture.md, "Adding things").
"""

from __future__ import annotations

import csv
import json
import sqlite3
from collections.abc import Iterator
from pathlib import Path

import pytest

from tactorbelt.cli import main
from tactorbelt.experiment.schedule import make_schedule
from tactorbelt.experiment.study import Study
from tactorbelt.factors import Factor, factors, registered

POSTURE = Factor(
    key="posture", column="posture", type="text",
    description="The wearer's posture during the block.",
    levels={"sitting": "seated on a chair, back against it",
            "standing": "standing upright, feet apart"},
)

STUDY = """
name = "posture"
[layout]
tactors = 6
[targets]
count = 6
[response]
timeout_s = 10.0
[session]
seed = 3
iti_s = 0.2
break_every = 0
[training]
passes = 1
conditions = ["static"]
[design]
targets = [6]
condition = ["static", "dynamic"]
posture = ["sitting", "standing"]
repetitions = 3
order = "latin"
"""
PARTICIPANTS = ("P01", "P02", "P03", "P04")


def _cli(*args: str) -> None:
    try:
        main(list(args))
    except SystemExit as exc:
        assert not exc.code, f"tactorbelt {' '.join(args)} exited {exc.code}"


@pytest.fixture(scope="module")
def posture() -> Iterator[Factor]:
    with registered(POSTURE) as f:
        yield f
    assert POSTURE not in factors()


@pytest.fixture(scope="module")
def study_file(posture: Factor, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("posture") / "posture.toml"
    path.write_text(STUDY, encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def store(study_file: Path) -> Path:
    db = study_file.parent / "posture.sqlite"
    for pid in PARTICIPANTS:
        _cli("run", str(study_file), "-p", pid, "--headless", "--input", "model",
             "--db", str(db))
    return db


def test_the_design_crosses_the_declared_factor(study_file: Path) -> None:
    study = Study.from_toml(study_file.read_text(), path=study_file)
    assert [b.label for b in study.test] == [
        "static-6-sitting", "static-6-standing", "dynamic-6-sitting", "dynamic-6-standing"]
    assert Study.from_toml(study.to_toml()) == study  # written back as a key of its own
    trials = make_schedule(study, "P01")
    test = [t for t in trials if t.block == "test"]
    assert {t.level(POSTURE) for t in test} == {"sitting", "standing"}
    assert all(t.level(POSTURE) == t.block_name.split("-")[-1] for t in test)
    # training has no posture of its own: the factor's default (none here)
    assert {t.level(POSTURE) for t in trials if t.block == "training"} == {None}


def test_a_level_the_declaration_does_not_allow_is_refused(posture: Factor) -> None:
    bad = STUDY.replace('["sitting", "standing"]', '["sitting", "lying"]')
    with pytest.raises(Exception, match=r"design\.posture.*unknown posture 'lying'"):
        Study.from_toml(bad, path="bad.toml")


def test_the_store_keeps_it_in_its_own_column(store: Path) -> None:
    with sqlite3.connect(store) as c:
        rows = c.execute("SELECT block, block_name, posture FROM trials").fetchall()
    assert len(rows) == len(PARTICIPANTS) * (6 + 4 * 6 * 3)
    for block, name, level in rows:
        assert level == (None if block == "training" else name.split("-")[-1])


def test_every_export_writes_it(store: Path, tmp_path: Path) -> None:
    _cli("export", str(store), "-o", str(tmp_path / "csv"))
    with (tmp_path / "csv" / "trials.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert {r["posture"] for r in rows if r["block"] == "test"} == {"sitting", "standing"}

    _cli("export", str(store), "-o", str(tmp_path / "pq"), "--format", "parquet")
    import pandas as pd
    pq = pd.read_parquet(tmp_path / "pq" / "trials.parquet")
    assert set(pq.loc[pq["block"] == "test", "posture"]) == {"sitting", "standing"}

    _cli("export", str(store), "-o", str(tmp_path / "tidy"), "--format", "tidy")
    tidy = pd.read_csv(tmp_path / "tidy" / "trials_tidy.csv")
    assert set(tidy["posture"].dropna()) == {"sitting", "standing"}
    codebook = (tmp_path / "tidy" / "codebook.csv").read_text()
    assert "posture" in codebook and POSTURE.description in codebook

    _cli("export", str(store), "-o", str(tmp_path / "psychopy"), "--format", "psychopy")
    first = sorted((tmp_path / "psychopy").glob("*.csv"))[0]
    with first.open(newline="") as fh:
        assert {r["posture"] for r in csv.DictReader(fh)} >= {"sitting", "standing"}

    _cli("export", str(store), "-o", str(tmp_path / "bids"), "--format", "bids",
         "--authors", "A. Author")
    beh = sorted((tmp_path / "bids").rglob("*_beh.tsv"))[0]
    with beh.open(newline="") as fh:
        assert {r["posture"] for r in csv.DictReader(fh, delimiter="\t")} >= {
            "sitting", "standing"}
    sidecar = json.loads(beh.with_suffix(".json").read_text())
    assert sidecar["posture"]["Description"] == POSTURE.description
    assert sidecar["posture"]["Levels"] == dict(POSTURE.levels)


def test_the_analysis_models_it(store: Path, tmp_path: Path) -> None:
    _cli("analyze", str(store), "-o", str(tmp_path), "--bootstrap-sims", "0")
    summary = json.loads((tmp_path / "summary.json").read_text())
    model = summary["mixed_model"]
    assert model["formula"].startswith("correct ~ condition * posture + ")
    assert set(model["fixed_effects"]) >= {"posturestanding", "conditionstatic:posturestanding"}
    cells = {(c["condition"], c["posture"]): c for c in summary["cells"]}
    assert set(cells) == {(c, p) for c in ("static", "dynamic") for p in ("sitting", "standing")}
    assert all(c["n"] == len(PARTICIPANTS) * 6 * 3 for c in cells.values())
    report = (tmp_path / "report.html").read_text()
    assert "Results by cell (condition x targets x load x posture)" in report
    assert (tmp_path / "resolution.png").exists()


def test_lme4_fits_the_same_model(store: Path, tmp_path: Path) -> None:
    import shutil
    if shutil.which("Rscript") is None:
        pytest.skip("R is not installed (apt install r-base-core r-cran-lme4)")
    fits = {}
    for engine in ("tactorbelt", "lme4"):
        _cli("analyze", str(store), "-o", str(tmp_path / engine), "--engine", engine,
             "--bootstrap-sims", "0")
        fits[engine] = json.loads((tmp_path / engine / "summary.json").read_text())[
            "mixed_model"]
    ours, theirs = fits["tactorbelt"], fits["lme4"]
    fixed = "correct ~ condition * posture + "
    assert ours["formula"].startswith(fixed) and theirs["formula"].startswith(fixed)
    # the random parts may be simplified differently (a near-singular participant
    # slope); the posture terms barely depend on it
    for term in ("posturestanding", "conditionstatic:posturestanding"):
        a, b = ours["fixed_effects"][term], theirs["fixed_effects"][term]
        assert a["estimate"] == pytest.approx(b["estimate"], abs=0.05 + 0.05 * abs(b["estimate"]))
        assert a["se"] == pytest.approx(b["se"], rel=0.1)


def test_the_lsl_markers_carry_it(posture: Factor) -> None:
    from tactorbelt.lsl import marker_fields
    for marker in ("block_start", "trial_start", "stimulus_onset"):
        assert "posture" in marker_fields(marker)


def test_an_installed_package_declares_a_factor_for_the_command_line(tmp_path: Path) -> None:
    """A package with an entry point in ``tactorbelt.factors`` declares it for every
    command, with no code run by the user."""
    import subprocess
    import sys

    site = tmp_path / "site"
    dist = site / "toyposture-0.1.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: toyposture\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text("[tactorbelt.factors]\nposture = toyposture:POSTURE\n")
    (site / "toyposture.py").write_text(
        "from tactorbelt.factors import Factor\n"
        f"POSTURE = Factor(key='posture', column='posture', type='text', "
        f"description={POSTURE.description!r}, levels={dict(POSTURE.levels)!r})\n")
    study = tmp_path / "posture.toml"
    study.write_text(STUDY, encoding="utf-8")
    proc = subprocess.run([sys.executable, "-m", "tactorbelt", "study", "check", str(study)],
                          env={"PYTHONPATH": str(site), "PATH": "/usr/bin:/bin"},
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "x 2 posture levels = 4 cells" in proc.stdout
    assert "static-6-standing" in proc.stdout

    (dist / "entry_points.txt").write_text("[tactorbelt.factors]\nposture = toyposture:nothing\n")
    proc = subprocess.run([sys.executable, "-m", "tactorbelt", "study", "check", str(study)],
                          env={"PYTHONPATH": str(site), "PATH": "/usr/bin:/bin"},
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "entry point posture = toyposture:nothing" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_the_built_in_declarations_match_what_they_declare() -> None:
    from tactorbelt.experiment.store.schema import table
    from tactorbelt.factors import BUILTIN, CONDITION
    from tactorbelt.stimuli import MODES

    assert tuple(CONDITION.levels) == MODES
    columns = {c.name: c for c in table("trials").columns}
    for f in BUILTIN:
        assert columns[f.column].type == f.type


def test_the_power_analysis_crosses_it(study_file: Path, tmp_path: Path) -> None:
    from tactorbelt.power.design import PowerDesign

    design = PowerDesign.from_study(Study.from_toml(study_file.read_text()))
    assert [b.levels["posture"] for b in design.blocks] == [
        "sitting", "standing", "sitting", "standing"]
    trials = design.trials()
    assert sorted(set(trials.levels["posture"])) == ["sitting", "standing"]
    _cli("power", "--study", str(study_file), "--participants", "4", "--sims", "2",
         "--odds-ratio", "2", "--jobs", "1", "--out", str(tmp_path))
    doc = json.loads((tmp_path / "power.json").read_text())
    assert doc["formula"].startswith("correct ~ condition * posture + ")


def test_a_factor_cannot_take_a_name_in_use_nor_change_what_is_played() -> None:
    from tactorbelt._errors import ConfigError
    from tactorbelt.experiment.export import BEH_COLUMNS, DTYPES, TLX_COLUMNS
    from tactorbelt.experiment.export_formats import PSYCHOPY_COLUMNS, TIDY_COLUMNS
    from tactorbelt.experiment.store.schema import table
    from tactorbelt.experiment.study import BlockSpec, DesignSpec
    from tactorbelt.factors import BUILTIN, RESERVED, register

    builtin = {n for f in BUILTIN for n in (f.key, f.column)}
    used = ({c.name for t in ("trials", "samples") for c in table(t, added=False).columns}
            | set(DTYPES["trials"]) | set(BEH_COLUMNS) | set(TLX_COLUMNS)
            | {c[0] for c in TIDY_COLUMNS}
            | {c for c in PSYCHOPY_COLUMNS if c.islower() and "." not in c}
            | set(BlockSpec.model_fields) | set(DesignSpec.model_fields))
    assert used - builtin <= RESERVED
    for name in ("status", "rt_s", "name", "target", "levels"):
        with pytest.raises(ConfigError, match="a name tactorbelt uses already"):
            register(Factor(key=name, column=name, type="text", description="x"))
    with pytest.raises(ConfigError, match="changes nothing a session plays"):
        register(Factor(key="speed", column="speed", type="text", description="x",
                        changes="stimulus"))
    assert not {"status", "rt_s", "name", "target", "levels", "speed"} & {
        f.key for f in factors()}
