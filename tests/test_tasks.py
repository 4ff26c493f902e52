"""Secondary tasks, pure parts: the study file's [tasks.NAME], the item sequences, the
scoring of presses and a task run's schedule (independent of the trials' timing)."""

from __future__ import annotations

import itertools
import random
from pathlib import Path
from typing import Any

import pytest

from support.studies import make_study, write_study
from tactorbelt import ConfigError, StudyFileError
from tactorbelt.experiment.study import TaskSpec, load_study
from tactorbelt.tasks import TLX_ITEMS, check_tlx
from tactorbelt.tasks.kinds.nback import NBACK_LETTERS, NBACK_TONES
from tactorbelt.tasks.schedule import TaskItem, classify, item_sequence
from tactorbelt.tasks.session import TaskSession

MS = 1_000_000


def _load_error(tmp_path: Path, **task: Any) -> StudyFileError:
    path = write_study(tmp_path, tasks={"nb": {"kind": "nback", **task}},
                       design={"targets": [8], "condition": ["static"],
                               "load": ["none", "nb"], "repetitions": 1})
    with pytest.raises(StudyFileError) as info:
        load_study(path)
    return info.value


def _line_of(path: Path, key: str) -> int:
    lines = path.read_text().splitlines()
    start = lines.index("[tasks.nb]")
    return next(i + 1 for i, line in enumerate(lines) if i > start
                and line.startswith(f"{key} ="))


@pytest.mark.parametrize(("task", "field", "words"), [
    ({"n": 4}, "n", "n must be 1, 2 or 3"),
    ({"n": 0}, "n", "n must be 1, 2 or 3"),
    ({"kind": "nbak"}, "kind", "'nback', 'arithmetic' or 'none'"),
    ({"interval_s": 0.4}, "interval_s", "must be longer than stimulus_s (0.5 s)"),
    ({"interval_s": 1.0, "stimulus_s": 1.0}, "interval_s", "must be longer than stimulus_s"),
    ({"response": "pedal:1"}, "response", "unknown response"),
    ({"match_rate": 1.0}, "match_rate", "must be in (0, 1)"),
    ({"practice": 201}, "practice", "must be in [0, 200]"),
])
def test_bad_task_fields_name_the_file_line_and_field(tmp_path: Path, task: dict[str, Any],
                                                       field: str, words: str) -> None:
    err = _load_error(tmp_path, **task)
    path = tmp_path / "study.toml"
    assert err.path == str(path)
    assert err.field == f"tasks.nb.{field}"
    assert err.line == _line_of(path, next(iter(task)))
    assert words in str(err)
    assert str(err).startswith(f"{path}:{err.line}: tasks.nb.{field}: ")


@pytest.mark.parametrize("response", ["key:space", "key:return", "key:enter", "joystick:0",
                                      "mouse:left", "Joystick:0"])
def test_the_buttons_that_confirm_a_localisation_are_refused(tmp_path: Path,
                                                              response: str) -> None:
    err = _load_error(tmp_path, response=response)
    assert err.field == "tasks.nb.response"
    assert err.line == _line_of(tmp_path / "study.toml", "response")
    assert "is taken" in str(err) and '"joystick:1"' in str(err)  # says what to use


def test_n_is_checked_only_for_nback() -> None:
    study = make_study(tasks={"sums": {"kind": "arithmetic", "n": 7}},
                       design={"targets": [8], "condition": ["static"],
                               "load": ["sums"], "repetitions": 1})
    assert study.tasks["sums"].kind == "arithmetic"


def test_task_defaults_and_round_trip() -> None:
    study = make_study(tasks={"nb": {"kind": "nback", "response": "key:J", "modality": "visual"}},
                       questionnaire={"tlx": True},
                       design={"targets": [8], "condition": ["static"],
                               "load": ["none", "nb"], "repetitions": 1})
    spec = study.tasks["nb"]
    assert (spec.n, spec.interval_s, spec.stimulus_s, spec.match_rate, spec.practice,
            spec.baseline) == (2, 2.5, 0.5, 0.3, 12, 0)
    assert spec.response == "key:j"
    assert TaskSpec(kind="nback").response == "joystick:1"
    again = type(study).from_toml(study.to_toml())
    assert again == study


# -- item sequences ------------------------------------------------------------------

