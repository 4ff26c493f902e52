"""The belt's own board as the vibration sensor (firmware 1.2, SENSE_START): ``Belt.sense``.

Against a fake firmware (tests/support/belts.py): the capability is declared, not probed;
a firmware without SENSE names the upload command, one whose IMU did not start says so;
samples come back in g on the host clock, and lost batches are counted.

Against the emulator (marker ``emulator``), whose board simulates its IMU from the same ERM
model as the sim belt: the envelope the board senses rises after the command, on the host
clock, with the model's 10-90 % rise time; a recording ends by its duration, by stop(), or
with the belt. The emulator samples its model at each sample's device time stamp, so these
checks do not depend on the load of the machine.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from support import wire_device
from support.belts import FakeFirmware, LoopTransport
from tactorbelt import ConfigError, DeviceError
from tactorbelt.devices import open_belt, wire
from tactorbelt.devices._firmware import FirmwareBelt, SenseRecording
from tactorbelt.devices.emulator import EmulatorBelt, build_emulator, firmware_dir
from tactorbelt.devices.erm import ErmParams

#: The 10-90 % rise of amplitude = speed**2 from rest at full drive.
RISE_TAU = ErmParams().rise_tau_s
ANALYTIC_RISE_S = -RISE_TAU * math.log(1 - math.sqrt(0.9)) + RISE_TAU * math.log(
    1 - math.sqrt(0.1))
#: From the drive's start to 10 %.
ANALYTIC_LATENCY_S = -RISE_TAU * math.log(1 - math.sqrt(0.1))

SENSE_CAPS = int(wire.Capability.PLAY_TARGET | wire.Capability.SENSE)


def _fake_belt(device: FakeFirmware) -> FirmwareBelt:
    return FirmwareBelt(LoopTransport(device), "loop:fake", keepalive=False)


# --- the capability and its errors --------------------------------------------------------

def test_a_belt_without_a_sensor_of_its_own_says_to_give_one() -> None:
    with open_belt("sim") as belt:
        assert not belt.senses_vibration
        with pytest.raises(DeviceError, match="no sensor of its own; give --sense URL"):
            belt.sense(1.0)


def test_firmware_1_1_cannot_stream_its_imu_and_names_the_upload() -> None:
    device = FakeFirmware(extensions=True, fw_version=(1, 1, 0))
    with _fake_belt(device) as belt:
        assert belt.extensions and not belt.senses_vibration
        with pytest.raises(DeviceError, match=r"this board's firmware .*cannot stream its IMU: "
                                              r".*tactorbelt firmware upload --port"):
            belt.sense(1.0)
        assert device.of_type(wire_device.SenseStart) == []  # declared, not probed


def test_a_device_that_refuses_sense_start_as_unknown_gets_the_same_advice() -> None:
    # claims the capability but has no SENSE_START (a foreign or broken build): NAK 2
    device = FakeFirmware(extensions=True, fw_version=(1, 1, 0), capabilities=SENSE_CAPS)
    with _fake_belt(device) as belt:
        assert belt.senses_vibration
        with pytest.raises(DeviceError, match=r"cannot stream its IMU: .*firmware upload"):
            belt.sense(1.0)


def test_an_imu_that_did_not_start_is_reported_as_such() -> None:
    # firmware 1.2 without the capability bit: asked, it says why (NAK 6: the IMU did not
    # start, e.g. a build for the other board revision)
    device = FakeFirmware(extensions=True, fw_version=(1, 2, 0), sense_unavailable=True)
    with _fake_belt(device) as belt:
        assert not belt.senses_vibration
        with pytest.raises(DeviceError, match=r"did not start.*TACTORBELT_IMU_LSM9DS1"):
            belt.sense(1.0)
        assert len(device.of_type(wire_device.SenseStart)) == 1
    # and NAK 6 from a device that claimed it
    device = FakeFirmware(extensions=True, fw_version=(1, 2, 0), capabilities=SENSE_CAPS,
                          sense_unavailable=True)
    with _fake_belt(device) as belt, pytest.raises(DeviceError, match="did not start"):
        belt.sense(1.0)
    # a 1.2 build without SENSE: NAK 2, the upload
    device = FakeFirmware(extensions=True, fw_version=(1, 2, 0))
    with _fake_belt(device) as belt, pytest.raises(DeviceError, match="cannot stream its IMU"):
        belt.sense(1.0)


@pytest.mark.parametrize("kwargs", [
    {"duration_s": 0.0}, {"duration_s": 3601.0}, {"duration_s": math.nan},
    {"duration_s": 1.0, "rate_hz": 0}, {"duration_s": 1.0, "rate_hz": 70000},
    {"duration_s": 1.0, "tactor": 6}, {"duration_s": 1.0, "tactor": True},
])
def test_sense_checks_its_arguments(kwargs: dict[str, object]) -> None:
    device = FakeFirmware(extensions=True, fw_version=(1, 2, 0), capabilities=SENSE_CAPS,
                          sense=lambda req, seq, t: [])
    with _fake_belt(device) as belt, pytest.raises(ConfigError):
        belt.sense(**kwargs)  # type: ignore[arg-type]
    assert device.of_type(wire_device.SenseStart) == []


# --- samples, host times and losses (fake firmware) ---------------------------------------

def _batches(req: wire_device.SenseStart, seq: int, t_us: int) -> list[wire.SenseData]:
    """A whole session at once: 3 batches of 7 samples, 625 us apart, the second lost
    (indices 7..13), values k, -k, 4096 + k for sample k."""
    out = []
    for b in (0, 2, 3):
        first = 7 * b
        values = tuple(v for k in range(first, first + 7) for v in (k, -k, 4096 + k))
        out.append(wire.SenseData(seq, wire.SenseFlag.LAST if b == 3 else 0, first,
                                  t_us + 625 * first, 625, 8000, values))
    return out


def test_samples_come_in_g_on_the_host_clock_and_losses_are_counted() -> None:
    device = FakeFirmware(extensions=True, fw_version=(1, 2, 0), capabilities=SENSE_CAPS,
                          sense=_batches)
    with _fake_belt(device) as belt:
        assert belt.senses_vibration
        before = time.perf_counter_ns()
        rec = belt.sense(0.5, rate_hz=1600, tactor=3)
        after = time.perf_counter_ns()
        assert isinstance(rec, SenseRecording)
        assert device.of_type(wire_device.SenseStart) == [wire_device.SenseStart(1600, 500, 3)]
        assert rec.rate_hz == 1600.0 and rec.period_us == 625 and rec.full_scale_g == 8.0
        assert rec.finished and not rec.active and rec.interrupted is None
        t, acc = rec.samples()
        assert acc.shape == (21, 3) and t.dtype == np.int64
        k = np.r_[0:7, 14:28]
        np.testing.assert_array_equal(acc[:, 0], k * 8.0 / 32768.0)
        np.testing.assert_array_equal(acc[:, 2], (4096 + k) * 8.0 / 32768.0)
        # the fake's clock is perf_counter_ns // 1000 + 1 h: sample 0 was stamped while the
        # request was handled, sample k 625 us later
        assert np.all(np.diff(t)[np.diff(k) == 1] == 625_000)
        unc = rec.uncertainty_ns
        assert 0 < unc < 5_000_000
        assert before - unc - 1000 <= t[0] <= after + unc
        np.testing.assert_array_equal(t - t[0], (k * 625_000))
        # the lost batch: 7 samples between the first batch and the next
        assert rec.lost() == 7
        assert rec.lost(int(t[0]), int(t[3])) == 0
        assert rec.lost(int(t[5]), int(t[9])) == 7
        assert rec.problem(int(t[0]), int(t[3])) is None
        problem = rec.problem(int(t[5]), int(t[9]))
        assert problem is not None and "7 samples" in problem
        # an interval: [t0, t1) on the host clock
        t_mid, acc_mid = rec.samples(int(t[2]), int(t[5]))
        np.testing.assert_array_equal(t_mid, t[2:5])
        np.testing.assert_array_equal(acc_mid, acc[2:5])
        rec.forget_before(int(t[7]))
        assert len(rec) == 14 and rec.samples()[0][0] == t[7]
        rec.stop()  # already over on the device: nothing sent
        assert device.of_type(wire_device.SenseStop) == []
        assert belt.unmatched_replies == 0 and belt.stray_sense_batches == 0


def test_no_samples_after_the_ack_is_an_error() -> None:
    device = FakeFirmware(extensions=True, fw_version=(1, 2, 0), capabilities=SENSE_CAPS,
                          sense=lambda req, seq, t: [])
    with _fake_belt(device) as belt, pytest.raises(DeviceError, match="sent no samples"):
        belt.sense(1.0)


# --- the emulator's board ---------------------------------------------------------------------

@pytest.fixture(scope="module")
def emulator_built() -> Path:
    import shutil

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


def _vibration(acc: np.ndarray, baseline: np.ndarray) -> np.ndarray:
    """|acceleration - its resting mean| (gravity out), smoothed over 8 samples (5 ms)."""
    mag = np.linalg.norm(acc - baseline, axis=1)
    return np.convolve(mag, np.ones(8) / 8, mode="same")


def _crossing(t_ns: np.ndarray, env: np.ndarray, level: float, after_ns: int) -> float:
    """The first upward crossing of ``level`` after ``after_ns`` (interpolated, ns)."""
    i = int(np.flatnonzero((env >= level) & (t_ns > after_ns))[0])
    f = (level - env[i - 1]) / (env[i] - env[i - 1])
    return float(t_ns[i - 1] + f * (t_ns[i] - t_ns[i - 1]))


@pytest.mark.emulator
def test_the_board_senses_the_erm_rise_after_the_command_on_the_host_clock(
        emu: EmulatorBelt) -> None:
    assert emu.firmware_version == "1.3.0" and emu.senses_vibration
    with emu.sense(3.0, tactor=2) as rec:
        assert rec.rate_hz == 1600.0 and rec.full_scale_g == 8.0 and rec.tactor == 2
        time.sleep(0.15)  # at rest
        sent_ns = time.perf_counter_ns()
        emu.set_amplitudes([0, 0, 1.0, 0, 0, 0])
        onset = emu.last_onset()
        assert rec.wait_for(sent_ns + 450_000_000, 5.0)
        emu.stop()
        rec.stop()
    assert rec.finished and rec.interrupted is None and rec.lost() == 0
    assert onset is not None
    onset_ns, onset_unc = onset
    t, acc = rec.samples()
    rest = t < sent_ns - 20_000_000
    env = _vibration(acc, acc[rest].mean(axis=0))
    on = (t > sent_ns + 350_000_000) & (t < sent_ns + 420_000_000)
    steady = float(np.median(env[on]))
    assert 1.9 < steady < 2.1  # the emulator's 2 g at rated speed
    assert np.all(env[t < sent_ns - 5_000_000] < 0.05 * steady)  # still before the command
    t10 = _crossing(t, env, 0.1 * steady, sent_ns - 5_000_000)
    t90 = _crossing(t, env, 0.9 * steady, sent_ns - 5_000_000)
    rise_s = (t90 - t10) / 1e9
    assert abs(rise_s - ANALYTIC_RISE_S) < 0.05 * ANALYTIC_RISE_S, (rise_s, ANALYTIC_RISE_S)
    # on the host clock: after the command was sent, the model's latency after the device's
    # own onset (both device times, mapped by the same fit; 2 ms for the smoothing and the
    # sampling)
    assert t10 > sent_ns - rec.uncertainty_ns
    latency_s = (t10 - onset_ns) / 1e9
    assert abs(latency_s - ANALYTIC_LATENCY_S) < 0.002, latency_s
    assert onset_unc < 50_000_000


@pytest.mark.emulator
def test_a_recording_ends_by_its_duration_and_a_lower_rate_is_honoured(
        emu: EmulatorBelt) -> None:
    rec = emu.sense(0.2, rate_hz=500)
    assert rec.period_us == 2000 and rec.rate_hz == 500.0
    # it ends by itself: waiting for later samples returns False once it is over
    assert not rec.wait_for(time.perf_counter_ns() + 10_000_000_000, 3.0)
    assert rec.finished and rec.interrupted is None and rec.lost() == 0
    t, acc = rec.samples()
    # 0.2 s at 500 Hz, on one grid (the emulator's model is read at the stamps, so a
    # loaded host delays samples but loses none)
    assert len(t) == 100 and np.all(np.diff(t) == 2_000_000)
    # at rest: gravity, -1 g on y, and little else
    assert np.allclose(acc.mean(axis=0), [0.0, -1.0, 0.0], atol=0.01)
    assert float(acc.std(axis=0).max()) < 0.01
    rec.stop()  # over already: a no-op
    # a new recording on the same belt
    with emu.sense(0.1) as again:
        assert again.rate_hz == 1600.0


@pytest.mark.emulator
def test_closing_the_belt_ends_its_recording(emulator_built: Path) -> None:
    belt = open_belt("emulator", build=False)
    rec = belt.sense(60.0)
    assert rec.wait_for(time.perf_counter_ns() + 50_000_000, 3.0)
    belt.close()
    assert not rec.active and rec.interrupted == "the belt was closed"
    t, _ = rec.samples()
    assert len(t) > 50  # what came stays readable
    problem = rec.problem(int(t[0]), int(t[-1]) + 1_000_000_000)
    assert problem is not None and "ended early" in problem
    rec.stop()  # safe after the close


@pytest.mark.emulator
@pytest.mark.parametrize(("imu", "rate_hz", "error"), [
    ("lsm9ds1", 1e6 / 1051, None),
    ("none", None, "cannot stream its IMU"),
    ("broken", None, "did not start"),
])
def test_the_emulator_imu_kinds(emulator_built: Path, imu: str, rate_hz: float | None,
                                error: str | None) -> None:
    with open_belt("emulator", build=False, imu=imu) as belt:
        assert belt.senses_vibration == (error is None)
        if error is not None:
            with pytest.raises(DeviceError, match=error):
                belt.sense(1.0)
            return
        with belt.sense(0.1) as rec:
            assert rec.rate_hz == pytest.approx(rate_hz)


def test_the_emulator_refuses_an_unknown_imu() -> None:
    with pytest.raises(ConfigError, match="imu must be one of"):
        open_belt("emulator", build=False, imu="bmx160")


def _falling(t_ns: np.ndarray, env: np.ndarray, level: float, after_ns: int) -> float:
    """The first downward crossing of ``level`` after ``after_ns`` (ns)."""
    return float(t_ns[int(np.flatnonzero((env <= level) & (t_ns > after_ns))[0])])


@pytest.mark.emulator
def test_the_board_senses_the_shaped_drive_rise_and_fall_faster_than_plain(
        emu: EmulatorBelt) -> None:
    """Firmware 1.3 shapes on the device (SET_DRIVE): at level 0.5 the kick at full duty
    and the brake pulse make the sensed 10-90 % rise and 90-10 % fall several times shorter
    than plain (the firmware host test measures 18.9 and 9.7 ms against 103.5 and 54.9)."""
    assert emu.can_shape and emu.can_brake
    times = {}
    for drive in ("plain", "shaped"):
        emu.set_drive(drive)
        with emu.sense(1.2, tactor=2) as rec:
            time.sleep(0.15)
            on_ns = time.perf_counter_ns()
            emu.set_amplitudes([0, 0, 0.5, 0, 0, 0])
            time.sleep(0.45)
            off_ns = time.perf_counter_ns()
            emu.set_amplitudes([0.0] * 6)
            assert rec.wait_for(off_ns + 400_000_000, 5.0)
            rec.stop()
        t, acc = rec.samples()
        env = _vibration(acc, acc[t < on_ns - 20_000_000].mean(axis=0))
        steady = float(np.median(env[(t > off_ns - 80_000_000) & (t < off_ns - 10_000_000)]))
        assert steady > 0.3  # 2 g * 0.5**2
        rise = (_crossing(t, env, 0.9 * steady, on_ns - 5_000_000)
                - _crossing(t, env, 0.1 * steady, on_ns - 5_000_000)) / 1e6
        fall = (_falling(t, env, 0.1 * steady, off_ns - 5_000_000)
                - _falling(t, env, 0.9 * steady, off_ns - 5_000_000)) / 1e6
        times[drive] = (rise, fall)
    (plain_rise, plain_fall), (shaped_rise, shaped_fall) = times["plain"], times["shaped"]
    assert plain_rise > 80.0 and plain_fall > 40.0, times
    assert shaped_rise < 30.0 and shaped_fall < 30.0, times


@pytest.mark.emulator
def test_an_emulated_board_wired_the_old_way_shapes_but_cannot_brake(
        emulator_built: Path) -> None:
    """``emulator?brake=0`` (the emulator's --wiring in1): INFO bit SHAPE without BRAKE."""
    with open_belt("emulator?brake=0&drive=shaped", build=False) as belt:
        assert belt.can_shape and not belt.can_brake and belt.drive == "shaped"
        assert belt.info.capabilities & 0x0C == wire.Capability.SHAPE
