"""Pure geometry of the window and the joystick mapping: no pygame display needed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactorbelt import ConfigError
from tactorbelt.experiment.trial import cursor_angle_deg
from tactorbelt.inputs.joystick import stick_to_cursor
from tactorbelt.inputs.kinds import JoystickConfig
from tactorbelt.inputs.screen import EllipseGeometry, fit_ellipse, ray_radius, target_positions

CENTER = (400.0, 300.0)
RX, RY = 250.0, 200.0


def test_targets_on_the_axes_are_at_the_ellipse_extremes() -> None:
    pos = target_positions([0, 90, 180, 270], CENTER, RX, RY)
    # front at the top (screen y grows down), 90 deg (right flank) on the right
    np.testing.assert_allclose(pos, [[400, 100], [650, 300], [400, 500], [150, 300]],
                               atol=1e-9)


@given(st.floats(0, 360, exclude_max=True), st.floats(20, 900), st.floats(20, 900))
def test_each_target_lies_on_the_ellipse_along_its_ray(theta: float, rx: float, ry: float
                                                       ) -> None:
    (px, py), = target_positions([theta], CENTER, rx, ry)
    dx, dy = px - CENTER[0], CENTER[1] - py
    # on the ellipse
    assert (dx / rx) ** 2 + (dy / ry) ** 2 == pytest.approx(1.0, abs=1e-9)
    # on the ray at theta, clockwise from the top
    assert abs((math.degrees(math.atan2(dx, dy)) - theta + 180) % 360 - 180) < 1e-6


def test_ray_radius_formula() -> None:
    t = math.radians(30)
    want = 1 / math.sqrt((math.sin(t) / RX) ** 2 + (math.cos(t) / RY) ** 2)
    assert ray_radius(30, RX, RY) == pytest.approx(want)


@given(st.floats(-1.2, 1.2), st.floats(-1.2, 1.2))
def test_cursor_to_pixels_and_back(x: float, y: float) -> None:
    g = EllipseGeometry(*CENTER, RX, RY)
    px, py = g.to_pixels(x, y)
    bx, by = g.from_pixels(px, py, clamp=False)
    assert (bx, by) == pytest.approx((x, y), abs=1e-9)


@given(st.floats(0, 360, exclude_max=True))
def test_a_cursor_on_a_drawn_target_has_that_target_s_angle(theta: float) -> None:
    """What the participant sees is what the trial machine scores."""
    g = EllipseGeometry(*CENTER, RX, RY)
    (px, py), = g.targets([theta])
    x, y = g.from_pixels(px, py)
    assert math.hypot(x, y) == pytest.approx(1.0, abs=1e-9)
    diff = (cursor_angle_deg(x, y) - theta + 180) % 360 - 180
    assert abs(diff) < 1e-6


def test_axes_map_by_plain_scaling() -> None:
    g = EllipseGeometry(*CENTER, RX, RY)
    assert g.to_pixels(0.5, 0.0) == pytest.approx((400 + 0.5 * RX, 300))
    assert g.to_pixels(0.0, -0.5) == pytest.approx((400, 300 + 0.5 * RY))


def test_from_pixels_clamps_to_the_ellipse() -> None:
    g = EllipseGeometry(*CENTER, RX, RY)
    x, y = g.from_pixels(CENTER[0] + 3 * RX, CENTER[1])
    assert (x, y) == pytest.approx((1.0, 0.0))


def test_fit_ellipse_stays_inside_the_window() -> None:
    for w, h in [(1280, 800), (800, 1280), (320, 240), (1920, 1080)]:
        g = fit_ellipse(w, h, aspect=1.25, top_band=40)
        assert g.rx / g.ry == pytest.approx(1.25)
        assert g.cx - g.rx > 0 and g.cx + g.rx < w
        assert g.cy - g.ry > 40 and g.cy + g.ry < h


# -- joystick mapping ----------------------------------------------------------------------
def test_stick_centre_and_dead_zone_give_the_centre() -> None:
    assert stick_to_cursor(0.0, 0.0) == (0.0, 0.0)
    assert stick_to_cursor(0.04, -0.03, dead_zone=0.05) == (0.0, 0.0)
    x, y = stick_to_cursor(0.2, 0.0, dead_zone=0.05)
    assert x > 0 and y == 0


def test_dead_zone_rescales_so_full_deflection_still_reaches_the_ellipse() -> None:
    assert stick_to_cursor(1.0, 0.0, dead_zone=0.2) == pytest.approx((1.0, 0.0))
    # just past the dead zone the cursor starts from 0, continuously
    x, _ = stick_to_cursor(0.21, 0.0, dead_zone=0.2)
    assert 0 < x < 0.02


def test_stick_forward_is_the_front() -> None:
    # SDL reports -1 on the vertical axis when the stick is pushed forward
    assert stick_to_cursor(0.0, -1.0, dead_zone=0.0) == pytest.approx((0.0, 1.0))
    assert stick_to_cursor(0.0, 1.0, dead_zone=0.0) == pytest.approx((0.0, -1.0))
    assert stick_to_cursor(1.0, 0.0, dead_zone=0.0) == pytest.approx((1.0, 0.0))


def test_inversion() -> None:
    assert stick_to_cursor(0.5, 0.0, 0.0, invert_x=True) == pytest.approx((-0.5, 0.0))
    assert stick_to_cursor(0.0, -0.5, 0.0, invert_y=True) == pytest.approx((0.0, -0.5))


def test_full_diagonal_reaches_the_ellipse_at_45_degrees() -> None:
    x, y = stick_to_cursor(1.0, -1.0, dead_zone=0.0)
    assert math.hypot(x, y) == pytest.approx(1.0)
    assert cursor_angle_deg(x, y) == pytest.approx(45.0)


@given(st.floats(-5, 5), st.floats(-5, 5), st.floats(0, 0.9), st.booleans(), st.booleans())
def test_cursor_never_leaves_the_ellipse(ax: float, ay: float, dz: float, ix: bool, iy: bool
                                         ) -> None:
    x, y = stick_to_cursor(ax, ay, dz, ix, iy)
    assert x * x + y * y <= 1.0 + 1e-12


def test_non_finite_axes_give_the_centre() -> None:
    assert stick_to_cursor(float("nan"), 0.3) == (0.0, 0.0)


def test_bad_dead_zone_and_axes_are_refused() -> None:
    with pytest.raises(ConfigError, match="dead zone"):
        stick_to_cursor(0, 0, dead_zone=1.0)
    with pytest.raises(ConfigError, match="dead zone"):
        JoystickConfig(dead_zone=-0.1)
    with pytest.raises(ConfigError, match="both 0"):
        JoystickConfig(axis_x=0, axis_y=0)
    assert JoystickConfig.parse_device("1") == 1
    assert JoystickConfig.parse_device(" Warthog ") == "Warthog"
    assert JoystickConfig.parse_device("") is None
