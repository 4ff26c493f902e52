"""The direction display's one-frame path (the render thread, update()) computes on plain
floats; it must give the very numbers of the array path (pump(), several frames)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
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
def test_the_pair_of_one_angle_is_the_array_pair(layout: Layout, a: float) -> None:
    with open_belt("sim", clock=SimClock(), layout=layout) as belt:
        d = DirectionDisplay(belt, mode="dynamic", device_render=False)
        ka, kb = d._pairs(np.array([a]))
        assert d._pair_at(a) == (int(ka[0]), int(kb[0]))


@given(angles, angles, st.integers(0, 3_000_000_000),
       st.sampled_from([180.0, 45.0, float("inf")]))
def test_one_frame_slew_is_the_array_slew(start: float, goal: float, dt_ns: int,
                                          slew: float) -> None:
    clock = SimClock()
    with open_belt("sim", clock=clock) as belt:
        one, two = (DirectionDisplay(belt, device_render=False, slew_deg_per_s=slew,
                                     hysteresis_deg=0.0) for _ in range(2))
        for d in (one, two):
            d._requested, d._displayed, d._t_ns = normalize(goal), normalize(start), 0
        t = np.array([dt_ns], dtype=np.int64)
        x1 = one._slew(t)  # the one-frame path
        x2 = two._slew(np.repeat(t, 2))  # the array path, same time twice
        assert x1[0] == x2[-1] and one._displayed == two._displayed
        assert one._t_ns == two._t_ns


def _state(d: DirectionDisplay) -> tuple[object, ...]:
    return (d._pair, d._seg, d._seg_start_ns, d._last_frame_ns, d.pair_changes)


# an angle moving a little or jumping, and the time to its frame: a millisecond (the
# render thread) or long enough to pass through a dwell or a transit
frames = st.lists(st.tuples(
    st.one_of(angles, st.floats(-3.0, 3.0).map(lambda d: ("step", d))),
    st.one_of(st.integers(0, 3), st.integers(0, 900)).map(lambda ms: ms * 1_000_000)),
    min_size=1, max_size=80)


@settings(max_examples=150, deadline=None)
@given(st.sampled_from(LAYOUTS), frames, st.sampled_from([(1.0, 0.1), (0.5, 0.2), (2.0, 0.05)]))
def test_one_frame_locations_are_the_array_locations(layout: Layout, steps: list,
                                                     timing: tuple[float, float]) -> None:
    """The felt location of one frame on floats (update(), the render thread) is the
    array path's (pump()) bit for bit, with the same trapezoid state after, frame after
    frame: dwells, transits, pair changes and waits on a crossed tactor."""
    period, transit = timing
    with open_belt("sim", clock=SimClock(), layout=layout) as belt:
        one, two = (DirectionDisplay(belt, mode="dynamic", period_s=period, transit_s=transit,
                                     device_render=False) for _ in range(2))
        t, x = 0, 10.0
        for move, dt in steps:
            x = x + move[1] if isinstance(move, tuple) else move
            t += dt
            a = one._dynamic_locations(np.array([t], dtype=np.int64), np.array([x]))
            b = two._locations(np.array([t], dtype=np.int64), np.array([x]))
            assert a.tobytes() == b.tobytes(), (t, x)
            assert _state(one) == _state(two)
