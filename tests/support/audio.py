"""A real JACK server for audio-belt tests, a recording JACK client, and envelope tools.

:func:`ensure_jack` starts ``jackd`` with its dummy backend (no sound card: 48 kHz,
periods of 256 frames, 8 playback ports) when it is installed and no server runs, for
the rest of the test session (stopped at exit, or by :func:`stop_jack`), and skips the
test with the reason when jackd, libportaudio, sounddevice or JACK-Client is missing.
Belts then play through PortAudio's JACK host API (device ``system``) and a
:class:`Recorder` captures what they output, port by port.
"""

from __future__ import annotations

import atexit
import ctypes.util
import itertools
import os
import shutil
import subprocess
import sys
import threading
import time
from typing import Any

import numpy as np
from numpy.typing import NDArray

RATE = 48000
PERIOD = 256
OUTPUTS = 8
#: the PortAudio device that is the JACK server
DEVICE = "system"

_server: subprocess.Popen[bytes] | None = None
_lock = threading.Lock()


def _skip(reason: str) -> None:
    import pytest

    pytest.skip(reason)


def missing() -> str | None:
    """Why audio tests cannot run here, or None."""
    if shutil.which("jackd") is None:
        return "jackd is not installed (Debian: apt install jackd2)"
    if ctypes.util.find_library("portaudio") is None:
        return "the PortAudio library is not installed (Debian: apt install libportaudio2)"
    try:
        import jack  # noqa: F401
        import sounddevice  # noqa: F401
    except (ImportError, OSError) as exc:
        return f"sounddevice or JACK-Client cannot be imported: {exc}"
    return None


def _running() -> bool:
    import jack

    try:
        client = jack.Client("tactorbelt-probe", no_start_server=True)
    except jack.JackError:
        return False
    client.close()
    return True


def _realtime() -> bool:
    """Whether the running server schedules its clients' threads in realtime."""
    import jack

    client = jack.Client("tactorbelt-probe", no_start_server=True)
    try:
        return bool(client.realtime)
    finally:
        client.close()


def ensure_jack(timeout_s: float = 15.0, realtime: bool = False) -> None:
    """Skip unless a JACK server runs (started here if need be, within ``timeout_s``).

    ``realtime``: start it with realtime scheduling (``-R``, jackd's own default and what
    an audio lab runs; jackd falls back to normal scheduling where the system refuses).
    The tests run it without, so they never depend on the machine's limits; a test that
    asks for it gets it even where an earlier module started the server without it (that
    server is started again with it: as CI's, so the timing tests run in ``make test``).
    """
    global _server
    reason = missing()
    if reason:
        _skip(reason)
    with _lock:
        if _running():
            if not realtime or _server is None or _realtime():
                return
            stop_jack()  # ours, without realtime
        env = dict(os.environ, JACK_NO_AUDIO_RESERVATION="1")
        _server = subprocess.Popen(
            ["jackd", "-R" if realtime else "--no-realtime", "-d", "dummy", "-r", str(RATE),
             "-p", str(PERIOD), "-P", str(OUTPUTS), "-C", "2"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env,
            start_new_session=True)
        atexit.register(stop_jack)
        end = time.monotonic() + timeout_s
        while not _running():
            if _server.poll() is not None or time.monotonic() > end:
                stop_jack()
                _skip("jackd -d dummy did not start")
            time.sleep(0.1)
        if "sounddevice" in sys.modules:  # PortAudio looked for JACK before it ran
            rescan()


def rescan() -> None:
    """Make PortAudio list the JACK clients as they are now (it lists each client with
    ports as a device, once, when it starts). No stream may be open."""
    if "sounddevice" in sys.modules:
        sd = sys.modules["sounddevice"]
        if sd._initialized:  # not after stop_jack
            sd._terminate()
        sd._initialize()


def stop_jack() -> None:
    """Stop the server :func:`ensure_jack` started (none started: nothing)."""
    global _server
    proc, _server = _server, None
    if proc is not None and proc.poll() is None:
        sd = sys.modules.get("sounddevice")
        while sd is not None and sd._initialized:  # PortAudio leaves JACK first: its
            sd._terminate()  # Pa_Terminate asserts when the server went away under it
        proc.terminate()
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)


