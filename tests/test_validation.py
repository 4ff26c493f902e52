"""``tactorbelt validate onsets`` on the sim belt, its estimator and sensor registry, and
the command as a user runs it (the audio sensor through JACK: test_validation_audio.py).

The sim belt's own model is the sensor: the measured latency (command to 10 % of the
steady vibration), the 10-90 % rise and the 90-10 % fall must be the ERM model's
analytic values (amplitude = speed**2, first-order speed): 10 % at
``-tau ln(1 - sqrt(0.1))``, 90 % at ``-tau ln(1 - sqrt(0.9))``, the fall
``fall_tau / 2 ln 9``.
"""

from __future__ import annotations

import json
import math
import re
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from support.cli import tactorbelt
from tactorbelt import ConfigError, DeviceError
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.devices.calibration import Calibration, TactorCalibration
from tactorbelt.devices.erm import ErmParams
from tactorbelt.devices.sim import SimBelt
from tactorbelt.validation import (
    NoPulseError,
    OnsetSettings,
    open_sensor,
    run_onsets,
    validate_onsets,
)
from tactorbelt.validation.envelope import (
    linearity,
    measure_pulse,
    rectified_envelope,
)
from tactorbelt.validation.sensors import ModelSensor, Window, resolve_sensor

#: The brief asks for 5 %; the default schedule measures within 1 %.
TOLERANCE = 0.02


def analytic(params: ErmParams) -> tuple[float, float, float]:
    """Latency to 10 %, 10-90 % rise, 90-10 % fall (ms) of the ERM model at level 1."""
    t10 = -params.rise_tau_s * math.log(1 - math.sqrt(0.1))
    t90 = -params.rise_tau_s * math.log(1 - math.sqrt(0.9))
    return t10 * 1e3, (t90 - t10) * 1e3, params.fall_tau_s / 2 * math.log(9) * 1e3


@pytest.mark.parametrize("params", [ErmParams(), ErmParams(rise_tau_s=0.02, fall_tau_s=0.03)])
def test_sim_virtual_measures_the_models_analytic_latency_rise_and_fall(
        params: ErmParams) -> None:
    latency, rise, fall = analytic(params)
    t0 = time.perf_counter()
    with open_belt("sim:virtual?drive=plain", params=params) as belt, \
            open_sensor(None, belt) as sensor:
        result = validate_onsets(belt, sensor, OnsetSettings(pulses=3, levels=(0.5, 1.0)))
    assert time.perf_counter() - t0 < 10.0  # 36 pulses on a simulated clock: no waiting
    assert [t.tactor for t in result.tactors] == list(range(6))
    for t in result.tactors:
        d = t.to_dict()
        assert d["latency_ms"] == pytest.approx(latency, rel=TOLERANCE)
        assert d["rise_ms"] == pytest.approx(rise, rel=TOLERANCE)
        assert d["fall_ms"] == pytest.approx(fall, rel=TOLERANCE)
        assert d["pulses"] == 6 and d["levels"] == [0.5, 1.0]
        # amplitude = level**2 (above the dead zone): 0.25 and 1, a line through both
        assert d["amplitudes"] == pytest.approx([0.25, 1.0], rel=0.01)
        fit = d["linearity"]
        assert fit["slope"] == pytest.approx(1.5, rel=0.01)
        assert fit["intercept"] == pytest.approx(-0.5, rel=0.02)
        assert fit["r2"] == pytest.approx(1.0)
        assert d["settled"]
    assert result.warnings == [] and result.repeats == []
    assert result.onset_reference.startswith("host")


def test_sim_on_the_wall_clock_measures_the_same() -> None:
    latency, rise, fall = analytic(ErmParams())
    with open_belt("sim?drive=plain") as belt, open_sensor(None, belt) as sensor:
        result = validate_onsets(belt, sensor, OnsetSettings(pulses=3, lead_s=0.05),
                                 tactors=[2])
    (t,) = result.tactors
    d = t.to_dict()
    assert t.tactor == 2 and d["pulses"] == 3
    # the host stamp comes before the sim belt's own by what set_amplitudes takes (tens
    # of microseconds; more where the OS preempted the thread): never early
    got = [p.latency_ms for p in t.pulses]
    assert min(got) >= latency * (1 - TOLERANCE)
    assert min(got) == pytest.approx(latency, rel=0.03)
    assert d["rise_ms"] == pytest.approx(rise, rel=TOLERANCE)
    assert d["fall_ms"] == pytest.approx(fall, rel=TOLERANCE)


