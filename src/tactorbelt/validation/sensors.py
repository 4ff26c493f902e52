"""Sensors of a belt's vibration, and their registry (``--sense URL``).

Every sensor gives, for a tactor and an interval of the commands' clock, the envelope of
the vibration it sensed there (:meth:`Sensor.envelope`), with time stamps on the same
clock as the commands (the belt's clock, or ``time.perf_counter_ns`` for a belt on wall
time). :mod:`tactorbelt.validation.run` pulses the tactors and measures the envelopes.

The registry, :data:`SENSORS`, is modelled on the belt registry
(:mod:`tactorbelt.devices.registry`): one :class:`SensorBackend` per URL scheme, its
opener imported only when used, its ``?key=value`` options parsed and checked here, in
one place (:func:`resolve_sensor`), and the ``--sense`` help generated from it:

- ``model``: the belt's own vibration model (``belt.vibration``; the sim belt). Taken
  when no ``--sense`` is given and the belt ``models_vibration``.
- ``audio:DEVICE?channel=N``: an input channel of a sound card through PortAudio (a
  loopback cable from an audio belt's output, or a piezo disc or an analog accelerometer
  on a tactor); :class:`AudioSensor`.
- ``board``: the IMU on the belt's own board (``belt.sense()``: firmware 1.2 whose IMU
  started); other belts: a DeviceError saying what is needed. :class:`BoardSensor`.

Sensors of raw signals subclass :class:`SampledSensor`: they deliver samples with time
stamps on the commands' clock (:meth:`SampledSensor.samples`) and the envelope is
estimated in one place (:func:`~tactorbelt.validation.envelope.rectified_envelope`). The
board IMU sensor delivers the magnitude of its acceleration with gravity removed, its
device time stamps mapped to host time with the belt's clock fit (as
``Belt.last_onset`` maps the device's onsets), and says in ``problem`` when samples were
lost in the interval.

Imports the standard library and NumPy; sounddevice only when an audio sensor opens.
"""

from __future__ import annotations

import bisect
import contextlib
import math
import threading
import time
from abc import ABC, abstractmethod
from dataclasses import dataclass
from types import TracebackType
from typing import TYPE_CHECKING, Any, Final

import numpy as np
from numpy.typing import NDArray

from .._errors import ConfigError, DeviceError
from .._registry import resolve
from ..devices.audio import AudioDevice, checked_latency, find_device, parse_latency, portaudio
from .envelope import rectified_envelope
from .registry import SENSORS, SensorBackend, resolve_sensor, sense_url_help

if TYPE_CHECKING:
    from ..devices.base import Belt

__all__ = [
    "SENSORS",
    "AudioSensor",
    "BoardSensor",
    "ModelSensor",
    "SampledSensor",
    "Sensor",
    "SensorBackend",
    "Window",
    "open_sensor",
    "resolve_sensor",
    "sense_url_help",
]

IntArray = NDArray[np.int64]
FloatArray = NDArray[np.float64]

#: The model sensor samples the belt's model at this rate by default (Hz).
MODEL_RATE_HZ: Final = 10_000.0
#: The audio sensor's envelope window by default: one period of a 250 Hz carrier (ms).
DEFAULT_WINDOW_MS: Final = 4.0
#: The host-time mapping of an audio input is the earliest callback within this long of
#: the interval asked for (so the sound card's clock may drift from the host's).
MAP_SPAN_NS: Final = 2_000_000_000
#: The board IMU's envelope window by default (ms): 8 samples at 1600 Hz.
BOARD_WINDOW_MS: Final = 5.0
#: How long :meth:`AudioSensor.samples` waits beyond an interval's end for its samples.
ARRIVAL_TIMEOUT_S: Final = 2.0


@dataclass
class Window:
    """A sensed interval: times (ns, the commands' clock), the envelope, and why it cannot
    be used (``problem``: samples were lost in it), or None."""

    t_ns: IntArray
    env: FloatArray
    problem: str | None = None


