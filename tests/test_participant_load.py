"""The model participant under cognitive load (participant/load.py): what its documented
assumptions promise (docs/participant-model.md, "Under cognitive load")."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from support.power_trials import between_accuracy
from tactorbelt import ConfigError
from tactorbelt.experiment.study import paper_study
from tactorbelt.inputs.model import sim_vibrator
from tactorbelt.participant import ModelParams, simulate_participant, stimulus_cues
from tactorbelt.participant.load import (
    TLX_ITEMS,
    LoadParams,
    TaskResponder,
    load_level,
    loaded_params,
    task_d_prime,
    task_hit_fa,
    task_rt_median_s,
    tlx_ratings,
)
from tactorbelt.power.design import PowerDesign


@dataclass(frozen=True)
class Spec:
    kind: str
    n: int = 2
    interval_s: float = 2.5


def test_load_levels_grow_with_n() -> None:
    assert load_level(None) == 0.0
    assert load_level(Spec("none")) == 0.0
    levels = [load_level(Spec("nback", n)) for n in (1, 2, 3)]
    assert levels == sorted(levels) and levels[0] > 0 and levels[-1] == 1.0
    assert 0 < load_level(Spec("arithmetic")) < 1
    with pytest.raises(ConfigError, match="unknown secondary task kind"):
        load_level(Spec("radio"))


def test_no_load_leaves_the_observer_unchanged() -> None:
    p = ModelParams()
    assert loaded_params(p, 0.0) is p
    loaded = loaded_params(p, 1.0)
    assert loaded.weber_amplitude > p.weber_amplitude
    assert loaded.loc_sd_max_deg > p.loc_sd_max_deg
    assert loaded.nondecision_s > p.nondecision_s
    # the fields that shape the cues stay: the fast path can reuse its cues
    assert (loaded.gamma, loaded.observe_static_s, loaded.observe_dynamic_s) == (
        p.gamma, p.observe_static_s, p.observe_dynamic_s)
    with pytest.raises(ConfigError, match=r"load level is in \[0, 1\]"):
        loaded_params(p, 1.5)


def test_the_model_localises_worse_and_slower_under_load() -> None:
    protocol = PowerDesign.from_study(paper_study()).protocol()
    base = ModelParams()
    cues = stimulus_cues(protocol, sim_vibrator(protocol.layout), base)
    alone = simulate_participant(protocol, cues, base, np.random.default_rng(1))
    loaded = simulate_participant(protocol, cues, loaded_params(base, load_level(Spec("nback", 3))),
                                  np.random.default_rng(1))
    assert loaded.correct.mean() < alone.correct.mean() - 0.05
    for cond in ("static", "dynamic"):
        assert between_accuracy(loaded, cond) < between_accuracy(alone, cond)
    assert np.median(loaded.rt_s) > np.median(alone.rt_s) + 0.1


def test_secondary_sensitivity_falls_with_n_and_under_dual_task() -> None:
    d = [task_d_prime(Spec("nback", n), "baseline") for n in (1, 2, 3)]
    assert d[0] > d[1] > d[2]
    for n in (1, 2, 3):
        assert task_d_prime(Spec("nback", n), "dual") < task_d_prime(Spec("nback", n), "practice")
        assert task_rt_median_s(Spec("nback", n), "dual") > task_rt_median_s(Spec("nback", n),
                                                                              "baseline")
    assert task_rt_median_s(Spec("nback", 3), "dual") > task_rt_median_s(Spec("nback", 1), "dual")
    with pytest.raises(ConfigError, match="task phase"):
        task_d_prime(Spec("nback", 2), "warmup")


def _run(spec: Spec, phase: str, n_items: int, seed: int) -> tuple[float, float, list[float]]:
    """The responder on a random n-back stream; (hit rate, fa rate, RTs) by the truth."""
    rng = np.random.default_rng(seed)
    r = TaskResponder(np.random.default_rng(seed + 1))
    r.start(spec, phase, spec.interval_s)
    letters = "BCDFGHJK"
    seq: list[str] = []
    hits = go = fa = nogo = 0
    rts: list[float] = []
    step = round(spec.interval_s * 1e9)
    for k in range(n_items):
        repeat = k >= spec.n and rng.random() < 0.3
        s = seq[k - spec.n] if repeat else letters[rng.integers(0, 8)]
        seq.append(s)
        onset = k * step
        t = r.item(s, onset)
        target = k >= spec.n and seq[k - spec.n] == s
        presses = r.presses(onset + step - 1)
        assert presses == ([] if t is None else [t])
        if t is not None:
            assert onset < t < onset + step  # inside the item's response window
        if target:
            go += 1
            hits += t is not None
            if t is not None:
                rts.append((t - onset) / 1e9)
        else:
            nogo += 1
            fa += t is not None
    return hits / go, fa / nogo, rts


def test_the_model_nback_accuracy_is_lower_at_3_than_at_1() -> None:
    h1, f1, rt1 = _run(Spec("nback", 1), "dual", 3000, 5)
    h3, f3, rt3 = _run(Spec("nback", 3), "dual", 3000, 5)
    assert h3 < h1 - 0.1
    assert f3 > f1
    assert np.median(rt3) > np.median(rt1)
    # and the rates are the documented signal-detection ones
    e1, e3 = task_hit_fa(Spec("nback", 1), "dual"), task_hit_fa(Spec("nback", 3), "dual")
    assert abs(h1 - e1[0]) < 0.03 and abs(f1 - e1[1]) < 0.02
    assert abs(h3 - e3[0]) < 0.03 and abs(f3 - e3[1]) < 0.03


def test_the_model_does_worse_on_the_task_with_localisation_than_alone() -> None:
    hb, fb, _ = _run(Spec("nback", 2), "baseline", 3000, 9)
    hd, fd, _ = _run(Spec("nback", 2), "dual", 3000, 9)
    assert hd < hb and fd > fb


def test_the_model_computes_arithmetic_parity_itself() -> None:
    r = TaskResponder(np.random.default_rng(0))
    r.start(Spec("arithmetic"), "practice")
    assert r.is_go("3+4") is True
    assert r.is_go("3+5") is False
    r.start(Spec("nback", 2), "practice")
    assert [r.is_go(s) for s in ("B", "C", "B", "D", "B")] == [None, None, True, False, True]


def test_no_presses_when_no_task_runs() -> None:
    r = TaskResponder(np.random.default_rng(0))
    assert r.item("B", 0) is None
    r.start(Spec("nback", 1), "dual")
    planned = [r.item("B", k * 10**9) for k in range(20)]  # 1-back: all but one match
    assert any(t is not None for t in planned)
    r.start(None, None)  # the run ends before those presses are due
    assert not r.active and r.item("B", 0) is None and r.presses(10**12) == []


def test_tlx_ratings_rise_with_load_and_are_on_the_slider_steps() -> None:
    rng = np.random.default_rng(3)
    none = [tlx_ratings(0.0, rng) for _ in range(300)]
    high = [tlx_ratings(load_level(Spec("nback", 2)), rng) for _ in range(300)]
    for item in TLX_ITEMS:
        assert np.mean([r[item] for r in high]) >= np.mean([r[item] for r in none])
    raw = [np.mean(list(r.values())) for r in none], [np.mean(list(r.values())) for r in high]
    assert np.mean(raw[1]) > np.mean(raw[0]) + 15
    for r in none + high:
        assert set(r) == set(TLX_ITEMS)
        assert all(0 <= v <= 100 and v % 5 == 0 for v in r.values())


def test_load_params_are_checked() -> None:
    with pytest.raises(ConfigError, match="d_prime_nback"):
        LoadParams(d_prime_nback=(3.0, 2.0))  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="weber_gain"):
        LoadParams(weber_gain=-1.0)


def test_the_fast_path_draws_loaded_blocks_with_the_loaded_observer() -> None:
    from tactorbelt.experiment.study import Study, template_toml
    from tactorbelt.participant.factorial import simulate_factorial_participant

    study = Study.from_toml(template_toml("load").replace(
        "repetitions = 2                # every", "repetitions = 6                # every"),
        path="load.toml")
    fp = PowerDesign.from_study(study).factorial()
    assert fp.load_levels == ((0.0, load_level(Spec("nback", 2)), 0.0,
                               load_level(Spec("nback", 2))),)
    base = ModelParams().for_period(fp.period_s)
    cues = tuple(stimulus_cues(p, sim_vibrator(study.layout_obj()), base) for p in fp.parts)
    table = simulate_factorial_participant(fp, cues, base, np.random.default_rng(4))[24]
    per_block = 24 * 6
    blocks = [table.correct[i * per_block:(i + 1) * per_block].mean() for i in range(4)]
    # blocks in canonical order: static-none, static-nback2, dynamic-none, dynamic-nback2
    assert blocks[1] < blocks[0] and blocks[3] < blocks[2]
    # a study without a load draws exactly as before loads existed
    plain = PowerDesign.from_study(paper_study()).factorial()
    assert plain.load_levels == ()


def test_a_more_able_participant_detects_better() -> None:
    spec = Spec("nback", 2)
    typical = task_hit_fa(spec, "dual")
    able = task_hit_fa(spec, "dual", ability=1.3)
    assert able[0] > typical[0] and able[1] < typical[1]
    assert task_d_prime(spec, "dual", ability=1.3) == pytest.approx(
        1.3 * task_d_prime(spec, "dual"))


def test_fast_path_agrees_with_the_full_runner_under_load(tmp_path) -> None:  # type: ignore[no-untyped-def]
    import math

    from tactorbelt import open_belt
    from tactorbelt.clock import SimClock
    from tactorbelt.experiment.runner import run_session
    from tactorbelt.experiment.store import open_store
    from tactorbelt.experiment.study import Study, template_toml
    from tactorbelt.inputs.model import make_model_cursor
    from tactorbelt.participant.factorial import simulate_factorial_participant

    text = template_toml("load").replace(
        "repetitions = 2                # every", "repetitions = 4  # every").replace(
        "passes = 1                # 0 = no training", "passes = 0  # none")
    study = Study.from_toml(text, path="load.toml")
    base = ModelParams().for_period(study.stimulus.period_s)
    with open_store(tmp_path / "full.sqlite") as store:
        for i in range(2):
            clock = SimClock()
            with open_belt("sim", clock=clock, layout=study.layout_obj()) as belt:
                cursor = make_model_cursor(belt, clock, 31 + i, base)
                run_session(study, f"model-{i + 1:02d}", belt, cursor, store, clock, seed=1,
                            study_toml=text, input_name="model")
        rows = [r for r in store.trials() if r["block"] == "test"]
    fp = PowerDesign.from_study(study).factorial()
    cues = tuple(stimulus_cues(p, sim_vibrator(study.layout_obj()), base) for p in fp.parts)
    rng = np.random.default_rng(8)
    tables = [simulate_factorial_participant(fp, cues, base, rng)[24] for _ in range(30)]
    for load in ("none", "nback2"):
        for cond in ("static", "dynamic"):
            full = [bool(r["correct"]) for r in rows
                    if r["load"] == load and r["condition"] == cond]
            fast = np.concatenate([t.correct[(t.load == load) & (t.condition == cond)]
                                   for t in tables])
            p = float(fast.mean())
            se = math.sqrt(max(p * (1 - p), 0.01) / len(full))
            assert abs(np.mean(full) - p) < 4 * se, (load, cond, np.mean(full), p)