def test_a_level_in_the_dead_zone_is_an_error_naming_the_tactor_and_level() -> None:
    with open_belt("sim:virtual") as belt, open_sensor(None, belt) as sensor, \
            pytest.raises(NoPulseError, match=r"saw no pulse on tactor 0 at level 0\.2") as info:
        validate_onsets(belt, sensor, OnsetSettings(pulses=2, levels=(0.2, 1.0)))
    assert isinstance(info.value, DeviceError)
    assert (info.value.tactor, info.value.level) == (0, 0.2)
    assert belt.levels is not None and not belt.levels.any()  # motors off


class _DelayedOnsetBelt(SimBelt):
    """A sim belt that reports device onsets 5 ms after its commands (as a firmware belt
    reports when its output changed)."""

    @property
    def reports_onsets(self) -> bool:
        return True

    def last_onset(self, timeout_s: float = 0.1) -> tuple[int, int] | None:
        return self.clock.now_ns() + 5_000_000, 100_000


def test_the_command_time_is_the_device_onset_where_the_belt_reports_it() -> None:
    latency, rise, _ = analytic(ErmParams())
    with _DelayedOnsetBelt(clock=SimClock()) as belt, ModelSensor(belt) as sensor:
        result = validate_onsets(belt, sensor, OnsetSettings(pulses=2), tactors=[0])
    d = result.tactors[0].to_dict()
    assert d["latency_ms"] == pytest.approx(latency - 5.0, rel=TOLERANCE)
    assert d["rise_ms"] == pytest.approx(rise, rel=TOLERANCE)
    assert result.onset_reference.startswith("device")
    assert result.onset_uncertainty_ms == pytest.approx(0.1)


@pytest.mark.emulator
def test_the_boards_own_imu_senses_the_emulators_motors(emulator_exe: Path) -> None:
    """The emulator's board simulates its IMU from the same ERM model; its samples come
    with device times mapped to the host clock, and the commands are timed from the
    device's own onsets (firmware 1.1+)."""
    latency, rise, fall = analytic(ErmParams())
    with open_belt("emulator", build=False) as belt, open_sensor("board", belt) as sensor:
        result = validate_onsets(belt, sensor, OnsetSettings(pulses=2), tactors=[1, 4])
    assert result.onset_reference.startswith("device") and sensor.url == "board"
    for t in result.tactors:
        d = t.to_dict()
        # the IMU's 1600 Hz samples, each read up to a period after its stamp, and a 5 ms
        # window: within 5 % of the model
        assert d["latency_ms"] == pytest.approx(latency, rel=0.05)
        assert d["rise_ms"] == pytest.approx(rise, rel=0.05)
        assert d["fall_ms"] == pytest.approx(fall, rel=0.05)
        assert d["amplitudes"] == pytest.approx([2.0], rel=0.05)  # the emulator's 2 g


class _Lossy(ModelSensor):
    """The model, but the first ``lose`` windows asked for report lost samples."""

    def __init__(self, belt: Any, lose: int) -> None:
        super().__init__(belt)
        self.lose = lose

    def envelope(self, tactor: int, t0_ns: int, t1_ns: int) -> Window:
        w = super().envelope(tactor, t0_ns, t1_ns)
        if self.lose > 0:
            self.lose -= 1
            w.problem = "the sensor lost input (a test)"
        return w


def test_a_pulse_whose_samples_were_lost_is_pulsed_again() -> None:
    latency, _, _ = analytic(ErmParams())
    with open_belt("sim:virtual?drive=plain") as belt, _Lossy(belt, lose=2) as sensor:
        result = validate_onsets(belt, sensor, OnsetSettings(pulses=2), tactors=[0, 1])
    assert [r["reason"] for r in result.repeats] == ["the sensor lost input (a test)"] * 2
    assert [t.to_dict()["pulses"] for t in result.tactors] == [2, 2]
    assert result.tactors[0].to_dict()["latency_ms"] == pytest.approx(latency, rel=TOLERANCE)
    with open_belt("sim:virtual") as belt, _Lossy(belt, lose=99) as sensor, \
            pytest.raises(DeviceError, match=r"tactor 0 at level 1: the sensor lost input "
                                             r"\(a test\) in each of 3 attempts"):
        validate_onsets(belt, sensor, OnsetSettings(pulses=1, max_repeats=2))


