"""A cognitive-load study end to end with model participants: the load template, the
demo, the stored task events and ratings, and what summary.json and the report say of
them (recomputed here from the raw rows)."""

from __future__ import annotations

import json
import sqlite3
import statistics
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from support.cli import tactorbelt
from tactorbelt.experiment.store import open_store
from tactorbelt.experiment.study import Study, load_study, template_toml
from tactorbelt.inputs.model import ModelCursor
from tactorbelt.participant.load import load_level
from tactorbelt.tasks import TLX_ITEMS, WorkloadInfo
from tactorbelt.tasks.schedule import TaskItem

PARTICIPANTS = 3


def _small_load_study() -> str:
    """The load template with one repetition per block and no training (fast)."""
    text = template_toml("load")
    for old, new in (("repetitions = 2                # every", "repetitions = 1       # every"),
                     ("passes = 1                # 0 = no", "passes = 0                # 0 = no")):
        assert old in text
        text = text.replace(old, new)
    return text


def test_study_init_writes_the_load_template(tmp_path: Path) -> None:
    path = tmp_path / "load.toml"
    proc = tactorbelt("study", "init", str(path), "--template", "load")
    assert proc.returncode == 0, proc.stderr
    assert path.read_text() == template_toml("load")
    s = load_study(path)
    assert s.target_counts() == [24]
    assert {(b.condition, b.load) for b in s.test} == {
        ("static", "none"), ("dynamic", "none"), ("static", "nback2"), ("dynamic", "nback2")}
    task = s.tasks["nback2"]
    assert (task.kind, task.n, task.modality) == ("nback", 2, "auditory")
    assert task.baseline > 0  # so the report has a dual-task cost
    assert s.questionnaire.tlx
    check = tactorbelt("study", "check", str(path))
    assert check.returncode == 0, check.stderr


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("load-demo")
    study = d / "load.toml"
    study.write_text(_small_load_study(), encoding="utf-8")
    proc = tactorbelt("demo", "-o", str(d / "out"), "--participants", str(PARTICIPANTS),
                      "--seed", "5", "--study", str(study))
    assert proc.returncode == 0, proc.stderr
    return d / "out"


def _rows(db: Path, sql: str) -> list[dict[str, Any]]:
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True)
    con.row_factory = sqlite3.Row
    try:
        return [dict(r) for r in con.execute(sql)]
    finally:
        con.close()


def _participants(db: Path) -> dict[int, str]:
    return {r["session_id"]: r["participant"]
            for r in _rows(db, "SELECT session_id, participant FROM sessions")}


def _z(p: float) -> float:
    return statistics.NormalDist().inv_cdf(p)


def test_the_demo_stores_task_events_of_every_phase_and_ratings_of_every_block(
        demo_dir: Path) -> None:
    db = demo_dir / "study.sqlite"
    study = Study.from_toml((demo_dir / "study.toml").read_text(), path="study.toml")
    spec = study.tasks["nback2"]
    with open_store(db) as store:
        events = store.task_events()
        ratings = store.ratings()
    assert len(_participants(db)) == PARTICIPANTS
    for sid in _participants(db):
        ev = [e for e in events if e["session_id"] == sid and e["item_index"] >= 0]
        phases = defaultdict(int)
        for e in ev:
            phases[e["phase"]] += 1
        assert phases["practice"] == spec.practice
        assert phases["baseline"] == spec.baseline
        assert phases["dual"] > 20  # the two loaded blocks, one item every 2.5 s
        presses = [e for e in ev if e["response"] == "press"]
        assert presses and all(0 < e["rt_s"] < spec.interval_s for e in presses)
        blocks = {r["block_index"] for r in ratings if r["session_id"] == sid}
        assert len(blocks) == len(study.test)  # TLX after every test block
        for b in blocks:
            items = {r["item"]: r["value"] for r in ratings
                     if r["session_id"] == sid and r["block_index"] == b}
            assert set(items) == set(TLX_ITEMS)
            assert all(0 <= v <= 100 for v in items.values())