SPECS = [TaskSpec(kind="nback", n=n, modality=m) for n in (1, 2, 3)
         for m in ("auditory", "visual")] + [
    TaskSpec(kind="arithmetic", modality=m, match_rate=0.5) for m in ("auditory", "visual")]


@pytest.mark.parametrize("spec", SPECS, ids=lambda s: f"{s.kind}-{s.n}-{s.modality}")
def test_item_sequence_is_deterministic_and_keeps_the_match_rate(spec: TaskSpec) -> None:
    items = list(itertools.islice(item_sequence(spec, seed=7), 4000))
    assert items == list(itertools.islice(item_sequence(spec, seed=7), 4000))
    assert items != list(itertools.islice(item_sequence(spec, seed=8), 4000))
    assert [it.index for it in items] == list(range(4000))
    rate = sum(it.target for it in items) / len(items)
    assert abs(rate - spec.match_rate) < 0.03
    if spec.kind == "nback":
        pool = NBACK_TONES if spec.modality == "auditory" else NBACK_LETTERS
        assert {it.stimulus for it in items} == set(pool)
        for k, it in enumerate(items):  # a go item is exactly a repeat of n back
            assert it.target == (k >= spec.n and items[k - spec.n].stimulus == it.stimulus)
    else:
        top = 4 if spec.modality == "auditory" else 9
        for it in items:
            a, b = (int(x) for x in it.stimulus.split("+"))
            assert 1 <= a <= top and 1 <= b <= top
            assert it.target == ((a + b) % 2 == 1)


def test_a_task_of_kind_none_has_no_items() -> None:
    with pytest.raises(ValueError, match="no items"):
        item_sequence(TaskSpec(kind="none"), 1)


# -- scoring -------------------------------------------------------------------------

def _items(*targets: bool) -> list[tuple[TaskItem, int]]:
    return [(TaskItem(k, f"s{k}", t), 1000 + k * 1000) for k, t in enumerate(targets)]


def test_classify_hits_misses_false_alarms_and_extra_presses() -> None:
    items = _items(False, True, True, False)  # onsets 1000, 2000, 3000, 4000
    presses = [2400, 2900, 4200, 500, 5000]
    ev = classify(items, presses, 1000, block_index=3, task="nb", phase="dual")
    rows = [(e.item_index, e.t_ns, e.response, e.target, e.correct, e.rt_s) for e in ev]
    assert rows == [
        (-1, 500, "press", False, False, None),      # before the first item
        (0, 1000, "", False, True, None),            # correct rejection
        (1, 2000, "press", True, True, 400 / 1e9),   # hit, the first press counts
        (-1, 2900, "press", False, False, None),     # a second press of item 1
        (2, 3000, "", True, False, None),            # miss
        (3, 4000, "press", False, False, 200 / 1e9),  # false alarm
        (-1, 5000, "press", False, False, None),     # after the last item's window
    ]
    assert {(e.block_index, e.task, e.phase) for e in ev} == {(3, "nb", "dual")}
    assert [e.stimulus for e in ev if e.item_index >= 0] == ["s0", "s1", "s2", "s3"]
    assert all(e.stimulus is None for e in ev if e.item_index < 0)


def test_a_press_at_the_next_onset_belongs_to_the_next_item() -> None:
    ev = classify(_items(True, True), [1999, 2000], 1000)
    assert [(e.item_index, e.rt_s) for e in ev] == [(0, 999 / 1e9), (1, 0.0)]


def test_the_first_press_counts_whatever_order_presses_come_in() -> None:
    ev = classify(_items(True), [1700, 1300], 1000)
    assert [(e.item_index, e.rt_s) for e in ev] == [(0, 300 / 1e9), (-1, None)]


# -- a task run's schedule -----------------------------------------------------------

SPEC = TaskSpec(kind="nback", n=2, interval_s=2.0)


def _step(ts: TaskSession, times: list[int]) -> list[tuple[TaskItem, int, int]]:
    out = []
    for now in times:
        out += [(it, onset, now) for it, onset in ts.announce(now, 100 * MS)]
    return out


