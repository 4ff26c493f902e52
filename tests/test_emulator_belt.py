"""The emulator belt: the real firmware core on a pseudo-terminal, through the serial backend.

These tests run in real time against a real process (the firmware's timing is what they
check), so they wait on the wall clock; each keeps to a fraction of a second. The
emulator is built once per session; the tests are skipped when g++ or make is missing.
"""

from __future__ import annotations

import functools
import os
import shutil
import signal
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from support.belts import hang, wait_for, write_raw
from tactorbelt import DeviceError, Layout, ProtocolError
from tactorbelt.devices import open_belt, wire
from tactorbelt.devices.emulator import EmulatorBelt, build_emulator, firmware_dir
from tactorbelt.stimuli import make_stimulus

pytestmark = pytest.mark.emulator


@pytest.fixture(scope="session")
def emulator_built() -> Path:
    missing = [t for t in ("g++", "make") if shutil.which(t) is None]
    if missing:
        pytest.skip(f"the firmware emulator needs {' and '.join(missing)} to build")
    return build_emulator(firmware_dir())


@pytest.fixture
def emu(emulator_built: Path) -> Iterator[EmulatorBelt]:
    belt = open_belt("emulator", build=False)
    assert isinstance(belt, EmulatorBelt)
    yield belt
    belt.close()


def test_get_info_gives_the_layout_and_version(emu: EmulatorBelt) -> None:
    assert emu.url == "emulator"
    assert emu.layout == Layout.even(6)
    assert emu.firmware_version == emu.info.firmware_version
    assert emu.info.protocol_version == 1
    assert emu.can_render()
    assert emu.stream_rate_hz == 1000.0
    assert emu.pty_path in emu.name


def test_the_emulator_has_the_extensions_and_reports_onsets(emu: EmulatorBelt) -> None:
    """Firmware 1.3.0: GET_DIAG answered, ONSET events on, no watchdog reset reported, and
    a board IMU that streams (tests/test_board_sense.py)."""
    assert emu.firmware_version == "1.3.0"
    assert emu.extensions and emu.reports_onsets and not emu.watchdog_reset
    assert emu.senses_vibration and emu.info.can_sense
    # firmware 1.3: the device shapes, and the emulated board has both bridge inputs wired
    assert emu.can_shape and emu.can_brake and emu.drive == "plain"
    assert emu.diagnostics is not None and emu.diagnostics.reset_flags == 0
    t0 = time.perf_counter_ns()
    emu.play(make_stimulus(emu.layout, 45.0, mode="dynamic"))
    onset = emu.last_onset()
    assert onset is not None
    host_ns, uncertainty_ns = onset
    # after the request was built, and long before now (a loaded machine: 1 s of room)
    assert t0 - uncertainty_ns <= host_ns <= time.perf_counter_ns() + uncertainty_ns
    assert 0 < uncertainty_ns < 50_000_000
    assert emu.unmatched_replies == 0 and emu.bad_replies == 0
    with pytest.raises(ProtocolError, match=r"refused DEBUG_HANG \(NAK code 2\)"):
        hang(emu)  # DEBUG_HANG needs an emulator started with --debug-frames


def test_tactor_count_and_heartbeat_options(emulator_built: Path) -> None:
    with open_belt("emulator", build=False, tactors=8, heartbeat_ms=400) as belt:
        assert belt.layout == Layout.even(8)
        assert isinstance(belt, EmulatorBelt)
        assert belt.heartbeat_ms == 400


def test_set_amplitudes_reach_the_outputs(emu: EmulatorBelt) -> None:
    amps = [0.0, 0.1, 0.25, 0.5, 0.999, 1.0]
    emu.set_amplitudes(amps)
    status = emu.status()
    assert status.state == wire.State.STREAMING
    assert status.levels == tuple(wire.amplitude_to_level(a) for a in amps)
    assert status.seq_gaps == 0


def test_stop_all_turns_everything_off(emu: EmulatorBelt) -> None:
    emu.set_amplitudes([1.0] * 6)
    emu.stop()
    status = emu.status()
    assert status.state == wire.State.IDLE
    assert status.levels == (0,) * 6


def read_levels_log(path: Path) -> np.ndarray:
    """The emulator's levels log: rows of (t_us, state, level_0, ...), one per change."""
    text = path.read_text().strip().splitlines()
    assert text[0].startswith("t_us,state,level_0")
    return np.array([[int(v) for v in line.split(",")] for line in text[1:]], dtype=np.int64)


