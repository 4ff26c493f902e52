"""The registry of secondary-task kinds (tactorbelt.tasks.kinds): every kind is complete
and the model participant works its answers out as a person would; a new kind is one
module and one registry line, and runs a whole load study (stored, analysed) with
nothing else changed."""

from __future__ import annotations

import json
import random
import sqlite3
from collections import deque
from pathlib import Path

import numpy as np
import pytest

from support.studies import study_toml
from tactorbelt.tasks.kinds import TASK_KINDS, TaskKind, task_kind
from tactorbelt.tasks.sounds import beeps, tone


class _Spec:
    def __init__(self, kind: str, n: int = 2, modality: str = "visual") -> None:
        self.kind, self.n, self.modality = kind, n, modality
        self.interval_s, self.stimulus_s, self.match_rate = 2.5, 0.5, 0.3


@pytest.mark.parametrize("name", sorted(TASK_KINDS))
@pytest.mark.parametrize("modality", ["auditory", "visual"])
def test_the_model_works_out_every_kinds_go_items_from_the_stimuli(name: str,
                                                                   modality: str) -> None:
    for n in (1, 2, 3):
        kind = task_kind(name)
        spec = _Spec(name, n, modality)
        items = kind.items(spec, random.Random(7))
        memory: deque[str] = deque()
        seen = judged = 0
        for _ in range(300):
            item = next(items)
            go = kind.model_is_go(spec, item.stimulus, memory)
            seen += item.target
            if go is not None:
                judged += 1
                assert go == item.target, (name, n, item)
        assert judged >= 297 and 0.2 < seen / 300 < 0.4  # match_rate 0.3
        if modality == "auditory":  # the kind's sound: the item's tone, or its beeps
            a, plus, b = item.stimulus.partition("+")
            want = (beeps(int(a), int(b), 0.3, 8000) if plus
                    else tone(int(item.stimulus.removeprefix("tone")), 0.3, 8000))
            np.testing.assert_array_equal(kind.sound(item.stimulus, 0.3, 8000), want)


@pytest.mark.parametrize("name", sorted(TASK_KINDS))
def test_every_kind_describes_itself_to_people_and_the_model(name: str) -> None:
    kind = task_kind(name)
    assert isinstance(kind, TaskKind) and kind.name == name
    spec = _Spec(name)
    for text in (kind.describe(spec), kind.title(spec), kind.prompt(spec, "button 1"),
                 *kind.rule(spec, "button 1"), *kind.go_words):
        assert isinstance(text, str) and text
    assert "button 1" in kind.prompt(spec, "button 1")
    assert 0.0 < kind.load_level(spec) <= 1.0


def test_an_unknown_kind_names_every_registered_one() -> None:
    with pytest.raises(ValueError, match="'nback', 'arithmetic' or 'none' \\(got 'stroop'\\)"):
        task_kind("stroop")


def test_a_new_kind_is_a_module_and_a_registry_line(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, request: pytest.FixtureRequest) -> None:
    """A toy kind (support/toy_task.py: press on an even digit, auditory) runs a whole
    load study of model participants: the study file accepts it, the schedule draws its
    items, the model answers them, the store keeps its events, the analysis reports the
    load cells and the task; nothing outside the kind's module knows its name."""
    from tactorbelt.app.demo import run_model_study
    from tactorbelt.experiment.description import describe
    from tactorbelt.experiment.study import Study
    from tactorbelt.tasks.sounds import SoundBank

    monkeypatch.setitem(TASK_KINDS, "even", "support.toy_task:KIND")
    task_kind.cache_clear()
    request.addfinalizer(task_kind.cache_clear)  # the toy kind is not kept after the test
    text = study_toml(
        name="toy-load", tactors=6, targets=6, iti_s=0.5, break_every=0, training=0,
        timeout_s=4.0, blocks=[
            {"name": "calm", "condition": "static", "repetitions": 2},
            {"name": "busy", "condition": "static", "repetitions": 2, "load": "ev"},
            {"name": "calm-d", "condition": "dynamic", "repetitions": 2},
            {"name": "busy-d", "condition": "dynamic", "repetitions": 2, "load": "ev"}],
        tasks={"ev": {"kind": "even", "modality": "auditory", "interval_s": 2.0,
                      "practice": 4, "baseline": 6}},
        questionnaire={"tlx": True})
    study = Study.from_toml(text)
    assert "even digits" in describe(study).to_text()
    result = run_model_study(tmp_path / "out", 3, seed=5, study_toml=text)
    assert result is not None
    con = sqlite3.connect(tmp_path / "out" / "study.sqlite")
    rows = con.execute("SELECT stimulus, correct FROM task_events WHERE stimulus IS NOT NULL"
                       ).fetchall()
    con.close()
    assert rows and {r[0] for r in rows} <= set("0123456789")
    assert sum(r[1] for r in rows) / len(rows) > 0.8  # d' 3.2: the model does the task
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert {c["load"] for c in summary["cells"]} == {"none", "ev"}
    sound = SoundBank(8000).get("4", 0.25, task_kind("even").sound)
    assert sound.shape == (2000,) and not sound.flags.writeable
    # the study file refuses what the kind refuses
    with pytest.raises(Exception, match="n is not used by an even-digit task"):
        Study.from_toml(text.replace('kind = "even"', 'kind = "even"\nn = 3'))
