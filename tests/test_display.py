"""DirectionDisplay on the sim belt and a simulated clock (nothing sleeps)."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from tactorbelt import ConfigError, Layout, make_stimulus, open_belt
from tactorbelt.clock import SimClock
from tactorbelt.devices.base import Belt
from tactorbelt.display import DirectionDisplay

MS = 1_000_000
S = 1_000_000_000


@pytest.fixture
def clock() -> SimClock:
    return SimClock()


@pytest.fixture
def belt(clock):
    with open_belt("sim", clock=clock) as b:
        yield b


def _levels(belt, t0: int, t1: int, rate: float = 1000.0) -> np.ndarray:
    return belt.commanded(t0, t1, rate)[1]


def _check_sweep_levels(levels: np.ndarray, layout: Layout) -> None:
    on = levels > 0.0
    # never all off
    assert on.any(axis=1).all()
    # never more than two tactors, and two only when they are neighbours
    assert on.sum(axis=1).max() <= 2
    cw, _ = layout.neighbour_indices()
    for row in np.unique(on[on.sum(axis=1) == 2], axis=0):
        a, b = np.flatnonzero(row)
        assert cw[a] == b or cw[b] == a


# -- what is shown ---------------------------------------------------------------------------
@pytest.mark.parametrize("mode", ["static", "dynamic"])
@pytest.mark.parametrize("angle", [45.0, 100.0, 90.0, 347.5])
def test_a_held_direction_is_the_papers_stimulus(belt, clock, mode, angle):
    d = DirectionDisplay(belt, mode=mode, device_render=False)
    t0 = clock.now_ns()
    d.show(angle)
    d.pump(t0 + 3 * S)
    ref = make_stimulus(belt.layout, angle, mode).amplitudes(np.arange(3000) / 1000.0)
    # to 1e-6 as the golden tables (frame times are whole nanoseconds)
    np.testing.assert_allclose(_levels(belt, t0, t0 + 3 * S), ref, atol=1e-6)


@pytest.mark.parametrize("mode", ["static", "dynamic"])
@pytest.mark.parametrize("device_render", [False, True])
def test_a_sweep_never_goes_dark_and_drives_at_most_two_neighbours(belt, clock, mode,
                                                                   device_render):
    d = DirectionDisplay(belt, mode=mode, device_render=device_render)
    t0 = clock.now_ns()
    for i in range(1800):  # 0.2 deg every 5 ms: one turn in 9 s
        d.show(i * 0.2)
        d.pump(clock.now_ns() + 5 * MS)
    d.pump(clock.now_ns() + S)
    _check_sweep_levels(_levels(belt, t0, clock.now_ns()), belt.layout)
    d.hide()


def test_sweep_on_an_uneven_layout(clock):
    layout = Layout.from_angles([0, 40, 120, 200, 300])
    with open_belt("sim", clock=clock, layout=layout) as belt:
        d = DirectionDisplay(belt, mode="dynamic", device_render=False)
        t0 = clock.now_ns()
        for i in range(720):
            d.show(i * 0.5)
            d.pump(clock.now_ns() + 10 * MS)
        _check_sweep_levels(_levels(belt, t0, clock.now_ns()), layout)


@pytest.mark.parametrize("mode", ["static", "dynamic"])
def test_show_at_a_high_call_rate_never_jumps_amplitudes(belt, clock, mode):
    """Requests at 10 kHz, wandering and jumping; frames stay smooth at 1 kHz."""
    slew = 180.0
    d = DirectionDisplay(belt, mode=mode, device_render=False, slew_deg_per_s=slew)
    rng = np.random.default_rng(11)
    t0 = clock.now_ns()
    angle = 20.0
    for i in range(10_000):  # 1 s of requests every 0.1 ms
        angle += rng.normal(0.0, 2.0)
        if i % 2500 == 0:
            angle += 150.0  # a sudden new direction
        d.show(angle)
        d.pump(clock.now_ns() + 100_000)
    levels = _levels(belt, t0, clock.now_ns())
    step = np.abs(np.diff(levels, axis=0)).max()
    falloff, dt = 15.0, 1e-3
    # the paper law changes by at most 1/T per degree; the displayed angle moves at most
    # slew*dt per frame; the dynamic location at most gap/transit*dt (its transit)
    bound = (slew if mode == "static" else 60.0 / 0.1) * dt / falloff
    assert step <= bound + 1e-9
    assert d.max_frame_change <= bound + 1e-9
    assert d.frames_written == pytest.approx(1000, abs=2)


def test_the_displayed_angle_slews_the_short_way(belt, clock):
    d = DirectionDisplay(belt, device_render=False, slew_deg_per_s=100.0, hysteresis_deg=0)
    d.show(350.0)
    d.pump(clock.now_ns() + 10 * MS)
    d.show(30.0)  # 40 degrees clockwise through the navel
    seen = []
    for _ in range(50):
        d.pump(clock.now_ns() + 10 * MS)
        seen.append(d.displayed_deg)
    signed = (np.array(seen) + 180.0) % 360.0 - 180.0
    assert np.all(np.diff(signed) >= 0)  # always clockwise
    assert signed.min() >= -10.0 - 1e-9
    assert d.displayed_deg == pytest.approx(30.0)
    # 40 degrees at 100 deg/s take 0.4 s
    assert seen[38] != pytest.approx(30.0) and seen[40] == pytest.approx(30.0)


def test_dynamic_crossing_a_tactor_restarts_in_the_new_pair_with_the_papers_timing(belt,
                                                                                  clock):
    d = DirectionDisplay(belt, mode="dynamic", device_render=False, slew_deg_per_s=20.0)
    d.show(80.0)
    d.pump(clock.now_ns() + 2 * S)
    d.show(105.0)  # crosses tactor 1 (90) into the pair 90..150
    d.pump(clock.now_ns() + 3 * S)
    # one change of pair (two when a frame lands on the tactor itself: on-tactor, then out)
    assert 1 <= d.pair_changes <= 2
    t0 = clock.now_ns()
    d.pump(t0 + 2 * S)
    got = _levels(belt, t0, t0 + S)
    stim = make_stimulus(belt.layout, 105.0, "dynamic")
    # the paper's timing for 105 deg: 0.6 s on the nearer tactor (90), 0.2 s on 150
    peak = 1.0 - math.exp(-4.0)
    assert np.count_nonzero(np.isclose(got[:, 1], peak)) == pytest.approx(
        1000 * stim.dwell_near_s, abs=2)
    assert np.count_nonzero(np.isclose(got[:, 2], peak)) == pytest.approx(
        1000 * stim.dwell_far_s, abs=2)
    # and the same waveform, up to its phase (the phase need not sit on the 1 ms grid)
    ref = stim.amplitudes(np.arange(2000) / 1000.0)
    best = min(np.abs(got - ref[k:k + 1000]).max() for k in range(1000))
    assert best < 0.6 * (60.0 / 0.1) / 15.0 / 1000.0  # half a frame of transit


def test_show_any_angle_not_only_the_24_targets(belt, clock):
    d = DirectionDisplay(belt, device_render=False, hysteresis_deg=0)
    for angle in (7.3, 123.456, 359.99, -45.0, 725.0):
        d.show(angle)
        d.pump(clock.now_ns() + 2 * S)
        expect = make_stimulus(belt.layout, angle, "static").amplitudes(0.0)
        np.testing.assert_allclose(belt.levels, expect, atol=1e-9)


# -- heading, filter and hysteresis ------------------------------------------------------------
def test_show_bearing_shows_bearing_minus_heading(belt, clock):
    d = DirectionDisplay(belt, device_render=False, hysteresis_deg=0)
    for i in range(20):
        d.show_bearing(100.0, 70.0, t_s=i * 0.05)
        d.pump(clock.now_ns() + 50 * MS)
    assert d.requested_deg == pytest.approx(30.0)
    d.pump(clock.now_ns() + S)
    np.testing.assert_allclose(belt.levels, make_stimulus(belt.layout, 30.0).amplitudes(0.0),
                               atol=1e-9)


@pytest.mark.parametrize("mode", ["static", "dynamic"])
def test_heading_jitter_at_a_tactor_boundary_switches_the_dominant_tactor_at_most_once(
        belt, clock, mode):
    # body angle = bearing - heading = 60: the boundary between tactors 0 (30) and 1 (90)
    d = DirectionDisplay(belt, mode=mode, device_render=False)
    rng = np.random.default_rng(5)
    t0 = clock.now_ns()
    dominant = []
    for i in range(400):  # 20 s of heading at 20 Hz, +-3 deg around 40
        d.show_bearing(100.0, 40.0 + rng.uniform(-3.0, 3.0), t_s=i / 20.0)
        d.pump(clock.now_ns() + 50 * MS)
        dominant.append(d.dominant_tactor)
    assert sum(1 for a, b in itertools.pairwise(dominant) if a != b) <= 1
    if mode == "static":
        # the strongest tactor on the belt follows the display's dominant tactor
        levels = _levels(belt, t0, clock.now_ns(), 100.0)
        strongest = levels.argmax(axis=1)
        assert np.count_nonzero(np.diff(strongest)) <= 1


def test_bad_bearing_or_heading_is_a_config_error(belt):
    d = DirectionDisplay(belt, device_render=False)
    with pytest.raises(ConfigError):
        d.show_bearing("north", 10.0)
    with pytest.raises(ConfigError):
        d.show_bearing(10.0, float("nan"))
    with pytest.raises(ConfigError):
        d.show(float("inf"))


# -- hide, context manager ------------------------------------------------------------------------
@pytest.mark.parametrize("device_render", [False, True])
def test_hide_turns_every_motor_off(belt, clock, device_render):
    d = DirectionDisplay(belt, mode="dynamic", device_render=device_render)
    d.show(75.0)
    d.pump(clock.now_ns() + S)
    assert belt.levels.max() > 0
    d.hide()
    assert not d.playing and d.displayed_deg is None
    d.pump(clock.now_ns() + S)
    assert np.all(belt.levels == 0.0)
    # and it can show again afterwards
    d.show(200.0)
    d.pump(clock.now_ns() + S)
    assert belt.levels.max() > 0


def test_leaving_the_with_block_turns_motors_off_even_on_error(belt, clock):
    with pytest.raises(RuntimeError), DirectionDisplay(belt, device_render=False) as d:
        d.show(10.0)
        d.pump(clock.now_ns() + 100 * MS)
        raise RuntimeError("application failed")
    assert np.all(belt.levels == 0.0)
    assert not belt.closed  # the display does not close the belt


# -- device rendering ---------------------------------------------------------------------------
class CountingRenderBelt(Belt):
    """A belt that renders on the device: counts PLAY_TARGETs (and frames, stops)."""

    def _device_renders(self, stimulus):
        return True

    def __init__(self, clock: SimClock, layout: Layout | None = None) -> None:
        super().__init__("fake-render", "fake render belt", layout or Layout.even(6))
        self.clock = clock
        self.plays: list[tuple[int, float, str]] = []
        self.frames = 0
        self.stops = 0

    def _write_levels(self, levels):
        self.frames += 1

    def _write_stop(self):
        self.stops += 1

    def _write_play(self, stimulus, duration_s):
        assert duration_s is None
        self.plays.append((self.clock.now_ns(), stimulus.target_deg, stimulus.mode))


def _wrapdiff(a: float, b: float) -> float:
    return abs((a - b + 180.0) % 360.0 - 180.0)


@pytest.mark.parametrize("mode", ["static", "dynamic"])
def test_device_belt_gets_play_target_only_when_the_direction_moves_more_than_the_step(mode):
    clock = SimClock()
    belt = CountingRenderBelt(clock)
    with DirectionDisplay(belt, mode=mode, step_deg=2.0) as d:
        assert d.device_render
        d.show(40.0)
        d.pump(clock.now_ns() + 2 * S)
        assert len(belt.plays) == 1 and belt.plays[0][1] == pytest.approx(40.0)
        # small wobbles within the step: nothing sent, at any call rate
        rng = np.random.default_rng(2)
        for _ in range(2000):
            d.show(40.0 + rng.uniform(-1.9, 1.9))
            d.pump(clock.now_ns() + MS)
        assert len(belt.plays) == 1
        assert belt.frames == 0
        # a real change: sent (in slewed steps), ending on the new direction
        d.show(100.0)
        d.pump(clock.now_ns() + 3 * S)
        sent = [a for _, a, _ in belt.plays]
        assert len(sent) >= 2 and sent[-1] == pytest.approx(100.0)
        assert all(_wrapdiff(a, b) > 2.0 for a, b in itertools.pairwise(sent))
        assert d.plays_sent == len(sent)
    assert belt.stops >= 1  # motors off on exit


def test_device_dynamic_changes_wait_for_the_start_of_a_dwell_on_the_nearer_tactor():
    clock = SimClock()
    belt = CountingRenderBelt(clock)
    d = DirectionDisplay(belt, mode="dynamic", slew_deg_per_s=math.inf, hysteresis_deg=0)
    d.show(20.0)  # between 330 and 30, nearer 30: dwell on 30 first
    d.pump(clock.now_ns() + 300 * MS)
    d.show(25.0)  # same nearer tactor: waits for the next period start
    d.pump(clock.now_ns() + 2 * S)
    (t_a, a, _), (t_b, b, _) = belt.plays[:2]
    assert b == pytest.approx(25.0)
    assert (t_b - t_a) == 1 * S  # one period after the first onset
    d.hide()


def test_device_render_needs_a_capable_identity_belt(belt):
    from tactorbelt.devices.calibration import Calibration, TactorCalibration

    class Streaming(CountingRenderBelt):
        def _device_renders(self, stimulus):
            return False

    with pytest.raises(ConfigError, match="cannot render"):
        DirectionDisplay(Streaming(SimClock()), device_render=True)
    cal = Calibration(tuple(TactorCalibration(start=0.2) for _ in range(6)))
    with open_belt("sim", clock=SimClock(), calibration=cal) as calibrated:
        assert not DirectionDisplay(calibrated).device_render  # auto: stream
        with pytest.raises(ConfigError, match="calibration"):
            DirectionDisplay(calibrated, device_render=True)
    assert DirectionDisplay(belt).device_render  # the sim belt renders itself


@pytest.mark.parametrize("kwargs", [{"mode": "wobbly"}, {"law": "cubic"}, {"slew_deg_per_s": 0},
                                    {"step_deg": -1}, {"rate_hz": 0}, {"hysteresis_deg": 45},
                                    {"falloff_deg": -3}, {"transit_s": 0.6}])
def test_bad_parameters_are_config_errors(belt, kwargs):
    with pytest.raises(ConfigError):
        DirectionDisplay(belt, **kwargs)


def test_pump_is_refused_on_a_wall_clock_display():
    from tactorbelt.clock import WallClock

    with open_belt("sim", clock=WallClock()) as wall_belt:
        d = DirectionDisplay(wall_belt, device_render=False)
        with pytest.raises(Exception, match="pump"):
            d.pump(0)


@pytest.mark.parametrize("angle", [40.0, 75.0, 60.0, 30.0])
def test_a_steady_dynamic_direction_streams_exactly_the_papers_stimulus(belt, clock, angle):
    """For a direction that does not move, the streamed perturbation is the stimulus's own
    (make_stimulus(...).amplitudes(t since onset)): the display's trapezoid is the paper's."""
    d = DirectionDisplay(belt, mode="dynamic", device_render=False, hysteresis_deg=0.0)
    onset = clock.now_ns()
    d.show(angle)
    d.pump(onset + 3000 * MS)
    stim = make_stimulus(belt.layout, angle, "dynamic")
    t = np.arange(3000) / 1000.0
    got = _levels(belt, onset, onset + 3000 * MS)
    assert np.allclose(got, stim.amplitudes(t), atol=1e-9)