class Recorder:
    """A JACK client with ``n`` input ports recording everything they receive.

    ``connect(pattern)`` connects the output ports of another client (PortAudio's) in
    order; ``take()`` returns the samples so far, (frames, n), and whether each block
    was connected.
    """

    def __init__(self, n: int = OUTPUTS, seconds: float = 30.0) -> None:
        import jack

        self.client = jack.Client("tactorbelt-recorder")
        self.ports = [self.client.inports.register(f"in_{k}") for k in range(n)]
        self.buf = np.zeros((round(seconds * RATE), n), dtype=np.float32)
        self.connected = np.zeros(self.buf.shape[0], dtype=bool)
        #: JACK's frame time of each recorded sample: a jump is a cycle the recorder lost
        self.time = np.zeros(self.buf.shape[0], dtype=np.int64)
        self.frames = 0
        self.recording = False
        self.client.set_process_callback(self._process)
        self.client.activate()

    def _process(self, frames: int) -> None:
        if not self.recording or self.frames + frames > self.buf.shape[0]:
            return
        i = self.frames
        for k, port in enumerate(self.ports):
            self.buf[i:i + frames, k] = port.get_array()
        self.connected[i:i + frames] = self.ports[0].number_of_connections > 0
        self.time[i:i + frames] = self.client.last_frame_time + np.arange(frames)
        self.frames = i + frames

    def sources(self, timeout_s: float = 10.0) -> list[Any]:
        """PortAudio's output ports, in channel order (waits for them to appear)."""
        end = time.monotonic() + timeout_s
        while True:
            ports = [p for p in self.client.get_ports(is_audio=True, is_output=True)
                     if not p.name.startswith(("system:", "tactorbelt-recorder:"))]
            if ports or time.monotonic() > end:
                return sorted(ports, key=lambda p: int(p.name.rsplit("_", 1)[-1]))
            time.sleep(0.05)

    def connect(self, timeout_s: float = 10.0) -> int:
        """Connect PortAudio's outputs to our inputs; returns how many."""
        ports = self.sources(timeout_s)
        assert ports, "no PortAudio output ports appeared in JACK"
        for src, dst in zip(ports, self.ports, strict=False):
            self.client.connect(src, dst)
        return len(ports)

    def start(self) -> None:
        self.frames = 0
        self.recording = True

    def take(self) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """What was recorded, on JACK's timeline: every block at its frame time, NaN for
        the cycles the recorder lost (a loaded machine loses some); and per sample
        whether our ports were connected."""
        self.recording = False
        time.sleep(0.02)
        n = self.frames
        if n == 0:
            return np.zeros((0, len(self.ports))), np.zeros(0, dtype=bool)
        t = self.time[:n] - self.time[0]
        y = np.full((int(t.max()) + 1, len(self.ports)), np.nan)
        connected = np.zeros(y.shape[0], dtype=bool)
        y[t] = self.buf[:n]
        connected[t] = self.connected[:n]
        return y, connected

    def pieces(self, min_frames: int = 0) -> list[NDArray[np.float32]]:
        """The last recording cut at every cycle it lost or got out of step: pieces of
        consecutive JACK cycles (at least ``min_frames`` long)."""
        t = self.time[:self.frames]
        cuts = [0, *(np.flatnonzero(np.diff(t) != 1) + 1).tolist(), self.frames]
        return [self.buf[a:b].copy() for a, b in itertools.pairwise(cuts)
                if b - a >= min_frames]

    def close(self) -> None:
        self.client.deactivate()
        self.client.close()


def envelope(x: NDArray[Any], carrier_hz: float, rate: float = RATE) -> NDArray[np.float64]:
    """Amplitude envelope of a carrier-modulated signal, per column: I/Q demodulation
    with a moving average over whole carrier periods (centred; same length)."""
    x = np.asarray(x, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    t = np.arange(x.shape[0]) / rate
    w = max(1, round(rate / carrier_hz))
    kernel = np.ones(w) / w
    out = np.empty_like(x)
    for k in range(x.shape[1]):
        i = np.convolve(x[:, k] * np.sin(2 * np.pi * carrier_hz * t), kernel, "same")
        q = np.convolve(x[:, k] * np.cos(2 * np.pi * carrier_hz * t), kernel, "same")
        out[:, k] = 2.0 * np.hypot(i, q)
    return out


def smooth(env: NDArray[Any], carrier_hz: float, rate: float = RATE) -> NDArray[np.float64]:
    """The same moving average :func:`envelope` applies, for an expected envelope."""
    w = max(1, round(rate / carrier_hz))
    kernel = np.ones(w) / w
    env = np.asarray(env, dtype=float)
    return np.stack([np.convolve(env[:, k], kernel, "same") for k in range(env.shape[1])], 1)


def max_step(x: NDArray[Any]) -> float:
    """The largest sample-to-sample step of a recording (lost cycles left out)."""
    d = np.abs(np.diff(np.asarray(x, dtype=float), axis=0))
    return float(np.nanmax(d, initial=0.0))


def peak(x: NDArray[Any]) -> float:
    """The largest magnitude in a recording (lost cycles left out)."""
    return float(np.nanmax(np.abs(np.asarray(x, dtype=float)), initial=0.0))
