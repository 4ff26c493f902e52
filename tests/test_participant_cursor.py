"""The model participant as a cursor source, alone and in the session runner."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from tactorbelt import ConfigError, open_belt
from tactorbelt.clock import SimClock
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import paper_study
from tactorbelt.geometry import Layout, TargetSet
from tactorbelt.inputs.base import TrialCue
from tactorbelt.inputs.model import ModelCursor, make_model_cursor, sim_vibrator
from tactorbelt.participant import ModelParams
from tactorbelt.stimuli import make_stimulus

LAYOUT = Layout.even(6)
TARGETS = TargetSet.even(24).angles_deg


def cue(block: str = "test", condition: str = "static", shown: float | None = None) -> TrialCue:
    return TrialCue(0, block, condition, TARGETS, LAYOUT, shown)


def sense_for(target_deg: float, mode: str = "static"):  # type: ignore[no-untyped-def]
    """A sense function that returns the vibration of ``target_deg`` from each onset."""
    vibrate = sim_vibrator(LAYOUT)
    stim = make_stimulus(LAYOUT, target_deg, mode)

    def sense(t0_ns: int, t1_ns: int):  # type: ignore[no-untyped-def]
        t_s, vib = vibrate(stim, (t1_ns - t0_ns) / 1e9)
        return t0_ns + np.round(t_s * 1e9).astype(np.int64), vib

    return sense


def run_trial(cursor: ModelCursor, c: TrialCue, onset: int = 10**9,
              until_s: float = 5.0) -> list[tuple[int, float, float]]:
    cursor.trial_started(c, onset)
    out = []
    for k in range(round(until_s * 100)):
        s = cursor.read(onset + k * 10_000_000)
        out.append((s.t_ns, s.x, s.y))
    cursor.trial_ended(onset + round(until_s * 1e9))
    return out


def test_it_answers_what_it_feels_not_the_trial() -> None:
    """The answer follows the vibration: the cue of a test trial holds no answer."""
    for target in (90.0, 210.0):  # on-tactor: a typical observer gets these right
        cur = ModelCursor(sense_for(target), seed=1, params=ModelParams().replace(lapse=0))
        samples = run_trial(cur, cue())
        t, x, y = samples[-1]
        assert math.degrees(math.atan2(x, y)) % 360 == pytest.approx(target, abs=6)
        assert cur.last_decision is not None
        assert cur.last_decision.answer_deg == target


def test_movement_is_minimum_jerk_from_home_after_the_decision() -> None:
    p = ModelParams().replace(lapse=0, exgauss_sigma_s=0, exgauss_tau_s=0, jitter=0,
                              endpoint_sd_deg=0)
    cur = ModelCursor(sense_for(90.0), seed=2, params=p)
    onset = 10**9
    samples = run_trial(cur, cue(), onset)
    r = np.hypot([s[1] for s in samples], [s[2] for s in samples])
    t = (np.array([s[0] for s in samples]) - onset) / 1e9
    start = p.observe_static_s + p.nondecision_s + p.hick_s_per_bit * math.log2(24)
    assert np.all(r[t <= start] == 0.0)  # at home until the movement starts
    assert r[t >= start + p.movement_s] == pytest.approx(1.0)  # then on the ellipse
    mid = np.argmin(np.abs(t - (start + p.movement_s / 2)))
    assert r[mid] == pytest.approx(0.5, abs=0.08)  # min-jerk: half way at half time
    assert np.all(np.diff(r) >= -1e-12)


def test_trial_ended_springs_back_home() -> None:
    cur = ModelCursor(sense_for(90.0), seed=3)
    run_trial(cur, cue(), 10**9, until_s=3.0)
    later = cur.read(10**9 + 3 * 10**9 + round(ModelParams().return_s * 1e9) + 10**6)
    assert math.hypot(later.x, later.y) < 0.05


def test_dynamic_blocks_take_longer_to_decide() -> None:
    times = {}
    for cond in ("static", "dynamic"):
        cur = ModelCursor(sense_for(60.0, cond), seed=4)
        run_trial(cur, cue(condition=cond))
        assert cur.last_decision is not None
        times[cond] = cur.last_decision.decided_ns - 10**9
    assert times["static"] == round(ModelParams().observe_static_s * 1e9)
    assert times["dynamic"] == round(ModelParams().observe_dynamic_s * 1e9)


def test_training_moves_to_the_shown_target_without_sensing() -> None:
    def no_sense(t0: int, t1: int):  # type: ignore[no-untyped-def]
        raise AssertionError("training must not need the belt")

    cur = ModelCursor(no_sense, seed=5)
    samples = run_trial(cur, cue(block="training", shown=135.0))
    _, x, y = samples[-1]
    assert math.degrees(math.atan2(x, y)) % 360 == pytest.approx(135.0, abs=6)


def test_make_model_cursor_needs_a_belt_that_models_vibration() -> None:
    class Silent:  # a belt that declares it models no vibration (a hardware belt)
        url = "serial:/dev/ttyACM0"
        models_vibration = False

    with pytest.raises(ConfigError, match="--belt sim"):
        make_model_cursor(Silent(), SimClock(), seed=1)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="seed"):
        make_model_cursor(Silent(), SimClock(), seed="x", sense=lambda a, b: (a, b))  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="params must be a ModelParams, got dict"):
        make_model_cursor(Silent(), SimClock(), seed=1, params={},  # type: ignore[arg-type]
                          sense=lambda a, b: (a, b))  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="load must be a LoadParams, got float"):
        make_model_cursor(Silent(), SimClock(), seed=1, load=0.5,  # type: ignore[arg-type]
                          sense=lambda a, b: (a, b))  # type: ignore[arg-type]


def _session(path: Path, seed: int, participant: str = "model-01") -> list[dict[str, object]]:
    study = paper_study()
    clock = SimClock()
    with Store.open(path) as store, open_belt("sim", clock=clock) as belt:
        cursor = make_model_cursor(belt, clock, seed=seed)
        result = run_session(study, participant, belt, cursor, store, clock, seed=1)
        assert result.status == "complete"
        return store.trials()


def test_a_paper_session_runs_in_the_runner_and_is_reproducible(tmp_path: Path) -> None:
    a = _session(tmp_path / "a.sqlite", seed=11)
    b = _session(tmp_path / "b.sqlite", seed=11)
    c = _session(tmp_path / "c.sqlite", seed=12)
    keys = ("target_deg", "response_deg", "rt_s", "correct", "status")
    assert len(a) == 48 + 240
    assert all(r["status"] == "done" for r in a)
    assert [tuple(r[k] for k in keys) for r in a] == [tuple(r[k] for k in keys) for r in b]
    assert [r["response_deg"] for r in a] != [r["response_deg"] for r in c]
    test = [r for r in a if r["block"] == "test"]
    on = [r["correct"] for r in test if r["on_tactor"]]
    assert np.mean(on) > 0.85
    training = [r for r in a if r["block"] == "training"]
    assert all(r["correct"] for r in training)
    rts = [r["rt_s"] for r in test]
    assert min(rts) > 0.3 and max(rts) < 10.0