def test_play_target_dynamic_follows_the_600_200_ms_pattern(
    emulator_built: Path, tmp_path: Path
) -> None:
    """Quarter point (45 deg between 30 and 90): 600 ms on tactor 0, 200 ms on tactor 1.

    Checked in device time with the emulator's levels log, so the load of this machine
    does not matter for the values: every output change the renderer made matches the
    stimulus at that instant. Durations allow for a starved 1 kHz tick (15 ms).
    """
    log = tmp_path / "levels.csv"
    with open_belt("emulator", build=False, levels_log=log) as belt:
        stim = make_stimulus(belt.layout, 45.0, mode="dynamic")
        belt.play(stim, 1.0)
        assert belt.status().state == wire.State.PLAYING  # type: ignore[attr-defined]
        assert wait_for(lambda: belt.status().state == wire.State.IDLE,  # type: ignore[attr-defined]
                        3.0)
    rows = read_levels_log(log)
    playing = np.flatnonzero(rows[:, 1] == wire.State.PLAYING)
    start_us = rows[playing[0], 0]
    end_us = rows[playing[-1] + 1, 0]  # the first row after playing: back to idle
    assert rows[playing[-1] + 1, 1] == wire.State.IDLE
    # ends on the first 1 ms tick at or after 1 s (later if the emulator was starved)
    assert 1_000_000 <= end_us - start_us <= 1_020_000
    t = (rows[playing, 0] - start_us) / 1e6
    want = np.vectorize(wire.amplitude_to_level)(stim.amplitudes(t))
    assert np.max(np.abs(rows[playing, 2:] - want)) <= 2
    # dwell times of the first period from the step function of the log
    levels, held = rows[playing, 2:], np.diff(np.append(rows[playing, 0], end_us))
    first = t < 1.0
    plateau = wire.amplitude_to_level(1 - np.exp(-4))
    on_near = first & (abs(levels[:, 0] - plateau) <= 2) & (levels[:, 1] == 0)
    on_far = first & (abs(levels[:, 1] - plateau) <= 2) & (levels[:, 0] == 0)
    assert abs(held[on_near].sum() - 600_000) <= 15_000
    assert abs(held[on_far].sum() - 200_000) <= 15_000


def test_play_with_a_duration_ends_by_itself(emu: EmulatorBelt) -> None:
    emu.play(make_stimulus(emu.layout, 90.0), 0.05)
    assert emu.status().state == wire.State.PLAYING
    assert wait_for(lambda: emu.status().state == wire.State.IDLE, 1.0)
    assert emu.status().levels == (0,) * 6


def _fired_since(log: Path, n0: int) -> bool:
    return bool(np.any(read_levels_log(log)[n0:, 1] == wire.State.FAILSAFE))


def test_failsafe_fires_within_the_heartbeat_timeout_plus_20_ms(
    emulator_built: Path, tmp_path: Path
) -> None:
    """With the keep-alive stopped, the outputs go off between hb and hb + 20 ms after the
    last packet, in device time (the levels log).

    The emulator's 1 kHz tick can be starved on a loaded machine, so one trial in three
    must be within 20 ms; every trial must fire, and none early.
    """
    log = tmp_path / "levels.csv"
    with open_belt("emulator", build=False, levels_log=log, heartbeat_ms=100) as belt:
        assert isinstance(belt, EmulatorBelt)
        belt.stop_keepalive()
        delays_ms = []
        for trial in range(3):
            count0 = belt.status().failsafe_count
            n0 = len(read_levels_log(log))
            belt.set_amplitudes([0.2 + 0.1 * trial] * 6)  # the last packet: a logged change
            assert wait_for(functools.partial(_fired_since, log, n0), 2.0)
            rows = read_levels_log(log)[n0:]
            (sent,) = np.flatnonzero(rows[:, 1] == wire.State.STREAMING)
            (fired,) = np.flatnonzero(rows[:, 1] == wire.State.FAILSAFE)
            assert np.all(rows[fired, 2:] == 0)
            delays_ms.append((rows[fired, 0] - rows[sent, 0]) / 1000)
            status = belt.status()
            assert status.state == wire.State.FAILSAFE
            assert status.failsafe_count == count0 + 1
            if delays_ms[-1] <= 120:
                break
        assert all(d >= 100 for d in delays_ms), delays_ms
        assert min(delays_ms) <= 120, delays_ms
        # a new frame after the failsafe streams again
        belt.start_keepalive()
        belt.set_amplitudes([0.25] * 6)
        assert belt.status().state == wire.State.STREAMING


def test_the_keepalive_holds_the_failsafe_off(emu: EmulatorBelt) -> None:
    emu.set_config(60)
    emu.set_amplitudes([0.5] * 6)
    count0 = emu.status().failsafe_count
    deadline = time.perf_counter() + 0.25  # four heartbeat timeouts
    while time.perf_counter() < deadline:
        time.sleep(0.01)
    status = emu.status()
    assert status.state == wire.State.STREAMING
    assert status.failsafe_count == count0


