"""``validate onsets`` for real through a JACK server (dummy backend): an audio belt's
outputs looped back into an audio sensor's input, directly or through a known filter.

What a loop through JACK should measure (docs/validation.md): the command waits for the
next JACK cycle (0 to one period P, about P/2 on average), in which the belt's callback
starts its ramp; the sensor's stream is in the same PortAudio client and is processed
after the belt's (it was opened after it), so a direct connection hands it the same
cycle's samples (no delay), while a loop through another client (the filter) closes a
cycle in JACK's graph and is delayed by one period. PortAudio's reported input latency
(0 for these ports) is subtracted; its reported output latency (one period: the way to
the system's playback port) is not on this path. Add the 10 % point of the signal chain
itself (the belt's 5 ms ramp, the filter, the sensor's estimator), computed by
``support.jack_filter.chain_crossings``.

Skipped without jackd, libportaudio, sounddevice or JACK-Client (tests/support/audio.py).
"""

from __future__ import annotations

import math
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from support.audio import DEVICE, PERIOD, RATE, Recorder, ensure_jack, peak, stop_jack
from support.jack_filter import EnvelopeFilter, Wiring, chain_crossings
from tactorbelt import DeviceError
from tactorbelt.validation import OnsetSettings, run_onsets
from tactorbelt.validation.run import OnsetValidation
from tactorbelt.validation.sensors import AudioSensor

BELT = f"audio:{DEVICE}?channels=2"
SENSE = f"audio:{DEVICE}?channel=0"
P_MS = PERIOD / RATE * 1e3
#: How far a callback may run late after its cycle began (the command's main thread holds
#: the GIL while it spins the last millisecond before a deadline), beyond what the sensor
#: measured (``AudioSensor.callback_late_ms``), for the upper end of the range.
JITTER_MS = 1.5
#: The 10 % point of a ramp read through the estimator moves with the carrier's phase at
#: the ramp by a few tenths of a millisecond.
PHASE_MS = 0.6
#: Pulses that lost cycles are pulsed again: up to this often, each reported by the
#: belt (an underrun) or the sensor (an overflow that moved its mapping).
REPEATS = 10


@pytest.fixture(scope="module")
def jack_server() -> Iterator[None]:
    ensure_jack(realtime=True)  # as jackd runs by default; it falls back where refused
    yield
    stop_jack()


@pytest.fixture
def realtime(jack_server: None) -> None:
    """Timing is asserted only on a server with realtime scheduling (jackd's default, and
    an audio lab's): without it, on a loaded machine, callbacks run milliseconds after
    their cycle began (an onset measures early by as much) and cycles are dropped."""
    import jack

    client = jack.Client("tactorbelt-validation-probe")
    try:
        rt = client.realtime
    finally:
        client.close()
    if not rt:
        pytest.skip("the JACK server runs without realtime scheduling (started elsewhere "
                    "with --no-realtime?): its timing is not a sound card's")


def _validate(tmp_path: Path, through: EnvelopeFilter | None,
              settings: OnsetSettings) -> tuple[OnsetValidation, float]:
    """The validation, and how late the sensor's callbacks ran (ms): the belt's, in the
    same cycle before them, ran no later, so an onset may measure early by as much."""
    wiring = Wiring()
    sensors: list[AudioSensor] = []

    def connect(belt: object, sensor: object) -> None:
        assert isinstance(sensor, AudioSensor)
        sensors.append(sensor)
        wiring.find()
        wiring.loop(through)

    try:
        result, _ = run_onsets(BELT, tmp_path, sense_url=SENSE, settings=settings,
                               on_open=connect)
    except DeviceError as exc:
        if "attempts (an overloaded machine?" not in str(exc):
            raise
        pytest.skip(f"every attempt at a pulse lost JACK cycles (a loaded machine): {exc}")
    finally:
        wiring.close()
    return result, sensors[0].callback_late_ms


def _latencies(result: OnsetValidation, n: int) -> np.ndarray:
    """The ``n`` pulses' latencies that could be measured. A pulse whose vibration had
    not stopped before it (the stop before it came late: a loaded machine) has none, and
    the result warns of it by tactor; three quarters of them are measured."""
    lat = np.array([p.latency_ms for t in result.tactors for p in t.pulses])
    assert lat.size == n
    for t in result.tactors:
        if any(math.isnan(p.latency_ms) for p in t.pulses):
            assert any(w.startswith(f"tactor {t.tactor} ") and "had not stopped" in w
                       for w in result.warnings), result.warnings
    assert np.isfinite(lat).mean() >= 0.75, lat
    return lat[np.isfinite(lat)]


