"""The amplitude laws and stimuli: golden tables, the properties every law keeps
(support/laws.py, over every name in LAWS), each law's own shape, dynamic timing."""

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st

from support.laws import LAW_PROPERTIES, angles
from tactorbelt import ConfigError
from tactorbelt.geometry import ANGLE_TOLERANCE_DEG, Layout, TargetSet, wrap
from tactorbelt.laws import LAWS, amplitudes
from tactorbelt.stimuli import make_stimulus, render_batch


def load(path):
    return np.loadtxt(path, delimiter=",", skiprows=1)


def test_static_golden_table(reference_dir):
    ref = load(reference_dir / "paper_law_static_24.csv")
    got = amplitudes(Layout.even(6), ref[:, 0], "paper", 15.0)
    np.testing.assert_allclose(got, ref[:, 1:], atol=1e-6)
    # through stimuli too
    for row in ref:
        s = make_stimulus(Layout.even(6), row[0], "static")
        np.testing.assert_allclose(s.amplitudes(np.array([0.0, 0.5]))[1], row[1:], atol=1e-6)


@pytest.mark.parametrize("deg", [15, 60])
def test_dynamic_golden_tables(reference_dir, deg):
    ref = load(reference_dir / f"paper_law_dynamic_{deg}deg_1000hz.csv")
    t, amps = make_stimulus(Layout.even(6), deg, "dynamic").render(1000.0, 1.0)
    np.testing.assert_allclose(t, ref[:, 0], atol=1e-9)
    np.testing.assert_allclose(amps, ref[:, 1:], atol=1e-6)


def test_reference_copy_matches_shared(reference_dir):
    shared = reference_dir.parents[3] / "shared" / "reference"
    if not shared.is_dir():
        pytest.skip("shared/reference not beside the checkout")
    for f in shared.glob("*.csv"):
        assert (reference_dir / f.name).read_bytes() == f.read_bytes()


def test_on_tactor_is_not_renormalised():
    a = amplitudes(Layout.even(6), 30.0)
    assert a[0] == pytest.approx(1 - np.exp(-4))
    assert np.count_nonzero(a) == 1


@given(angles, st.integers(3, 16))
# within the 1e-6 deg on-tactor tolerance of tactor 1, neighbours() says "on 1" (1, 2),
# yet the location is between 0 and 1 and tactor 0 gets 3e-8
@example(90.0 - 5e-7, 6)
@example(90.0, 6)
def test_paper_law_even_layout_at_most_two_adjacent(x, n):
    layout = Layout.even(n)
    a = amplitudes(layout, x, "paper")
    nz = np.flatnonzero(a > 0)
    assert 1 <= len(nz) <= 2
    assert np.all(np.abs(wrap(x - layout.angles[nz])) < 360.0 / n)
    if len(nz) == 2:
        cw, _ = layout.neighbour_indices()
        assert cw[nz[0]] == nz[1] or cw[nz[1]] == nz[0]
        if np.abs(wrap(x - layout.angles)).min() > 2 * ANGLE_TOLERANCE_DEG:
            assert set(nz) == set(layout.neighbours(x))


@pytest.mark.parametrize("check", LAW_PROPERTIES, ids=lambda c: c.__name__)
@pytest.mark.parametrize("law", LAWS)
def test_every_law_keeps_the_properties_of_a_law(law, check):
    """support/laws.py: range, mirror and rotation symmetry, on-tactor means one tactor."""
    check(law)


def test_uneven_layout_uses_spacing_on_targets_side():
    layout = Layout.from_angles([0, 40, 180])
    # target 20: between 0 and 40; s = 40 for both tactors -> symmetric
    a = amplitudes(layout, 20.0, "linear")
    assert a[0] == pytest.approx(0.5) and a[1] == pytest.approx(0.5) and a[2] == 0
    # target 100: between 40 and 180 (gap 140): D=60 from 40 -> 1 - 60/140
    a = amplitudes(layout, 100.0, "linear")
    assert a[1] == pytest.approx(1 - 60 / 140) and a[2] == pytest.approx(1 - 80 / 140)
    assert a[0] == 0


def test_energy_law_keeps_total_energy():
    layout = Layout.even(6)
    x = np.linspace(30, 90, 61)
    a = amplitudes(layout, x, "energy")
    np.testing.assert_allclose((a**2).sum(axis=1), 1.0, atol=1e-9)


def _dwell_times(stim, rate=10000.0):
    t, amps = stim.render(rate, stim.period_s)
    single_near = (amps[:, stim.near_idx] > 0) & (amps[:, stim.far_idx] == 0)
    single_far = (amps[:, stim.far_idx] > 0) & (amps[:, stim.near_idx] == 0)
    return single_near.sum() / rate, single_far.sum() / rate


