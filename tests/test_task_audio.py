"""The secondary tasks' sounds: what they are, and that they come out at their onsets.

The timing test plays n-back tones through SDL's ``disk`` audio driver, which writes the
mixed stream to a file, in a fresh process (SDL picks its driver once per process:
``support/task_audio_probe.py``). The disk driver writes a block to the file as soon as
the callback filled it, so the clock reading at the callback is the time the block's
first frame came out; every tone must be in the file, whole, on the frame output at its
onset (within 5 ms), unless the machine starved SDL's audio thread at that block (then
the tone comes out late, and its placement must say so).
"""

from __future__ import annotations

import gc
import itertools
import json
import os
import subprocess
import sys
import weakref
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tactorbelt._errors import ConfigError, DeviceError
from tactorbelt.clock import SimClock, WallClock
from tactorbelt.tasks.audio import LATE_NS, SdlTaskAudio, SilentTaskAudio, open_task_audio
from tactorbelt.tasks.kinds import task_kind
from tactorbelt.tasks.sounds import (
    BEEP_HZ,
    PEAK,
    RATE,
    TONE_HZ,
    SoundBank,
    beep_slot_s,
    beeps,
    tone,
)

PROBE = Path(__file__).resolve().parent / "support" / "task_audio_probe.py"


def _peak_hz(x: Any, rate: int = RATE) -> float:
    spec = np.abs(np.fft.rfft(np.asarray(x, float) * np.hanning(len(x)), 8 * len(x)))
    return float(np.fft.rfftfreq(8 * len(x), 1 / rate)[int(np.argmax(spec))])


