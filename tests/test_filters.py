"""The heading filter (One Euro on angles) and the tactor hysteresis."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from tactorbelt import ConfigError, Layout
from tactorbelt.display.filters import Hysteresis, OneEuroFilter
from tactorbelt.geometry import wrap

#: The documented step lag of the default filter (the filters module, docs/direction-display.md).
STEP_LAG_S = 0.20


def step_lag_s(step_deg: float, rate: float) -> float:
    """The lag of the default filter on a noiseless heading step: at rest at 0 for one
    second, then at ``step_deg``; the time from the step to the first sample whose output
    is within 10 % of the step (a multiple of ``1/rate``)."""
    f = OneEuroFilter()
    n_rest = round(rate)
    for i in range(n_rest):
        f(0.0, i / rate)
    for j in range(round(60 * rate)):
        if abs(float(wrap(f(step_deg, (n_rest + j) / rate) - step_deg))) <= abs(step_deg) * 0.1:
            return j / rate
    raise AssertionError(f"a {step_deg} deg step never settled")


def _signed(a: np.ndarray) -> np.ndarray:
    return (np.asarray(a) + 180.0) % 360.0 - 180.0


def test_first_sample_passes_and_constant_input_stays():
    f = OneEuroFilter()
    assert f.value is None
    assert f(123.0, 0.0) == pytest.approx(123.0)
    for i in range(1, 50):
        assert f(123.0, i * 0.05) == pytest.approx(123.0)


def test_heading_crossing_north_is_not_dragged_the_long_way():
    f = OneEuroFilter()
    out = [f(h, i * 0.05) for i, h in enumerate([355.0, 357.0, 359.0, 1.0, 3.0, 5.0, 5.0])]
    # every output stays near north, never swings through 180
    assert np.all(np.abs(_signed(np.array(out))) < 10.0)
    assert all(0.0 <= v < 360.0 for v in out)


def test_documented_step_lag_matches_measurement():
    # the figures in the filters module docstring and docs/direction-display.md
    assert step_lag_s(30.0, 20.0) == pytest.approx(STEP_LAG_S, abs=0.051)
    documented = {5.0: 0.60, 10.0: 0.45, 30.0: 0.20, 90.0: 0.05}
    for step, lag in documented.items():
        assert step_lag_s(step, 20.0) == pytest.approx(lag, abs=0.051), step
    # a step the other way, across north, lags the same
    assert step_lag_s(-30.0, 20.0) == pytest.approx(STEP_LAG_S, abs=0.051)


def test_jitter_at_rest_is_divided_by_about_three():
    rng = np.random.default_rng(7)
    noise = rng.uniform(-3.0, 3.0, 2000)
    f = OneEuroFilter()
    out = np.array([f(90.0 + n, i / 20.0) for i, n in enumerate(noise)])
    ratio = noise[100:].std() / _signed(out[100:] - 90.0).std()
    assert ratio > 2.8


def test_timestamps_must_not_go_back_and_repeats_are_ignored():
    f = OneEuroFilter()
    f(10.0, 1.0)
    assert f(50.0, 1.0) == pytest.approx(10.0)  # same time: ignored
    with pytest.raises(ConfigError, match="must not decrease"):
        f(10.0, 0.5)


@pytest.mark.parametrize("kwargs", [{"min_cutoff_hz": 0}, {"beta": -1}, {"d_cutoff_hz": "x"},
                                    {"min_cutoff_hz": float("nan")}])
def test_bad_filter_parameters(kwargs):
    with pytest.raises(ConfigError):
        OneEuroFilter(**kwargs)


def test_scalar_mode_does_not_wrap():
    f = OneEuroFilter(angular=False)
    f(350.0, 0.0)
    assert f(370.0, 0.05) > 350.0


def test_hysteresis_holds_the_dominant_tactor_against_jitter_at_a_boundary():
    layout = Layout.even(6)  # 30, 90, ...: the boundary between tactor 0 and 1 is at 60
    h = Hysteresis(layout, 4.0)
    rng = np.random.default_rng(3)
    dominants = []
    for a in 60.0 + rng.uniform(-3.0, 3.0, 500):
        held = h(a)
        dominants.append(h.dominant)
        # the held angle is always inside the dominant tactor's sector
        assert abs(_signed(np.array(held - layout.angles_deg[h.dominant]))) < 30.0
    assert sum(1 for a, b in itertools.pairwise(dominants) if a != b) <= 1
    assert h.switches <= 1


def test_hysteresis_switches_once_past_the_margin():
    h = Hysteresis(Layout.even(6), 4.0)
    assert h(50.0) == 50.0 and h.dominant == 0
    assert h(62.0) == pytest.approx(59.99)  # held just inside tactor 0's sector
    assert h.dominant == 0
    assert h(64.5) == 64.5 and h.dominant == 1
    assert h(58.0) == pytest.approx(60.01) and h.dominant == 1
    assert h.switches == 1
    assert h(200.0) == 200.0 and h.dominant == 3  # a jump switches at once


def test_hysteresis_zero_margin_is_off_and_too_big_is_refused():
    h = Hysteresis(Layout.even(6), 0.0)
    h(59.0)
    assert h(61.0) == 61.0 and h.dominant == 1
    with pytest.raises(ConfigError, match="half the smallest gap"):
        Hysteresis(Layout.even(6), 30.0)
    with pytest.raises(ConfigError):
        Hysteresis(Layout.even(6), -1.0)