def test_a_belt_lost_mid_run_keeps_the_pulses_measured_before(tmp_path: Path) -> None:
    """A belt that stops answering after three pulses are measured (its cable pulled) ends
    the run with those, and the pulses played before whose windows are over, measured and
    the reason in ``stopped`` (validation.json keeps it, and its figure draws), the motors
    off; lost before any pulse is measured, the error itself."""
    from support.recordingbelt import RecordingBelt, read_commands
    from tactorbelt.validation.run import onset_figure

    for pull_after in (3, 0):
        log = tmp_path / f"belt-{pull_after}.log"
        belt = RecordingBelt(log, clock=SimClock())

        def pulled(done: int, total: int, belt: RecordingBelt = belt,
                   after: int = pull_after) -> None:
            if done >= after:
                belt.unplugged = True

        with belt, open_sensor(None, belt) as sensor:
            if pull_after == 0:
                with pytest.raises(DeviceError, match="unplugged"):
                    validate_onsets(belt, sensor, OnsetSettings(pulses=2), progress=pulled)
            else:
                result = validate_onsets(belt, sensor, OnsetSettings(pulses=2),
                                         progress=pulled)
                assert [t.tactor for t in result.tactors] == [0, 1, 2, 3]
                assert result.stopped == ("the pulse of tactor 5 at level 1, with 4 of 12 "
                                          "measured: belt 'sim' does not answer (unplugged)")
                data = json.loads(json.dumps(result.to_dict()))
                assert data["stopped"] == result.stopped and len(data["pulses"]) == 4
                assert onset_figure(result, tmp_path / "partial.png").stat().st_size > 0
            assert read_commands(log)[-1][0] == "stop"  # motors off


def test_a_run_stopped_by_a_lost_belt_is_written_and_leaves_the_calibration_alone(
        tmp_path: Path) -> None:
    """run_onsets writes what a stopped run measured (validation.json with ``stopped``,
    the figure) but not the calibration file, which holds complete measurements; with
    ``--tune`` the stopped plain run is written and nothing is fitted from it. A complete
    run says ``stopped: null``."""
    cal_file = tmp_path / "belt.toml"
    Calibration((TactorCalibration(0.3, 1.0, 0.8),) * 6).save(cal_file, belt="sim:virtual")
    before = cal_file.read_text()
    for tune in (False, True):
        opened: list[Any] = []

        def dead(levels: Any) -> None:
            raise DeviceError("belt 'sim:virtual' stopped answering")

        def lose(done: int, total: int, opened: list[Any] = opened) -> None:
            if done >= 4 and opened:
                opened[0]._write_levels = dead

        def keep(belt: Any, sensor: Any, opened: list[Any] = opened) -> None:
            opened.append(belt)

        result, paths = run_onsets(
            "sim:virtual", tmp_path / f"val-{tune}", calibration_file=cal_file,
            settings=OnsetSettings(pulses=2), tune=tune, progress=lose,
            drive=None if tune else "plain", on_open=keep)
        assert result.stopped is not None and "stopped answering" in result.stopped
        assert result.drive == "plain" and result.shaping is None
        assert sum(len(t.pulses) for t in result.tactors) >= 4  # and those played before
        assert json.loads(paths["results"].read_text())["stopped"] == result.stopped
        assert paths["figure"].is_file() and "calibration" not in paths
        assert cal_file.read_text() == before
    result, _ = run_onsets("sim:virtual", tmp_path / "whole", settings=OnsetSettings(pulses=1))
    assert result.stopped is None and result.to_dict()["stopped"] is None


def test_without_a_sensor_a_belt_that_models_no_vibration_is_refused() -> None:
    class Silent(SimBelt):
        @property
        def models_vibration(self) -> bool:
            return False

    with Silent(clock=SimClock()) as belt:
        with pytest.raises(ConfigError, match=r"models no vibration.*--sense audio"):
            open_sensor(None, belt)
        with pytest.raises(ConfigError, match="models no vibration"):
            open_sensor("model", belt)


@pytest.mark.parametrize(("url", "error", "message"), [
    ("microphone", ConfigError, r"unknown sensor URL 'microphone'; allowed: model, "
                                r"audio:DEVICE, board"),
    ("audio", ConfigError, r"sensor URL 'audio' needs a device"),
    ("audio:0?chanel=1", ConfigError, r"unknown option 'chanel' in sensor URL.*allowed: "
                                      r"channel, map"),
    ("audio:0?channel=x", ConfigError, r"option 'channel' of sensor URL 'audio:0\?channel=x' "
                                       r"must be an integer"),
    ("audio:0?window_ms=0", ConfigError, r"option 'window_ms' of sensor URL .* must be in"),
    ("model:3", ConfigError, r"takes no target"),
    ("board", DeviceError, r"sensor 'board' \(the belt's own IMU\) is not available for "
                           r"belt 'sim:virtual': it needs belt firmware that streams IMU"),
])
def test_sensor_urls_are_checked_in_one_place(url: str, error: type[Exception],
                                              message: str) -> None:
    with open_belt("sim:virtual") as belt, pytest.raises(error, match=message):
        open_sensor(url, belt)