class Sensor(contextlib.AbstractContextManager["Sensor"], ABC):
    """Senses a belt's vibration (see the module docstring). A context manager.

    Attributes:
        url: how it was opened (``model``, ``audio:3?channel=0``).
        description: a human-readable name.
        method: how the envelope is had (written to validation.json).
        unit: the unit of the envelope.
    """

    url: str
    description: str
    method: str
    unit: str = "arbitrary units"
    #: True when each tactor is sensed on a signal of its own (the model; one input
    #: channel per tactor): pulses of other tactors may then follow one another closely,
    #: and ``validate stimulus`` senses every tactor over one play. False (one IMU, one
    #: input channel): one pulse at a time, and a stimulus is replayed per tactor.
    separates_tactors: bool = False

    def start(self) -> None:  # an optional hook
        """Begin recording (called after the belt is open, before the first pulse)."""

    @abstractmethod
    def envelope(self, tactor: int, t0_ns: int, t1_ns: int) -> Window:
        """The envelope of ``tactor``'s vibration over [t0, t1) on the commands' clock;
        waits for samples still to come.

        Raises:
            DeviceError: the sensor stopped delivering samples.
        """

    def forget_before(self, t_ns: int) -> None:  # an optional hook
        """Nothing before ``t_ns`` will be asked for again (a recording may drop it)."""

    def close(self) -> None:  # an optional hook
        """Stop recording and release the device."""

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


class ModelSensor(Sensor):
    """The belt's own vibration model as the sensor (``belt.vibration``): exact, no noise,
    on the belt's clock (instant on ``sim:virtual``)."""

    unit = "vibration amplitude (1 = rated speed)"
    separates_tactors = True

    url = "model"

    def __init__(self, belt: Belt, rate_hz: float = MODEL_RATE_HZ) -> None:
        if not belt.models_vibration:
            raise ConfigError(f"belt {belt.url!r} models no vibration, so it cannot be its "
                              "own sensor; give --sense audio:DEVICE?channel=N (a piezo or "
                              "accelerometer on the tactor, or a loopback cable)")
        self.belt = belt
        self.rate_hz = float(rate_hz)
        self.description = f"the vibration model of belt {belt.url!r}"
        self.method = (f"belt.vibration() of {belt.url!r} sampled at {self.rate_hz:g} Hz "
                       "(the modelled amplitude, no estimator)")

    def envelope(self, tactor: int, t0_ns: int, t1_ns: int) -> Window:
        t, vib = self.belt.vibration(t0_ns, t1_ns, self.rate_hz)
        return Window(t, np.ascontiguousarray(vib[:, tactor]))


class SampledSensor(Sensor):
    """A sensor of raw samples: the envelope is :func:`rectified_envelope` of them over
    ``window_s`` (one carrier period by default). Subclasses implement :meth:`samples`;
    the interval is widened by a window each side, so the estimate has no edge there."""

    window_s: float = DEFAULT_WINDOW_MS / 1000.0
    rate_hz: float
    #: the envelope's scale: pi/2 reads a sine's amplitude from its rectified mean
    scale: float = math.pi / 2

    @abstractmethod
    def samples(self, tactor: int, t0_ns: int, t1_ns: int
                ) -> tuple[IntArray, FloatArray, str | None]:
        """Raw samples of ``tactor``'s channel over [t0, t1): times (ns on the commands'
        clock), values, and why the interval cannot be used (None: it can)."""

    def envelope(self, tactor: int, t0_ns: int, t1_ns: int) -> Window:
        pad = round(self.window_s * 1e9)
        t, x, problem = self.samples(tactor, t0_ns - pad, t1_ns + pad)
        env = rectified_envelope(x, self.rate_hz, self.window_s, self.scale)
        keep = (t >= t0_ns) & (t < t1_ns)
        return Window(t[keep], env[keep], problem)


