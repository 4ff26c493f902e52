"""Audio belts played through a real JACK server (dummy backend) and recorded by a JACK
client: envelopes against the stimulus, the carrier, ramps, silence on every exit path,
and clear errors for bad devices and settings. Skipped when jackd, libportaudio,
sounddevice or JACK-Client is missing (tests/support/audio.py)."""

from __future__ import annotations

import itertools
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from support.audio import (
    DEVICE,
    RATE,
    Recorder,
    ensure_jack,
    envelope,
    max_step,
    peak,
    smooth,
    stop_jack,
)
from tactorbelt import ConfigError, DeviceError, Layout
from tactorbelt.devices import open_belt
from tactorbelt.devices.calibration import Calibration
from tactorbelt.player import Player
from tactorbelt.stimuli import Stimulus, make_stimulus

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


def _retry_on_underruns(attempt: Callable[[list[int]], None], tries: int = 3) -> None:
    """Run ``attempt`` (it plays, records, sets ``seen[0]`` to the underruns the belt
    reported, then asserts). A failed assertion is excused only by a reported underrun
    (an output gap on a loaded machine): then it is tried again, and skipped at last."""
    for _ in range(tries):
        seen = [0]
        try:
            attempt(seen)
            return
        except AssertionError:
            if seen[0] == 0:
                raise
    pytest.skip(f"the belt reported underruns in each of {tries} attempts that failed "
                "(a loaded machine; see benchmarks/bench_audio.py)")