@settings(deadline=None, max_examples=40)
@given(angles, st.sampled_from([0.05, 0.1, 0.2]), st.sampled_from([0.8, 1.0, 1.5]))
def test_dynamic_dwell_times_follow_inverse_distance(x, transit, period):
    layout = Layout.even(6)
    assume(not layout.is_on_tactor(x))
    stim = make_stimulus(layout, x, "dynamic", period_s=period, transit_s=transit)
    ccw, cw = layout.neighbours(x)
    d1 = abs(x - layout.angles_deg[ccw]) % 360
    d1 = min(d1, 360 - d1)
    d2 = 60.0 - d1
    dn, df = min(d1, d2), max(d1, d2)
    near_s, far_s = _dwell_times(stim)
    hold = period - 2 * transit
    # in the paper law a tactor is off only when the location is a full spacing away,
    # so "only one tactor on" is exactly the dwell (plus the sample on each edge)
    assert near_s == pytest.approx(hold * df / (dn + df), abs=2e-4)
    assert far_s == pytest.approx(hold * dn / (dn + df), abs=2e-4)
    assert layout.angles_deg[stim.near_idx] == pytest.approx(
        layout.angles_deg[ccw] if d1 <= d2 else layout.angles_deg[cw])


def test_quarter_point_is_600_200():
    stim = make_stimulus(Layout.even(6), 45.0, "dynamic")
    assert (stim.dwell_near_s, stim.dwell_far_s) == pytest.approx((0.6, 0.2))
    assert stim.near_idx == 0
    assert _dwell_times(stim) == pytest.approx((0.6, 0.2), abs=2e-4)


def test_midpoint_counts_counter_clockwise_as_near():
    stim = make_stimulus(Layout.even(6), 0.0, "dynamic")  # between 330 (5) and 30 (0)
    assert stim.near_idx == 5
    assert stim.location(0.0) == pytest.approx(330.0)


def test_transit_goes_through_target():
    stim = make_stimulus(Layout.even(6), 0.0, "dynamic")
    loc = stim.location(np.array([0.45]))  # mid transit 330 -> 30 through 0
    assert float(loc[0]) == pytest.approx(0.0, abs=1e-9) or float(loc[0]) == pytest.approx(360.0)


def test_on_tactor_renders_static_even_in_dynamic_mode():
    stim = make_stimulus(Layout.even(6), 90.0, "dynamic")
    assert not stim.is_dynamic
    _, amps = stim.render(1000.0, 1.0)
    assert np.all(amps == amps[0])


def test_uneven_dynamic_dwell():
    layout = Layout.from_angles([0, 40, 180])
    stim = make_stimulus(layout, 10.0, "dynamic")
    assert stim.near_idx == 0 and stim.far_idx == 1
    assert stim.dwell_near_s == pytest.approx(0.8 * 30 / 40)
    assert _dwell_times(stim, rate=1000.0)[0] == pytest.approx(0.6, abs=2e-3)


def test_render_sample_count_and_times():
    stim = make_stimulus(Layout.even(6), 15.0, "dynamic")
    t, amps = stim.render(250.0, 0.5)
    assert len(t) == round(0.5 * 250) and amps.shape == (125, 6)
    assert t[1] == pytest.approx(1 / 250)


def test_render_batch_matches_single():
    layout = Layout.even(6)
    stims = [make_stimulus(layout, x, "dynamic") for x in TargetSet.even(24)]
    t, amps = render_batch(stims, 1000.0, 1.0)
    assert amps.shape == (24, 1000, 6)
    np.testing.assert_array_equal(amps[3], stims[3].render(1000.0, 1.0)[1])


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"mode": "wobbly"}, "unknown mode"),
        ({"law": "cubic"}, "unknown law"),
        ({"falloff_deg": 0}, "falloff"),
        ({"period_s": -1}, "period"),
        ({"transit_s": 0.5}, "2\\*transit"),
        ({"target_deg": float("nan")}, "finite"),
    ],
)
def test_bad_stimulus_arguments(kwargs, match):
    args = {"target_deg": 15.0} | kwargs
    with pytest.raises(ConfigError, match=match):
        make_stimulus(Layout.even(6), **args)


def test_every_law_name_has_a_function_and_is_offered_by_the_cli() -> None:
    """A law is one name in _lawnames and one function in LAW_FUNCTIONS; the CLI lists it."""
    import subprocess
    import sys

    from tactorbelt._lawnames import LAWS
    from tactorbelt.laws import LAW_FUNCTIONS

    assert tuple(LAW_FUNCTIONS) == LAWS
    out = subprocess.run([sys.executable, "-m", "tactorbelt", "render", "--help"],
                         capture_output=True, text=True, check=True).stdout
    for law in LAWS:
        assert law in out