# -- the audio input sensor -----------------------------------------------------------------
class AudioSensor(SampledSensor):
    """An input channel of a sound card (see docs/validation.md).

    Time stamps: every callback notes the host time it was called
    (``time.perf_counter_ns``) and the number of frames delivered before it. A callback
    is never early, so the host time of frame k is at most ``t_callback - (k - k_block) /
    rate`` for the callback delivering it; the least of ``t_callback - k_block / rate`` over
    the callbacks within :data:`MAP_SPAN_NS` of an interval (the most punctual of them)
    maps the frames to host time, and PortAudio's reported input latency of the stream is
    subtracted, for the time the signal was at the input (the ADC). A callback that
    reports an input overflow (an xrun: frames may be lost) starts a new stretch, mapped
    on its own; stretches whose mappings agree within half a block lost nothing and are
    joined again (lost frames move the mapping by a whole block). An interval across two
    stretches is reported as a ``problem`` (the pulse is measured again).

    Attributes:
        device: the input; ``channels``: the input channel of each tactor.
        samplerate; latency_s: PortAudio's reported input latency of the stream (0 where
            it reports no latency: :func:`~tactorbelt.devices.audio.checked_latency`).
        overflows: callbacks that reported lost input.
        callback_late_ms: the most a callback that delivered frames of a measured interval
            ran after the mapping (the most punctual callback near it). An audio belt in
            the same process (the same PortAudio client: its callback runs in the same
            cycle, before the sensor's) started a change at most this long after its
            cycle began, so an onset measured through it may be early by as much.
    """

    unit = "input amplitude (1 = full scale)"

    def __init__(self, url: str, device: AudioDevice, channels: tuple[int, ...] | int,
                 n_tactors: int, samplerate: float, latency: float | str, blocksize: int,
                 window_ms: float) -> None:
        sd = portaudio("audio sensors")
        self.url = url
        self.device = device
        self.channels = ((channels,) * n_tactors if isinstance(channels, int)
                         else tuple(channels))
        self.separates_tactors = len(set(self.channels)) == len(self.channels)
        self.samplerate = self.rate_hz = float(samplerate)
        self.window_s = window_ms / 1000.0
        self.description = f"audio input {device.label()}"
        opened = sorted(set(self.channels))
        self._col = {c: i for i, c in enumerate(opened)}
        self._lock = threading.Lock()
        self._blocks: list[tuple[int, int, bool, NDArray[np.float32]]] = []
        self._frames = 0
        self._recording = False
        self._error: BaseException | None = None
        self.overflows = 0
        self.callback_late_ms = 0.0
        n_open = max(opened) + 1
        self._pick = np.asarray(opened, dtype=np.intp)
        try:
            self._stream = sd.InputStream(device=device.index, channels=n_open,
                                          samplerate=self.samplerate, dtype="float32",
                                          latency=latency, blocksize=blocksize,
                                          callback=self._callback)
            self._stream.start()  # running (its ports connected) from now; kept from start()
        except Exception as exc:
            with contextlib.suppress(Exception):
                self._stream.close()
            raise DeviceError(f"cannot open audio input {device.label()} ({n_open} channels "
                              f"at {self.samplerate:g} Hz): {exc}") from None
        reported = float(self._stream.latency)
        self.latency_s = checked_latency(reported, "input", device.label())
        lat = f"{self.latency_s * 1e3:.2f} ms"
        if self.latency_s != reported:
            lat += f"; it reported {reported:.6g} s, which is no latency"
        chans = (f"channel {self.channels[0]}" if len(set(self.channels)) == 1
                 else f"channels {','.join(map(str, self.channels))}")
        self.method = (f"input {device.name!r} ({device.hostapi}) {chans} at "
                       f"{self.samplerate:g} Hz; envelope: full-wave rectified, centred "
                       f"moving mean over {window_ms:g} ms, x pi/2; time: the earliest "
                       f"callback's host time minus the frame position, minus PortAudio's "
                       f"input latency ({lat})")

    def _callback(self, indata: Any, frames: int, time_info: Any, status: Any) -> None:
        t = time.perf_counter_ns()
        try:
            overflow = bool(status.input_overflow)
            if overflow:
                self.overflows += 1
            if not self._recording:
                return
            block = np.array(indata[:, self._pick], dtype=np.float32)
            with self._lock:
                self._blocks.append((t, self._frames, overflow, block))
                self._frames += frames
        except BaseException as exc:  # tell the next caller
            self._error = exc
            raise portaudio("audio sensors").CallbackAbort from None

    def start(self) -> None:
        self._recording = True

    def forget_before(self, t_ns: int) -> None:
        cut = t_ns - MAP_SPAN_NS
        with self._lock:  # the stretches of the rest stay as they were
            del self._blocks[:bisect.bisect_left(self._blocks, cut, key=lambda b: b[0])]

    def _snapshot(self) -> tuple[IntArray, IntArray, IntArray, list[NDArray[np.float32]]]:
        with self._lock:
            blocks = list(self._blocks)
        t = np.array([b[0] for b in blocks], dtype=np.int64)
        k = np.array([b[1] for b in blocks], dtype=np.int64)
        stretch = np.cumsum([b[2] for b in blocks], dtype=np.int64)
        return t, k, stretch, [b[3] for b in blocks]

    @staticmethod
    def _merge(stretch: IntArray, offset: IntArray, near: NDArray[np.bool_],
               block_ns: float) -> IntArray:
        """Join consecutive stretches whose mappings agree within half a block: their
        overflow lost no frames here (an xrun of another client of the sound server, or
        a late callback that still got every frame). Frames lost move the mapping by a
        whole block or more."""
        ids = np.unique(stretch)
        if ids.size == 1:
            return stretch
        group = np.zeros(ids.size, dtype=np.int64)
        ref = None
        for i, s in enumerate(ids):
            mine = stretch == s
            pick = mine & near
            off = int(offset[pick].min() if pick.any() else offset[mine].min())
            if ref is not None and abs(off - ref) >= block_ns / 2:
                group[i] = group[i - 1] + 1
                ref = off
            else:
                group[i] = group[i - 1] if i else 0
                ref = off if ref is None else min(ref, off)
        return np.asarray(group[np.searchsorted(ids, stretch)])

    def _mapped(self, t0_ns: int, t1_ns: int) -> tuple[IntArray, FloatArray, str | None] | None:
        """The interval's frames if they have all arrived: (times, the block data's rows,
        problem); None while some are still to come."""
        t_cb, k, stretch, data = self._snapshot()
        if t_cb.size == 0:
            return None
        period = 1e9 / self.samplerate
        offset = t_cb - np.round(k * period).astype(np.int64)  # host time of frame 0
        near = (t_cb >= t0_ns - MAP_SPAN_NS) & (t_cb <= t1_ns + MAP_SPAN_NS)
        lat = round(self.latency_s * 1e9)
        lengths = np.array([d.shape[0] for d in data], dtype=np.int64)
        stretch = self._merge(stretch, offset, near, float(np.median(lengths)) * period)
        times = np.empty(t_cb.size, dtype=np.int64)  # host time of each block's first frame
        late = np.empty(t_cb.size, dtype=np.int64)  # each callback after its mapping
        for s in np.unique(stretch):  # each stretch's mapping, from its blocks near
            mine = stretch == s
            pick = mine & near
            off = int(offset[pick].min() if pick.any() else offset[mine].min())
            times[mine] = off + np.round(k[mine] * period).astype(np.int64) - lat
            late[mine] = offset[mine] - off
        ends = times + np.round(lengths * period).astype(np.int64)
        inside = np.flatnonzero((ends > t0_ns) & (times < t1_ns))
        if inside.size:
            self.callback_late_ms = max(self.callback_late_ms, float(late[inside].max()) / 1e6)
        if ends[-1] < t1_ns:
            return None
        problem = None
        if inside.size == 0 or times[inside[0]] > t0_ns:
            problem = "the sensor recorded nothing at the start of the interval"
        elif np.unique(stretch[inside]).size > 1:
            problem = "the sensor lost input (an overflow) in the interval"
        if inside.size == 0:
            return np.zeros(0, dtype=np.int64), np.zeros((0, len(self._col))), problem
        rows = np.concatenate([data[i] for i in inside]).astype(float)
        frame_t = np.concatenate([times[i] + np.round(np.arange(lengths[i]) * period)
                                  .astype(np.int64) for i in inside])
        return frame_t, rows, problem

    def samples(self, tactor: int, t0_ns: int, t1_ns: int
                ) -> tuple[IntArray, FloatArray, str | None]:
        end = time.monotonic() + ARRIVAL_TIMEOUT_S + max(0.0, (t1_ns - time.perf_counter_ns())
                                                         / 1e9)
        while True:
            if self._error is not None:
                raise DeviceError(f"the audio input {self.device.label()} failed: "
                                  f"{self._error}")
            got = self._mapped(t0_ns, t1_ns)
            if got is not None:
                break
            if time.monotonic() > end or not self._stream.active:
                raise DeviceError(f"the audio input {self.device.label()} delivered no "
                                  "samples for the last pulse (did the sound server or the "
                                  "device go away?)")
            time.sleep(0.005)
        frame_t, rows, problem = got
        col = self._col[self.channels[tactor]]
        keep = (frame_t >= t0_ns) & (frame_t < t1_ns)
        return frame_t[keep], rows[keep, col], problem

    def close(self) -> None:
        self._recording = False
        with contextlib.suppress(Exception):
            self._stream.stop()
        with contextlib.suppress(Exception):
            self._stream.close()