def test_garbage_is_counted_and_skipped(emu: EmulatorBelt) -> None:
    before = emu.status()
    rng = np.random.default_rng(7)
    write_raw(emu, rng.integers(1, 256, 300, dtype=np.uint8).tobytes() + b"\x00")  # too long
    write_raw(emu, b"\x05\x01\x02\x03\x04\x00")  # valid COBS, bad CRC
    write_raw(emu, b"\x02\x01\x00")  # too short
    write_raw(emu, rng.integers(0, 256, 500, dtype=np.uint8).tobytes() + b"\x00")
    after = emu.status()  # a valid request still works
    assert after.framing_errors >= before.framing_errors + 2
    assert after.crc_errors >= before.crc_errors + 1
    assert after.seq_gaps == before.seq_gaps
    emu.set_amplitudes([0.5] * 6)
    assert emu.status().levels == (32768,) * 6


def test_a_frozen_emulator_raises_naming_the_port(emu: EmulatorBelt) -> None:
    os.kill(emu.process.pid, signal.SIGSTOP)
    try:
        assert wait_for(lambda: emu.lost is not None, 2.0)
        with pytest.raises(DeviceError, match=f"{emu.pty_path} stopped answering"):
            emu.set_amplitudes([0.0] * 6)
    finally:
        os.kill(emu.process.pid, signal.SIGCONT)


def test_a_dead_emulator_raises_naming_the_port(emu: EmulatorBelt) -> None:
    emu.process.kill()
    assert wait_for(lambda: emu.lost is not None, 2.0)
    with pytest.raises(DeviceError, match=f"{emu.pty_path} stopped answering"):
        emu.status()


def test_close_stops_the_motors_and_ends_the_emulator(emulator_built: Path) -> None:
    belt = open_belt("emulator", build=False)
    assert isinstance(belt, EmulatorBelt)
    belt.set_amplitudes([1.0] * 6)
    belt.close()
    assert belt.process.returncode is not None
    assert belt.lost is not None


def test_closing_the_port_turns_the_outputs_off(emulator_built: Path, tmp_path: Path) -> None:
    """Like unplugging USB: the host closes the port without STOP_ALL; the device stops."""
    from tactorbelt.devices._firmware import FirmwareBelt
    from tactorbelt.devices.serial import SerialTransport

    log = tmp_path / "levels.csv"
    with open_belt("emulator", build=False, levels_log=log) as belt:
        assert isinstance(belt, EmulatorBelt)
        belt.set_amplitudes([0.75] * 6)
        assert belt.status().state == wire.State.STREAMING
        belt.stop_keepalive()
        belt._transport.close()  # the port closes; no STOP_ALL was sent
        # the emulator sees the hang-up only while nobody has the port open: wait for it
        assert wait_for(lambda: tuple(read_levels_log(log)[-1, 1:]) == (0,) * 7, 2.0)
        assert read_levels_log(log)[-2, 1] == wire.State.STREAMING
        again = FirmwareBelt(SerialTransport(belt.pty_path), "serial:" + belt.pty_path,
                             keepalive=False)
        with again:
            status = again.status()
            assert status.state == wire.State.IDLE and status.levels == (0,) * 6
            assert status.failsafe_count == 0  # the port closing, not the failsafe


def _running(pid: int) -> bool:
    """True while ``pid`` runs (a zombie, exited but not yet reaped, has ended)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


@pytest.mark.skipif(not Path("/proc").is_dir(), reason="needs /proc to find the child")
def test_ctrl_c_in_a_terminal_stops_cleanly_and_ends_the_emulator(emulator_built: Path) -> None:
    """The terminal sends SIGINT to the whole foreground process group: the emulator must
    not die before the host has stopped the motors (it runs in its own session)."""
    import subprocess
    import sys

    cmd = [sys.executable, "-m", "tactorbelt", "play", "45", "--belt", "emulator",
           "--seconds", "10"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            start_new_session=True)
    try:
        assert proc.stdout is not None
        assert "playing" in proc.stdout.readline()  # the belt is open
        time.sleep(1.0)  # and playing
        children = [int(p) for p in Path(f"/proc/{proc.pid}/task/{proc.pid}/children")
                    .read_text().split()]
        assert children, "the emulator child was not found"
        os.killpg(proc.pid, signal.SIGINT)  # what Ctrl-C in a terminal does
        out, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert "stopped answering" not in err and "could not stop" not in err, err
    assert "motors off" in err
    assert proc.returncode == 130  # a user interrupt, as on the sim belt
    assert wait_for(lambda: not any(_running(c) for c in children), 5.0)


def test_the_emulator_exits_when_its_host_dies(emulator_built: Path) -> None:
    import subprocess
    import sys

    script = ("from tactorbelt.devices import open_belt\n"
              "import os, time\n"
              "belt = open_belt('emulator', build=False)\n"
              "print(belt.process.pid, flush=True)\n"
              "time.sleep(60)\n")
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        child = int(proc.stdout.readline())
        assert _running(child)
        proc.kill()
        proc.wait(10)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert wait_for(lambda: not _running(child), 5.0)
