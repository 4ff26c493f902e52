"""Audio belts played through a real JACK server (dummy backend) and recorded by a JACK
client: envelopes against the stimulus, the carrier, ramps, silence on every exit path,
and clear errors for bad devices and settings. Skipped when jackd, libportaudio,
sounddevice or JACK-Client is missing (tests/support/audio.py)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from support.audio import DEVICE, RATE, Recorder, ensure_jack, envelope, max_step, smooth, stop_jack
from tactorbelt import ConfigError, DeviceError, Layout
from tactorbelt.devices import open_belt
from tactorbelt.devices.calibration import Calibration
from tactorbelt.player import Player
from tactorbelt.stimuli import make_stimulus

CARRIER = 250.0
URL = f"audio:{DEVICE}?channels=6&carrier_hz={CARRIER:g}"
#: the largest sample-to-sample step of a 250 Hz sine at 48 kHz plus one ramp step
MAX_STEP = 2 * np.pi * CARRIER / RATE + 1.0 / 240 + 1e-3


@pytest.fixture(scope="session")
def jack_server() -> Iterator[None]:
    ensure_jack()
    yield
    stop_jack()


@pytest.fixture
def recorder(jack_server: None) -> Iterator[Recorder]:
    rec = Recorder()
    try:
        yield rec
    finally:
        rec.close()


def _record(rec: Recorder, seconds: float) -> np.ndarray:
    rec.start()
    time.sleep(seconds)
    x, _ = rec.take()
    return x


def _onset(x: np.ndarray) -> int:
    """The first sample where any channel leaves silence."""
    nz = np.flatnonzero(np.abs(x).max(axis=1) > 1e-6)
    assert nz.size, "the recording is silent"
    return int(nz[0])


def test_a_dynamic_quarter_point_stimulus_keeps_its_dwells_to_the_sample(
        recorder: Recorder) -> None:
    with open_belt(URL) as belt:
        assert recorder.connect() == 6
        stim = make_stimulus(belt.layout, 45.0, "dynamic")  # a quarter of 30..90
        assert (stim.dwell_near_s, stim.dwell_far_s) == pytest.approx((0.6, 0.2))
        recorder.start()
        time.sleep(0.1)
        belt.play(stim, 2.6)
        time.sleep(2.8)
        x, _ = recorder.take()
        assert belt.underruns == 0 or pytest.skip("underruns on a loaded machine")
    s0 = _onset(x)
    got = envelope(x[s0:s0 + round(2.5 * RATE)], CARRIER)
    want = smooth(stim.amplitudes(np.arange(got.shape[0]) / RATE), CARRIER)
    ramp = round(0.005 * RATE) + 2 * 192
    near, far = stim.near_idx, stim.far_idx
    # each transition, found by aligning the recorded envelope to the stimulus's locally
    starts = [0.6, 0.6 + 0.1 + 0.2, 1.6, 1.6 + 0.3]
    shifts = []
    for t in starts:
        i0, i1 = round((t - 0.02) * RATE), round((t + 0.12) * RATE)
        errs = [np.abs(got[i0 + d:i1 + d, [near, far]] - want[i0:i1, [near, far]]).max()
                for d in range(-192, 193)]
        shifts.append(int(np.argmin(errs)) - 192)
        assert min(errs) < 0.01
    dwells_ms = np.diff(shifts) / RATE * 1000  # deviation of each dwell from the stimulus's
    assert np.all(np.abs(dwells_ms) <= 2.0), (shifts, dwells_ms)
    assert np.abs(got[ramp:] - want[ramp:]).max() < 0.01


def test_a_static_stimulus_has_the_laws_ratios_and_the_carrier(recorder: Recorder) -> None:
    with open_belt(URL) as belt:
        recorder.connect()
        stim = make_stimulus(belt.layout, 50.0, "static")
        belt.play(stim, 1.5)
        time.sleep(0.2)
        x = _record(recorder, 1.0)
    got = envelope(x, CARRIER)[2000:-2000].mean(axis=0)[:6]
    want = stim.amplitudes(np.zeros(1))[0]
    k = int(np.argmax(want))
    assert np.allclose(got / got[k], want / want[k], atol=0.01)
    assert got[k] == pytest.approx(want[k], rel=0.01)
    crossings = np.count_nonzero(np.diff(np.signbit(x[:, k])))
    assert crossings / 2 / (x.shape[0] / RATE) == pytest.approx(CARRIER, rel=0.005)


def test_switching_stimuli_and_streaming_frames_never_click(recorder: Recorder) -> None:
    with open_belt(URL) as belt:
        recorder.connect()
        recorder.start()
        belt.play(make_stimulus(belt.layout, 10.0, "dynamic"), None)
        time.sleep(0.3)
        belt.play(make_stimulus(belt.layout, 200.0, "static"), None)  # a switch
        time.sleep(0.2)
        player = Player(belt, device_render=False)  # streamed frames, ramped
        player.play(make_stimulus(belt.layout, 100.0), 0.2)
        belt.set_amplitudes([1.0, 0, 1.0, 0, 1.0, 0])
        time.sleep(0.1)
        belt.stop()
        time.sleep(0.2)
        x, _ = recorder.take()
    assert np.abs(x).max() > 0.5
    assert max_step(x, recorder.gaps()) <= MAX_STEP or belt.underruns, belt.underruns


def test_outputs_are_silent_after_stop_and_after_close(recorder: Recorder) -> None:
    belt = open_belt(URL)
    try:
        recorder.connect()
        belt.set_amplitudes([1.0] * 6)
        belt.stop()
        assert belt.settle()
        assert np.abs(_record(recorder, 0.2)).max() == 0.0
        belt.set_amplitudes([1.0] * 6)
        time.sleep(0.1)
    finally:
        belt.close()
    assert not belt.active
    assert np.abs(_record(recorder, 0.2)).max() == 0.0


def test_an_error_in_the_with_block_stops_the_stream_silent(recorder: Recorder) -> None:
    with pytest.raises(KeyboardInterrupt), open_belt(URL) as belt:
        recorder.connect()
        recorder.start()
        belt.play(make_stimulus(belt.layout, 0.0), None)
        time.sleep(0.1)
        raise KeyboardInterrupt
    x, connected = recorder.take()
    assert not belt.active
    on = x[connected]
    assert np.abs(on).max() > 0.5 and np.abs(on[-100:]).max() == 0.0
    assert max_step(x, recorder.gaps()) <= MAX_STEP or belt.underruns, belt.underruns


def test_sigterm_to_tactorbelt_play_ramps_down_and_exits_143(recorder: Recorder) -> None:
    exe = Path(sys.executable).with_name("tactorbelt")
    proc = subprocess.Popen([str(exe), "play", "45", "--mode", "dynamic", "--seconds", "30",
                             "--belt", URL], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        recorder.connect(timeout_s=20)
        recorder.start()
        time.sleep(0.5)
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
    time.sleep(0.1)
    x, connected = recorder.take()
    assert proc.returncode == 143, err
    on = x[connected]
    assert np.abs(on).max() > 0.2
    assert np.abs(on[-100:]).max() == 0.0, err  # silent before its ports went away
    assert max_step(x, recorder.gaps()) <= MAX_STEP or "underrun" in err, err
    assert np.abs(x[~connected]).max(initial=0.0) == 0.0


def test_calibration_gain_response_and_channel_map(recorder: Recorder, tmp_path: Path) -> None:
    cal_file = tmp_path / "cal.toml"
    rows = "".join(f"[[tactor]]\nstart = 0.0\nceiling = 1.0\ngain = {g}\nchannel = {c}\n"
                   f"response = [[100.0, 2.0], [250.0, {r}], [400.0, 2.0]]\n\n"
                   for g, c, r in ((1.0, 5, 0.5), (0.5, 4, 1.0), (1.0, 3, 1.0), (1.0, 2, 1.0)))
    cal_file.write_text('format = "tactorbelt-calibration"\nversion = 1\n\n' + rows)
    cal = Calibration.load(cal_file)
    assert cal.is_identity is False and cal.channels == (5, 4, 3, 2)
    with open_belt(f"audio:{DEVICE}?channels=6", calibration=cal) as belt:
        assert belt.n_tactors == 4
        recorder.connect()
        belt.set_amplitudes([0.8, 0.8, 0.0, 0.4])
        assert belt.settle()
        x = _record(recorder, 0.3)
    got = envelope(x, CARRIER)[1000:-1000].mean(axis=0)[:6]
    assert got == pytest.approx([0, 0, 0.4, 0, 0.4, 0.4], abs=0.01)


def test_devices_lists_the_audio_outputs_with_their_channels(jack_server: None) -> None:
    from tactorbelt.devices.audio import discover

    found = discover()
    (row,) = [r for r in found.rows if DEVICE in r.description]
    assert "8 output channels" in row.note and row.url.startswith("audio:")


@pytest.mark.parametrize(("url", "error", "message"), [
    ("audio:no-such-card", DeviceError, "'no-such-card' not found; outputs: .*system"),
    (f"audio:{DEVICE}?channels=9", DeviceError, "has 8 output channels; .* needs 9"),
    (f"audio:{DEVICE}?map=0,1,2,3,4,12", DeviceError, "has 8 output channels; .* needs 13"),
    (f"audio:{DEVICE}?channels=6&carrier_hz=30000", ConfigError, r"Nyquist frequency \(24000 Hz\)"),
    (f"audio:{DEVICE}?samplerate=44100", DeviceError,
     "refuses 44100 Hz .*; it offers 48000 Hz"),
    (f"audio:{DEVICE}?map=0,1,1", ConfigError, "names a channel twice"),
    (f"audio:{DEVICE}?latency=fast", ConfigError, "must be low, high or seconds"),
])
def test_bad_devices_and_settings_are_clear_errors(jack_server: None, url: str,
                                                   error: type[Exception], message: str) -> None:
    with pytest.raises(error, match=message):
        open_belt(url)


def test_a_carrier_outside_the_tactor_band_warns(jack_server: None,
                                                 caplog: pytest.LogCaptureFixture) -> None:
    with open_belt(f"audio:{DEVICE}?channels=6&carrier_hz=1000") as belt:
        assert belt.carrier_hz == 1000.0
    assert "outside the band" in caplog.text


def test_the_cli_plays_on_an_audio_belt(jack_server: None) -> None:
    env = dict(os.environ)
    for args in (["play", "30", "--seconds", "0.3"], ["belt-test", "--seconds-each", "0.05",
                                                      "--gap", "0"]):
        proc = subprocess.run([str(Path(sys.executable).with_name("tactorbelt")), *args,
                               "--belt", URL], capture_output=True, text=True, timeout=60,
                              env=env)
        assert proc.returncode == 0, proc.stderr
        assert "motors off" in proc.stdout


def test_a_stimulus_for_another_layout_is_refused(jack_server: None) -> None:
    with open_belt(URL, layout=Layout.even(6)) as belt:
        assert not belt.can_render(make_stimulus(Layout.even(5), 0.0))
