"""Information transfer from confusion matrices: exact cases, hand-computed corrections,
the [0, H(S)] bounds, and the small-sample bias of the chosen estimator."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from support.it_estimators import (
    ESTIMATORS,
    bootstrap_corrected_transfer,
    confusion_matrix,
    jackknife_transfer,
    miller_madow_bias,
    miller_madow_transfer,
    panzeri_treves_transfer,
    stimulus_entropy,
)
from support.it_estimators import _pt_bins as pt_bins
from tactorbelt.analysis.tables.transfer import (
    ESTIMATOR,
    chao_shen_transfer,
    estimate_transfer,
    information_transfer,
)

LN2 = math.log(2)


@pytest.mark.parametrize("m", [2, 6, 24])
def test_perfect_identification_transfers_log2_m(m: int) -> None:
    assert information_transfer(np.eye(m) * 5) == pytest.approx(math.log2(m))


def test_uniform_responses_transfer_nothing() -> None:
    assert information_transfer(np.ones((8, 8))) == pytest.approx(0.0, abs=1e-12)
    assert information_transfer(np.zeros((3, 3))) == 0.0


def test_hand_computed_matrix() -> None:
    # p = [[3, 1], [1, 3]] / 8: margins 1/2; IT = 2*(3/8 log2(3/2)) + 2*(1/8 log2(1/2))
    expected = 0.75 * math.log2(1.5) - 0.25
    assert information_transfer([[3, 1], [1, 3]]) == pytest.approx(expected)
    assert expected == pytest.approx(0.18872187554086717)
    # bias: (2-1)(2-1) / (2 * 8 * ln 2)
    assert miller_madow_bias([[3, 1], [1, 3]]) == pytest.approx(1 / (16 * LN2))
    assert miller_madow_transfer([[3, 1], [1, 3]]) == pytest.approx(expected - 1 / (16 * LN2))


def test_only_occupied_cells_count_in_the_bias() -> None:
    full = np.arange(1, 10).reshape(3, 3)
    assert miller_madow_bias(full) == pytest.approx(2 * 2 / (2 * 45 * LN2))
    m = np.zeros((4, 4))
    m[0, 0] = m[1, 1] = 10  # a perfect 2x2: R_s = 1 per row, R = 2 columns
    assert miller_madow_bias(m) == pytest.approx(-1 / (2 * 20 * LN2))
    m[0, 1] = 5
    assert miller_madow_bias(m) == pytest.approx(0.0)


def _plugin_nats(m: np.ndarray) -> float:
    return information_transfer(m, clamp=False) * LN2  # type: ignore[operator]


def test_jackknife_is_the_delete_one_trial_formula() -> None:
    # against the definition, trial by trial: N I - (N - 1) mean of the N leave-one-out I
    m = np.array([[3, 1, 0], [1, 2, 2], [0, 0, 4]], dtype=float)
    n = int(m.sum())
    loo = []
    for i, j in zip(*np.nonzero(m), strict=True):
        d = m.copy()
        d[i, j] -= 1
        loo += [information_transfer(d, clamp=False)] * int(m[i, j])
    want = n * information_transfer(m, clamp=False) - (n - 1) * float(np.mean(loo))
    assert jackknife_transfer(m, clamp=False) == pytest.approx(want, abs=1e-12)
    # by hand for a perfect 12 x 2 matrix: every leave-one-out matrix is perfect with one
    # row of 1: I_-k = H(1/23 ... 2/23) = log2 23 - 22/23, so I_J = 24 log2 12 - 23 I_-k
    loo_hand = math.log2(23) - 22 / 23
    assert jackknife_transfer(np.eye(12) * 2, clamp=False) == pytest.approx(
        24 * math.log2(12) - 23 * loo_hand)


def test_chao_shen_by_hand() -> None:
    # rows [3, 1] and [1, 3]: n = 4, one singleton, coverage C = 3/4, p~ = C p_k,
    # H = -sum p~ ln p~ / (1 - (1 - p~)^n); the marginal [4, 4] has no singleton
    def term(pa: float, n: int) -> float:
        return -pa * math.log(pa) / (1 - (1 - pa) ** n)

    h_row = term(0.75 * 0.75, 4) + term(0.75 * 0.25, 4)
    h_marg = 2 * term(0.5, 8)
    want = (h_marg - h_row) / LN2
    assert want == pytest.approx(-0.2833481301833113)
    assert chao_shen_transfer([[3, 1], [1, 3]], clamp=False) == pytest.approx(want)
    assert chao_shen_transfer([[3, 1], [1, 3]]) == 0.0  # clamped
    # rows of different sizes: [2, 1, 0] (C = 2/3) and [0, 1, 3] (C = 3/4); marginal
    # [2, 2, 3] (C = 1)
    h1 = term(2 / 3 * 2 / 3, 3) + term(2 / 3 * 1 / 3, 3)
    h2 = term(3 / 4 * 1 / 4, 4) + term(3 / 4 * 3 / 4, 4)
    hm = 2 * term(2 / 7, 7) + term(3 / 7, 7)
    want = (hm - 3 / 7 * h1 - 4 / 7 * h2) / LN2
    assert chao_shen_transfer([[2, 1, 0], [0, 1, 3]], clamp=False) == pytest.approx(want)
    # all singletons: f1 = n - 1 keeps the coverage above 0 (Chao & Shen 2003)
    assert chao_shen_transfer([[1, 1], [1, 1]], clamp=False) == pytest.approx(
        (2 * term(0.5, 4) - 2 * term(0.25, 2)) / LN2)


def _pt_reference(c: np.ndarray) -> int:
    """Panzeri & Treves' (1996) bin count, written out as their loop."""
    d, nt = len(c), c.sum()
    p = c[c > 0] / nt
    rn = len(p)
    if rn >= d:
        return rn
    e = float(np.sum(1 - (1 - p) ** nt))
    prev, delta, x = float(d), abs(rn - e), 0
    while delta < prev and rn + x < d:
        x += 1
        g = x * (1 - (nt / (nt + rn)) ** (1 / nt))
        q = (1 - g) * (p * nt + 1) / (nt + rn)
        e = float(np.sum(1 - (1 - q) ** nt)) + x * (1 - (1 - g / x) ** nt)
        prev, delta = delta, abs(rn - e)
    return rn + x - 1 + int(delta < prev)


