"""The player: absolute deadlines, exact statistics, no drift, errors never lost."""

from __future__ import annotations

import itertools
import threading

import numpy as np
import pytest

from tactorbelt import ConfigError, DeviceError, TactorbeltError
from tactorbelt.clock import SimClock
from tactorbelt.devices.base import Belt
from tactorbelt.devices.erm import PREROLL_NS
from tactorbelt.devices.sim import SimBelt, open_sim
from tactorbelt.geometry import Layout
from tactorbelt.player import Player, PlayerStats
from tactorbelt.stimuli import make_stimulus

MS = 1_000_000
S = 1_000_000_000
LAYOUT = Layout.even(6)


class FrameLog(Belt):
    """A minimal streaming belt: records (time, levels) of every write."""

    def __init__(self, clock: object, fail_at: int | None = None,
                 exc: BaseException | None = None, stream_rate_hz: float | None = None) -> None:
        super().__init__("log", "frame log", LAYOUT)
        self.clock = clock
        self.writes: list[tuple[int, np.ndarray]] = []
        self.stops = 0
        self.fail_at = fail_at
        self.exc = exc or DeviceError("belt 'log' stopped answering")
        if stream_rate_hz is not None:
            self.stream_rate_hz = stream_rate_hz

    def _write_levels(self, levels: np.ndarray) -> None:
        if self.fail_at is not None and len(self.writes) >= self.fail_at:
            raise self.exc
        self.writes.append((self.clock.now_ns(), levels))  # type: ignore[attr-defined]

    def _write_stop(self) -> None:
        self.stops += 1


class JumpClock(SimClock):
    """A clock that does not sleep but says it is a wall clock (so the thread runs)."""

    simulated = False


STATIC = make_stimulus(LAYOUT, 15.0, "static")
DYNAMIC = make_stimulus(LAYOUT, 15.0, "dynamic")


def test_deadline_statistics_from_a_jittery_clock_are_exact() -> None:
    jitter = [0, 100_000, 200_000, 50_000, 10_000]
    it = itertools.cycle(jitter)
    clock = SimClock(start_ns=7 * S, jitter=lambda: next(it))
    belt = FrameLog(clock)
    stats = Player(belt).play(STATIC, 1.0)
    errors = np.array(jitter * 200)
    assert stats.frames == 1000 and stats.missed == 0
    assert stats.deadline_error_p50_ms == np.percentile(errors, 50) / 1e6
    assert stats.deadline_error_p99_ms == np.percentile(errors, 99) / 1e6
    assert stats.deadline_error_max_ms == 0.2
    assert stats.onset_ns == 7 * S
    assert belt.stops >= 1  # motors off at the end