def test_summary_secondary_tasks_are_the_counts_of_the_raw_events(demo_dir: Path) -> None:
    db = demo_dir / "study.sqlite"
    who = _participants(db)
    raw = _rows(db, "SELECT * FROM task_events")
    summary = json.loads((demo_dir / "summary.json").read_text())
    rows = {(r["participant"], r["phase"]): r for r in summary["secondary_tasks"]["rows"]}
    assert len(rows) == PARTICIPANTS * 3
    for (pid, phase), row in rows.items():
        ev = [e for e in raw if who[e["session_id"]] == pid and e["phase"] == phase
              and e["item_index"] >= 0]
        hits = sum(1 for e in ev if e["target"] and e["response"] == "press")
        misses = sum(1 for e in ev if e["target"] and e["response"] != "press")
        fa = sum(1 for e in ev if not e["target"] and e["response"] == "press")
        cr = sum(1 for e in ev if not e["target"] and e["response"] != "press")
        assert (row["hits"], row["misses"], row["false_alarms"], row["correct_rejections"]) \
            == (hits, misses, fa, cr)
        d = _z((hits + 0.5) / (hits + misses + 1)) - _z((fa + 0.5) / (fa + cr + 1))
        assert row["d_prime"] == pytest.approx(d, abs=1e-9)
        rts = [e["rt_s"] for e in ev if e["target"] and e["response"] == "press"]
        assert row["median_rt_s"] == pytest.approx(statistics.median(rts))
    (cost,) = summary["secondary_tasks"]["dual_task_cost"]
    assert cost["n_participants"] == PARTICIPANTS
    for p in cost["participants"]:
        assert p["d_prime_cost"] == pytest.approx(
            rows[(p["participant"], "baseline")]["d_prime"]
            - rows[(p["participant"], "dual")]["d_prime"])


def test_summary_tlx_is_the_mean_of_the_raw_ratings_and_higher_under_load(
        demo_dir: Path) -> None:
    db = demo_dir / "study.sqlite"
    who = _participants(db)
    load_of = {(r["session_id"], r["block_index"]): r["load"] for r in _rows(
        db, "SELECT DISTINCT session_id, block_index, load FROM trials WHERE block = 'test'")}
    per: dict[tuple[str, str], list[float]] = defaultdict(list)
    block_vals: dict[tuple[int, int], list[float]] = defaultdict(list)
    for r in _rows(db, "SELECT * FROM ratings WHERE scale = 'nasa_tlx'"):
        block_vals[(r["session_id"], r["block_index"])].append(r["value"])
    for (sid, b), vals in block_vals.items():
        per[(who[sid], load_of[(sid, b)])].append(sum(vals) / len(vals))
    summary = json.loads((demo_dir / "summary.json").read_text())
    tlx = summary["tlx"]
    assert tlx["loads"] == ["none", "nback2"]
    got = {(r["participant"], r["load"]): r["raw_tlx"] for r in tlx["per_participant"]}
    assert got.keys() == per.keys()
    for key, vals in per.items():
        assert got[key] == pytest.approx(sum(vals) / len(vals))
    for pid in set(who.values()):  # the model rates a 2-back block as more demanding
        assert got[(pid, "nback2")] > got[(pid, "none")]
    assert tlx["test"]["computed"] and tlx["test"]["n_participants"] == PARTICIPANTS
    assert tlx["test"]["p_value"] == pytest.approx(2 / 2**PARTICIPANTS)


def test_the_report_shows_the_load_section_and_its_figures(demo_dir: Path) -> None:
    html = (demo_dir / "report.html").read_text()
    for text in ("<h2>Cognitive load</h2>", "Localisation by load", "Secondary task",
                 "Dual-task cost", "Workload (raw NASA-TLX)", "load.png", "secondary.png",
                 "tlx.png"):
        assert text in html, text
    for name in ("load.png", "secondary.png", "tlx.png"):
        assert (demo_dir / name).stat().st_size > 1000
    summary = json.loads((demo_dir / "summary.json").read_text())
    assert {c["load"] for c in summary["cells"]} == {"none", "nback2"}
    people = json.loads((demo_dir / "participants.json").read_text())
    assert people["load_model"]["d_prime_nback"] == [3.5, 2.7, 1.8]  # what the model assumed


def test_analyze_of_the_demo_store_gives_the_same_task_results(demo_dir: Path,
                                                                tmp_path: Path) -> None:
    proc = tactorbelt("analyze", str(demo_dir / "study.sqlite"), "-o", str(tmp_path))
    assert proc.returncode == 0, proc.stderr
    a = json.loads((tmp_path / "summary.json").read_text())
    b = json.loads((demo_dir / "summary.json").read_text())
    assert a["secondary_tasks"] == b["secondary_tasks"] and a["tlx"] == b["tlx"]


def test_a_study_without_load_has_no_task_results(tmp_path: Path) -> None:
    from tactorbelt.app.demo import run_model_study
    from tactorbelt.experiment.study import PAPER_STUDY_TOML

    text = PAPER_STUDY_TOML.replace("repetitions = 5", "repetitions = 1").replace(
        "passes = 1 ", "passes = 0 ")
    run_model_study(tmp_path, 1, 3, study_toml=text)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["secondary_tasks"] is None and summary["tlx"] is None
    assert "Cognitive load" not in (tmp_path / "report.html").read_text()
    assert not (tmp_path / "tlx.png").exists()


