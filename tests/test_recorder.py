"""The session seam (SessionRecorder): what a front end other than the runner (the
browser bridge, a script) relies on to store a session the way ``tactorbelt run`` does."""

from __future__ import annotations

from pathlib import Path

import pytest

from support.studies import study_toml
from tactorbelt import ConfigError, StoreError
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.experiment.recorder import SessionRecorder
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.schedule import make_schedule
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import Study
from tactorbelt.inputs.scripted import ScriptedCursor

SMALL = study_toml(minimal=True, name="small", tactors=4, targets=8,
                   max_presentation_s=2.0, timeout_s=3.0, iti_s=0.5, break_every=5,
                   training=1, training_conditions=["static"], repetitions=1)
MS = 1_000_000


def test_a_new_session_has_the_schedule_run_makes_and_resumes_where_it_stopped(
        tmp_path: Path) -> None:
    study = Study.from_toml(SMALL)
    with Store.open(tmp_path / "s.sqlite") as store:
        rec = SessionRecorder.open_or_resume(store, study, "P01", input_kind="browser",
                                             belt_url="sim", seed=7,
                                             metadata={"user_agent": "Firefox/140"})
        assert not rec.resumed
        assert rec.schedule == make_schedule(study, "P01", 7)
        assert store.session(rec.session_id)["input"] == "browser"
        assert store.run_options(rec.session_id) == {"metadata": {"user_agent": "Firefox/140"}}
        first, second = rec.schedule[0], rec.schedule[1]
        hit = rec.result_for(first.trial_index, onset_ns=10 * MS,
                             response_deg=first.target_deg + 1.0, rt_s=0.8)
        assert (hit.status, hit.correct, hit.response_target_deg) == (
            "done", True, first.target_deg)
        rec.record(hit, skin_onset=(12 * MS, MS))
        rec.record(rec.result_for(second.trial_index, onset_ns=20 * MS, response_deg=None,
                                  rt_s=None))
        with pytest.raises(StoreError):  # a trial is stored once
            rec.record(rec.result_for(first.trial_index, onset_ns=1, response_deg=0.0,
                                      rt_s=0.5))
        rec.end("interrupted")
        rows = store.trials(rec.session_id)
        assert [(r["status"], r["skin_onset_ns"]) for r in rows] == [
            ("done", 12 * MS), ("timeout", None)]

        again = SessionRecorder.open_or_resume(store, study, "P01", input_kind="browser")
        assert (again.resumed, again.session_id, again.seed) == (True, rec.session_id, 7)
        assert again.finished() == {first.trial_index, second.trial_index}
        assert again.todo() == rec.schedule[2:]
        again.end("completed")
        assert store.session(rec.session_id)["status"] == "complete"
        with pytest.raises(ConfigError, match="unknown session status 'paused'"):
            again.end("paused")


def test_a_changed_study_is_not_resumed(tmp_path: Path) -> None:
    study = Study.from_toml(SMALL)
    with Store.open(tmp_path / "s.sqlite") as store:
        SessionRecorder.open(store, study, "P01")
        other = Study.from_toml(SMALL.replace('name = "small"', 'name = "other"'))
        with pytest.raises(StoreError, match="the study changed"):
            SessionRecorder.open(store, other, "P01", resume=True)
        with pytest.raises(StoreError, match="no unfinished session"):
            SessionRecorder.open(store, study, "P02", resume=True)


def test_the_runner_stores_through_the_seam(tmp_path: Path) -> None:
    """A session the runner stores and one a front end stores from the same responses
    have the same schedule and the same outcomes."""
    study = Study.from_toml(SMALL)
    sched = make_schedule(study, "P01")
    clock = SimClock()
    with Store.open(tmp_path / "s.sqlite") as store, \
            open_belt("sim", clock=clock, layout=study.layout_obj()) as belt:
        cursor = ScriptedCursor(None, answers={t.trial_index: t.target_deg for t in sched})
        res = run_session(study, "P01", belt, cursor, store, clock)
        ran = store.trials(res.session_id)
        rec = SessionRecorder.open(store, study, "P02")
        assert rec.schedule == make_schedule(study, "P02")
        for t, row in zip(rec.schedule, ran, strict=False):
            rec.record(rec.result_for(t.trial_index, onset_ns=row["onset_ns"],
                                      response_deg=t.target_deg, rt_s=row["rt_s"]))
        mine = store.trials(rec.session_id)
        assert [r["correct"] for r in mine] == [r["correct"] for r in ran]
        assert store.session(res.session_id)["status"] == "complete"