# -- openers ----------------------------------------------------------------------------------
def open_model(target: str, belt: Belt, **options: Any) -> ModelSensor:
    """``model``: the belt's own vibration model (``rate_hz``: its sampling rate)."""
    return ModelSensor(belt, float(options.get("rate_hz", MODEL_RATE_HZ)))


def _parse_channels(text: str, url: str, n: int) -> tuple[int, ...]:
    try:
        chans = tuple(int(p) for p in text.replace(" ", "").split(",") if p != "")
    except ValueError:
        chans = ()
    if not chans or min(chans) < 0:
        raise ConfigError(f"option 'map' of sensor URL {url!r} must be input channels "
                          f"separated by commas (map=0,1,2,3,4,5), got {text!r}")
    if len(chans) != n:
        raise ConfigError(f"sensor URL {url!r} maps {len(chans)} input channels but the belt "
                          f"has {n} tactors")
    return chans


def open_audio_sensor(target: str, belt: Belt, **options: Any) -> AudioSensor:
    """``audio:DEVICE?channel=N``: an input channel of a sound card (see docs/validation.md).

    Options: ``channel`` (the input channel that senses every tactor, one at a time;
    default 0) or ``map`` (tactor k's input channel), ``samplerate`` (the device's
    default), ``latency`` (``low``, ``high`` or seconds; default ``low``), ``blocksize``
    (0: PortAudio's), ``window_ms`` (the envelope's window, 4 ms: one period of 250 Hz).

    Raises:
        ConfigError: both ``channel`` and ``map``, a bad map, a belt on a simulated clock.
        DeviceError: no such input, too few channels, no PortAudio.
    """
    url = f"audio:{target}"
    if belt.clock is not None and belt.clock.simulated:
        raise ConfigError(f"belt {belt.url!r} runs on a simulated clock: a sound card cannot "
                          "sense it (use the sim belt on wall time, --belt sim)")
    if "channel" in options and "map" in options:
        raise ConfigError(f"sensor URL {url!r}: give channel= or map=, not both")
    channels: tuple[int, ...] | int = int(options.get("channel", 0))
    if "map" in options:
        channels = _parse_channels(str(options["map"]), url, belt.n_tactors)
    latency = parse_latency(options.get("latency", "low"), url, "sensor")
    device = find_device(target, "input")
    need = (channels if isinstance(channels, int) else max(channels)) + 1
    if device.channels < need:
        raise DeviceError(f"audio input {device.label()} has {device.channels} input "
                          f"channels; sensor {url!r} needs channel {need - 1}")
    rate = float(options.get("samplerate") or device.samplerate)
    return AudioSensor(url, device, channels, belt.n_tactors, rate, latency,
                       int(options.get("blocksize", 0)),
                       float(options.get("window_ms", DEFAULT_WINDOW_MS)))