def test_onsets_follow_the_task_clock_whatever_the_ticks() -> None:
    start = 5_000 * MS
    steady = TaskSession("nb", SPEC, "dual", 2, seed=11, start_ns=start, n_items=None)
    rng = random.Random(3)
    t, times = 0, []
    while t < start + 60_000 * MS:  # irregular ticks: 1 ms to 400 ms apart
        t += rng.randint(1, 400) * MS
        times.append(t)
    jittery = TaskSession("nb", SPEC, "dual", 2, seed=11, start_ns=start, n_items=None)
    a = _step(steady, list(range(0, start + 60_000 * MS, 10 * MS)))
    b = _step(jittery, times)
    assert [x[:2] for x in a] == [x[:2] for x in b][:len(a)]
    assert [onset for _, onset, _ in a] == [start + k * 2_000 * MS for k in range(len(a))]
    assert [it.index for it, _, _ in a] == list(range(len(a)))
    # announced ahead: 100 ms before the onset on a 10 ms tick
    assert all(onset - now >= 90 * MS for _, onset, now in a)
    expect = list(itertools.islice(item_sequence(SPEC, 11), len(a)))
    assert [it for it, _, _ in a] == expect


def test_a_run_of_n_items_ends_after_the_last_window() -> None:
    ts = TaskSession("nb", SPEC, "practice", 0, seed=1, start_ns=0, n_items=3)
    _step(ts, list(range(0, 10_000 * MS, 10 * MS)))
    assert len(ts.announced) == 3
    assert not ts.done(6_000 * MS - 1) and ts.done(6_000 * MS)
    assert [e.item_index for e in ts.finish(6_000 * MS)] == [0, 1, 2]


def test_finish_scores_what_was_shown_and_drops_an_unanswered_cut_item() -> None:
    ts = TaskSession("nb", SPEC, "dual", 4, seed=1, start_ns=0, n_items=None,
                     first_index=10)
    _step(ts, list(range(0, 5_000 * MS, 10 * MS)))  # items at 0, 2, 4 s (and 6 s ahead)
    ts.press(4_500 * MS)  # answers the item cut short at 4 s
    ev = ts.finish(5_000 * MS)
    assert [(e.item_index, e.response) for e in ev] == [(10, ""), (11, ""), (12, "press")]
    ts2 = TaskSession("nb", SPEC, "dual", 4, seed=1, start_ns=0, n_items=None)
    _step(ts2, list(range(0, 5_000 * MS, 10 * MS)))
    assert [e.item_index for e in ts2.finish(5_000 * MS)] == [0, 1]  # 4 s item: no chance
    assert ts2.finish(6_000 * MS) == []
    ts2.press(5_500 * MS)  # after the end: ignored
    assert ts2.announce(9_000 * MS, 0) == []


def test_tlx_ratings_are_checked() -> None:
    good = dict.fromkeys(TLX_ITEMS, 50)
    assert check_tlx(good) == dict.fromkeys(TLX_ITEMS, 50.0)
    assert list(check_tlx(dict(reversed(good.items())))) == list(TLX_ITEMS)
    for bad in ({**good, "mental": 101}, {**good, "effort": float("nan")},
                {k: v for k, v in good.items() if k != "physical"}, {**good, "fun": 3}):
        with pytest.raises(ConfigError, match="NASA-TLX"):
            check_tlx(bad)


def test_study_check_shows_the_tasks_and_counts_their_time() -> None:
    from tactorbelt.experiment.description import describe

    design = {"targets": [8], "condition": ["static"], "load": ["none", "nb2", "rest"],
              "repetitions": 1}
    plain = make_study(design={**design, "load": ["none"]}, training=0)
    study = make_study(design=design, training=0, questionnaire={"tlx": True},
                       tasks={"nb2": {"kind": "nback", "n": 2, "practice": 10, "baseline": 20},
                              "rest": {"kind": "none"}, "unused": {"kind": "arithmetic"}})
    assert list(study.used_tasks()) == ["nb2"]
    text = describe(study).to_text()
    assert ("  task        nb2: auditory 2-back, an item every 2.5 s (0.5 s long), press "
            "joystick:1 on 30% go items; 10 practice items, 20 baseline items before its "
            "first block") in text
    assert "unused" not in text and "rest:" not in text
    assert "  ratings     raw NASA-TLX (6 items, 0-100) after each test block" in text
    per_block = plain.estimate_duration_s()  # one block of 8 trials
    assert study.estimate_duration_s() == pytest.approx(
        3 * per_block + 30 * 2.5 + 3 * 60.0)