def test_an_audio_sensor_cannot_sense_a_simulated_clock() -> None:
    pytest.importorskip("sounddevice")
    backend, target, options = resolve_sensor("audio:default?channel=0&window_ms=2")
    assert (backend.scheme, target, options) == ("audio", "default",
                                                 {"channel": 0, "window_ms": 2.0})
    with open_belt("sim:virtual") as belt, pytest.raises(ConfigError, match="simulated clock"):
        open_sensor("audio:default?channel=0", belt)


# -- the estimator ---------------------------------------------------------------------------
def test_the_rectified_envelope_of_a_steady_sine_is_its_amplitude() -> None:
    rate, carrier = 48000.0, 250.0
    x = 0.37 * np.sin(2 * np.pi * carrier * np.arange(4800) / rate + 0.3)
    env = rectified_envelope(x, rate, 1 / carrier)
    assert env[300:-300] == pytest.approx(0.37, rel=1e-3)
    # a window of 1.5 periods leaves a ripple of about 1 / (2 * 1.5) of the amplitude
    ripple = rectified_envelope(x, rate, 1.5 / carrier)[300:-300]
    assert 0.37 * 0.85 < ripple.min() < ripple.max() < 0.37 * 1.15


def _first_order(tau_s: float, rate: float = 10_000.0, on_s: float = 0.4, off_s: float = 0.4,
                 noise: float = 0.0) -> tuple[np.ndarray, np.ndarray, int, int]:
    t = np.arange(-0.05, on_s + off_s, 1 / rate)
    y = np.where(t < 0, 0.0, 1 - np.exp(-np.clip(t, 0, None) / tau_s))
    after = t >= on_s
    y[after] = y[~after][-1] * np.exp(-(t[after] - on_s) / tau_s)
    y = 2.0 * y + 0.5 + noise * np.random.default_rng(1).standard_normal(t.size)
    return np.round(t * 1e9).astype(np.int64), y, 0, round(on_s * 1e9)


def test_measure_pulse_of_a_first_order_response() -> None:
    t, y, on, off = _first_order(0.02)
    m = measure_pulse(t, y, on, off, tactor=3, level=0.5)
    assert m.seen and m.amplitude == pytest.approx(2.0, rel=1e-3) and m.baseline == 0.5
    assert m.latency_ms == pytest.approx(20 * math.log(10 / 9), abs=0.01)
    assert m.rise_ms == pytest.approx(20 * math.log(9), abs=0.01)
    assert m.fall_ms == pytest.approx(20 * math.log(9), abs=0.01)
    assert m.settled and m.stopped
    t, y, on, off = _first_order(0.02, noise=0.002)  # 0.1 % noise: crossings hold
    m = measure_pulse(t, y, on, off, tactor=3, level=0.5)
    assert m.rise_ms == pytest.approx(20 * math.log(9), rel=0.03)


def test_an_unsettled_or_unstopped_pulse_is_flagged_and_a_flat_one_is_not_seen() -> None:
    t, y, on, off = _first_order(0.2)  # tau 200 ms in a 400 ms pulse: still rising
    m = measure_pulse(t, y, on, off, tactor=0, level=1.0)
    assert m.seen and not m.settled
    assert math.isnan(m.fall_ms)  # not down to 10 % within the window
    noise = 0.001 * np.random.default_rng(2).standard_normal(t.size)
    m = measure_pulse(t, 0.5 + noise, on, off, tactor=0, level=1.0)
    assert not m.seen and math.isnan(m.latency_ms)
    m = measure_pulse(t, np.zeros(t.size), on, off, tactor=0, level=1.0)  # silence
    assert not m.seen


def test_linearity() -> None:
    assert linearity([0.5, 1.0], [0.25, 1.0]) == pytest.approx((1.5, -0.5, 1.0))
    fit = linearity([0.25, 0.5, 0.75, 1.0], [0.0625, 0.25, 0.5625, 1.0])
    assert fit is not None
    slope, _, r2 = fit
    assert slope == pytest.approx(1.25) and 0.9 < r2 < 1.0
    assert linearity([1.0, 1.0], [0.9, 1.0]) is None