def _cursor(seed: int = 11) -> ModelCursor:
    def sense(t0: int, t1: int) -> tuple[Any, Any]:
        raise AssertionError("no trial in this test")

    return ModelCursor(sense, seed)


def test_the_model_cursor_judges_items_from_the_stimuli_not_the_answer() -> None:
    study = Study.from_toml(template_toml("load"), path="load.toml")
    spec = study.tasks["nback2"]
    stimuli = ["tone1", "tone2", "tone1", "tone3", "tone1", "tone1", "tone5", "tone1"] * 40
    step = round(spec.interval_s * 1e9)

    def presses(lie: bool) -> list[int]:
        c = _cursor()
        c.task_phase(spec, "dual")
        out: list[int] = []
        for k, s in enumerate(stimuli):
            truth = k >= 2 and stimuli[k - 2] == s
            c.task_item(TaskItem(k, s, (not truth) if lie else truth), k * step)
            out += c.task_presses(k * step + step - 1)
        c.task_phase(None, None)
        return out

    honest = presses(False)
    assert honest == presses(True)  # item.target is never read
    go = {k for k, s in enumerate(stimuli) if k >= 2 and stimuli[k - 2] == s}
    pressed = {t // step for t in honest}
    assert len(pressed & go) > 0.6 * len(go)
    assert len(pressed - go) < 0.2 * (len(stimuli) - len(go))


def test_the_model_cursor_localises_with_the_loaded_observer_only_in_dual_phase() -> None:
    study = Study.from_toml(template_toml("load"), path="load.toml")
    spec = study.tasks["nback2"]
    c = _cursor()
    base = c.active_params
    c.task_phase(spec, "practice")  # the task alone: no trial runs
    assert c.active_params == base
    c.task_phase(spec, "dual")
    assert c.load_level == load_level(spec)
    assert c.active_params.weber_amplitude > base.weber_amplitude
    assert c.active_params.nondecision_s > base.nondecision_s
    c.task_phase(None, None)
    assert c.active_params == base


def test_the_model_cursor_rates_a_loaded_block_higher() -> None:
    study = Study.from_toml(template_toml("load"), path="load.toml")
    c = _cursor()
    none = [np.mean(list(v.values())) for v in (
        c.rate_workload(WorkloadInfo(i, "static-24", "static", 24, "none")) for i in range(40))
        if v is not None]
    loaded = [np.mean(list(v.values())) for v in (
        c.rate_workload(WorkloadInfo(i, "static-24-nback2", "static", 24, "nback2",
                                     study.tasks["nback2"])) for i in range(40))
        if v is not None]
    assert len(none) == len(loaded) == 40
    assert np.mean(loaded) > np.mean(none) + 10


def test_power_plans_a_load_study_with_the_loaded_model(tmp_path: Path) -> None:
    from tactorbelt.power.study import run_power_study

    study = Study.from_toml(_small_load_study(), path="load.toml")
    result = run_power_study(study, [4], 3, 2, tmp_path, jobs=1)
    doc = json.loads((tmp_path / "power.json").read_text())
    assert "loads" in doc and "under that load" in doc["loads"]
    assert result.rows[0].sims == 3
    assert any("under that load" in n for n in result.notes)


def test_power_finds_the_models_load_effect_and_names_its_columns(tmp_path: Path) -> None:
    from tactorbelt import ConfigError
    from tactorbelt.experiment.study import paper_study
    from tactorbelt.power.study import run_power_study

    study = Study.from_toml(_small_load_study(), path="load.toml")
    result = run_power_study(study, [8], 20, 3, tmp_path, jobs=1, effect="load nback2")
    (row,) = result.rows
    assert result.pair == ("loaded", "no_load")
    assert row.static_acc < row.dynamic_acc  # under load below without, as the model says
    assert row.power > 0.5
    header = (tmp_path / "power.csv").read_text().splitlines()[0]
    assert "mean_loaded_between_acc,mean_no_load_between_acc" in header
    doc = json.loads((tmp_path / "power.json").read_text())
    assert {"loaded_acc", "no_load_acc"} <= set(doc["rows"][0])
    assert "under load nback2" in doc["test"]
    with pytest.raises(ConfigError, match="no load 'nback3'"):
        run_power_study(study, [4], 2, 3, tmp_path, jobs=1, effect="load nback3")
    with pytest.raises(ConfigError, match="blocks without a load and blocks under one"):
        run_power_study(paper_study(), [4], 2, 3, tmp_path, jobs=1, effect="load")
