import math

import numpy as np
import pytest
from hypothesis import example, given
from hypothesis import strategies as st

from tactorbelt import ConfigError
from tactorbelt.geometry import Layout, TargetSet, normalize, parse_angle, wrap

finite = st.floats(-1e6, 1e6, allow_nan=False)


def test_default_layout_puts_front_tactors_symmetric_about_navel():
    layout = Layout.even(6)
    assert layout.angles_deg == (30.0, 90.0, 150.0, 210.0, 270.0, 330.0)
    assert Layout.even(8).angles_deg[0] == 22.5


def same_angle(a: float, b: float, atol: float = 1e-6) -> bool:
    """a and b differ by a multiple of 360 (the wrapped difference, so 359.9... == 0)."""
    d = math.remainder(a - b, 360.0)  # in [-180, 180], exact
    return abs(d) <= atol


# values whose np.mod rounds up to the modulus: normalize/wrap must fold them back
EDGES = [-1e-17, -5e-324, math.nextafter(360.0, 0.0), math.nextafter(180.0, math.inf),
         math.nextafter(-180.0, -math.inf), 540.0 + 1e-13, -180.0, 180.0, 0.0, -0.0]


@given(finite)
@example(EDGES[0])
@example(EDGES[1])
@example(EDGES[2])
@example(math.nextafter(0.0, -1.0))
def test_normalize_is_in_range_and_idempotent(a):
    n = normalize(a)
    assert 0.0 <= n < 360.0
    assert same_angle(n, a)
    assert normalize(n) == n


@given(finite)
@example(EDGES[3])  # np.mod(180 - a, 360) rounds to 360: wrap gave -180
@example(EDGES[4])
@example(EDGES[5])
@example(-180.0)
@example(180.0)
def test_wrap_is_in_half_open_interval(a):
    w = wrap(a)
    assert -180.0 < w <= 180.0
    assert same_angle(w, a)


def test_wrap_and_normalize_arrays_fold_the_edges():
    w = wrap(np.array(EDGES))
    n = normalize(np.array(EDGES))
    assert np.all((w > -180.0) & (w <= 180.0))
    assert np.all((n >= 0.0) & (n < 360.0))


@given(st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                          st.sampled_from(EDGES)), max_size=30))
def test_an_array_is_wrapped_element_by_element(values):
    """Every element of an array (NaNs and the folded edges mixed in any order) is
    wrapped as the float alone, bit for bit; the input array is left as it was."""
    arr = np.array(values, dtype=float)
    before = arr.copy()
    with np.errstate(invalid="ignore"):
        got = wrap(arr)
    assert got.shape == arr.shape and np.array_equal(arr, before, equal_nan=True)
    for g, a in zip(got.tolist(), values, strict=True):
        w = wrap(float(a))
        assert (math.isnan(g) and math.isnan(w)) or (g == w and math.copysign(1, g)
                                                      == math.copysign(1, w))


def test_wrap_edges():
    assert wrap(180.0) == 180.0
    assert wrap(-180.0) == 180.0
    assert wrap(190.0) == -170.0


@pytest.mark.parametrize("text", ["abc", "nan", "inf", "-inf", ""])
def test_parse_angle_refuses_non_finite(text):
    with pytest.raises(ConfigError, match="finite number"):
        parse_angle(text)


def test_parse_angle_normalises():
    assert parse_angle("375") == 15.0
    assert parse_angle("-15") == 345.0


def test_neighbours_bracket_every_angle():
    layout = Layout.even(6)
    assert layout.neighbours(45.0) == (0, 1)
    assert layout.neighbours(0.0) == (5, 0)
    assert layout.neighbours(345.0) == (5, 0)
    assert layout.neighbours(30.0)[0] == 0  # on a tactor: ccw is that tactor
    ccw, cw = layout.neighbours(np.array([10.0, 100.0, 200.0]))
    assert list(ccw) == [5, 1, 2] and list(cw) == [0, 2, 3]


def test_uneven_unsorted_layout_neighbours():
    layout = Layout.from_angles([90, 10, 200])
    assert layout.neighbours(50.0) == (1, 0)
    assert layout.neighbours(300.0) == (2, 1)
    assert list(layout.gaps_deg()) == [110.0, 80.0, 170.0]


def test_on_tactor_and_targets():
    layout = Layout.even(6)
    targets = TargetSet.even(24)
    on = targets.on_tactor(layout)
    assert on.sum() == 6
    assert list(targets.angles[on]) == [30, 90, 150, 210, 270, 330]
    assert targets.nearest(16.0) == 15.0
    assert targets.nearest(359.0) == 0.0


@pytest.mark.parametrize(
    "angles, match",
    [([30.0], "at least 2"), ([30.0, 30.0, 90.0], "duplicate"), ([10.0, 370.0], "duplicate")],
)
def test_bad_layouts(angles, match):
    with pytest.raises(ConfigError, match=match):
        Layout.from_angles(angles)


def test_even_layout_needs_two_tactors():
    with pytest.raises(ConfigError):
        Layout.even(1)


@given(st.floats(allow_nan=True, allow_infinity=True))
@example(EDGES[0])
@example(EDGES[3])
@example(-0.0)
@example(math.nextafter(0.0, -1.0))
def test_a_float_is_wrapped_and_normalised_as_in_an_array(a):
    """The scalar path (Python's %) gives the array path's numbers, bit for bit."""
    with np.errstate(invalid="ignore"):
        arr_n, arr_w = normalize(np.array([a]))[0], wrap(np.array([a]))[0]
    n, w = normalize(a), wrap(a)
    assert type(n) is float and type(w) is float
    assert (math.isnan(n) and math.isnan(arr_n)) or (n == arr_n and math.copysign(1, n)
                                                      == math.copysign(1, arr_n))
    assert (math.isnan(w) and math.isnan(arr_w)) or (w == arr_w and math.copysign(1, w)
                                                      == math.copysign(1, arr_w))
