"""The runner on a simulated clock: exact timing, storage, observers, faults, motors off."""

from __future__ import annotations

import hashlib
import itertools
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from support.studies import study_toml
from tactorbelt import ConfigError, DeviceError, TactorbeltError
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.devices.calibration import Calibration, TactorCalibration
from tactorbelt.experiment.listeners import Command, NullObserver
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.schedule import make_schedule
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import Study, paper_study
from tactorbelt.experiment.trial import TrialState
from tactorbelt.geometry import Layout
from tactorbelt.inputs.scripted import ScriptedCursor, ScriptedResponse

MS = 1_000_000

SMALL = study_toml(minimal=True, name="small", tactors=4, targets=8,
                   max_presentation_s=2.0, timeout_s=3.0, iti_s=0.5, break_every=5,
                   training=1, training_conditions=["static"], repetitions=1)


def small_study() -> Study:
    return Study.from_toml(SMALL)


def _cursor(study: Study, participant: str = "P01", **resp: Any) -> ScriptedCursor:
    sched = make_schedule(study, participant)
    return ScriptedCursor(ScriptedResponse(**resp) if resp else None,
                          answers={t.trial_index: t.target_deg for t in sched})


def _belt(study: Study, clock: SimClock, **kw: Any) -> Any:
    return open_belt("sim", clock=clock, layout=study.layout_obj(), **kw)


def test_full_paper_session_on_a_sim_clock(tmp_path: Path) -> None:
    study = paper_study()
    clock = SimClock()
    text = study.to_toml()
    with Store.open(tmp_path / "s.sqlite") as store, _belt(study, clock) as belt:
        res = run_session(study, "P01", belt, _cursor(study), store, clock, study_toml=text,
                          input_name="scripted")
        assert res.status == "complete"
        assert (res.n_total, res.n_done, res.n_run) == (288, 288, 288)
        assert res.accuracy == 1.0
        assert not belt.levels.any()  # motors off at the end
        rows = store.trials(res.session_id)
        assert [r["trial_index"] for r in rows] == list(range(288))
        assert {r["status"] for r in rows} == {"done"}
        assert [r["block"] for r in rows] == ["training"] * 48 + ["test"] * 240
        sched = store.schedule(res.session_id)
        assert [(r["target_deg"], r["condition"]) for r in rows] == [
            (t.target_deg, t.condition) for t in sched]
        s = store.session(res.session_id)
        assert s["status"] == "complete" and s["ended_at"] >= s["started_at"]
        assert s["study_toml"] == text
        assert s["study_sha256"] == hashlib.sha256(text.encode()).hexdigest()
        assert (s["seed"], s["belt"], s["clock"], s["input"]) == (1, "sim", "sim", "scripted")
        assert s["package_version"] and s["host"]
        assert s["condition_order"] == '["static", "dynamic"]'


def test_rt_and_sampling_are_exact(tmp_path: Path) -> None:
    study = small_study()
    clock = SimClock(start_ns=123_456_789)
    with Store.open(tmp_path / "s.sqlite") as store, _belt(study, clock) as belt:
        cursor = _cursor(study, reaction_s=0.2, movement_s=0.3)
        res = run_session(study, "P01", belt, cursor, store, clock)
        for r in store.trials(res.session_id):
            assert r["rt_s"] == (r["acquired_ns"] - r["onset_ns"]) / 1e9
            assert (r["acquired_ns"] - r["onset_ns"]) % (10 * MS) == 0
            t = np.array([s[0] for s in store.samples(r["trial_id"])])
            k = np.rint(t * 1e9).astype(np.int64)
            assert k[0] == 0
            assert set(np.diff(k).tolist()) == {10 * MS}
            assert k[-1] == r["acquired_ns"] - r["onset_ns"]
            assert r["n_samples"] == len(t)
            # min-jerk: radius passes 0.9 between 0.2 + 0.3*0.74 s and 0.5 s
            assert 0.42 <= r["rt_s"] <= 0.5
            # the stimulus stops at acquisition
            assert r["stimulus_off_ns"] == r["acquired_ns"]


def test_stimulus_stops_at_longest_presentation_and_trial_times_out(tmp_path: Path) -> None:
    study = small_study()
    clock = SimClock()
    with Store.open(tmp_path / "s.sqlite") as store, _belt(study, clock) as belt:
        res = run_session(study, "P01", belt, ScriptedCursor(ScriptedResponse(None)), store,
                          clock, limit=0)
        rows = store.trials(res.session_id)
        assert len(rows) == 8  # training only (limit 0 test trials)
        assert res.status == "interrupted"
        for r in rows:
            assert r["status"] == "timeout" and r["rt_s"] is None and r["correct"] is None
            assert r["stimulus_off_ns"] - r["onset_ns"] == 2000 * MS
            assert r["n_samples"] == 301  # 0 .. 3.0 s inclusive at 100 Hz


