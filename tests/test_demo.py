"""``tactorbelt demo`` and ``tactorbelt power``: outputs, agreement with the raw trials,
reproducibility, running twice, and bad input."""

from __future__ import annotations

import csv
import json
import sqlite3
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from tactorbelt.cli import main


@click.command(context_settings={"ignore_unknown_options": True, "allow_extra_args": True})
@click.pass_context
def _entry(ctx: click.Context) -> None:
    main(ctx.args)


def run(*args: str) -> tuple[int, str, str]:
    """Run the CLI in-process like the console script; (exit code, stdout, stderr)."""
    result = CliRunner().invoke(_entry, list(args), catch_exceptions=False)
    return result.exit_code, result.stdout, result.stderr


@pytest.fixture(scope="module")
def demo_dir(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str]:
    out = tmp_path_factory.mktemp("demo") / "out"
    code, stdout, stderr = run("demo", "--out", str(out), "--participants", "2", "--seed", "3")
    assert code == 0, stderr
    return out, stdout


def test_demo_writes_every_output_named_in_design(demo_dir: tuple[Path, str]) -> None:
    out, stdout = demo_dir
    for name in ("study.toml", "study.sqlite", "report.html", "summary.json", "per_target.csv"):
        assert (out / name).is_file(), name
    pngs = list(out.glob("*.png"))
    assert pngs
    for png in pngs:
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    html = (out / "report.html").read_text(encoding="utf-8")
    assert "data:image/png;base64," in html
    assert "report:" in stdout and "between-tactor" in stdout
    people = json.loads((out / "participants.json").read_text())
    assert sorted(people["participants"]) == ["model-01", "model-02"]
    assert "no evidence about people" in people["note"]


def test_demo_leaves_only_the_store_and_its_outputs(demo_dir: tuple[Path, str]) -> None:
    out, _ = demo_dir
    names = {p.name for p in out.iterdir()}
    assert {n for n in names if "sqlite" in n} == {"study.sqlite"}  # no -wal, -shm, .lock
    assert names - {"study.sqlite"} <= {"study.toml", "participants.json", "report.html",
                                        "summary.json", "per_target.csv"} | {
        p.name for p in out.glob("*.png")}


def test_analyze_on_the_demo_store_reproduces_the_demo_report(
        demo_dir: tuple[Path, str], tmp_path: Path) -> None:
    out, _ = demo_dir
    code, _, stderr = run("analyze", str(out / "study.sqlite"), "--out", str(tmp_path))
    assert code == 0, stderr
    demo = json.loads((out / "summary.json").read_text())
    again = json.loads((tmp_path / "summary.json").read_text())
    assert again == demo
    assert again["provenance"]["analysis_seed"] == 3  # the demo's --seed, derived from its sessions
    assert (tmp_path / "per_target.csv").read_text() == (out / "per_target.csv").read_text()
    assert {p.name for p in out.iterdir() if "sqlite" in p.name} == {"study.sqlite"}
    # export reads it too and leaves nothing behind
    assert run("export", str(out / "study.sqlite"), str(tmp_path / "csv"))[0] == 0
    assert {p.name for p in out.iterdir() if "sqlite" in p.name} == {"study.sqlite"}


def test_demo_numbers_agree_with_the_raw_trials(demo_dir: tuple[Path, str]) -> None:
    out, _ = demo_dir
    summary = json.loads((out / "summary.json").read_text())
    with sqlite3.connect(out / "study.sqlite") as db:
        rows = db.execute(
            "SELECT condition, on_tactor, AVG(correct), COUNT(*) FROM trials "
            "WHERE block = 'test' AND status != 'aborted' GROUP BY condition, on_tactor"
        ).fetchall()
        sessions = db.execute("SELECT participant, status FROM sessions").fetchall()
    assert sorted(sessions) == [("model-01", "complete"), ("model-02", "complete")]
    assert len(rows) == 4
    for condition, on_tactor, accuracy, n in rows:
        kind = "on_tactor" if on_tactor else "between_tactor"
        cell = summary["conditions"][condition][kind]
        assert cell["n"] == n
        assert cell["accuracy"] == pytest.approx(accuracy, abs=1e-9)
    # the model's qualitative result (from its assumptions, not evidence about people)
    c = summary["conditions"]
    assert c["dynamic"]["between_tactor"]["accuracy"] > c["static"]["between_tactor"]["accuracy"]
    assert c["dynamic"]["between_tactor"]["median_rt_s"] > c["static"]["between_tactor"][
        "median_rt_s"]
    with (out / "per_target.csv").open(newline="") as fh:
        per_target = list(csv.DictReader(fh))
    assert {"participant", "condition", "target_deg", "on_tactor", "n", "accuracy",
            "median_rt_s", "mean_signed_error_deg"} <= set(per_target[0])
    assert len(per_target) == 2 * 2 * 24


def test_demo_is_reproducible_and_runs_twice_in_a_row(tmp_path: Path) -> None:
    out = tmp_path / "again"
    assert run("demo", "--out", str(out), "--seed", "5")[0] == 0
    code, _, stderr = run("demo", "--out", str(out), "--seed", "5")
    assert code == 0, stderr
    assert "previous store was moved" in stderr
    query = ("SELECT trial_index, target_deg, response_deg, rt_s, correct FROM trials "
             "ORDER BY trial_index")
    with sqlite3.connect(out / "study.sqlite") as new, \
            sqlite3.connect(out / "study.previous.sqlite") as old:
        assert new.execute(query).fetchall() == old.execute(query).fetchall()
        assert new.execute("SELECT COUNT(*) FROM sessions").fetchone() == (1,)