def _bursts(x: Any) -> list[tuple[int, int]]:
    """(start, end) of each run of sound separated by exact silence."""
    on = np.abs(np.asarray(x)) > 0
    edges = np.diff(np.concatenate([[0], on.astype(int), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


# -- the sounds ----------------------------------------------------------------------------
def test_the_eight_tones_have_their_own_pitch_and_last_the_stimulus() -> None:
    pitches = []
    for k in range(8):
        x = tone(k, 0.5)
        assert x.dtype == np.float32 and x.shape == (round(0.5 * RATE),)
        assert np.max(np.abs(x)) == pytest.approx(PEAK, rel=1e-5)
        assert abs(x[0]) < 1e-3 and abs(x[-1]) < 1e-3  # faded in and out: no click
        pitches.append(_peak_hz(x))
    assert pitches == pytest.approx(list(TONE_HZ), abs=3.0)
    # neighbours four semitones apart: clearly different for anyone
    assert all(b / a > 1.25 for a, b in itertools.pairwise(pitches))


@pytest.mark.parametrize(("a", "b"), [(1, 1), (2, 3), (4, 4), (3, 1)])
def test_an_arithmetic_item_is_a_high_beeps_then_b_low_beeps(a: int, b: int) -> None:
    x = beeps(a, b, 0.5)
    bursts = _bursts(x)
    assert len(bursts) == a + b
    hz = [_peak_hz(x[s:e]) for s, e in bursts]
    assert hz[:a] == pytest.approx([BEEP_HZ[0]] * a, rel=0.05)
    assert hz[a:] == pytest.approx([BEEP_HZ[1]] * b, rel=0.05)
    slot = round(beep_slot_s(0.5) * RATE)
    starts = [s for s, _ in bursts]
    gaps = np.diff(starts)
    # one slot between beeps of an operand, two between the operands
    assert all(abs(g - slot) <= 2 for i, g in enumerate(gaps) if i != a - 1)
    assert abs(gaps[a - 1] - 2 * slot) <= 2
    assert len(x) <= 9 * slot


def test_items_without_a_sound_are_refused_and_the_bank_reuses_sounds() -> None:
    nback, arithmetic = task_kind("nback"), task_kind("arithmetic")
    for kind, bad in ((nback, "K"), (nback, "tone8"), (arithmetic, "5+"), (arithmetic, "")):
        with pytest.raises(ConfigError, match="no sound"):
            kind.sound(bad, 0.5, RATE)
    with pytest.raises(ConfigError, match="positive"):
        tone(0, 0.0)
    bank = SoundBank()
    a = bank.get("tone2", 0.5, nback.sound)
    assert bank.get("tone2", 0.5, nback.sound) is a and not a.flags.writeable
    assert bank.get("tone2", 0.25, nback.sound).shape[0] == a.shape[0] // 2


# -- the output ----------------------------------------------------------------------------
def test_a_simulated_clock_gets_a_silent_output_that_records_each_onset() -> None:
    out = open_task_audio(SimClock())
    assert isinstance(out, SilentTaskAudio) and not out.plays_sound
    out.schedule(tone(0, 0.1), 5_000, "tone0")
    assert [(p.label, p.onset_ns, p.late_ns) for p in out.played] == [("tone0", 5_000, 0)]
    out.close()


def _run_probe(tmp_path: Path, *args: str,
               driver: str = "disk") -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, SDL_AUDIODRIVER=driver,
               SDL_DISKAUDIOFILE=str(tmp_path / "stream.raw"), PYGAME_HIDE_SUPPORT_PROMPT="1")
    proc = subprocess.run([sys.executable, str(PROBE), *args], env=env, capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    return proc


def test_tones_come_out_of_the_sound_stream_at_their_onsets(tmp_path: Path) -> None:
    _run_probe(tmp_path, str(tmp_path / "probe.json"))
    d = json.loads((tmp_path / "probe.json").read_text())
    assert d["driver"] == "disk" and d["error"] == "None"
    rate = d["rate"]
    x = np.fromfile(tmp_path / "stream.raw", dtype=np.float32)
    played = {p[0]: p for p in d["played"]}
    assert set(played) == {"marker", "long", *(f"tone{k}" for k in range(8))}
    # the marker (an onset long past) starts on the stream's first frame: where the
    # stream begins in the file (SDL wrote silence before the device was started)
    marker = tone(7, 0.05)
    assert played["marker"][2] == 0 and played["marker"][4] > 0
    first = int(np.flatnonzero(x)[0])
    pre = first - int(np.flatnonzero(marker)[0])
    assert np.array_equal(x[pre:pre + marker.size], marker)

    frames = np.array([b[0] for b in d["blocks"]], dtype=np.int64)
    base = np.array([b[1] for b in d["blocks"]], dtype=np.int64)
    written = np.array([b[2] for b in d["blocks"]], dtype=np.int64)
    errors_ms = []
    for k, onset in enumerate(d["onsets"]):
        label, asked, frame, start_ns, late_ns = played[f"tone{k}"]
        assert asked == onset
        sound = tone(k, 0.1)
        # the whole tone is in the file from its frame on, untouched
        assert np.array_equal(x[pre + frame:pre + frame + sound.size], sound), label
        assert not x[pre + frame - 10:pre + frame].any()
        # it says how late it starts, on the stream's timeline
        assert abs(start_ns - onset - late_ns) <= 1e9 / rate, (label, start_ns - onset, late_ns)
        i = int(np.searchsorted(frames, frame, side="right")) - 1
        # handed over before the block before its own was filled (the probe's thread, 100
        # ms ahead, unless a loaded machine woke it late): on time (within LATE_NS),
        # unless the stream fell behind the clock just before its block (SDL's thread woke
        # late, and the timeline follows it), and then by no more than that
        if not (i > 0 and d["handed"][k] <= written[i - 1]):
            continue
        behind_ns = base[i] - base[i - 1] - (frames[i] - frames[i - 1]) * 1e9 / rate
        assert late_ns <= max(LATE_NS, behind_ns + 1e9 / rate), (label, late_ns, behind_ns)
        # when that frame came out: its block's write time plus its place in the block
        out_ns = written[i] + (frame - frames[i]) * 1e9 / rate
        error_ms = (out_ns - onset) / 1e6
        # a block SDL's thread filled more than 4 ms after the previous one ended (the
        # machine starved the thread) comes out late whatever the scheduler does: then
        # the tone must say how late it is
        starved = written[i] - written[i - 1] - (frames[i] - frames[i - 1]) * 1e9 / rate > 4e6
        if starved:
            assert late_ns / 1e6 >= error_ms - 1.0, (label, error_ms, late_ns)
        else:
            errors_ms.append(error_ms)
    assert len(errors_ms) >= 4
    assert max(abs(e) for e in errors_ms) <= 5.0, errors_ms
    # the long tone played until the stop, then faded out within a block and the ramp
    long_frame = played["long"][2]
    stop = d["stop_frame"]
    assert np.abs(x[pre + stop - 480:pre + stop]).max() > 0.1  # sounding when stopped
    silent_from = pre + stop + 2 * 480  # the next block fades over 5 ms (240 frames)
    assert not x[silent_from:pre + long_frame + rate].any()
    # closed in silence
    assert x.size >= pre + d["frames"] and not x[pre + d["frames"] - 480:].any()


@pytest.mark.timeout(120)
def test_closing_while_python_is_busy_never_hangs(tmp_path: Path) -> None:
    proc = _run_probe(tmp_path, "--cycles", driver="dummy")
    assert "closed 20" in proc.stdout


def test_without_sdl_through_ctypes_the_output_is_refused_before_it_opens(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Closing through pygame keeps the GIL and can hang: refused, with what to do."""
    from tactorbelt.tasks import audio as audio_mod

    monkeypatch.setattr(audio_mod, "_sdl_library", lambda: None)
    with pytest.raises(DeviceError, match=r"cannot reach the SDL2 library pygame loaded "
                       r"through ctypes.*install pygame from its wheel"):
        SdlTaskAudio(WallClock())


def test_the_output_is_silent_and_closed_when_the_session_fails() -> None:
    audio = SdlTaskAudio(WallClock())
    with pytest.raises(KeyboardInterrupt), audio:
        audio.schedule(tone(3, 0.2), WallClock().now_ns() + 150_000_000, "tone3")
        raise KeyboardInterrupt
    with pytest.raises(Exception, match="closed"):
        audio.schedule(tone(3, 0.2), 0)
    assert audio.played == []  # closed before its onset: never played


def test_a_closed_output_is_released() -> None:
    audio = SdlTaskAudio(WallClock())
    audio.schedule(tone(0, 0.05), 0, "tone0")
    audio.close()
    ref = weakref.ref(audio)
    del audio
    gc.collect()
    assert ref() is None  # SDL's device keeps no reference to it or its buffers


def test_stop_drops_the_sounds_scheduled_before_it_and_keeps_the_ones_after() -> None:
    clock = WallClock()
    with SdlTaskAudio(clock) as audio:
        now = clock.now_ns()
        audio.schedule(tone(1, 0.1), now + 150_000_000, "before")
        audio.stop()  # the break: what was scheduled is dropped ...
        audio.schedule(tone(2, 0.1), now + 150_000_000, "after")  # ... not what follows
        clock.sleep_until_ns(now + 300_000_000)
    assert [p.label for p in audio.played] == ["after"]


def test_the_task_sound_output_is_chosen_by_name(monkeypatch: pytest.MonkeyPatch) -> None:
    # SDL's dummy driver has one output: "System audio output device"
    monkeypatch.setenv("TACTORBELT_TASK_AUDIO", "no such headphones")
    with pytest.raises(DeviceError, match=r"'no such headphones' \(TACTORBELT_TASK_AUDIO\) "
                       r"matches no SDL output; outputs: 'System audio output device'"):
        open_task_audio(WallClock())
    monkeypatch.setenv("TACTORBELT_TASK_AUDIO", "system OUTPUT")
    with open_task_audio(WallClock()) as audio:
        assert audio.plays_sound


def test_a_measured_output_latency_is_taken_from_the_environment(
        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("TACTORBELT_TASK_AUDIO_LATENCY_MS", "23.5")
    with open_task_audio(WallClock()) as audio:
        assert isinstance(audio, SdlTaskAudio) and audio.latency_ns == 23_500_000
    monkeypatch.setenv("TACTORBELT_TASK_AUDIO_LATENCY_MS", "fast")
    with pytest.raises(ConfigError, match="TACTORBELT_TASK_AUDIO_LATENCY_MS must be"):
        open_task_audio(WallClock())


def test_the_silent_output_drops_the_sounds_a_stop_comes_before() -> None:
    """As an output that plays: a stop drops the sounds scheduled for onsets the clock
    has not reached (a task run ended before an item it announced), keeps the others."""
    from tactorbelt.clock import SimClock
    from tactorbelt.tasks.audio import SilentTaskAudio

    clock = SimClock()
    out = SilentTaskAudio(clock)
    tone = np.zeros(10, dtype=np.float32)
    out.schedule(tone, 10_000_000, "a")
    out.schedule(tone, 30_000_000, "b")
    clock.advance(20_000_000)
    out.stop()
    assert [p.label for p in out.played] == ["a"]
    out.schedule(tone, 40_000_000, "c")  # scheduled after the stop: kept
    assert [p.label for p in out.played] == ["a", "c"]