def test_iti_and_onsets(tmp_path: Path) -> None:
    study = small_study()
    clock = SimClock()
    with Store.open(tmp_path / "s.sqlite") as store, _belt(study, clock) as belt:
        res = run_session(study, "P01", belt, _cursor(study), store, clock)
        rows = store.trials(res.session_id)
        for a, b in itertools.pairwise(rows):
            assert b["onset_ns"] - a["acquired_ns"] >= 500 * MS


def test_limit_counts_test_trials(tmp_path: Path) -> None:
    study = small_study()
    clock = SimClock()
    with Store.open(tmp_path / "s.sqlite") as store, _belt(study, clock) as belt:
        res = run_session(study, "P01", belt, _cursor(study), store, clock, limit=3)
        assert res.status == "interrupted"
        blocks = [r["block"] for r in store.trials(res.session_id)]
        assert blocks == ["training"] * 8 + ["test"] * 3
        assert store.session(res.session_id)["status"] == "interrupted"


def test_streaming_belt_gives_the_same_exact_timing(tmp_path: Path) -> None:
    study = small_study()
    clock = SimClock()
    cal = Calibration((TactorCalibration(start=0.2, gain=1.0, ceiling=1.0),) * 4)
    with Store.open(tmp_path / "s.sqlite") as store, _belt(study, clock,
                                                           calibration=cal) as belt:
        res = run_session(study, "P01", belt, _cursor(study), store, clock, limit=2)
        assert len(res.results) == 10
        for r in res.results:
            assert r.onset_ns is not None
            k = np.array(r.sample_t_ns) - r.onset_ns
            assert set(np.diff(k).tolist()) == {10 * MS}
        assert not belt.levels.any()


class Recorder(NullObserver):
    def __init__(self, commands: dict[int, Command] | None = None) -> None:
        self.events: list[tuple[Any, ...]] = []
        self.commands = commands or {}
        self.polls = 0

    def on_session_start(self, info: Any, schedule: Any) -> None:
        self.events.append(("start", info.n_total, info.resumed))

    def on_block_start(self, block: str, condition: str) -> None:
        self.events.append(("block", block, condition))

    def on_trial_state(self, trial: Any, state: TrialState, now_ns: int) -> None:
        self.events.append(("state", trial.trial_index, state))

    def on_trial_done(self, result: Any) -> None:
        self.events.append(("done", result.trial.trial_index, result.status))

    def on_break(self, n_done: int, n_total: int) -> None:
        self.events.append(("break", n_done, n_total))

    def on_session_end(self, status: str) -> None:
        self.events.append(("end", status))

    def poll(self, now_ns: int) -> Command | None:
        self.polls += 1
        return self.commands.get(self.polls)


def test_observer_sees_blocks_states_breaks_and_end(tmp_path: Path) -> None:
    study = small_study()
    clock = SimClock()
    obs = Recorder()
    with Store.open(tmp_path / "s.sqlite") as store, _belt(study, clock) as belt:
        run_session(study, "P01", belt, _cursor(study), store, clock, observer=obs)
    ev = obs.events
    assert ev[0] == ("start", 24, False)
    assert ev[-1] == ("end", "complete")
    assert [e for e in ev if e[0] == "block"] == [
        ("block", "training", "static"), ("block", "test", "static"),
        ("block", "test", "dynamic")]
    assert [e for e in ev if e[0] == "break"] == [
        ("break", n, 24) for n in (5, 10, 15, 20)]
    states = [e[2] for e in ev if e[0] == "state" and e[1] == 0]
    assert states == [TrialState.WAIT_HOME, TrialState.STIMULUS, TrialState.RESPONSE,
                      TrialState.ITI]


def test_pause_aborts_the_trial_then_redoes_it(tmp_path: Path) -> None:
    study = small_study()
    clock = SimClock()
    # poll 20 falls in trial 0's stimulus: pause; resume 5 polls later
    obs = Recorder({20: Command.PAUSE, 25: Command.RESUME})
    with Store.open(tmp_path / "s.sqlite") as store, _belt(study, clock) as belt:
        res = run_session(study, "P01", belt, _cursor(study), store, clock, observer=obs)
        assert res.status == "complete"
        done = [e for e in obs.events if e[0] == "done"]
        assert done[0] == ("done", 0, "aborted") and done[1] == ("done", 0, "done")
        rows = store.trials(res.session_id)
        assert [r["trial_index"] for r in rows] == list(range(24))
        assert rows[0]["attempts"] == 2


def test_abort_turns_motors_off_and_marks_the_session(tmp_path: Path) -> None:
    study = small_study()
    clock = SimClock()
    obs = Recorder({30: Command.ABORT})
    with Store.open(tmp_path / "s.sqlite") as store, _belt(study, clock) as belt:
        res = run_session(study, "P01", belt, _cursor(study), store, clock, observer=obs)
        assert res.status == "aborted"
        assert not belt.levels.any()
        assert store.session(res.session_id)["status"] == "aborted"
        rows = store.trials(res.session_id)
        assert rows[-1]["status"] == "aborted"
        assert obs.events[-1] == ("end", "aborted")


