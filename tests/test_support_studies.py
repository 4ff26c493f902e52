"""The study-file builder the tests share (tests/support/studies.py) writes what it is asked."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest

from support.studies import make_study, study_dict, study_toml, write_study
from tactorbelt import StudyFileError
from tactorbelt.experiment.study import Study, load_study, paper_study


def test_no_overrides_is_the_papers_protocol() -> None:
    assert make_study() == paper_study()


def test_overrides_land_in_their_tables() -> None:
    s = make_study(name="small", tactors=4, targets=8, law="energy", timeout_s=3.0,
                   iti_s=0.5, break_every=0, seed=7, training=0, conditions=["dynamic"],
                   repetitions=2)
    assert (s.name, s.layout.tactors, s.targets.count) == ("small", 4, 8)
    assert (s.stimulus.law, s.response.timeout_s) == ("energy", 3.0)
    assert (s.session.iti_s, s.session.break_every, s.session.seed) == (0.5, 0, 7)
    assert s.training.passes == 0
    assert [(b.condition, b.repetitions) for b in s.test] == [("dynamic", 2)]
    assert s.n_trials() == 16
    # what is not overridden stays the paper's
    assert s.stimulus.period_s == paper_study().stimulus.period_s


def test_angles_blocks_and_training() -> None:
    s = make_study(tactors=[0, 80, 180], training=2, training_conditions=["static"],
                   training_order="random",
                   blocks=[{"name": "a", "condition": "static", "repetitions": 1},
                           {"name": "b", "condition": "static", "repetitions": 3}])
    assert s.layout_obj().angles_deg == (0.0, 80.0, 180.0)
    assert (s.training.passes, s.training.conditions, s.training.order) == (
        2, ["static"], "random")
    assert [b.label for b in s.test] == ["a", "b"]


def test_minimal_leaves_the_defaults_to_the_file_format() -> None:
    data = tomllib.loads(study_toml(minimal=True))
    assert set(data) == {"name", "layout", "targets", "test"}
    assert make_study(minimal=True).response == Study.from_toml(study_toml()).response


def test_none_leaves_a_key_out_and_bad_values_are_written_as_given() -> None:
    assert "seed" not in study_dict(seed=None)["session"]
    assert study_dict(tactors=None)["layout"] == {}
    with pytest.raises(StudyFileError, match=r"response\.threshold"):
        make_study(threshold=1.5)


def test_typos_and_contradictions_are_refused() -> None:
    with pytest.raises(TypeError, match="timeout"):
        study_toml(timeout=3)
    with pytest.raises(TypeError, match="not both"):
        study_toml(repetitions=1, blocks=[{"condition": "static", "repetitions": 1}])


def test_the_text_reads_like_a_hand_written_file(tmp_path: Path) -> None:
    path = write_study(tmp_path / "sub", tactors=[10, 100, 200], repetitions=1)
    text = path.read_text()
    assert "angles_deg = [10, 100, 200]" in text
    assert text.count("[[test]]") == 2
    assert load_study(path) == make_study(tactors=[10, 100, 200], repetitions=1)
