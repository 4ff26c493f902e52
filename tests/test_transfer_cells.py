"""Information transfer per factorial cell: the estimate, its bootstrap interval, JSON."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from tactorbelt.analysis.tables.cells import (
    IT_CI_METHOD,
    cell_summary,
    cells_to_json,
    participant_cells,
)
from tactorbelt.analysis.tables.transfer import (
    ESTIMATOR,
    bootstrap_draws,
    cell_interval,
    estimate_transfer,
)


def _trials(answers: dict[str, dict[int, list[int]]], condition: str = "static") -> Any:
    """Test trials: ``answers[participant][n_targets]`` lists, per trial in target order
    (cycling), how many targets clockwise the answer lands (None: a timeout)."""
    import pandas as pd

    rows = []
    for p, per_count in answers.items():
        for n, offsets in per_count.items():
            step = 360.0 / n
            for k, off in enumerate(offsets):
                target = (k % n) * step
                done = off is not None
                resp = (target + (off or 0) * step) % 360.0 if done else float("nan")
                rows.append({"participant": p, "block": "test", "condition": condition,
                             "status": "done" if done else "timeout", "target_deg": target,
                             "response_target_deg": resp, "response_deg": resp,
                             "correct": float(done and off == 0), "rt_s": 1.0,
                             "on_tactor": (k % n) % (n // 6) == 0, "n_targets": n,
                             "load": "none"})
    return pd.DataFrame(rows)


def test_an_all_correct_cell_reports_log2_targets_with_a_point_interval() -> None:
    # issue 39: a 12-target cell with every answer right read 3.92 bits
    tr = _trials({p: {12: [0] * 36, 24: [0] * 48} for p in ("P1", "P2", "P3")})
    cells = cell_summary(tr)
    for n in (12, 24):
        c = cells.loc[cells["n_targets"] == n].iloc[0]
        assert c["it_bits"] == math.log2(n)
        assert c["it_bits_ci_low"] == c["it_bits_ci_high"] == math.log2(n)
        assert c["it_bits_pooled"] == math.log2(n)
    per = participant_cells(tr)
    assert (per["it_bits"] <= np.log2(per["n_targets"])).all()


def _noisy(seed: int, n_part: int, n: int, reps: int, p_right: float) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    out: dict[str, dict[int, list[Any]]] = {}
    for i in range(n_part):
        offs = rng.choice([-1, 0, 1], size=n * reps, p=[(1 - p_right) / 2, p_right,
                                                        (1 - p_right) / 2]).tolist()
        out[f"P{i}"] = {n: [None if k == 3 else o for k, o in enumerate(offs)]}
    return out


@pytest.mark.parametrize(("n_part", "p_right"), [(1, 0.7), (4, 0.5), (9, 0.9)])
def test_the_interval_holds_the_estimate_and_stays_in_bounds(n_part: int,
                                                              p_right: float) -> None:
    tr = _trials(_noisy(n_part, n_part, 24, 3, p_right))
    c = cell_summary(tr, seed=3).iloc[0]
    per = participant_cells(tr)
    assert c["it_bits"] == pytest.approx(per["it_bits"].mean())
    assert 0 <= c["it_bits_ci_low"] < c["it_bits"] < c["it_bits_ci_high"] <= math.log2(24)
    # reproducible with the seed, another seed moves it a little
    again = cell_summary(tr, seed=3).iloc[0]
    assert (again["it_bits_ci_low"], again["it_bits_ci_high"]) == (
        c["it_bits_ci_low"], c["it_bits_ci_high"])
    other = cell_summary(tr, seed=4).iloc[0]
    assert other["it_bits_ci_low"] == pytest.approx(c["it_bits_ci_low"], abs=0.1)


def test_the_interval_narrows_with_participants_and_trials() -> None:
    widths = {}
    for n_part, reps in ((3, 3), (12, 3), (3, 10)):
        tr = _trials(_noisy(11, n_part, 24, reps, 0.6))
        c = cell_summary(tr).iloc[0]
        widths[(n_part, reps)] = c["it_bits_ci_high"] - c["it_bits_ci_low"]
    assert widths[(12, 3)] < 0.75 * widths[(3, 3)]
    assert widths[(3, 10)] < widths[(3, 3)]


def test_a_cells_interval_does_not_depend_on_the_other_cells() -> None:
    both = _trials({"P1": {12: [0, 1, -1] * 12, 24: [0, 1] * 24},
                    "P2": {12: [0, 0, 1] * 12, 24: [0, -1] * 24}})
    alone = both.loc[both["n_targets"] == 12]
    a = cell_summary(both, seed=5)
    b = cell_summary(alone, seed=5)
    assert a.iloc[0][["it_bits", "it_bits_ci_low", "it_bits_ci_high"]].tolist() == \
        b.iloc[0][["it_bits", "it_bits_ci_low", "it_bits_ci_high"]].tolist()


def test_summary_json_names_the_estimator_and_the_interval() -> None:
    tr = _trials(_noisy(2, 3, 12, 3, 0.7))
    doc = cells_to_json(cell_summary(tr))
    c = doc[0]
    assert c["it_bits_ci_low"] <= c["it_bits"] <= c["it_bits_ci_high"]
    assert c["it_bits_method"].startswith(ESTIMATOR) and "clamped" in c["it_bits_method"]
    assert c["it_bits_ci_method"] == IT_CI_METHOD
    assert "bootstrap" in IT_CI_METHOD and "participants" in IT_CI_METHOD


def test_cell_interval_edge_cases() -> None:
    rng = np.random.default_rng(0)
    assert all(math.isnan(v) for v in cell_interval([], rng=rng))
    # one participant: the trial bootstrap alone; an empty matrix (all timeouts) is 0
    lo, hi = cell_interval([np.zeros((6, 6))], rng=rng)
    assert lo == hi == 0.0
    m = np.array([[3, 1, 0], [0, 2, 2], [1, 0, 3]])
    lo, hi = cell_interval([m], rng=rng, n_boot=500)
    assert lo <= estimate_transfer(m) <= hi
    # the row totals stay: every resample of a 3-trial row has 3 trials
    d = bootstrap_draws(m, 50, rng)
    assert d.shape == (50,) and np.all((d >= 0) & (d <= math.log2(3)))


_participant = st.integers(2, 6).flatmap(
    lambda s: arrays(np.int64, (s, s), elements=st.integers(0, 4)))


@settings(max_examples=40)
@given(mats=st.lists(_participant, min_size=1, max_size=5), seed=st.integers(0, 2**16))
def test_interval_contains_the_mean_estimate_and_respects_the_bounds(
        mats: list[np.ndarray], seed: int) -> None:
    size = mats[0].shape[0]
    mats = [m[:size, :size] if m.shape[0] >= size
            else np.pad(m, ((0, size - m.shape[0]), (0, size - m.shape[0]))) for m in mats]
    est = float(np.mean([estimate_transfer(m) for m in mats]))
    lo, hi = cell_interval(mats, rng=np.random.default_rng(seed), n_boot=400)
    assert 0.0 <= lo <= hi <= math.log2(size) + 1e-12
    assert lo - 1e-12 <= est <= hi + 1e-12


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fast_resamples_give_the_estimator_of_the_full_matrices(seed: int) -> None:
    from support.it_estimators import dense
    from tactorbelt.analysis.tables.transfer import _Plan

    rng = np.random.default_rng(seed)
    m = rng.multinomial(3, np.full(9, 1 / 9), size=12) * (rng.random((12, 9)) < 0.4)
    m[5] = 0  # a target without an answer
    m[0, 0] += 2
    plan = _Plan(m.astype(float))
    c = plan.draw(300, np.random.default_rng(99))
    full = dense(plan, c)
    assert (full.sum(axis=2) == m.sum(axis=1)).all()     # every row keeps its total
    assert ((full > 0) <= (m > 0)).all()                 # and stays on its cells
    fast = bootstrap_draws(m, 300, np.random.default_rng(99))
    assert fast == pytest.approx(np.asarray(estimate_transfer(full)), abs=1e-12)
    # and the resamples are multinomial: the mean count of each cell is the original
    many = dense(plan, plan.draw(20000, np.random.default_rng(7))).mean(axis=0)
    assert many == pytest.approx(m, abs=0.05)