def test_belt_failure_mid_trial(tmp_path: Path) -> None:
    study = small_study()
    clock = SimClock()
    with Store.open(tmp_path / "s.sqlite") as store, _belt(study, clock) as belt:
        real_play = belt._write_play
        real_stop = belt._write_stop
        plays = {"n": 0}
        stop_calls: list[int] = []

        def failing_play(stimulus: Any, duration_s: Any) -> None:
            plays["n"] += 1
            real_play(stimulus, duration_s)
            if plays["n"] == 6:
                raise DeviceError("serial:/dev/ttyACM0: the belt stopped answering")

        def counting_stop() -> None:
            stop_calls.append(clock.now_ns())
            real_stop()

        belt._write_play = failing_play
        belt._write_stop = counting_stop
        with pytest.raises(DeviceError, match=r"belt sim failed.*--resume") as info:
            run_session(study, "P01", belt, _cursor(study), store, clock)
        assert "ttyACM0" in str(info.value)
        assert not belt.levels.any()
        assert stop_calls and stop_calls[-1] == clock.now_ns()
        (sess,) = store.sessions()
        assert sess["status"] == "interrupted"
        rows = store.trials(sess["session_id"])
        assert [r["status"] for r in rows] == ["done"] * 5 + ["aborted"]
        assert "device error" in rows[-1]["abort_reason"]
        # resumable with a working belt
        belt._write_play = real_play
        res = run_session(study, "P01", belt, _cursor(study), store, clock, resume=True)
        assert res.status == "complete" and res.n_run == 19
        assert [r["trial_index"] for r in store.trials(sess["session_id"])] == list(range(24))


def test_keyboard_interrupt_aborts_the_trial_and_leaves_it_resumable(tmp_path: Path) -> None:
    study = small_study()
    clock = SimClock()

    class Interrupting(ScriptedCursor):
        n = 0

        def read(self, now_ns: int) -> Any:
            self.n += 1
            if self.n == 300:
                raise KeyboardInterrupt
            return super().read(now_ns)

    sched = make_schedule(study, "P01")
    cursor = Interrupting(answers={t.trial_index: t.target_deg for t in sched})
    with Store.open(tmp_path / "s.sqlite") as store, _belt(study, clock) as belt:
        with pytest.raises(KeyboardInterrupt):
            run_session(study, "P01", belt, cursor, store, clock)
        assert not belt.levels.any()
        (sess,) = store.sessions()
        assert sess["status"] == "interrupted"
        rows = store.trials(sess["session_id"])
        assert rows[-1]["status"] == "aborted"
        assert rows[-1]["abort_reason"] == "interrupted (Ctrl-C)"


def test_layout_mismatch_is_refused(tmp_path: Path) -> None:
    study = small_study()
    clock = SimClock()
    with Store.open(tmp_path / "s.sqlite") as store, \
            open_belt("sim", clock=clock, layout=Layout.even(6)) as belt:
        with pytest.raises(ConfigError, match="layout"):
            run_session(study, "P01", belt, _cursor(study), store, clock)
        assert store.sessions() == []


def test_cursor_that_never_comes_home(tmp_path: Path) -> None:
    study = small_study()
    clock = SimClock()

    class Stuck(ScriptedCursor):
        def read(self, now_ns: int) -> Any:
            from tactorbelt.inputs.base import CursorSample

            return CursorSample(now_ns, 0.0, 0.5)

    with Store.open(tmp_path / "s.sqlite") as store, _belt(study, clock) as belt:
        with pytest.raises(TactorbeltError, match="home zone"):
            run_session(study, "P01", belt, Stuck(), store, clock)
        assert store.sessions()[0]["status"] == "interrupted"


def test_bad_arguments(tmp_path: Path) -> None:
    study = small_study()
    clock = SimClock()
    with Store.open(tmp_path / "s.sqlite") as store, _belt(study, clock) as belt:
        with pytest.raises(ConfigError, match="participant"):
            run_session(study, "  ", belt, _cursor(study), store, clock)
        with pytest.raises(ConfigError, match="limit"):
            run_session(study, "P01", belt, _cursor(study), store, clock, limit=-1)


def test_interrupt_on_the_instructions_screen_leaves_the_session_interrupted(
        tmp_path: Path) -> None:
    study = small_study()
    clock = SimClock()

    class ClosedAtInstructions(NullObserver):
        def on_session_start(self, info: Any, schedule: Any) -> None:
            raise KeyboardInterrupt

    with Store.open(tmp_path / "s.sqlite") as store, _belt(study, clock) as belt:
        with pytest.raises(KeyboardInterrupt):
            run_session(study, "P01", belt, _cursor(study), store, clock,
                        observer=ClosedAtInstructions())
        (sess,) = store.sessions()
        assert sess["status"] == "interrupted"
        assert store.find_resumable("P01") is not None