def test_power_writes_table_and_plot(tmp_path: Path) -> None:
    out = tmp_path / "power"
    code, stdout, stderr = run("power", "--participants", "4,6", "--sims", "3", "--out",
                               str(out), "--jobs", "1", "--seed", "2")
    assert code == 0, stderr
    with (out / "power.csv").open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["participants"] for r in rows] == ["4", "6"]
    assert all(r["sims"] == "3" for r in rows)
    assert all(0.0 <= float(r["power"]) <= 1.0 for r in rows)
    assert rows[0]["power"] == "0.0000"  # 4 pairs: the exact test cannot reach p < 0.05
    assert (out / "power.png").read_bytes()[:4] == b"\x89PNG"
    doc = json.loads((out / "power.json").read_text())
    assert doc["sims"] == 3 and "Wilcoxon" in doc["test"]
    assert "participants" in stdout and "power" in stdout


@pytest.mark.parametrize(("args", "message"), [
    (("power", "--participants", "1,x"), "--participants"),
    (("power", "--participants", "4", "--sims", "0"), "--sims"),
    (("demo", "--participants", "0"), "--participants"),
])
def test_bad_input_is_a_clear_error(args: tuple[str, ...], message: str) -> None:
    with pytest.raises(SystemExit) as exc:
        main(list(args))
    assert exc.value.code == 2


def test_demo_out_must_be_a_directory(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(SystemExit) as exc:
        main(["demo", "--out", str(f)])
    assert exc.value.code == 2
    assert "error:" in capsys.readouterr().err


def test_power_needs_both_conditions(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from tactorbelt.experiment.study import PAPER_STUDY_TOML

    text = PAPER_STUDY_TOML.split("[[test]]")[0] + (
        '[[test]]\nname = "static"\ncondition = "static"\nrepetitions = 5\n')
    study = tmp_path / "static-only.toml"
    study.write_text(text)
    with pytest.raises(SystemExit) as exc:
        main(["power", "--study", str(study), "--sims", "1", "--out", str(tmp_path / "p")])
    assert exc.value.code == 2
    assert "static and a dynamic" in capsys.readouterr().err


def test_help_mentions_models(capsys: pytest.CaptureFixture[str]) -> None:
    for command, word in (("demo", "model participants"), ("power", "--sims")):
        try:
            main([command, "--help"])
        except SystemExit as exc:
            assert exc.code == 0
        assert word in capsys.readouterr().out


def test_one_seed_policy_for_the_model_participants(demo_dir: tuple[Path, str]) -> None:
    from tactorbelt.app.demo import model_participants
    from tactorbelt.experiment.study import paper_study
    from tactorbelt.participant.params import ModelParams

    out, _ = demo_dir
    base = ModelParams().for_period(paper_study().stimulus.period_s)
    people = model_participants(2, 3, base)  # the demo ran with --seed 3
    stored = json.loads((out / "participants.json").read_text())["participants"]
    assert {p.pid: p.cursor_seed for p in people} == {k: v["seed"] for k, v in stored.items()}
    assert people[0].params.to_dict() == stored["model-01"]["params"]
    assert model_participants(2, 4, base)[0].cursor_seed != people[0].cursor_seed


def test_power_plans_a_factorial_study_for_a_named_effect(tmp_path: Path) -> None:
    study = tmp_path / "resolution.toml"
    assert run("study", "init", str(study), "--template", "resolution")[0] == 0
    out = tmp_path / "power"
    code, stdout, stderr = run("power", "--study", str(study), "--participants", "6,8",
                               "--sims", "3", "--jobs", "1", "--out", str(out),
                               "--effect", "dynamic vs static at 36")
    assert code == 0, stderr
    doc = json.loads((out / "power.json").read_text())
    assert doc["effect"] == "dynamic vs static at 36"
    assert "36-target blocks" in doc["test"] and doc["target_counts"] == [12, 24, 36, 48]
    assert [r["n_participants"] for r in doc["rows"]] == [6, 8]
    # the model finds dynamic far better than static at 36 targets
    assert all(r["dynamic_acc"] > r["static_acc"] + 0.2 for r in doc["rows"])
    assert "Power of 'dynamic vs static at 36'" in stdout
    code, _, stderr = run("power", "--study", str(study), "--participants", "6", "--sims",
                          "2", "--jobs", "1", "--out", str(out), "--effect", "interaction")
    assert code == 0, stderr
    assert "Friedman" in json.loads((out / "power.json").read_text())["test"]
    code, _, stderr = run("power", "--study", str(study), "--participants", "6", "--sims",
                          "2", "--out", str(out), "--effect", "dynamic vs static at 30")
    assert code == 2 and "no blocks of 30 targets" in stderr


def test_power_gives_the_same_numbers_whatever_the_number_of_processes(tmp_path: Path) -> None:
    docs = []
    for jobs in ("1", "2"):
        out = tmp_path / f"jobs{jobs}"
        code, _, stderr = run("power", "--participants", "4,6", "--sims", "60", "--seed", "3",
                              "--jobs", jobs, "--out", str(out))
        assert code == 0, stderr
        doc = json.loads((out / "power.json").read_text())
        docs.append(doc["rows"])
    assert docs[0] == docs[1]  # to the last bit: summed in the work's order