def _within(lat: np.ndarray, low: float, high: float, late_ms: float) -> None:
    """The measured latencies against the expected range of one JACK period (the wait
    for the next cycle): none earlier than the callbacks' measured lateness allows
    (``late_ms``: a loaded machine runs them milliseconds late, and a command that came
    in between is output from the cycle's start); most inside it (a command whose
    thread the OS preempted between its stamp and its write measures longer, as it
    would in a study); the median within one period of its middle."""
    print(f"latencies {np.round(lat, 2).tolist()} ms, expected {low:.2f}..{high:.2f} ms; "
          f"callbacks up to {late_ms:.2f} ms late")
    assert (lat >= low - late_ms - PHASE_MS).all(), (lat, late_ms)
    inside = (lat <= high + JITTER_MS).mean()
    assert inside >= 0.75, lat
    assert abs(np.median(lat) - (low + high) / 2) <= P_MS, lat


def test_a_direct_loopback_measures_the_wait_for_the_next_cycle(realtime: None,
                                                               tmp_path: Path) -> None:
    settings = OnsetSettings(pulses=4, on_s=0.1, off_s=0.1, max_repeats=REPEATS)
    t10, rise = chain_crossings(None, 5.0, 4.0, 250.0, RATE, settings.on_s)
    result, late_ms = _validate(tmp_path, None, settings)
    lat = _latencies(result, 8)
    # the chain's own 10 % point plus a wait of 0..P (no cycle of delay)
    _within(lat, t10, t10 + P_MS, late_ms)
    # a 5 ms ramp read through a 4 ms moving mean: the estimate moves with the carrier's
    # phase at the ramp by a few tenths of a millisecond
    rises = [p.rise_ms for t in result.tactors for p in t.pulses
             if not math.isnan(p.latency_ms)]
    assert rises == pytest.approx([rise] * lat.size, abs=0.6)


def test_through_a_first_order_filter_the_rise_and_fall_are_the_filters(
        realtime: None, tmp_path: Path) -> None:
    tau = 0.02
    settings = OnsetSettings(pulses=3, on_s=10 * tau, off_s=10 * tau, max_repeats=REPEATS)
    t10, rise = chain_crossings(tau, 5.0, 4.0, 250.0, RATE, settings.on_s)
    filt = EnvelopeFilter(tau)
    try:
        result, late_ms = _validate(tmp_path, filt, settings)
    finally:
        filt.close()
    want = tau * math.log(9) * 1e3  # 43.9 ms
    for t in result.tactors:
        d = t.to_dict()
        assert d["rise_ms"] == pytest.approx(want, rel=0.05)
        assert d["rise_ms"] == pytest.approx(rise, rel=0.01)  # the whole chain, exactly
        assert d["fall_ms"] == pytest.approx(want, rel=0.05)
        assert d["settled"]
    # the filter's own 10 % point, one cycle around the loop, and the wait
    _within(_latencies(result, 6), t10 + P_MS, t10 + 2 * P_MS, late_ms)


def _command(*args: str) -> list[str]:
    return [sys.executable, "-m", "tactorbelt", "validate", "onsets", "--belt", BELT, *args]


def test_an_unconnected_input_is_an_error_naming_the_tactor(jack_server: None,
                                                           tmp_path: Path) -> None:
    # PortAudio connects the sensor's input to the dummy server's (silent) capture port
    proc = subprocess.run(_command("--sense", f"audio:{DEVICE}?channel=1", "--on", "0.1",
                                   "--off", "0.1", "-o", str(tmp_path)),
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 3, proc.stderr
    assert "saw no pulse on tactor 0 at level 1:" in proc.stderr
    assert "Traceback" not in proc.stderr
    assert not (tmp_path / "validation.json").exists()


def test_sigterm_during_a_pulse_turns_the_outputs_off(jack_server: None,
                                                      tmp_path: Path) -> None:
    rec = Recorder()
    proc = subprocess.Popen(_command("--sense", SENSE, "--on", "3", "--off", "3", "-o",
                                     str(tmp_path)),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        rec.connect(timeout_s=30)
        rec.start()
        assert proc.stdout is not None
        assert "validating onsets" in proc.stdout.readline()
        time.sleep(1.0)  # the lead-in (0.2 s), then the first pulse is on for 3 s
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=30)
        time.sleep(0.1)
        x, connected = rec.take()
    finally:
        if proc.poll() is None:
            proc.kill()
        rec.close()
    assert proc.returncode == 143, err
    assert "stopped: motors off; nothing written" in err
    on = x[connected]
    assert peak(on) > 0.5, "the first pulse was not on when SIGTERM came"
    assert peak(on[-100:]) == 0.0  # silent before its ports went away
    assert not (tmp_path / "validation.json").exists()
