"""The direction display computes each frame on plain floats: its wrap, normalize and
tactor pair must give the very numbers of the geometry's array functions."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from tactorbelt import Layout, open_belt
from tactorbelt.clock import SimClock
from tactorbelt.display.direction import DirectionDisplay, _normalize1, _wrap1
from tactorbelt.geometry import normalize, wrap

LAYOUTS = [Layout.even(6), Layout.even(8), Layout((0.0, 50.0, 130.0, 180.0, 250.0))]

angles = st.one_of(
    st.floats(-1e4, 1e4, allow_nan=False),
    # on a tactor, within the on-tactor tolerance, and just past it
    st.tuples(st.sampled_from([0.0, 45.0, 50.0, 60.0, 130.0, 180.0, 300.0, 360.0, -360.0]),
              st.sampled_from([0.0, 1e-7, -1e-7, 2e-6, -2e-6, 1e-17, -1e-17, -3e-14])).map(sum),
)


@given(angles)
def test_float_wrap_and_normalize_are_the_array_ones(a: float) -> None:
    assert _wrap1(a) == wrap(a)
    assert _normalize1(a) == normalize(a)


@given(st.sampled_from(LAYOUTS), angles)
def test_the_pair_of_an_angle_is_the_layouts(layout: Layout, a: float) -> None:
    """The pair bracketing an angle, in plain Python, is the one Layout.tactor_at and
    Layout.neighbours find: (k, k) on tactor k, else (ccw, cw)."""
    with open_belt("sim", clock=SimClock(), layout=layout) as belt:
        d = DirectionDisplay(belt, mode="dynamic", device_render=False)
        on = int(np.asarray(layout.tactor_at(np.array([a])))[0])
        ccw, cw = (int(k[0]) for k in layout.neighbours(np.array([a])))
        assert d._pair_at(a) == ((on, on) if on >= 0 else (ccw, cw))
