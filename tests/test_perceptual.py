"""Perceptual calibration (tactorbelt.calibration.perceptual): QUEST+ tracks, the maximum-likelihood
fit, and the whole procedure with simulated observers and the model participant."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.typing import ArrayLike, NDArray

from tactorbelt.calibration.perceptual import (
    LAPSE,
    CalibrationSettings,
    Interval,
    Respondent,
    fit_psychometric,
    location_track,
    run_perceptual_calibration,
)
from tactorbelt.clock import SimClock
from tactorbelt.devices.sim import SimBelt
from tactorbelt.geometry import Layout
from tactorbelt.inputs.model import make_model_respondent

LAYOUT = Layout.even(6)


def psychometric(x: ArrayLike, pse: float, sd: float, lapse: float = LAPSE
                 ) -> NDArray[np.float64]:
    """``lapse + (1 - 2 lapse) * Phi((x - pse) / sd)``: the simulated observer's answers."""
    from scipy.special import ndtr

    return np.asarray(lapse + (1.0 - 2.0 * lapse) * ndtr((np.asarray(x, float) - pse) / sd))


#: The documented number of trials (docs/calibration-perceptual.md) after which QUEST+
#: finds the PSE of an observer with sd 2.4 deg within 2 deg in at least 90 % of runs.
TRIALS = 24


def test_quest_plus_converges_on_a_known_pse_and_slope() -> None:
    gap, pse, sd = 60.0, 0.3, 0.04  # PSE at 18 deg of a 60 deg gap, sd 2.4 deg
    settings = CalibrationSettings(location_trials=(TRIALS, TRIALS))
    hits, sds = 0, []
    for seed in range(200):
        rng = np.random.default_rng(seed)
        track = location_track(settings)
        while not track.done:
            x = track.next()
            track.update(x, int(rng.random() < psychometric(x, pse, sd)))
        fit = track.fit()
        assert fit.n == TRIALS
        hits += abs(fit.pse - pse) * gap <= 2.0
        sds.append(fit.sd)
    assert hits >= 180, hits
    assert 0.5 * sd < float(np.median(sds)) < 2.0 * sd


def test_the_fit_recovers_pse_and_slope_from_many_trials() -> None:
    rng = np.random.default_rng(3)
    x = rng.uniform(-1, 1, 4000)
    r = (rng.random(4000) < psychometric(x, 0.2, 0.3)).astype(int)
    fit = fit_psychometric(x, r, -1.0, 1.0)
    assert fit.pse == pytest.approx(0.2, abs=0.03)
    assert fit.sd == pytest.approx(0.3, rel=0.1)


class _Perfect(Respondent):
    """Feels exactly what is rendered: equal tactors, points where rendered."""

    def stronger(self, first: Interval, second: Interval) -> int:
        return int(second.frame.max() > first.frame.max())

    def side(self, interval: Interval, pair: tuple[int, int], marked_deg: float,
             layout: Layout) -> int:
        a = pair[0]
        mark = ((marked_deg - layout.angles_deg[a]) % 360.0) / 60.0
        return int(interval.value > mark)


def test_a_perfect_observer_gets_the_identity_profile() -> None:
    clock = SimClock()
    with SimBelt(layout=LAYOUT, clock=clock) as belt:
        res = run_perceptual_calibration(belt, clock, _Perfect(), participant="ideal")
    p = res.profile
    assert p.gains == pytest.approx((1.0,) * 6, abs=0.08)
    for w in p.warps:
        assert w.intended == (0.25, 0.75)
        assert w.rendered == pytest.approx(w.intended, abs=0.03)
        assert list(w.rendered) == sorted(w.rendered)
    assert res.n_trials <= 5 * 12 + 12 * 14
    assert belt.levels is not None and not belt.levels.any()


def test_the_model_participant_is_calibrated_from_what_it_feels() -> None:
    clock = SimClock()
    with SimBelt(layout=LAYOUT, clock=clock) as belt:
        res = run_perceptual_calibration(belt, clock, make_model_respondent(belt, 7),
                                         participant="M01", seed=7)
    p = res.profile
    assert p.participant == "M01" and len(p.fit) == 5 + 12
    # the model feels quarter points too near the tactor: the warp renders them further in
    inner = np.array([w.rendered for w in p.warps])
    assert inner[:, 0].mean() > 0.27 and inner[:, 1].mean() < 0.73
    assert all(0.7 < g < 1.4 for g in p.gains)


def test_the_prior_holds_a_few_trials_near_no_correction_and_yields_to_many() -> None:
    rng = np.random.default_rng(11)
    x = rng.uniform(0.02, 0.98, 4000)
    r = (rng.random(4000) < psychometric(x, 0.4, 0.1)).astype(int)
    many = fit_psychometric(x, r, 0.02, 0.98, prior=(0.25, 0.1))
    assert many.pse == pytest.approx(0.4, abs=0.02)
    few_plain = fit_psychometric(x[:10], r[:10], 0.02, 0.98)
    few = fit_psychometric(x[:10], r[:10], 0.02, 0.98, prior=(0.25, 0.1))
    assert abs(few.pse - 0.25) < abs(few_plain.pse - 0.25)