def _transits(piece: np.ndarray, stim: Stimulus) -> list[tuple[int, str, float]]:
    """Where each transit starts in a recorded piece: (sample, "nf" or "fn", misfit).

    Slides the stimulus's own envelope around each transit (20 ms before its start to
    20 ms after its end, identically smoothed) along the piece's envelope (near and far
    channels) and keeps the places where it fits within 0.02 rms.
    """
    from scipy.signal import correlate

    pair = [stim.near_idx, stim.far_idx]
    got = envelope(piece, CARRIER)[:, pair][400:-400]  # no moving-average edges
    full = smooth(stim.amplitudes(np.arange(3 * round(stim.period_s * RATE)) / RATE),
                  CARRIER)[:, pair]
    period = round(stim.period_s * RATE)
    before, length = RATE // 50, round((stim.transit_s + 0.04) * RATE)
    found = []
    for kind, start in (("nf", stim.dwell_near_s),
                        ("fn", stim.dwell_near_s + stim.transit_s + stim.dwell_far_s)):
        i0 = period + round(start * RATE) - before
        tpl = full[i0:i0 + length]
        if got.shape[0] < length:
            continue
        sq = np.cumsum(np.vstack([np.zeros((1, 2)), got ** 2]), axis=0)
        sse = (sq[length:] - sq[:-length]).sum(axis=1) + (tpl ** 2).sum()
        sse -= 2 * sum(correlate(got[:, c], tpl[:, c], "valid", "fft") for c in range(2))
        rms = np.sqrt(np.maximum(sse, 0) / (2 * length))
        for _ in range(8):
            p = int(np.argmin(rms))
            if rms[p] > 0.02:
                break
            found.append((p + before + 400, kind, float(rms[p])))
            rms[max(0, p - RATE // 4):p + RATE // 4] = np.inf
    return sorted(found)


def test_a_dynamic_quarter_point_stimulus_keeps_its_dwells_to_the_sample(
        recorder: Recorder) -> None:
    def attempt(seen: list[int]) -> None:
        with open_belt(URL) as belt:
            assert recorder.connect() == 6
            stim = make_stimulus(belt.layout, 45.0, "dynamic")  # a quarter of 30..90
            assert (stim.dwell_near_s, stim.dwell_far_s) == pytest.approx((0.6, 0.2))
            belt.play(stim, None)
            _record(recorder, 8.0)  # long enough for whole dwells between lost cycles
        seen[0] = belt.underruns
        transit = round(stim.transit_s * RATE)
        dwells: dict[str, list[float]] = {"near": [], "far": []}
        for piece in recorder.pieces(RATE // 2):
            marks = _transits(piece, stim)
            for (p0, k0, _), (p1, k1, _) in itertools.pairwise(marks):
                assert k0 != k1, marks  # transits alternate, one per dwell
                dwells["near" if k1 == "nf" else "far"].append((p1 - p0 - transit) / RATE * 1000)
        if not (dwells["near"] or dwells["far"]):
            pytest.skip("the recorder lost a JACK cycle in every dwell (a loaded machine)")
        assert np.allclose(dwells["near"], 600.0, atol=2.0), dwells
        assert np.allclose(dwells["far"], 200.0, atol=2.0), dwells

    _retry_on_underruns(attempt)


def test_every_channel_follows_the_stimulus(recorder: Recorder) -> None:
    def attempt(seen: list[int]) -> None:
        with open_belt(URL) as belt:
            recorder.connect()
            stim = make_stimulus(belt.layout, 45.0, "dynamic")
            belt.play(stim, None)
            _record(recorder, 2.0)
        seen[0] = belt.underruns
        period = round(stim.period_s * RATE)
        want = smooth(stim.amplitudes(np.arange(3 * period) / RATE), CARRIER)[period:2 * period]
        checked = 0
        for piece in recorder.pieces(RATE // 4):
            got = envelope(piece, CARRIER)[400:-400, :6]
            (p, _, _), *_ = _transits(piece, stim) or [(None, None, None)]
            if p is None:
                continue
            # sample p of the piece is where a transit starts: line the period up with it
            kind_start = [round(stim.dwell_near_s * RATE),
                          round((stim.dwell_near_s + stim.transit_s + stim.dwell_far_s) * RATE)]
            best = min(np.abs(got - want[(np.arange(got.shape[0]) + 400 - p + k) % period]).max()
                       for k in kind_start)
            assert best < 0.02
            checked += 1
        if not checked:
            pytest.skip("no piece of the recording held a transit (a loaded machine)")

    _retry_on_underruns(attempt)


def test_a_static_stimulus_has_the_laws_ratios_and_the_carrier(recorder: Recorder) -> None:
    def attempt(seen: list[int]) -> None:
        with open_belt(URL) as belt:
            recorder.connect()
            stim = make_stimulus(belt.layout, 50.0, "static")
            belt.play(stim, 1.5)
            time.sleep(0.2)
            x = _record(recorder, 1.0)
        seen[0] = belt.underruns
        got = np.nanmedian(envelope(x, CARRIER)[2000:-2000], axis=0)[:6]
        want = stim.amplitudes(np.zeros(1))[0]
        k = int(np.argmax(want))
        assert np.allclose(got / got[k], want / want[k], atol=0.01)
        assert got[k] == pytest.approx(want[k], rel=0.01)
        xs = max(recorder.pieces(), key=len)[:, k]  # consecutive cycles only
        assert xs.shape[0] > RATE // 10
        crossings = np.count_nonzero(np.diff(np.signbit(xs)))
        assert crossings / 2 / (xs.shape[0] / RATE) == pytest.approx(CARRIER, rel=0.005)

    _retry_on_underruns(attempt)


def test_switching_stimuli_and_streaming_frames_never_click(recorder: Recorder) -> None:
    def attempt(seen: list[int]) -> None:
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
        seen[0] = belt.underruns
        assert peak(x) > 0.5
        assert max_step(x) <= MAX_STEP

    _retry_on_underruns(attempt)


def test_outputs_are_silent_after_stop_and_after_close(recorder: Recorder) -> None:
    belt = open_belt(URL)
    try:
        recorder.connect()
        belt.set_amplitudes([1.0] * 6)
        belt.stop()
        assert belt.settle()
        assert peak(_record(recorder, 0.2)) == 0.0
        belt.set_amplitudes([1.0] * 6)
        time.sleep(0.1)
    finally:
        belt.close()
    assert not belt.active
    assert peak(_record(recorder, 0.2)) == 0.0


def test_an_error_in_the_with_block_stops_the_stream_silent(recorder: Recorder) -> None:
    def attempt(seen: list[int]) -> None:
        with pytest.raises(KeyboardInterrupt), open_belt(URL) as belt:
            recorder.connect()
            recorder.start()
            belt.play(make_stimulus(belt.layout, 0.0), None)
            time.sleep(0.1)
            raise KeyboardInterrupt
        x, connected = recorder.take()
        seen[0] = belt.underruns
        assert not belt.active
        on = x[connected]
        assert peak(on) > 0.5 and peak(on[-100:]) == 0.0
        assert max_step(x) <= MAX_STEP

    _retry_on_underruns(attempt)


def test_sigterm_to_tactorbelt_play_ramps_down_and_exits_143(recorder: Recorder) -> None:
    def attempt(seen: list[int]) -> None:
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
        seen[0] = sum(int(n) for n in re.findall(r"(\d+) audio underrun", err))
        assert proc.returncode == 143, err
        on = x[connected]
        assert peak(on) > 0.2
        assert peak(on[-100:]) == 0.0, err  # silent before its ports went away
        assert max_step(x) <= MAX_STEP
        assert peak(x[~connected]) == 0.0

    _retry_on_underruns(attempt)


def test_calibration_gain_response_and_channel_map(recorder: Recorder, tmp_path: Path) -> None:
    def attempt(seen: list[int]) -> None:
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
        seen[0] = belt.underruns
        got = np.nanmedian(envelope(x, CARRIER)[1000:-1000], axis=0)[:6]
        assert got == pytest.approx([0, 0, 0.4, 0, 0.4, 0.4], abs=0.01)

    _retry_on_underruns(attempt)


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


def test_point_and_run_work_on_an_audio_belt(jack_server: None, tmp_path: Path) -> None:
    from support.studies import write_study

    exe = str(Path(sys.executable).with_name("tactorbelt"))
    proc = subprocess.run([exe, "point", "--bearing", "90", "--seconds", "0.5", "--belt", URL],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert "motors off" in proc.stdout + proc.stderr
    study = write_study(tmp_path, tactors=6, targets=4, repetitions=1, training=0,
                        conditions=["dynamic"], iti_s=0.05, timeout_s=1.0)
    proc = subprocess.run([exe, "run", str(study), "-p", "P01", "--headless", "--input",
                           "scripted", "--db", str(tmp_path / "s.sqlite"), "--belt", URL],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "complete, 4/4 trials" in proc.stdout, proc.stdout


def test_a_calibrated_audio_belt_still_renders_stimuli_itself_through_the_calibration(
        recorder: Recorder) -> None:
    """The audio callback applies the calibration, so the player hands it the stimulus
    (exact timing) instead of streaming frames, and the output is the calibrated level."""
    def attempt(seen: list[int]) -> None:
        from tactorbelt.devices.calibration import TactorCalibration

        c = Calibration(tuple(TactorCalibration(start=0.0, gain=0.5 if k == 0 else 1.0)
                              for k in range(6)))
        with open_belt(URL, calibration=c) as belt:
            assert recorder.connect() == 6
            stim = make_stimulus(belt.layout, 30.0, "static")  # on tactor 0 alone
            player = Player(belt)
            assert player.renders_on_device(stim)
            player.start(stim, None)
            x = _record(recorder, 0.4)
            stats = player.stop()
        seen[0] = belt.underruns
        assert stats.frames == 0  # rendered in the callback, not streamed
        got = np.nanmedian(envelope(x, CARRIER)[2000:-2000], axis=0)[:6]
        want = c.apply(stim.amplitudes(0.0))
        assert got == pytest.approx(list(want), abs=0.01)

    _retry_on_underruns(attempt)


def test_underruns_are_the_players_missed_output(jack_server: None) -> None:
    """A callback that stalls past JACK's cycle makes the device miss output: the
    playback's statistics count it (``underruns``), as the streaming player counts its
    missed frames; a playback without a stall counts only what the belt reported."""
    with open_belt(URL) as belt:
        render = belt._render
        calls = [0]

        def stalling(outdata: object, frames: int) -> None:
            calls[0] += 1
            if calls[0] in (40, 80):
                time.sleep(0.05)  # ten JACK cycles of 5.3 ms
            render(outdata, frames)

        before = belt.dropouts()
        belt._render = stalling  # type: ignore[method-assign]
        with Player(belt) as player:
            stats = player.play(make_stimulus(belt.layout, 30.0, "dynamic"), 1.0)
        assert stats.frames == 0  # the device rendered
        assert stats.underruns >= 1, stats
        assert stats.underruns == belt.dropouts() - before == belt.underruns - before
        belt._render = render  # type: ignore[method-assign]
        with Player(belt) as player:
            before = belt.dropouts()
            calm = player.play(make_stimulus(belt.layout, 30.0, "static"), 0.3)
        assert calm.underruns == belt.dropouts() - before
