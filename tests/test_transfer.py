"""Information transfer from confusion matrices: exact cases and the small-sample bias."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tactorbelt.analysis.transfer import (
    confusion_matrix,
    information_transfer,
    miller_madow_bias,
    miller_madow_transfer,
)


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
    assert miller_madow_bias([[3, 1], [1, 3]]) == pytest.approx(1 / (16 * math.log(2)))
    assert miller_madow_transfer([[3, 1], [1, 3]]) == pytest.approx(
        expected - 1 / (16 * math.log(2)))


def test_only_occupied_cells_count_in_the_bias() -> None:
    full = np.arange(1, 10).reshape(3, 3)
    assert miller_madow_bias(full) == pytest.approx(2 * 2 / (2 * 45 * math.log(2)))
    m = np.zeros((4, 4))
    m[0, 0] = m[1, 1] = 10  # a perfect 2x2: R_s = 1 per row, R = 2 columns
    assert miller_madow_bias(m) == pytest.approx(-1 / (2 * 20 * math.log(2)))
    m[0, 1] = 5
    assert miller_madow_bias(m) == pytest.approx(0.0)


def test_bad_matrices_are_refused() -> None:
    with pytest.raises(ValueError, match="2-D"):
        information_transfer([1, 2, 3])
    with pytest.raises(ValueError, match=">= 0"):
        information_transfer([[1, -1], [0, 1]])


def test_confusion_matrix_counts_pairs_and_skips_unknown() -> None:
    cats = [0.0, 90.0, 180.0, 270.0]
    m = confusion_matrix([0, 0, 90, 180, 270], [0, 90, 90, float("nan"), 45], cats)
    assert m.tolist() == [[1, 1, 0, 0], [0, 1, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0]]


def _simulate(m: int, reps: int, p_correct: float, runs: int,
              rng: np.random.Generator) -> tuple[float, np.ndarray, np.ndarray]:
    """A participant right with p_correct, otherwise one of the two neighbours."""
    p = np.zeros((m, m))
    for i in range(m):
        p[i, i] = p_correct
        p[i, (i - 1) % m] += (1 - p_correct) / 2
        p[i, (i + 1) % m] += (1 - p_correct) / 2
    truth = information_transfer(p / m * 1e12)
    plain, corrected = [], []
    for _ in range(runs):
        counts = np.stack([rng.multinomial(reps, p[i]) for i in range(m)])
        plain.append(information_transfer(counts))
        corrected.append(miller_madow_transfer(counts))
    return truth, np.array(plain), np.array(corrected)


@pytest.mark.parametrize(("m", "reps", "p_correct"), [
    (6, 10, 0.8), (6, 5, 0.5), (12, 5, 0.6), (12, 10, 0.5), (24, 5, 0.5)])
def test_bias_correction_is_closer_to_the_truth_on_average(
        m: int, reps: int, p_correct: float) -> None:
    # One factorial cell's matrix: m targets x reps repetitions (at least 5: with fewer
    # repetitions than responses a stimulus draws, no first-order correction holds).
    rng = np.random.default_rng(20261123 + m * 100 + reps)
    truth, plain, corrected = _simulate(m, reps, p_correct, 300, rng)
    se = plain.std() / math.sqrt(len(plain))
    # the plug-in estimate overshoots by far more than the sampling error of its mean
    assert plain.mean() - truth > 8 * se
    # the corrected one is closer on average, and in mean squared error, with room for
    # the sampling error of the two means
    assert abs(corrected.mean() - truth) + 2 * se < plain.mean() - truth
    assert np.mean((corrected - truth) ** 2) < np.mean((plain - truth) ** 2)


def test_textbook_form_overshoots_on_sparse_matrices() -> None:
    # why occupied cells are counted: (rows-1)(cols-1)/(2N ln 2) removes more than the
    # whole transfer when a participant confuses only neighbours
    truth, plain, corrected = _simulate(24, 5, 0.5, 50, np.random.default_rng(3))
    nominal = plain - 23 * 23 / (2 * 24 * 5 * math.log(2))
    assert truth - nominal.mean() > 2  # about 3 of the 3.1 bits
    assert abs(corrected.mean() - truth) < 0.3
