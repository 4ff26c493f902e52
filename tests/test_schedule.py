"""The schedule: deterministic, balanced, counterbalanced across participants."""

from __future__ import annotations

import hashlib
import itertools
import json
import subprocess
import sys
from collections import Counter

import pytest

from support.studies import make_study
from tactorbelt.experiment.schedule import (
    ScheduledTrial,
    block_order,
    make_schedule,
    participant_number,
    schedule_from_json,
    schedule_to_json,
    williams_square,
)
from tactorbelt.experiment.study import paper_study


def test_same_inputs_same_schedule() -> None:
    s = paper_study()
    assert make_schedule(s, "P01", 7) == make_schedule(s, "P01", 7)


def test_schedule_is_stable_across_processes_and_versions() -> None:
    # Golden values: changing them breaks resume of stored sessions' reproducibility claims.
    sched = make_schedule(paper_study(), "P01", 1)
    assert [t.target_deg for t in sched[48:56]] == [
        90.0, 330.0, 345.0, 15.0, 225.0, 315.0, 105.0, 300.0]
    code = ("from tactorbelt.experiment.schedule import make_schedule, schedule_to_json;"
            "from tactorbelt.experiment.study import paper_study;"
            "print(schedule_to_json(make_schedule(paper_study(), 'P01', 1)))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, env={"PYTHONHASHSEED": "123"})
    assert out.stdout.strip() == schedule_to_json(sched)


def test_participant_and_seed_change_the_order() -> None:
    s = paper_study()
    a = [t.target_deg for t in make_schedule(s, "P01", 1) if t.block == "test"]
    b = [t.target_deg for t in make_schedule(s, "P03", 1) if t.block == "test"]
    c = [t.target_deg for t in make_schedule(s, "P01", 2) if t.block == "test"]
    assert a != b and a != c


def test_structure_of_the_paper_schedule() -> None:
    s = paper_study()
    sched = make_schedule(s, "P01")
    assert len(sched) == 288
    assert [t.trial_index for t in sched] == list(range(288))
    training, test = sched[:48], sched[48:]
    assert all(t.block == "training" for t in training)
    assert all(t.block == "test" for t in test)
    # training: every target once per condition, going round the belt
    assert [t.target_deg for t in training[:24]] == [k * 15.0 for k in range(24)]
    assert Counter(t.condition for t in training) == {"static": 24, "dynamic": 24}
    # each test block: every target exactly 5 times, each repetition a permutation
    for cond in ("static", "dynamic"):
        block = [t for t in test if t.condition == cond]
        assert len(block) == 120
        assert Counter(t.target_deg for t in block) == {k * 15.0: 5 for k in range(24)}
        for rep in range(5):
            chunk = block[rep * 24:(rep + 1) * 24]
            assert {t.repetition for t in chunk} == {rep + 1}
            assert sorted(t.target_deg for t in chunk) == [k * 15.0 for k in range(24)]
    # blocks are contiguous
    assert [t.block_index for t in sched] == sorted(t.block_index for t in sched)


def test_on_tactor_flags() -> None:
    sched = make_schedule(paper_study(), "P01")
    on = {t.target_deg for t in sched if t.on_tactor}
    assert on == {30.0, 90.0, 150.0, 210.0, 270.0, 330.0}


def test_full_and_no_randomisation() -> None:
    full = make_schedule(make_study(randomise="full"), "P01")
    block = [t for t in full if t.block == "test" and t.condition == "static"]
    assert Counter(t.target_deg for t in block) == {k * 15.0: 5 for k in range(24)}
    none = make_schedule(make_study(randomise="none"), "P01")
    angles = [t.target_deg for t in none if t.block == "test" and t.condition == "static"]
    assert angles == [k * 15.0 for k in range(24)] * 5


def test_participant_number() -> None:
    assert participant_number("P07") == 7
    assert participant_number("s12b") == 12
    assert participant_number("anne") == participant_number("anne") > 0


def test_alternating_counterbalance() -> None:
    s = make_study(condition_order="alternate")
    first = {p: make_schedule(s, p)[48].condition for p in ("P01", "P02", "P03", "P04")}
    assert first == {"P01": "static", "P02": "dynamic", "P03": "static", "P04": "dynamic"}
    # training follows the participant's condition order
    assert make_schedule(s, "P02")[0].condition == "dynamic"


def test_fixed_order() -> None:
    s = make_study(condition_order="fixed")
    assert {make_schedule(s, p)[48].condition for p in ("P01", "P02", "P03")} == {"static"}


def test_block_randomisation_does_not_depend_on_block_position() -> None:
    s = make_study(condition_order="alternate")
    a = [t.target_deg for t in make_schedule(s, "P01") if t.block_name == "static"
         and t.block == "test"]
    # a different participant with the same hash input would be needed to compare orders;
    # instead: fixed and alternate give the same static block for the same participant
    b = [t.target_deg for t in make_schedule(make_study(condition_order="fixed"), "P01")
         if t.block_name == "static" and t.block == "test"]
    assert a == b


@pytest.mark.parametrize("k", [2, 3, 4, 5, 6])
def test_williams_square_is_balanced(k: int) -> None:
    rows = williams_square(k)
    assert len(rows) == (k if k % 2 == 0 else 2 * k)
    for row in rows:
        assert sorted(row) == list(range(k))
    for pos in range(k):
        counts = Counter(row[pos] for row in rows)
        assert set(counts.values()) == {len(rows) // k}
    carry = Counter((a, b) for row in rows for a, b in itertools.pairwise(row))
    assert set(carry.values()) == {len(rows) * (k - 1) // (k * (k - 1))}
    assert len(carry) == k * (k - 1)


def test_latin_square_over_participants() -> None:
    s = make_study(condition_order="latin", blocks=[
        {"name": "static", "condition": "static", "repetitions": 5},
        {"name": "dynamic", "condition": "dynamic", "repetitions": 5},
        {"name": "again", "condition": "static", "repetitions": 5},
    ])
    orders = [tuple(block_order(s, f"P{p:02d}")) for p in range(1, 7)]
    assert len(set(orders)) == 6  # 3 blocks: 2*3 distinct rows
    for pos in range(3):
        assert Counter(o[pos] for o in orders) == {0: 2, 1: 2, 2: 2}


def test_json_round_trip() -> None:
    sched = make_schedule(paper_study(), "P01")
    assert schedule_from_json(schedule_to_json(sched)) == sched


#: SHA-256 (first 16 hex digits) of the schedule JSON of [[test]] files, over the fields
#: a schedule had before factorial designs; pinned so that stored sessions resume the same.
_GOLDEN_FIELDS = ("trial_index", "block", "block_index", "block_name", "condition",
                  "repetition", "target_deg", "on_tactor")
_GOLDEN = {
    "paper P01 1": "1807fc2c529b1ce5",
    "paper P02 7": "8a4f1aeed0d65ea6",
    "paper anne None": "2162cda5215ce0d5",
    "latin3 P05 3": "a3954723fb565977",
    "full fixed P03 2": "eee60f17c4116fea",
}


def _golden_case(name: str) -> tuple[list[ScheduledTrial], str]:
    three = [{"name": "a", "condition": "static", "repetitions": 2},
             {"name": "b", "condition": "dynamic", "repetitions": 1},
             {"name": "c", "condition": "static", "repetitions": 1}]
    study, p, seed = {
        "paper P01 1": (paper_study(), "P01", 1),
        "paper P02 7": (paper_study(), "P02", 7),
        "paper anne None": (paper_study(), "anne", None),
        "latin3 P05 3": (make_study(condition_order="latin", blocks=three), "P05", 3),
        "full fixed P03 2": (make_study(randomise="full", condition_order="fixed",
                                        training_order="random"), "P03", 2),
    }[name]
    sched = make_schedule(study, p, seed)
    rows = [{k: d[k] for k in _GOLDEN_FIELDS} for d in json.loads(schedule_to_json(sched))]
    return sched, hashlib.sha256(json.dumps(rows, separators=(",", ":")).encode()).hexdigest()


@pytest.mark.parametrize("name", list(_GOLDEN))
def test_test_block_files_keep_their_pinned_schedule(name: str) -> None:
    sched, digest = _golden_case(name)
    assert digest[:16] == _GOLDEN[name]