def test_panzeri_treves_bin_count() -> None:
    # by hand: two singletons out of 10 bins. x = 0: expected occupied 2(1 - 1/4) = 1.5;
    # x = 1, 2, 3 give 1.664, 1.743, 1.735: the closest to the 2 seen is at x = 2
    assert pt_bins(np.array([[1.0, 1.0, *[0.0] * 8]]))[0] == 4
    # a row that saw one response twice: no unseen bin is likely
    assert pt_bins(np.array([[2.0, 0.0, 0.0]]))[0] == 1
    rng = np.random.default_rng(5)
    vecs = [rng.multinomial(int(rng.integers(1, 30)), rng.dirichlet(np.full(d, a)))
            for d in (2, 5, 12, 30) for a in (0.1, 0.5, 3.0) for _ in range(40)]
    for v in vecs:
        assert pt_bins(v[None].astype(float))[0] == _pt_reference(v.astype(float)), v
    # the transfer: the Miller-Madow formula with these counts
    m = np.array([[1, 1, 0, 0], [0, 0, 2, 0], [0, 1, 0, 3]], dtype=float)
    rs = sum(_pt_reference(r) - 1 for r in m)
    rr = _pt_reference(m.sum(axis=0)) - 1
    want = information_transfer(m, clamp=False) - (rs - rr) / (2 * m.sum() * LN2)
    assert panzeri_treves_transfer(m, clamp=False) == pytest.approx(want)


def test_bootstrap_correction_is_seeded_and_exact_when_resamples_cannot_vary() -> None:
    # a perfect matrix resamples to itself: 2 I - I = I
    assert bootstrap_corrected_transfer(np.eye(6) * 3) == pytest.approx(math.log2(6))
    m = np.array([[3, 1, 0], [1, 2, 1], [0, 1, 3]])
    a = bootstrap_corrected_transfer(m, rng=7, clamp=False)
    assert a == bootstrap_corrected_transfer(m, rng=7, clamp=False)
    assert a < information_transfer(m)


def test_stacks_give_one_value_per_matrix() -> None:
    rng = np.random.default_rng(2)
    stack = rng.integers(0, 4, size=(3, 2, 5, 5)).astype(float)
    for name, f in ESTIMATORS.items():
        if name == "bootstrap":
            continue
        out = np.asarray(f(stack))
        assert out.shape == (3, 2)
        assert out[1, 0] == pytest.approx(f(stack[1, 0])), name


@pytest.mark.parametrize("reps", [1, 2, 3, 10])
@pytest.mark.parametrize("name", list(ESTIMATORS))
def test_an_all_correct_12_target_cell_is_log2_12(name: str, reps: int) -> None:
    # issue 39: Miller-Madow gave 3.92 bits for 12 targets x 2 repetitions all right
    m = np.eye(12) * reps
    v = ESTIMATORS[name](m)
    assert v <= math.log2(12)
    assert v == pytest.approx(math.log2(12), abs=1e-12)
    assert estimate_transfer(m) == math.log2(12)  # the clamp's ceiling, exactly