# -- results, files and the calibration --------------------------------------------------------
def test_run_onsets_writes_results_figure_and_calibration(tmp_path: Path) -> None:
    cal_file = tmp_path / "belt.toml"
    start = Calibration((TactorCalibration(0.3, 1.0, 0.8),) * 6)
    start.save(cal_file, belt="sim:virtual")
    result, paths = run_onsets("sim:virtual", tmp_path / "val", calibration_file=cal_file,
                               settings=OnsetSettings(pulses=2))
    doc = json.loads(paths["results"].read_text())
    for key in ("tactors", "belt", "sensor", "method", "date", "onset_reference", "settings"):
        assert key in doc
    assert doc["belt"] == "sim:virtual" and doc["sensor"] == "model"
    row = doc["tactors"][0]
    for key in ("tactor", "latency_ms", "rise_ms", "fall_ms", "latency_sd_ms", "rise_sd_ms",
                "fall_sd_ms", "pulses", "levels", "amplitudes"):
        assert key in row, key
    # driven through the calibration: level 1 -> drive 0.8 -> amplitude 0.64
    assert row["amplitudes"] == pytest.approx([0.64], rel=0.01)
    assert paths["figure"].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    cal = Calibration.load(cal_file)
    assert [t.start for t in cal.tactors] == [0.3] * 6  # the rest kept
    assert cal.validated == doc["date"] and cal.validation_method is not None
    ms, sd = cal.skin_latency(range(6))
    assert ms == pytest.approx(row["latency_ms"], abs=0.01) and sd >= 0.0
    assert 'belt = "sim:virtual"' in cal_file.read_text()
    with pytest.raises(ConfigError, match=r"validation\.json' exists.*--force"):
        run_onsets("sim:virtual", tmp_path / "val")
    with pytest.raises(ConfigError, match="has 6 tactors but the belt has 8"):
        run_onsets("sim:8,virtual", tmp_path / "val8", calibration_file=cal_file)


# -- the command --------------------------------------------------------------------------
def test_the_command_on_sim_virtual_creates_the_calibration(tmp_path: Path) -> None:
    proc = tactorbelt("validate", "onsets", "--belt", "sim:virtual", "--pulses", "2",
                      "--levels", "0.5,1.0", "--drive", "plain", "--calibration",
                      str(tmp_path / "new.toml"), "-o", str(tmp_path / "out"))
    assert proc.returncode == 0, proc.stderr
    assert "done: motors off" in proc.stdout
    latency, rise, _ = analytic(ErmParams())
    assert f"{latency:7.1f}" in proc.stdout and f"{rise:7.1f}" not in proc.stderr
    cal = Calibration.load(tmp_path / "new.toml")
    assert cal.is_identity and cal.tactors[5].latency_ms == pytest.approx(latency,
                                                                          rel=TOLERANCE)
    assert (tmp_path / "out" / "onsets.png").is_file()


@pytest.mark.parametrize(("args", "code", "message"), [
    (["--sense", "webcam"], 2, "error: unknown sensor URL 'webcam'"),
    (["--sense", "board"], 3, r"error: sensor 'board' .* is not available"),
    (["--levels", "0.1"], 3, r"saw no pulse on tactor 0 at level 0\.1"),
    (["--levels", "2"], 2, r"Invalid value for '--levels': must be in \(0, 1\], got 2"),
    (["--pulses", "0"], 2, r"Invalid value for '--pulses': must be in \[1, 1000\]"),
])
def test_the_command_refuses_clearly(tmp_path: Path, args: list[str], code: int,
                                     message: str) -> None:
    proc = tactorbelt("validate", "onsets", "--belt", "sim:virtual", "-o", str(tmp_path / "out"),
                      *args)
    assert proc.returncode == code, proc.stderr
    assert re.search(message, proc.stderr), proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "out").exists()


def test_ctrl_c_during_the_pulses_stops_with_the_motors_off_and_writes_nothing(
        tmp_path: Path) -> None:
    proc = subprocess.Popen([sys.executable, "-m", "tactorbelt", "validate", "onsets",
                             "--belt", "sim", "--pulses", "50", "-o", str(tmp_path / "out")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        assert "validating onsets" in proc.stdout.readline()
        time.sleep(1.0)
        proc.send_signal(signal.SIGINT)
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "stopped: motors off; nothing written" in err and "error" not in err
    assert not (tmp_path / "out").exists()


def test_the_sensor_help_imports_no_numpy() -> None:
    """``validate onsets --help`` lists the sensors without loading NumPy."""
    import subprocess
    import sys

    code = ("import sys\nfrom tactorbelt.cli import main\n"
            "try:\n    main(['validate', 'onsets', '--help'])\nexcept SystemExit:\n    pass\n"
            "print('NUMPY' if 'numpy' in sys.modules else 'none')\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, timeout=60).stdout
    assert "audio:default?channel=0" in out
    assert out.strip().endswith("none")
