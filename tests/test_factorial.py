"""Factorial study files: [design] blocks, their order across participants, training over
every target count, [tasks.NAME], and one clear error (file, line, field) per bad input."""

from __future__ import annotations

import hashlib
import itertools
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from support.studies import make_study, study_toml, write_study
from tactorbelt import StudyFileError
from tactorbelt.experiment.description import describe
from tactorbelt.experiment.schedule import (
    block_order,
    make_schedule,
    schedule_from_json,
    schedule_to_json,
)
from tactorbelt.experiment.study import (
    Study,
    load_study,
    paper_study,
    plural,
    template_toml,
)
from tactorbelt.geometry import TargetSet

DESIGN: dict[str, Any] = {"targets": [12, 24, 36], "condition": ["static", "dynamic"],
                          "load": ["none", "nback2"], "repetitions": 2, "order": "williams"}
TASKS = {"nback2": {"kind": "nback", "n": 2, "modality": "auditory", "interval_s": 2.5}}


def factorial(**design: Any) -> Study:
    return make_study(design={**DESIGN, **design}, tasks=TASKS)


def test_design_is_the_full_factorial() -> None:
    s = factorial()
    cells = [(s.block_n_targets(b), b.condition, b.load, b.repetitions) for b in s.test]
    assert cells == [(n, c, ld, 2) for n, c, ld in itertools.product(
        [12, 24, 36], ["static", "dynamic"], ["none", "nback2"])]
    assert [b.label for b in s.test][:4] == [
        "static-12", "static-12-nback2", "dynamic-12", "dynamic-12-nback2"]
    assert s.n_test_trials() == 2 * 2 * 2 * (12 + 24 + 36)
    assert s.tasks["nback2"].kind == "nback"
    assert s.block_n_targets(s.test[-1]) == 36


def test_design_study_reads_back_from_its_toml() -> None:
    s = factorial(order="random")
    assert Study.from_toml(s.to_toml()) == s
    assert "[[test]]" not in s.to_toml()


def test_paper_toml_is_unchanged_by_the_new_tables() -> None:
    # the study hash of stored sessions is taken over to_toml() when no file is at hand
    assert "design" not in paper_study().to_toml()
    assert "load" not in paper_study().to_toml()
    assert hashlib.sha256(paper_study().to_toml().encode()).hexdigest()[:12] == \
        paper_study().sha256()[:12]


def test_schedule_has_the_block_target_count_and_load() -> None:
    s = factorial()
    sched = make_schedule(s, "P01", 1)
    test = [t for t in sched if t.block == "test"]
    assert len(test) == s.n_test_trials()
    for name, trials in itertools.groupby(test, key=lambda t: t.block_name):
        block = list(trials)
        n = block[0].n_targets
        assert {t.n_targets for t in block} == {n}
        assert Counter(t.target_deg for t in block) == {k * 360 / n: 2 for k in range(n)}
        assert {t.load for t in block} == {"nback2" if name.endswith("nback2") else "none"}
        assert block[0].target_set() == TargetSet.even(n)
    # on-tactor: a target on one of the 6 tactors (30 + 60k), at every count
    on = {(t.n_targets, t.target_deg) for t in test if t.on_tactor}
    assert on == {(n, a) for n in (12, 24, 36) for a in (30.0, 90.0, 150.0, 210.0, 270.0,
                                                          330.0)}


def test_training_covers_every_target_count_first() -> None:
    s = factorial()
    sched = make_schedule(s, "P02", 1)
    training = [t for t in sched if t.block == "training"]
    assert len(training) == s.n_training_trials() == 2 * (12 + 24 + 36)
    assert [t.n_targets for t in training] == [12] * 24 + [24] * 48 + [36] * 72
    assert {t.load for t in training} == {"none"}
    assert all(t.block == "training" for t in sched[:len(training)])


def test_factorial_schedule_is_pinned() -> None:
    # Golden: a stored factorial session must resume with the same trials.
    text = schedule_to_json(make_schedule(factorial(), "P03", 5))
    assert hashlib.sha256(text.encode()).hexdigest()[:16] == "5bbe8c52f2a6f1bf"


def test_old_stored_schedules_read_back() -> None:
    s = paper_study()
    sched = make_schedule(s, "P01", 1)
    old = schedule_to_json(sched).replace(',"n_targets":24,"load":"none"', "")
    assert "n_targets" not in old
    assert schedule_from_json(old, s) == sched


