"""The sim belt: ERM model, device-side rendering, history, motors off on every exit."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tactorbelt import ConfigError, TactorbeltError
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.devices import sim as sim_module
from tactorbelt.devices.calibration import Calibration, TactorCalibration
from tactorbelt.devices.sim import ErmParams, SimBelt, erm_speed, open_sim, sample_grid
from tactorbelt.geometry import Layout
from tactorbelt.stimuli import make_stimulus

S = 1_000_000_000
MS = 1_000_000


def sim(**kw: object) -> tuple[SimBelt, SimClock]:
    """A sim belt on a simulated clock, plain unless ``drive`` is given (these tests hold
    the motor model as driven; tests/test_drive_shaping.py the shaped drive)."""
    clock = SimClock()
    belt = open_sim("", clock=clock, **{"drive": "plain", **kw})
    return belt, clock


def reference_speed(levels: np.ndarray, dt_s: float, p: ErmParams) -> np.ndarray:
    """A plain step-by-step solution of the same model (the slow way)."""
    w = np.zeros(levels.shape[1])
    out = []
    for row in levels:
        out.append(w.copy())
        u = np.where(row >= p.start_level, row, 0.0)
        tau = np.where(u > w, p.rise_tau_s, p.fall_tau_s)
        w = u + (w - u) * np.exp(-dt_s / tau)
    return np.array(out)


# -- the paper's stimuli through the motor model --------------------------------------


def test_dynamic_quarter_point_shows_the_600_200_ms_dwell_asymmetry() -> None:
    belt, clock = sim()
    stim = make_stimulus(belt.layout, 15.0, "dynamic")  # near tactor 0 (30), far tactor 5 (330)
    assert (stim.near_idx, stim.far_idx) == (0, 5)
    onset = clock.now_ns()
    belt.play(stim, 3.0)
    _, vib = belt.vibration(onset + 1 * S, onset + 2 * S)  # one whole period, spun up
    near, far = vib[:, 0], vib[:, 5]
    near_share = float(np.mean(near > far))
    assert 0.6 <= near_share <= 0.8, near_share  # 600 ms dwell + half of each transit
    assert 0.2 <= 1.0 - near_share <= 0.4
    # each motor is felt strongly for a time that follows its dwell
    t_near = float(np.sum(near > 0.5 * near.max())) / 1000
    t_far = float(np.sum(far > 0.5 * far.max())) / 1000
    assert t_near > 2.0 * t_far
    # the other four motors never move
    assert np.all(vib[:, 1:5] == 0.0)


def test_static_stimulus_gives_constant_vibration_once_spun_up() -> None:
    belt, clock = sim()
    stim = make_stimulus(belt.layout, 15.0, "static")
    onset = clock.now_ns()
    belt.play(stim, 3.0)
    _, levels = belt.commanded(onset, onset + 2 * S)
    _, vib = belt.vibration(onset + 1 * S, onset + 2 * S)
    assert np.ptp(vib, axis=0).max() < 1e-9
    expected = np.where(levels[0] >= belt.params.start_level, levels[0], 0.0) ** 2
    np.testing.assert_allclose(vib[-1], expected, atol=1e-9)
    # and it had to spin up: lower at the onset
    _, early = belt.vibration(onset, onset + 20 * MS)
    assert early[0].max() == 0.0 and early[-1].max() < expected.max()


# -- the model itself -----------------------------------------------------------------


def test_rise_and_fall_follow_their_time_constants() -> None:
    belt, clock = sim()
    p = belt.params
    belt.set_amplitudes([1, 0, 0, 0, 0, 0])
    t_on = clock.now_ns()
    clock.advance(2 * S)
    belt.stop()
    t_off = clock.now_ns()
    rise = belt.vibration_at([t_on + round(p.rise_tau_s * S)])[0, 0]
    assert rise == pytest.approx((1 - math.exp(-1)) ** 2, rel=1e-9)
    fall = belt.vibration_at([t_off + round(p.fall_tau_s * S)])[0, 0]
    assert fall == pytest.approx(math.exp(-1) ** 2, rel=1e-6)


def test_dead_zone_no_spin_below_the_start_level() -> None:
    belt, clock = sim(params=ErmParams(start_level=0.3))
    t0 = clock.now_ns()
    belt.set_amplitudes([0.29, 0.31, 0, 0, 0, 0])
    clock.advance(S)
    _, vib = belt.vibration(t0, t0 + S)
    assert np.all(vib[:, 0] == 0.0)
    assert vib[-1, 1] == pytest.approx(0.31**2, rel=1e-9)


def test_exact_solution_matches_step_by_step_reference_on_random_frames() -> None:
    rng = np.random.default_rng(7)
    p = ErmParams()
    levels = rng.random((1500, 6)) * (rng.random((1500, 6)) < 0.6)
    levels = np.repeat(levels, 3, axis=0)  # some constant stretches, some jumps
    t = np.arange(levels.shape[0], dtype=np.int64) * MS
    fast = erm_speed(t, levels, np.zeros(6), p)
    np.testing.assert_allclose(fast, reference_speed(levels, 1e-3, p), atol=1e-12)


@given(seed=st.integers(0, 2**32 - 1), n_changes=st.integers(0, 14),
       w0=st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6))
def test_a_drive_with_few_changes_matches_the_step_by_step_reference(
        seed: int, n_changes: int, w0: list[float]) -> None:
    """Few changes of drive (a static stimulus, stops, gaps) take the closed form stretch
    by stretch; many take the recurrence: both are the model, from any starting speed."""
    rng = np.random.default_rng(seed)
    p = ErmParams()
    n = 400
    cuts = np.sort(rng.choice(np.arange(1, n - 1), size=n_changes, replace=False))
    rows = rng.random((n_changes + 1, 6)) * (rng.random((n_changes + 1, 6)) < 0.7)
    levels = rows[np.searchsorted(cuts, np.arange(n), side="right")]
    t = np.arange(n, dtype=np.int64) * MS
    ref = np.zeros((n, 6))
    w = np.array(w0)
    for j in range(n):
        ref[j] = w
        u = np.where(levels[j] >= p.start_level, levels[j], 0.0)
        w = u + (w - u) * np.exp(-1e-3 / np.where(u > w, p.rise_tau_s, p.fall_tau_s))
    np.testing.assert_allclose(erm_speed(t, levels, np.array(w0), p), ref, atol=1e-12)


def test_vibration_state_carries_over_between_queries() -> None:
    belt, clock = sim()
    onset = clock.now_ns()
    belt.play(make_stimulus(belt.layout, 100.0, "dynamic"), 2.0)
    clock.advance(2_500 * MS)
    _, whole = belt.vibration(onset, onset + 2_500 * MS)
    pieces = [belt.vibration(onset + k * 250 * MS, onset + (k + 1) * 250 * MS)[1]
              for k in (3, 0, 7, 1, 2, 9, 4, 5, 6, 8)]
    order = [3, 0, 7, 1, 2, 9, 4, 5, 6, 8]
    joined = np.concatenate([pieces[order.index(k)] for k in range(10)])
    np.testing.assert_allclose(joined, whole, atol=1e-12)


def test_queries_as_time_goes_by_match_one_query_afterwards() -> None:
    # each query leaves a checkpoint between commands; later queries start from it
    belt, clock = sim()
    ref, ref_clock = sim()
    stim = make_stimulus(belt.layout, 100.0, "dynamic")
    for b in (belt, ref):
        b.play(stim)
    step = 37 * MS + 123
    times, got = [], []
    for k in range(40):
        clock.advance(step)
        if k == 20:
            belt.set_amplitudes([0, 0.3, 0.9, 0, 0, 0])
            ref_clock.advance(21 * step)
            ref.set_amplitudes([0, 0.3, 0.9, 0, 0, 0])
        t, v = belt.vibration(k * step, (k + 1) * step)
        times.append(t)
        got.append(v)
    np.testing.assert_allclose(np.concatenate(got), ref.vibration_at(np.concatenate(times)),
                               atol=1e-12)


def test_streamed_frames_and_rendered_stimulus_give_the_same_vibration() -> None:
    stim = make_stimulus(Layout.even(6), 45.0, "dynamic")
    a, ca = sim()
    a.play(stim, 1.0)
    b, cb = sim()
    _, amps = stim.render(1000.0, 1.0)
    for row in amps:
        b.set_amplitudes(row)
        cb.advance(MS)
    b.stop()
    np.testing.assert_allclose(a.vibration(0, 1_200 * MS)[1], b.vibration(0, 1_200 * MS)[1],
                               atol=1e-12)


class _GridBelt(SimBelt):
    """A sim belt that always takes the general solution (every breakpoint on one grid)."""

    def _speed_pieces(self, times, t_a, w_a, grid=None):  # type: ignore[no-untyped-def]
        return None


_OPS = st.one_of(
    st.tuples(st.just("advance"), st.integers(1, 900_000_000)),
    st.tuples(st.just("play"), st.floats(0.0, 359.0), st.sampled_from(["static", "dynamic"]),
              st.sampled_from([None, 0.25, 1.0, 1.5003]),
              st.sampled_from([1.0, 0.5, 0.3337])),
    st.tuples(st.just("set"), st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6)),
    st.tuples(st.just("stop"),),
    st.tuples(st.just("query"), st.integers(0, 3_000_000_000), st.integers(1, 900),
              st.sampled_from([1000.0, 997.0, 250.0])),
)


@given(ops=st.lists(_OPS, min_size=1, max_size=25))
def test_piecewise_solution_equals_the_general_one_for_any_history(ops: list[tuple]) -> None:
    """Constant stretches in closed form and periodic renders from their response from
    rest (by superposition) give the model's speeds: those of the general solution, for
    any commands, durations, periods (whole ticks or not) and query times."""
    clock = SimClock()
    fast = SimBelt(clock=clock)
    grid = _GridBelt(clock=clock)
    for op in ops:
        if op[0] == "advance":
            clock.advance(op[1])
        elif op[0] == "play":
            stim = make_stimulus(fast.layout, op[1], op[2], period_s=op[4],
                                 transit_s=min(0.2, op[4] / 4))
            fast.play(stim, op[3])
            grid.play(stim, op[3])
        elif op[0] == "set":
            fast.set_amplitudes(op[1])
            grid.set_amplitudes(op[1])
        elif op[0] == "stop":
            fast.stop()
            grid.stop()
        else:
            t0 = max(0, clock.now_ns() - op[1])
            t1 = t0 + op[2] * MS
            a, b = fast.vibration(t0, t1, op[3]), grid.vibration(t0, t1, op[3])
            np.testing.assert_array_equal(a[0], b[0])
            np.testing.assert_allclose(a[1], b[1], rtol=0, atol=1e-12)
    t_end = clock.now_ns() + 500 * MS
    np.testing.assert_allclose(fast.vibration(0, t_end)[1], grid.vibration(0, t_end)[1],
                               rtol=0, atol=1e-12)


@pytest.mark.parametrize("mode", ["static", "dynamic"])
@pytest.mark.parametrize("before", [0.0, 0.3, 1.0])
def test_a_window_from_a_render_onset_is_the_same_to_the_bit_trial_after_trial(
        mode: str, before: float) -> None:
    """The model participant reads each trial's stimulus over the same window from its
    onset (1 kHz, from the motors' state then): the terms memoised for that window give
    exactly the speeds of the same times read without it (``vibration_at``), whether the
    motors were still falling from the trial before (``before``), at rest, or spinning
    too fast for the response from rest (then the general path is taken)."""
    clock = SimClock()
    a, b = SimBelt(clock=clock), SimBelt(clock=clock)
    layout = a.layout
    for trial, target in enumerate([37.5, 37.5, 100.0, 37.5, 0.0, 37.5]):
        stim = make_stimulus(layout, target, mode)
        if before:
            for belt in (a, b):
                belt.set_amplitudes([before] * layout.n)
            clock.advance(200 * MS)
            for belt in (a, b):
                belt.stop()
            clock.advance((50 + 30 * trial) * MS)  # still falling at the next onset
        onset = clock.now_ns()
        for belt in (a, b):
            belt.play(stim, 2.0)
        clock.advance(900 * MS)
        times, got = a.vibration(onset, clock.now_ns())
        np.testing.assert_array_equal(got, b.vibration_at(times))
        assert got[-1].max() > 0.1  # the stimulus is felt
        clock.advance(1100 * MS)
        for belt in (a, b):
            belt.stop()
        clock.advance(700 * MS)


@given(w=st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6),
       dt_ns=st.integers(0, 30_000_000_000))
def test_an_undriven_stretch_is_one_fall_factor_to_the_bit(w: list[float], dt_ns: int) -> None:
    """Between trials no motor is driven: the state after such a stretch is the state
    times one fall factor, exactly what the closed form of a stretch gives for a zero
    drive (so the stored results do not depend on the shortcut)."""
    p = ErmParams()
    state = np.array(w)
    expected = sim_module._relax_to(np.zeros(6), state, dt_ns, p)
    np.testing.assert_array_equal(state * sim_module._fall_factor_to(dt_ns, p), expected)


def test_a_render_started_on_spinning_motors_is_solved_exactly() -> None:
    """From rest the render's motors rise; from full speed they fall at first: another
    rise/fall pattern, where superposition on the response from rest would be wrong."""
    clock = SimClock()
    fast, grid = SimBelt(clock=clock), _GridBelt(clock=clock)
    for belt in (fast, grid):
        belt.set_amplitudes([1.0] * 6)
    clock.advance(S)
    stim = make_stimulus(fast.layout, 15.0, "dynamic")
    for belt in (fast, grid):
        belt.play(stim, 1.0)
    clock.advance(1500 * MS)
    a, b = fast.vibration(S, 2500 * MS)[1], grid.vibration(S, 2500 * MS)[1]
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-12)
    assert a[0, 0] > 0.99 and a[:, 0].min() < 0.5  # it did fall from full speed


def test_the_process_wide_tables_stay_within_their_memory_and_stay_exact(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Many stimuli: the oldest tables and responses are dropped to keep
    within the budget; a dropped one is made again, and every query stays exact."""
    monkeypatch.setattr(sim_module, "_RESPONSES_BUDGET", 300_000)
    monkeypatch.setattr(sim_module, "_TABLES_BUDGET", 200_000)
    clock = SimClock()
    fast, grid = SimBelt(clock=clock), _GridBelt(clock=clock)
    for k in range(12):
        stim = make_stimulus(fast.layout, 7.0 + 10.0 * (k % 6) + 0.5 * k, "dynamic")
        t0 = clock.now_ns()
        for belt in (fast, grid):
            belt.play(stim, 0.6)
        clock.advance(800 * MS)
        np.testing.assert_allclose(fast.vibration(t0, clock.now_ns())[1],
                                   grid.vibration(t0, clock.now_ns())[1], rtol=0, atol=1e-12)
        assert sum(r.nbytes for r in sim_module._RESPONSES.values()) <= 300_000
        assert sum(t.nbytes for t in sim_module._PERIODS.values()) <= 200_000
    assert 1 <= len(sim_module._RESPONSES) < 12 and len(sim_module._PERIODS) < 12


def test_a_stimulus_object_played_again_shares_its_tables_until_pruned() -> None:
    """A study plays the same stimulus objects again and again: later renders take the
    first one's table and response (no lookup) and stay exact; once the first render
    leaves the kept history, the belt forgets the object (memory stays bounded)."""
    clock = SimClock()
    fast, grid = SimBelt(clock=clock, horizon_s=3.0), _GridBelt(clock=clock, horizon_s=3.0)
    stims = [make_stimulus(fast.layout, a, "dynamic") for a in (20.0, 80.0)]
    shared = 0
    for k in range(8):
        t0 = clock.now_ns()
        for belt in (fast, grid):
            belt.play(stims[k % 2], 0.7)
        clock.advance(900 * MS)
        np.testing.assert_allclose(fast.vibration(t0, clock.now_ns())[1],
                                   grid.vibration(t0, clock.now_ns())[1], rtol=0, atol=1e-12)
        first = fast._played[id(stims[k % 2])]
        latest = fast._renders[max(fast._renders)]
        if latest is not first:  # (a first render pruned from the history: a new first)
            assert latest._table is first._table
            assert latest._response is first._response
            shared += 1
    assert shared >= 4
    for _ in range(10):  # past the horizon and its slack: the history is pruned
        clock.advance(S)
        fast.stop()
    assert not fast._played


def test_a_render_beyond_its_tabulated_response_takes_the_general_solution() -> None:
    clock = SimClock()
    fast, grid = SimBelt(clock=clock), _GridBelt(clock=clock)
    stim = make_stimulus(fast.layout, 40.0, "dynamic")
    fast.play(stim)
    grid.play(stim)
    clock.advance(12 * S)  # past the 10 s kept from rest
    np.testing.assert_allclose(fast.vibration(11 * S, 12 * S)[1],
                               grid.vibration(11 * S, 12 * S)[1], rtol=0, atol=1e-12)
    np.testing.assert_allclose(fast.vibration(0, 12 * S)[1], grid.vibration(0, 12 * S)[1],
                               rtol=0, atol=1e-12)


# -- device-side rendering --------------------------------------------------------------


def test_play_renders_the_stimulus_at_1khz_until_its_end() -> None:
    belt, clock = sim()
    stim = make_stimulus(belt.layout, 15.0, "dynamic")
    clock.advance(123 * MS)
    onset = clock.now_ns()
    belt.play(stim, 1.5)
    t, levels = belt.commanded(onset, onset + 2 * S)
    _, expected = stim.render(1000.0, 1.5)
    np.testing.assert_allclose(levels[:1500], expected, atol=1e-12)
    assert np.all(levels[1500:] == 0.0)
    assert t[0] == onset and t[1] - t[0] == MS


def test_play_goes_through_the_calibration_and_stop_ends_it() -> None:
    cal = Calibration(tuple(TactorCalibration(0.3, 1.0, 0.8) for _ in range(6)))
    belt, clock = sim(calibration=cal)
    stim = make_stimulus(belt.layout, 30.0, "static")  # on tactor 0
    belt.play(stim, None)
    clock.advance(500 * MS)
    lv = belt.levels
    assert lv[0] == pytest.approx(0.3 + 0.5 * (1 - math.exp(-4)))
    assert np.all(lv[1:] == 0.0)
    belt.stop()
    assert np.all(belt.levels == 0.0)


def test_commanded_levels_follow_set_amplitudes_with_timestamps() -> None:
    belt, clock = sim()
    t0 = clock.now_ns()
    belt.set_amplitudes([0.5, 0, 0, 0, 0, 0])
    clock.advance(10 * MS)
    belt.set_amplitudes([0, 0.7, 0, 0, 0, 0])
    t, lv = belt.commanded(t0, t0 + 20 * MS, rate_hz=1000.0)
    assert t.dtype == np.int64 and t.shape == (20,)
    assert lv.shape == (20, 6)
    assert np.all(lv[:10, 0] == 0.5) and np.all(lv[10:, 1] == 0.7)
    cmds = belt.commands()
    assert [c.t_ns for c in cmds] == [t0, t0 + 10 * MS]


def test_sample_grid_has_no_drift() -> None:
    t = sample_grid(5, 5 + 10 * S, 3000.0)
    assert t.shape == (30_000,)
    assert t[-1] == 5 + (29_999 * S) // 3000


# -- bounded history -----------------------------------------------------------------------


def test_history_is_bounded_and_vibration_stays_exact_after_pruning() -> None:
    short, c1 = sim(horizon_s=5.0)
    long_, c2 = sim(horizon_s=1000.0)
    rng = np.random.default_rng(3)
    for _ in range(60):  # 60 s at 100 Hz, random frames and pauses
        frames = rng.random((100, 6)) * (rng.random() < 0.7)
        for row in frames:
            for belt, clock in ((short, c1), (long_, c2)):
                belt.set_amplitudes(row)
                clock.advance(10 * MS)
    assert len(short.commands()) <= (5 + 2) * 100
    assert len(long_.commands()) == 6000
    now = c1.now_ns()
    np.testing.assert_allclose(short.vibration(now - 2 * S, now)[1],
                               long_.vibration(now - 2 * S, now)[1], atol=1e-12)
    with pytest.raises(ConfigError, match="history"):
        short.vibration(0, S)


# -- motors off on every exit path ---------------------------------------------------------


def test_motors_off_after_normal_exit() -> None:
    clock = SimClock()
    with open_belt("sim", clock=clock) as belt:
        belt.set_amplitudes([1.0] * 6)
    assert belt.closed and np.all(belt.levels == 0.0)


def test_motors_off_after_an_exception_in_the_with_block() -> None:
    clock = SimClock()
    with pytest.raises(RuntimeError), open_belt("sim", clock=clock) as belt:
        belt.play(make_stimulus(belt.layout, 15.0, "dynamic"))
        raise RuntimeError("experiment crashed")
    assert np.all(belt.levels == 0.0)


def test_motors_off_after_keyboard_interrupt() -> None:
    clock = SimClock()
    with pytest.raises(KeyboardInterrupt), open_belt("sim", clock=clock) as belt:
        belt.set_amplitudes([0.5] * 6)
        raise KeyboardInterrupt
    assert np.all(belt.levels == 0.0)
    clock.advance(S)
    assert np.all(belt.vibration_at([clock.now_ns()]) < 1e-8)


# -- bad input -------------------------------------------------------------------------------


@pytest.mark.parametrize("values", [[0.5] * 5, [0.5] * 7, [0.1, 0.2, math.nan, 0, 0, 0],
                                    [1.5, 0, 0, 0, 0, 0], [-0.1, 0, 0, 0, 0, 0], "abc"])
def test_bad_frames_raise_and_leave_no_motor_running(values: object) -> None:
    clock = SimClock()
    with pytest.raises(ConfigError), open_belt("sim", clock=clock) as belt:
        belt.set_amplitudes([0.5] * 6)
        belt.set_amplitudes(values)  # type: ignore[arg-type]
    assert np.all(belt.levels == 0.0)


def test_urls_and_options() -> None:
    belt = open_belt("sim:8,virtual")
    assert belt.n_tactors == 8 and belt.clock.simulated  # type: ignore[attr-defined]
    belt.close()
    with pytest.raises(ConfigError, match="unknown belt URL"):
        open_belt("bogus:thing")
    with pytest.raises(ConfigError, match="unknown sim belt option"):
        open_belt("sim:fast")
    with pytest.raises(ConfigError, match="unknown option"):
        open_belt("sim", colour="red")
    with pytest.raises(ConfigError, match="tactors"):
        open_belt("sim:4", layout=Layout.even(6))
    with pytest.raises(ConfigError, match="calibration"):
        open_belt("sim", calibration=Calibration.identity(4))


def test_closed_belt_refuses_commands_but_answers_queries() -> None:
    belt, clock = sim()
    belt.close()
    with pytest.raises(TactorbeltError, match="closed"):
        belt.set_amplitudes([0.1] * 6)
    assert belt.vibration(0, 10 * MS)[1].shape == (10, 6)


@pytest.mark.parametrize("kw", [{"rise_tau_s": 0}, {"fall_tau_s": math.nan},
                                {"start_level": 1.0}, {"amplitude_exponent": -1}])
def test_erm_params_are_validated(kw: dict[str, float]) -> None:
    with pytest.raises(ConfigError, match="ErmParams"):
        ErmParams(**kw)


def test_bad_query_intervals() -> None:
    belt, _ = sim()
    with pytest.raises(ConfigError):
        belt.vibration(10, 0)
    with pytest.raises(ConfigError):
        belt.commanded(0, 10, rate_hz=0)
    t, v = belt.vibration(5, 5)
    assert t.shape == (0,) and v.shape == (0, 6)