def test_late_wake_ups_skip_frames_and_count_them_as_missed_never_bursting() -> None:
    # every 10th wake-up is 2.5 periods late: frames i+1 and i+2 are skipped
    counter = itertools.count()
    clock = SimClock(jitter=lambda: 2_500_000 if next(counter) % 10 == 9 else 0)
    belt = FrameLog(clock)
    stats = Player(belt).play(STATIC, 1.0)
    assert stats.frames + stats.missed == 1000
    assert stats.missed > 0
    times = np.array([t for t, _ in belt.writes])
    assert np.all(np.diff(times) >= MS // 2)  # no burst of stale frames
    assert stats.deadline_error_max_ms == 0.5  # the frame written is the one due now


def test_no_drift_after_100000_frames() -> None:
    clock = SimClock(start_ns=123)
    belt = FrameLog(clock)
    player = Player(belt, rate_hz=3000.0)  # a period of 333,333.3 ns: rounding would drift
    stats = player.play(STATIC, 100_000 / 3000.0)
    assert stats.frames == 100_000 and stats.missed == 0
    assert stats.deadline_error_max_ms == 0.0
    assert belt.writes[-1][0] == 123 + (99_999 * S) // 3000
    assert clock.now_ns() == 123 + (100_000 * S) // 3000  # stopped at the end deadline


def test_streamed_frames_are_the_stimulus_at_i_over_rate() -> None:
    clock = SimClock()
    belt = FrameLog(clock)
    Player(belt).play(DYNAMIC, 1.0)
    _, expected = DYNAMIC.render(1000.0, 1.0)
    np.testing.assert_allclose(np.array([lv for _, lv in belt.writes]), expected, atol=1e-12)


def test_switch_uses_the_new_stimulus_from_the_next_frame_keeping_the_phase() -> None:
    clock = SimClock()
    belt = FrameLog(clock)
    player = Player(belt)
    onset = player.start(DYNAMIC, 2.0)
    player.pump(onset + 499 * MS)
    other = make_stimulus(LAYOUT, 100.0, "dynamic")
    player.switch(other)
    player.pump(onset + 2 * S)
    assert not player.playing
    frames = np.array([lv for _, lv in belt.writes])
    np.testing.assert_allclose(frames[:500], DYNAMIC.render(1000.0, 0.5)[1], atol=1e-12)
    np.testing.assert_allclose(frames[500:], other.amplitudes(np.arange(500, 2000) / 1000),
                               atol=1e-12)


def test_device_rendering_on_the_sim_belt() -> None:
    clock = SimClock()
    belt = open_sim("", clock=clock)
    player = Player(belt)
    assert player.device_render and player.clock is clock
    stats = player.play(DYNAMIC, 1.0)
    # the sim belt shapes by default: the stimulus's onset is its pre-roll after the play
    assert stats.frames == 0 and stats.onset_ns == PREROLL_NS == belt.preroll_ns
    assert clock.now_ns() == S
    _, levels = belt.commanded(0, S)
    np.testing.assert_allclose(levels, DYNAMIC.render(1000.0, 1.0)[1], atol=1e-12)
    assert np.all(belt.levels == 0.0)


def test_streaming_to_the_sim_belt_matches_its_own_rendering() -> None:
    a = open_sim("", clock=SimClock())
    b = open_sim("", clock=SimClock())
    Player(a, device_render=True).play(DYNAMIC, 1.0)
    Player(b, device_render=False).play(DYNAMIC, 1.0)
    np.testing.assert_allclose(a.vibration(0, 1_100 * MS)[1], b.vibration(0, 1_100 * MS)[1],
                               atol=1e-12)


def test_stop_turns_the_motors_off_now() -> None:
    clock = SimClock()
    belt: SimBelt = open_sim("", clock=clock)
    player = Player(belt, device_render=False)
    onset = player.start(STATIC)
    player.pump(onset + 100 * MS)
    assert player.playing and belt.levels.max() > 0
    stats = player.stop()
    assert not player.playing and np.all(belt.levels == 0.0)
    assert stats.frames == 101 + belt.preroll_ns // MS  # from the command, at 1 kHz


def test_rate_comes_from_the_belt() -> None:
    clock = SimClock()
    belt = FrameLog(clock, stream_rate_hz=40.0)
    player = Player(belt)
    assert player.rate_hz == 40.0
    player.play(STATIC, 1.0)
    times = [t for t, _ in belt.writes]
    assert len(times) == 40 and times[1] - times[0] == 25 * MS


def test_wall_thread_error_is_reraised_from_stop_and_motors_stop() -> None:
    clock = JumpClock()
    belt = FrameLog(clock, fail_at=5)
    player = Player(belt)
    player.start(STATIC)
    assert player._thread is not None
    player._thread.join(timeout=10)
    assert not player.playing
    assert belt.stops >= 1
    with pytest.raises(DeviceError, match="stopped answering"):
        player.stop()
    player.stop()  # reported once, then the player is usable again


def test_wall_thread_error_is_reraised_from_stats() -> None:
    clock = JumpClock()
    player = Player(FrameLog(clock, fail_at=3))
    player.start(STATIC)
    assert player._thread is not None
    player._thread.join(timeout=10)
    with pytest.raises(DeviceError):
        player.stats()


def test_threaded_playback_on_a_non_sleeping_wall_clock_finishes() -> None:
    clock = JumpClock()
    belt = FrameLog(clock)
    stats = Player(belt).play(DYNAMIC, 0.5)
    assert stats.frames == 500 and belt.stops >= 1
    assert threading.active_count() >= 1


def test_pump_error_propagates_and_motors_stop() -> None:
    clock = SimClock()
    belt = FrameLog(clock, fail_at=10, exc=KeyboardInterrupt())
    player = Player(belt)
    with pytest.raises(KeyboardInterrupt):
        player.play(STATIC, 1.0)
    assert belt.stops >= 1 and not player.playing


def test_pump_is_a_noop_when_device_rendering() -> None:
    clock = SimClock()
    belt = open_sim("", clock=clock)
    player = Player(belt)
    player.start(STATIC, 1.0)
    player.pump(10 * S)
    assert clock.now_ns() == 0


@pytest.mark.parametrize("rate", [0, -1, float("nan"), float("inf"), "x"])
def test_bad_rates(rate: object) -> None:
    with pytest.raises(ConfigError, match="rate"):
        Player(FrameLog(SimClock()), rate_hz=rate)  # type: ignore[arg-type]


@pytest.mark.parametrize("duration", [0, -1.0, float("nan"), float("inf")])
def test_bad_durations(duration: float) -> None:
    belt = FrameLog(SimClock())
    with pytest.raises(ConfigError, match="duration"):
        Player(belt).start(STATIC, duration)
    assert belt.writes == []


def test_wrong_layout_and_unrendering_belt() -> None:
    belt = FrameLog(SimClock())
    with pytest.raises(ConfigError, match="tactors"):
        Player(belt).start(make_stimulus(Layout.even(8), 10.0))
    with pytest.raises(ConfigError, match="cannot render"):
        Player(belt, device_render=True)
    with pytest.raises(TactorbeltError, match="start"):
        Player(belt).switch(STATIC)


def test_anything_but_a_stimulus_or_a_playable_is_refused() -> None:
    belt = FrameLog(SimClock())
    for bad in ("left", 30.0, np.ones(6)):
        with pytest.raises(ConfigError, match="expected a Stimulus"):
            Player(belt).start(bad, 1.0)  # type: ignore[arg-type]
    assert belt.writes == []


class SlowStop(FrameLog):
    """A belt whose stop takes 2 ms to be acknowledged (a request's round trip)."""

    def _write_stop(self) -> None:
        super()._write_stop()
        self.clock.advance(2 * MS)  # type: ignore[attr-defined]


def test_a_stream_played_to_its_end_says_when_its_stop_took_effect() -> None:
    """Midway through the stop, however late the computer woke for it; None where the
    device times the end itself or the playback was stopped before it."""
    clock = SimClock(start_ns=5 * S, jitter=lambda: 300_000)  # every wake-up 0.3 ms late
    stats = Player(SlowStop(clock)).play(STATIC, 0.5)
    assert stats.stopped_ns == 5 * S + 500 * MS + 300_000 + 1 * MS
    clock = SimClock()
    assert Player(open_sim("", clock=clock)).play(STATIC, 0.5).stopped_ns is None
    player = Player(FrameLog(clock))
    onset = player.start(STATIC, 1.0)
    player.pump(onset + 100 * MS)
    assert player.stop().stopped_ns is None


def test_stats_to_dict_has_the_documented_keys() -> None:
    stats = Player(FrameLog(SimClock())).play(STATIC, 0.01)
    assert isinstance(stats, PlayerStats)
    assert set(stats.to_dict()) == {"frames", "missed", "deadline_error_p50_ms",
                                    "deadline_error_p99_ms", "deadline_error_max_ms",
                                    "onset_ns", "underruns", "stopped_ns"}


def test_device_switch_restarts_on_the_device_for_the_rest_of_the_duration() -> None:
    clock = SimClock()
    belt = open_sim("", clock=clock)
    player = Player(belt)
    player.start(DYNAMIC, 2.0)
    clock.advance(500 * MS)
    other = make_stimulus(LAYOUT, 100.0, "static")
    player.switch(other)
    cmds = belt.commands()
    assert [c.t_ns for c in cmds] == [0, 500 * MS]
    assert cmds[1].stimulus == other and cmds[1].end_ns == 2 * S
    assert player.playing
    clock.advance(1500 * MS)
    assert not player.playing
    assert np.all(belt.levels == 0.0)


def test_a_shaped_belt_starts_its_drive_the_pre_roll_before_the_onset_it_gives() -> None:
    """The onset a session stores of a stimulus played on a shaped belt is the pre-roll
    after the command, device-rendered or streamed: the kick from rest starts before it
    (so the skin feels the stimulus near the onset, not a kick's time after); the end of a
    stream on the same terms. Plain, the onset is the command."""
    for drive, device in itertools.product(("plain", "shaped"), (True, False)):
        clock = SimClock()
        belt = open_sim("", clock=clock, drive=drive)
        pre = PREROLL_NS if drive == "shaped" else 0
        assert belt.preroll_ns == pre
        player = Player(belt, device_render=device)
        stats = player.play(STATIC, 0.5)
        assert stats.onset_ns == pre, (drive, device)
        assert stats.stopped_ns == (None if device else 500 * MS + pre), (drive, device)
        t, d = belt.driven(0, 20 * MS)
        first = int(t[np.flatnonzero(np.abs(d).max(axis=1) > 0)[0]])
        assert first == 0  # the drive starts at the command: the pre-roll before the onset
        assert player.device_onset() is None  # the sim belt reports no device onsets


@pytest.mark.emulator
def test_a_device_onset_of_a_shaped_play_is_the_pre_roll_after_the_boards(
        emulator_exe: object) -> None:
    """On a belt that reports its onsets (the emulated board), the player's device onset
    of a shaped play is the board's onset plus the pre-roll, as the onset the player gives;
    plain, the board's own."""
    from tactorbelt.devices import open_belt

    for drive in ("plain", "shaped"):
        with open_belt(f"emulator?heartbeat_ms=1000&drive={drive}", build=False) as belt:
            assert belt.reports_onsets
            player = Player(belt)
            assert player.renders_on_device(STATIC)
            player.start(STATIC, 0.2)
            board = belt.last_onset(timeout_s=1.0)
            got = player.device_onset(timeout_s=1.0)
            player.stop()
            assert board is not None and got is not None
            assert got == (board[0] + belt.preroll_ns, board[1])
            assert belt.preroll_ns == (PREROLL_NS if drive == "shaped" else 0)