def test_corrections_cross_the_bounds_before_the_clamp() -> None:
    m = np.eye(12) * 2
    assert miller_madow_transfer(m, clamp=False) == pytest.approx(
        math.log2(12) + 11 / (2 * 24 * LN2))  # 3.915, the value of the issue
    assert miller_madow_transfer(m, clamp=False) > 3.9
    assert estimate_transfer(np.ones((12, 12))) == 0.0


def test_the_ceiling_is_the_stimulus_entropy() -> None:
    # unequal rows (a timeout left a target with one answer): H(S) < log2 3
    m = np.array([[2, 0, 0], [0, 2, 0], [0, 0, 1]], dtype=float)
    hs = -(2 * 0.4 * math.log2(0.4) + 0.2 * math.log2(0.2))
    assert stimulus_entropy(m) == pytest.approx(hs)
    for f in ESTIMATORS.values():
        assert f(m) <= hs + 1e-12
    # an empty target row does not count
    assert stimulus_entropy(np.diag([3.0, 3.0, 0.0])) == pytest.approx(1.0)


_matrices = st.integers(1, 7).flatmap(lambda s: st.integers(1, 7).flatmap(
    lambda r: arrays(np.int64, (s, r), elements=st.integers(0, 12))))


@given(m=_matrices)
def test_no_estimate_leaves_zero_to_the_stimulus_entropy(m: np.ndarray) -> None:
    hs = float(stimulus_entropy(m))
    assert 0.0 <= hs <= math.log2(m.shape[0]) + 1e-12
    for name, f in ESTIMATORS.items():
        v = float(f(m, rng=1) if name == "bootstrap" else f(m))
        assert 0.0 <= v <= hs, (name, v, hs)
        assert v <= math.log2(m.shape[0])


def test_bad_matrices_are_refused() -> None:
    with pytest.raises(ValueError, match="2-D"):
        information_transfer([1, 2, 3])
    with pytest.raises(ValueError, match=">= 0"):
        information_transfer([[1, -1], [0, 1]])


def test_confusion_matrix_counts_pairs_and_skips_unknown() -> None:
    cats = [0.0, 90.0, 180.0, 270.0]
    m = confusion_matrix([0, 0, 90, 180, 270], [0, 90, 90, float("nan"), 45], cats)
    assert m.tolist() == [[1, 1, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0]]


def _angular(m: int, sd_deg: float) -> np.ndarray:
    """P(answer | target): the target plus a normal error of sd_deg, snapped."""
    from scipy.stats import norm

    step = 360.0 / m
    off = (np.arange(m)[None, :] - np.arange(m)[:, None]) % m * step
    p = sum(norm.cdf(off + step / 2 + 360 * w, scale=sd_deg)
            - norm.cdf(off - step / 2 + 360 * w, scale=sd_deg) for w in range(-3, 4))
    return np.asarray(p) / np.sum(p, axis=1, keepdims=True)


def _truth(p: np.ndarray) -> float:
    return float(information_transfer(p / p.shape[0] * 1e12))


# (targets, repetitions, angular error SD in degrees) of a belt-like channel. With 2,000
# matrices each (scripts/it_estimators.py's channel), the chosen estimator's bias was
# -0.005, -0.111, +0.017 and -0.104 bits, the plug-in's +0.55, +0.77, +0.32 and +0.77,
# Miller-Madow's +0.52, +0.57, +0.18 and +0.57
KNOWN = [(12, 3, 20.0), (24, 5, 20.0), (36, 10, 10.0), (48, 5, 10.0)]


@pytest.mark.parametrize(("m", "reps", "sd"), KNOWN)
def test_chosen_estimator_bias_on_known_channels(m: int, reps: int, sd: float) -> None:
    rng = np.random.default_rng(20261124 + m + reps)
    p = _angular(m, sd)
    truth = _truth(p)
    mats = rng.multinomial(reps, p, size=(300, m)).astype(float)
    est = np.asarray(estimate_transfer(mats))
    plain = np.asarray(information_transfer(mats))
    mm = np.asarray(miller_madow_transfer(mats))
    se = est.std() / math.sqrt(len(est))
    bias = est.mean() - truth
    assert ESTIMATOR == "Chao-Shen"
    # within 0.15 bits (the simulation: 0.11 at most), with room for the sampling
    # error of 300 matrices; the plug-in overshoots by far more
    assert abs(bias) < 0.15 + 4 * se
    assert plain.mean() - truth > 2 * abs(bias) + 4 * se
    assert np.mean((est - truth) ** 2) < np.mean((mm - truth) ** 2)
