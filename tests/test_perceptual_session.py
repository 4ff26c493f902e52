"""A study that requires a wearer profile ([calibration] perceptual = true): the runner
calibrates the model participant before training, keeps the profile with the participant
and the session, and renders the study for it; a person without a profile is told how to
measure one."""

from __future__ import annotations

from pathlib import Path

import pytest

from support.studies import study_toml
from tactorbelt import ConfigError
from tactorbelt.clock import SimClock
from tactorbelt.devices.sim import SimBelt
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.store import open_store
from tactorbelt.experiment.study import Study
from tactorbelt.inputs.base import CursorSource
from tactorbelt.inputs.model import make_model_cursor
from tactorbelt.stimuli import make_stimulus
from tactorbelt.wearer import WearerProfile


def _study(perceptual: bool = True) -> tuple[Study, str]:
    text = study_toml(targets=24, repetitions=1, training=0, conditions=["static"])
    if perceptual:
        text += "\n[calibration]\nperceptual = true\n"
    return Study.from_toml(text), text


def test_the_runner_calibrates_the_model_before_training(tmp_path: Path) -> None:
    study, text = _study()
    clock = SimClock()
    with SimBelt(layout=study.layout_obj(), clock=clock) as belt, \
            open_store(tmp_path / "s.sqlite") as store:
        cursor = make_model_cursor(belt, clock, seed=4)
        res = run_session(study, "M01", belt, cursor, store, clock, study_toml=text,
                          limit=6)
        kept = store.wearer_profile("M01")
        assert kept is not None
        profile = WearerProfile.from_toml(kept)
        assert profile.participant == "M01" and not profile.is_identity
        session_id = store.sessions("M01")[0]["session_id"]
        assert store.session_profile(session_id) == kept
        assert res.n_run == 6
        # the trials were rendered for this wearer (streamed: the sim belt models firmware)
        stim = make_stimulus(belt.layout, 45.0, profile=profile)
        assert not belt.can_render(stim)
        # a second session reuses the kept profile: no new calibration
        before = clock.now_ns()
        run_session(study, "M01", belt, make_model_cursor(belt, clock, seed=5), store, clock,
                    study_toml=text, limit=1, resume=True)
        assert clock.now_ns() - before < 60e9
        assert store.wearer_profile("M01") == kept


def test_a_person_without_a_profile_is_told_how_to_measure_one(tmp_path: Path) -> None:
    study, text = _study()
    clock = SimClock()

    class Person(CursorSource):
        pass

    with SimBelt(layout=study.layout_obj(), clock=clock) as belt, \
            open_store(tmp_path / "s.sqlite") as store, \
            pytest.raises(ConfigError, match="tactorbelt calibrate perceptual --participant "
                          "P07 --input keyboard --db "):
        run_session(study, "P07", belt, Person(), store, clock, study_toml=text)


def test_studies_without_the_key_are_unchanged() -> None:
    study, _ = _study(perceptual=False)
    assert not study.calibration.perceptual
    assert "calibration" not in study.to_toml()
    assert _study()[0].calibration.perceptual


def test_the_analysis_reports_results_with_and_without_profiles(tmp_path: Path) -> None:
    from tactorbelt.analysis.tables.profiles import COLUMNS, profile_table

    db = tmp_path / "s.sqlite"
    with open_store(db) as store:
        for perceptual, people in ((True, ("M01", "M02")), (False, ("M03",))):
            study, text = _study(perceptual)
            for k, who in enumerate(people):
                clock = SimClock()
                with SimBelt(layout=study.layout_obj(), clock=clock) as belt:
                    run_session(study, who, belt, make_model_cursor(belt, clock, seed=k),
                                store, clock, study_toml=text)
    table = profile_table([db])
    assert table is not None and tuple(table.columns) == COLUMNS
    rows = {r.profile: r for r in table.itertuples()}
    assert rows["with"].n_participants == 2 and rows["without"].n_participants == 1
    assert 0 < rows["with"].n <= 2 * 18 and 0.0 <= rows["with"].accuracy <= 1.0
    study, text = _study(False)
    plain = tmp_path / "plain.sqlite"
    with open_store(plain) as store:
        clock = SimClock()
        with SimBelt(layout=study.layout_obj(), clock=clock) as belt:
            run_session(study, "M09", belt, make_model_cursor(belt, clock, seed=1), store,
                        clock, study_toml=text)
    assert profile_table([plain]) is None


def test_a_missing_profile_leaves_no_session_behind(tmp_path: Path) -> None:
    study, text = _study()

    class Person(CursorSource):
        pass

    clock = SimClock()
    with SimBelt(layout=study.layout_obj(), clock=clock) as belt, \
            open_store(tmp_path / "s.sqlite") as store:
        with pytest.raises(ConfigError):
            run_session(study, "P07", belt, Person(), store, clock, study_toml=text)
        assert store.sessions("P07") == []
