"""The fast simulation path: the paper's qualitative finding, agreement with the runner, power."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pytest

from support.power_trials import between_accuracy
from tactorbelt import ConfigError, open_belt
from tactorbelt.clock import SimClock
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import paper_study
from tactorbelt.inputs.model import make_model_cursor, sim_vibrator
from tactorbelt.participant import (
    ModelParams,
    Protocol,
    draw_participant,
    simulate_participant,
    stimulus_cues,
)
from tactorbelt.participant.factorial import FactorialProtocol
from tactorbelt.power.design import PowerDesign
from tactorbelt.power.effects import Effect
from tactorbelt.power.outcomes import StudyOutcome, binomial_ci, power_row
from tactorbelt.power.simulation import simulate_factorial_studies


@pytest.fixture(scope="module")
def protocol() -> Protocol:
    return PowerDesign.from_study(paper_study()).protocol()


@pytest.fixture(scope="module")
def cues(protocol: Protocol):  # type: ignore[no-untyped-def]
    return stimulus_cues(protocol, sim_vibrator(protocol.layout))


def _split(correct: np.ndarray, cond: np.ndarray, on: np.ndarray) -> dict[tuple[str, bool], float]:
    return {(c, o): float(correct[(cond == c) & (on == o)].mean())
            for c in ("static", "dynamic") for o in (True, False)}


def test_default_model_reproduces_the_papers_qualitative_finding(protocol, cues) -> None:  # type: ignore[no-untyped-def]
    """Dynamic between-tactor accuracy is higher than static, RT slightly longer.

    This follows from the model's assumptions (docs/participant-model.md); it proves
    nothing about people.
    """
    rng = np.random.default_rng(1)
    tables = [simulate_participant(protocol, cues, ModelParams(), rng) for _ in range(20)]
    static = np.mean([between_accuracy(t, "static") for t in tables])
    dynamic = np.mean([between_accuracy(t, "dynamic") for t in tables])
    assert dynamic > static + 0.15
    rt = {c: np.median(np.concatenate([t.rt_s[(t.condition == c) & ~t.on_tactor]
                                       for t in tables])) for c in ("static", "dynamic")}
    assert rt["static"] < rt["dynamic"] < 1.5 * rt["static"]
    on = np.mean([t.correct[t.on_tactor].mean() for t in tables])
    assert on > 0.9


def test_fast_path_agrees_with_the_full_runner(tmp_path: Path, protocol, cues) -> None:  # type: ignore[no-untyped-def]
    study = paper_study()
    rows = []
    with Store.open(tmp_path / "full.sqlite") as store:
        for i, seed in enumerate((21, 22)):
            clock = SimClock()
            with open_belt("sim", clock=clock) as belt:
                cursor = make_model_cursor(belt, clock, seed=seed)
                run_session(study, f"model-{i + 1:02d}", belt, cursor, store, clock, seed=1)
        rows = [r for r in store.trials() if r["block"] == "test"]
    full_correct = np.array([bool(r["correct"]) for r in rows])
    full_cond = np.array([r["condition"] for r in rows])
    full_on = np.array([bool(r["on_tactor"]) for r in rows])
    full = _split(full_correct, full_cond, full_on)
    counts = {k: int(((full_cond == k[0]) & (full_on == k[1])).sum()) for k in full}

    rng = np.random.default_rng(3)
    tables = [simulate_participant(protocol, cues, ModelParams(), rng) for _ in range(40)]
    fast = _split(np.concatenate([t.correct for t in tables]),
                  np.concatenate([t.condition for t in tables]),
                  np.concatenate([t.on_tactor for t in tables]))
    for key, p_fast in fast.items():
        se = math.sqrt(max(p_fast * (1 - p_fast), 0.01) / counts[key])
        assert abs(full[key] - p_fast) < 4 * se, (key, full[key], p_fast)
    full_rt = np.median([r["rt_s"] for r in rows])
    fast_rt = np.median(np.concatenate([t.rt_s for t in tables]))
    assert full_rt == pytest.approx(fast_rt, abs=0.08)


def test_fast_path_refuses_an_observer_the_cues_were_not_sensed_with(protocol, cues) -> None:  # type: ignore[no-untyped-def]
    with pytest.raises(ConfigError, match="gamma"):
        simulate_participant(protocol, cues, ModelParams(gamma=1.5), np.random.default_rng(0))
    # individual observers keep the shared fields
    simulate_participant(protocol, cues, draw_participant(np.random.default_rng(0)),
                         np.random.default_rng(0))


def test_power_simulation_is_reproducible_and_summarised(protocol, cues) -> None:  # type: ignore[no-untyped-def]
    def test(static: np.ndarray, dynamic: np.ndarray) -> float:
        return 0.01 if dynamic.mean() > static.mean() else 0.5

    def simulate_studies(n: int, indices: Sequence[int]) -> list[StudyOutcome]:
        return simulate_factorial_studies(FactorialProtocol((protocol,)), (cues,),
                                          Effect("condition"), n, indices, seed=5, test=test)

    a = simulate_studies(3, range(4))
    b = simulate_studies(3, [2, 3])
    assert np.array_equal(a[2].static_acc, b[0].static_acc)  # independent of the split
    row = power_row(a, alpha=0.05)
    assert row.n_participants == 3 and row.sims == 4 and row.found == 4 and row.power == 1.0
    assert row.ci_low < 1.0 == row.ci_high
    assert row.dynamic_acc > row.static_acc
    with pytest.raises(ConfigError, match="at least 2"):
        simulate_studies(1, range(1))


def test_binomial_ci() -> None:
    lo, hi = binomial_ci(5, 10)
    assert lo == pytest.approx(0.187, abs=1e-3) and hi == pytest.approx(0.813, abs=1e-3)
    assert binomial_ci(0, 10)[0] == 0.0 and binomial_ci(10, 10)[1] == 1.0


def test_the_fast_exact_signed_rank_p_is_scipys() -> None:
    """The power analysis' shortcut for SciPy's exact permutation Wilcoxon (ties or
    zeros, n <= 13) gives SciPy's p-value exactly; elsewhere it defers to SciPy."""
    import warnings

    from scipy.stats import wilcoxon

    from tactorbelt.power.simulation import exact_signed_rank_p

    rng = np.random.default_rng(5)
    checked = 0
    while checked < 25:
        n = int(rng.integers(2, 14))
        k = int(rng.choice([6, 30, 90]))
        s = rng.integers(0, k + 1, n) / k
        d = np.clip(s + rng.integers(-3, 8, n) / k, 0, 1)
        if not np.any(d != s):
            continue
        p = exact_signed_rank_p(d - s)
        if p is None:
            continue
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            assert p == float(wilcoxon(d, s, alternative="two-sided").pvalue), (d, s)
        checked += 1
    assert exact_signed_rank_p(np.array([0.1, 0.2, 0.35])) is None  # no ties: SciPy's own
    assert exact_signed_rank_p(np.full(14, 0.1)) is None  # n > 13: the normal approximation