@pytest.mark.parametrize("k", range(2, 9))
def test_williams_order_is_balanced_across_participants(k: int) -> None:
    s = make_study(design={"targets": list(range(4, 4 + k)), "condition": ["static"],
                           "repetitions": 1, "order": "williams"}, training=0)
    rows = 2 * k if k % 2 else k
    orders = [block_order(s, f"P{p:02d}") for p in range(1, rows + 1)]
    assert len({tuple(o) for o in orders}) == rows
    for pos in range(k):  # every block once in each position per k participants
        assert set(Counter(o[pos] for o in orders).values()) == {rows // k}
    carry = Counter((a, b) for o in orders for a, b in itertools.pairwise(o))
    assert len(carry) == k * (k - 1)  # every block follows every other ...
    assert set(carry.values()) == {rows // k}  # ... equally often (twice for odd k's pair)
    assert block_order(s, f"P{rows + 1:02d}") == orders[0]


def test_latin_fixed_and_random_orders() -> None:
    latin = factorial(order="latin")
    orders = [block_order(latin, f"P{p}") for p in range(1, 13)]
    for pos in range(12):
        assert sorted(o[pos] for o in orders) == list(range(12))
    assert block_order(factorial(order="fixed"), "P07") == list(range(12))
    rnd = factorial(order="random")
    a = block_order(rnd, "P01")
    assert sorted(a) == list(range(12))
    assert a == block_order(rnd, "P01") != block_order(rnd, "P02")
    assert block_order(rnd, "P01", seed=2) != a
    assert next(t.block_name for t in make_schedule(rnd, "P01", 2) if t.block == "test") == \
        rnd.test[block_order(rnd, "P01", seed=2)[0]].label


def test_explicit_blocks_set_targets_load_and_stimulus() -> None:
    s = make_study(tasks=TASKS, blocks=[
        {"name": "coarse", "condition": "static", "repetitions": 1, "targets": 12},
        {"name": "fine", "condition": "dynamic", "repetitions": 1, "load": "nback2",
         "falloff_deg": 20.0},
    ])
    assert [s.block_n_targets(b) for b in s.test] == [12, 24]
    assert s.block_stimulus(s.test[1]).falloff_deg == 20.0
    assert s.block_stimulus(s.test[0]).falloff_deg == 15.0
    sched = make_schedule(s, "P01")
    assert {(t.block_name, t.n_targets, t.load) for t in sched if t.block == "test"} == {
        ("coarse", 12, "none"), ("fine", 24, "nback2")}
    assert Study.from_toml(s.to_toml()) == s


def test_no_load_and_questionnaire_parse() -> None:
    s = make_study(design={**DESIGN, "load": ["none"]}, questionnaire={"tlx": True})
    assert s.questionnaire.tlx is True
    assert {t.load for t in make_schedule(s, "P01")} == {"none"}


def test_templates() -> None:
    assert Study.from_toml(template_toml("paper")) == paper_study()
    r = Study.from_toml(template_toml("resolution"))
    assert r.design is not None and r.design.targets == [12, 24, 36, 48]
    assert r.design.order == "williams" and len(r.test) == 8
    assert 30 * 60 <= r.estimate_duration_s() <= 60 * 60
    with pytest.raises(Exception, match="paper, resolution"):
        template_toml("nope")


def test_describe_reports_cells_order_and_plurals() -> None:
    s = make_study(design={**DESIGN, "repetitions": 1}, tasks=TASKS, training=1)
    text = describe(s, "P02").to_text()
    assert "3 target counts x 2 conditions x 2 loads = 12 cells, 1 repetition of" in text
    assert "1 pass x 2 conditions x (12 + 24 + 36) targets" in text
    assert "static-12-nback2    12 trials (static, load nback2, 1 repetition x 12 targets)" \
        in text
    order = " -> ".join(s.test[i].label for i in block_order(s, "P02"))
    assert f"williams (balanced over 12 participants); P02: {order}" in text
    assert "duration    about" in text
    d = describe(paper_study())
    assert [c.trials for c in d.cells] == [120, 120]
    assert "5 repetitions x 24 targets" in d.to_text()
    assert (plural(1, "pass"), plural(2, "pass"), plural(3, "repetition")) == (
        "1 pass", "2 passes", "3 repetitions")


# -- bad input ---------------------------------------------------------------------


def _line(text: str, needle: str) -> int:
    return next(i for i, ln in enumerate(text.splitlines(), 1) if needle in ln)


# keywords for study_toml, field, the line's needle, message fragment
BAD: dict[str, tuple[dict[str, Any], str, str, str]] = {
    "zero count": ({"design": {**DESIGN, "targets": [12, 0]}}, "design.targets",
                   "targets = [12, 0]", "whole numbers from 1 to 360 (got 0)"),
    "negative count": ({"design": {**DESIGN, "targets": [-4]}}, "design.targets",
                       "targets = [-4]", "(got -4)"),
    "fractional count": ({"design": {**DESIGN, "targets": [12.5]}}, "design.targets",
                         "targets = [12.5]", "(got 12.5)"),
    "count over 360": ({"design": {**DESIGN, "targets": [400]}}, "design.targets",
                       "targets = [400]", "(got 400)"),
    "repeated count": ({"design": {**DESIGN, "targets": [12, 12]}}, "design.targets",
                       "targets = [12, 12]", "at most once"),
    "block count zero": ({"blocks": [{"condition": "static", "repetitions": 1,
                                      "targets": 0}]},
                         "test[0].targets", "targets = 0", "must be in [1, 360] (got 0)"),
    "block count float": ({"blocks": [{"condition": "static", "repetitions": 1,
                                       "targets": 8.0}]},
                          "test[0].targets", "targets = 8.0", "must be an integer"),
    "design and test": ({"design": DESIGN, "blocks": [{"condition": "static",
                                                       "repetitions": 1}]},
                        "design", "[design]", "not both"),
    "unknown load": ({"design": {**DESIGN, "load": ["none", "nbak2"]}}, "design.load[1]",
                     "load = [", "unknown load 'nbak2'"),
    "unknown block load": ({"tasks": TASKS, "blocks": [
        {"condition": "static", "repetitions": 1, "load": "nback3"}]},
        "test[0].load", "load = \"nback3\"", "did you mean 'nback2'?"),
    "misspelt repetitions": ({"blocks": [{"condition": "static", "repetitons": 1}]},
                             "test[0].repetitons", "repetitons",
                             "unknown key 'repetitons' (did you mean 'repetitions'?); "
                             "'repetitions' is required but missing"),
    "misspelt in design": ({"design": {**{k: v for k, v in DESIGN.items()
                                          if k != "repetitions"}, "repetitons": 1}},
                           "design.repetitons", "repetitons", "did you mean 'repetitions'?"),
    "bad order": ({"design": {**DESIGN, "order": "balanced"}}, "design.order",
                  "order = \"balanced\"", "'williams', 'latin', 'fixed' or 'random'"),
    "condition_order with design": ({"design": DESIGN, "condition_order": "latin"},
                                    "session.condition_order", "condition_order",
                                    "set design.order"),
    "bad task kind": ({"tasks": {"nback2": {"kind": "stroop"}}}, "tasks.nback2.kind",
                      "kind = \"stroop\"", "'nback', 'arithmetic' or 'none'"),
    "task interval": ({"tasks": {"nback2": {"kind": "nback", "interval_s": 0.0}}},
                      "tasks.nback2.interval_s", "interval_s = 0.0", "must be in (0, 60]"),
    "task named none": ({"tasks": {"none": {"kind": "none"}}}, "tasks.none", "[tasks.none]",
                        "not 'none'"),
    "too many blocks": ({"design": {**DESIGN, "targets": [4, 8, 12, 16, 20, 24, 28]}},
                        "design", "[design]", "28 blocks"),
    "block stimulus": ({"blocks": [{"condition": "dynamic", "repetitions": 1,
                                    "transit_s": 0.7}]},
                       "test[0]", "[[test]]", "2*transit_s"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_factorial_input(case: str, tmp_path: Path) -> None:
    kw, field, needle, fragment = BAD[case]
    if "design" in kw and "tasks" not in kw and case != "unknown load":
        kw = {**kw, "tasks": TASKS}
    path = write_study(tmp_path, **kw)
    text = path.read_text()
    with pytest.raises(StudyFileError) as info:
        load_study(path)
    err = info.value
    assert (err.path, err.field) == (str(path), field), str(err)
    assert err.line == _line(text, needle), str(err)
    assert fragment in str(err), str(err)


def test_unknown_load_lists_the_tasks(tmp_path: Path) -> None:
    path = write_study(tmp_path, design={**DESIGN, "load": ["none", "stroop"]}, tasks=TASKS)
    with pytest.raises(StudyFileError, match=r"use 'none', 'nback2', or declare \[tasks.stroop\]"):
        load_study(path)


def test_study_toml_builder_writes_design() -> None:
    text = study_toml(design=DESIGN, tasks=TASKS, questionnaire={"tlx": True})
    assert "[design]" in text and "[tasks.nback2]" in text and "[[test]]" not in text


# -- per-cell analysis ---------------------------------------------------------------


def _trials(study: Study, participants: list[str], noise: dict[str, int]) -> Any:
    """Trials of a simulated run: participant p answers ``noise[p]`` targets off (0: right)."""
    import pandas as pd

    rows = []
    for p in participants:
        for t in make_schedule(study, p, 1):
            step = 360.0 / t.n_targets
            resp = (t.target_deg + noise[p] * step * (t.repetition % 2)) % 360.0
            rows.append({"participant": p, "block": t.block, "condition": t.condition,
                         "status": "done", "target_deg": t.target_deg,
                         "response_target_deg": resp, "response_deg": resp,
                         "correct": float(resp == t.target_deg), "rt_s": 1.0 + t.n_targets / 100,
                         "on_tactor": t.on_tactor, "n_targets": t.n_targets, "load": t.load})
    return pd.DataFrame(rows)


def test_cell_summary_per_condition_count_and_load() -> None:
    from tactorbelt.analysis.tables.cells import CELL_COLUMNS, cell_summary

    s = factorial(repetitions=2)
    tr = _trials(s, ["P01", "P02"], {"P01": 0, "P02": 0})
    out = cell_summary(tr)
    assert list(out.columns) == CELL_COLUMNS
    assert [tuple(r) for r in out[["condition", "n_targets", "load"]].itertuples(index=False)] \
        == [(c, n, ld) for c in ("static", "dynamic") for n in (12, 24, 36)
            for ld in ("none", "nback2")]
    assert (out["n"] == 2 * 2 * out["n_targets"]).all()  # 2 participants x 2 repetitions
    assert (out["accuracy"] == 1.0).all() and (out["n_timeout"] == 0).all()
    assert np.allclose(out["it_bits_plain"], np.log2(out["n_targets"]))
    assert np.allclose(out["median_rt_s"], 1.0 + out["n_targets"] / 100)
    assert (out["mean_abs_error_deg"] == 0).all()
    assert (out["n_on_tactor"] == 2 * 2 * 6).all()
    assert (out["accuracy_between_tactor"] == 1.0).all()


def test_cell_information_transfer_is_per_participant_then_averaged() -> None:
    from tactorbelt.analysis.tables.cells import cell_summary, participant_cells

    s = make_study(design={**DESIGN, "targets": [12], "load": ["none"], "repetitions": 2},
                   training=0)
    # P01 right every time; P02 one target clockwise on odd repetitions: a consistent
    # bias that a pooled matrix would partly read as confusion
    tr = _trials(s, ["P01", "P02"], {"P01": 0, "P02": 1})
    per = participant_cells(tr)
    assert list(per["participant"]) == ["P01", "P01", "P02", "P02"]
    cell = cell_summary(tr).iloc[0]
    mine = per.loc[per["condition"] == cell["condition"], "it_bits"]
    assert cell["it_bits"] == pytest.approx(mine.mean())
    assert cell["accuracy"] == pytest.approx(0.75)
    assert cell["mean_abs_error_deg"] == pytest.approx(30.0 / 4)
    p1 = per.iloc[0]
    assert p1["it_bits_plain"] == pytest.approx(np.log2(12))


def test_old_trials_get_the_single_count_and_no_load() -> None:
    from tactorbelt.analysis.tables.cells import cell_summary
    from tactorbelt.analysis.tables.tables import infer_n_targets

    tr = _trials(paper_study(), ["P01"], {"P01": 0}).drop(columns=["n_targets", "load"])
    out = cell_summary(tr)
    assert list(out["n_targets"]) == [24, 24] and list(out["load"]) == ["none", "none"]
    assert infer_n_targets(np.array([0.0, 45.0, 90.0])) == 8
    assert cell_summary(tr, n_targets=24).equals(out)