class BoardSensor(SampledSensor):
    """The accelerometer on the belt's own board (``belt.sense()``: firmware 1.2 with an
    IMU). Its samples come with device time stamps mapped to host time by the belt's
    clock fit (:class:`~tactorbelt.devices._firmware.SenseRecording`); lost samples are a
    window's ``problem``. The signal is the magnitude of the acceleration less its median
    over the interval (gravity: the board does not move), so an ERM's rotating force reads
    as its amplitude (``scale`` 1) in g. One IMU senses every tactor.

    The opener of ``board`` (its URL has no target): ``rate_hz`` is the rate asked for
    (the IMU's highest by default), ``window_ms`` the envelope's window (5 ms)."""

    url = "board"
    unit = "acceleration (g)"
    scale = 1.0
    #: one IMU senses every tactor: ``validate stimulus`` replays a stimulus per tactor
    separates_tactors = False

    def __init__(self, target: str, belt: Belt, rate_hz: float | None = None,
                 window_ms: float = BOARD_WINDOW_MS) -> None:
        if not belt.senses_vibration:
            raise DeviceError(
                f"sensor 'board' (the belt's own IMU) is not available for belt "
                f"{belt.url!r}: it needs belt firmware that streams IMU acceleration "
                "samples with device time stamps (firmware 1.2 on a board whose IMU "
                "started); use --sense audio:DEVICE?channel=N with a piezo disc or an "
                "analog accelerometer on the tactor")
        self.belt = belt
        self.window_s = window_ms / 1000.0
        self._ask = rate_hz
        self.rate_hz = rate_hz or 0.0
        self._rec: Any = None
        self.description = f"the IMU of belt {belt.url!r}"
        self.method = (f"board IMU of {belt.url!r}: |acceleration - its median| in g, "
                       f"centred moving mean over {window_ms:g} ms; device times mapped "
                       "to host time by the belt's clock fit")

    def start(self) -> None:
        self._rec = self.belt.sense(None, rate_hz=self._ask)
        self.rate_hz = float(self._rec.rate_hz)
        self.method += f"; {self.rate_hz:g} Hz"

    def samples(self, tactor: int, t0_ns: int, t1_ns: int
                ) -> tuple[IntArray, FloatArray, str | None]:
        rec = self._rec
        wait = ARRIVAL_TIMEOUT_S + max(0.0, (t1_ns - time.perf_counter_ns()) / 1e9)
        if not rec.wait_for(t1_ns, wait):
            raise DeviceError(f"the IMU of belt {self.belt.url!r} delivered no samples for "
                              f"the last pulse ({rec.interrupted or 'none came in time'})")
        t, acc = rec.samples(t0_ns, t1_ns)
        x = (np.linalg.norm(acc - np.median(acc, axis=0), axis=1) if t.size
             else np.zeros(0))
        return t, np.asarray(x, dtype=float), rec.problem(t0_ns, t1_ns)

    def close(self) -> None:
        if self._rec is not None:
            with contextlib.suppress(Exception):
                self._rec.stop()


def open_sensor(url: str | None, belt: Belt) -> Sensor:
    """Open the sensor at ``url`` for ``belt`` (None: the belt's own model, when it has
    one).

    Raises:
        ConfigError: a bad URL, or no URL for a belt that models no vibration.
        DeviceError: the sensor cannot be opened (or is not available, ``board``).
    """
    if url is None:
        if not belt.models_vibration:
            raise ConfigError(f"belt {belt.url!r} models no vibration: say what senses it, "
                              "--sense audio:DEVICE?channel=N (a piezo or accelerometer on "
                              "the tactor, or a loopback cable from an audio belt)")
        return ModelSensor(belt)
    backend, target, options = resolve_sensor(url)
    sensor: Sensor = resolve(backend.opener)(target, belt, **options)
    sensor.url = url.strip()  # as given, options and all (validation.json records it)
    return sensor
