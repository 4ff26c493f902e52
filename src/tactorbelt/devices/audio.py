"""``audio:DEVICE`` belts: voice-coil and LRA tactors on the outputs of a sound card.

Each tactor is one output channel of a multichannel sound card (through an amplifier).
The felt amplitude of a tactor modulates a sine carrier (``carrier_hz``, default 250 Hz,
where the skin's Pacinian receptors are most sensitive): output sample =
``level * response_gain * sin(2 pi carrier_hz t)``, with ``level`` the calibrated drive
level of the tactor and ``response_gain`` its frequency-response correction at the
carrier (calibration ``response``, default 1).

The audio callback renders everything, block by block, at the audio rate:

- a played stimulus (:meth:`Belt.play`) from the stimulus itself,
  ``calibration(stimulus.amplitudes(t))`` for the block's sample times, so the dynamic
  perturbation's timing is sample-exact and does not depend on Python's scheduling;
- streamed frames (:meth:`Belt.set_amplitudes`) as constant levels until the next one.

Every change (a new frame, a new stimulus, stop, the end of a duration) is ramped
linearly over ``ramp_ms`` (default 5 ms) from the envelope last output, so there is no
click to feel or hear. Underruns (PortAudio's output-underflow flag) are counted
(:attr:`AudioBelt.underruns`) and reported as a warning when the belt stops or closes.
The stream is stopped, after the ramp to silence has been output, on every exit path
(``close``, an exception, Ctrl-C, SIGTERM through :mod:`tactorbelt.interrupts`).

URL: ``audio:DEVICE?channels=6&carrier_hz=250&map=0,1,2,3,4,5`` with DEVICE a PortAudio
device index, a part of its name (``system``, ``JACK``, ``USB``) or ``default``; see
docs/audio.md. The channel map (output channel of each tactor) comes from ``map=`` or the
calibration file's ``channel`` fields.

Imports sounddevice (and so PortAudio) only when a belt is opened or devices are listed.
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Final

import numpy as np
from numpy.typing import NDArray

from .._errors import ConfigError, DeviceError
from ..geometry import Layout
from .base import Belt
from .calibration import Calibration, response_gain
from .registry import BACKENDS, Discovery, Found, check_options

if TYPE_CHECKING:
    from ..stimuli import Stimulus

__all__ = [
    "DEFAULT_CARRIER_HZ",
    "DEFAULT_RAMP_MS",
    "MAX_LATENCY_S",
    "MAX_REPORTED_LATENCY_S",
    "TACTOR_BAND_HZ",
    "AudioBelt",
    "checked_latency",
    "discover",
    "open_audio",
    "parse_latency",
]

log = logging.getLogger("tactorbelt.devices")

#: The carrier frequency by default: the skin's most sensitive band (Pacinian receptors).
DEFAULT_CARRIER_HZ: Final = BACKENDS["audio"].carrier_hz or 250.0
#: Every amplitude change is ramped over this long by default.
DEFAULT_RAMP_MS: Final = 5.0
#: Carriers outside this band are felt poorly by most voice-coil tactors and LRAs (a warning).
TACTOR_BAND_HZ: Final = (40.0, 500.0)
#: Sample rates tried when listing what a device offers.
_COMMON_RATES: Final = (8000, 16000, 22050, 32000, 44100, 48000, 88200, 96000, 192000)
#: Samples of a dynamic stimulus computed at once (at the audio rate) by the callback.
_CHUNK: Final = 1024
#: Seconds ``close`` and ``settle`` wait at most beyond the ramp and the latency.
_SETTLE_SLACK_S: Final = 1.0
#: The longest latency (seconds) the ``latency=`` option of a belt or sensor may ask for.
MAX_LATENCY_S: Final = 2.0
#: A stream latency PortAudio reports above this (seconds) is not a latency but an error
#: of the host API, and is ignored (:func:`checked_latency`): twice the longest one may
#: ask for (PortAudio rounds a request up to whole buffers). PortAudio 19.6 reports a
#: JACK port that declares 0 latency as (0 - period) in unsigned 32-bit frames,
#: 89,478 s at 48 kHz; the least such value, at 192 kHz, is still 22,369 s.
MAX_REPORTED_LATENCY_S: Final = 2 * MAX_LATENCY_S

OPTIONS: Final = ("channels", "carrier_hz", "map", "samplerate", "latency", "blocksize",
                  "ramp_ms", "layout", "calibration", "clock", "name")

FloatArray = NDArray[np.float64]


def portaudio(users: str = "audio belts") -> Any:
    """Import sounddevice (PortAudio), or raise a DeviceError saying what ``users`` (audio
    belts, audio sensors) need installed."""
    try:
        import sounddevice
    except ImportError:
        raise DeviceError(f"{users} need the sounddevice package: "
                          "pip install 'tactorbelt[audio]'") from None
    except OSError as exc:  # sounddevice is there, the PortAudio library is not
        raise DeviceError(f"{users} need the PortAudio library ({exc}); on Debian or "
                          "Ubuntu: apt install libportaudio2") from None
    return sounddevice


# -- latency ---------------------------------------------------------------------------------
def checked_latency(reported_s: float, direction: str, device: str) -> float:
    """PortAudio's reported ``direction`` ("input" or "output") latency of a stream on
    ``device`` (its label), in seconds, where it is one; else 0.0 with a warning naming
    the value and the device. The one place the audio belt and the audio sensor read
    their streams' latency through (``float(stream.latency)`` is passed in).

    A value above :data:`MAX_REPORTED_LATENCY_S`, negative or not finite is no latency:
    PortAudio 19.6's JACK host API reports a port that declares 0 latency as 2^32
    frames (89,478 s at 48 kHz). Subtracted from a sensor's time stamps it would put
    every sample a day before the commands; 0 is what such a port declares.
    """
    value = float(reported_s)
    if math.isfinite(value) and 0.0 <= value <= MAX_REPORTED_LATENCY_S:
        return value
    log.warning("audio device %s: PortAudio reports its %s latency as %.6g s, which is not "
                "a latency (above %g s: a JACK port that declares none?); taken as 0",
                device, direction, value, MAX_REPORTED_LATENCY_S)
    return 0.0


def parse_latency(text: Any, url: str, kind: str = "belt") -> float | str:
    """The ``latency=`` option of a ``kind`` ("belt" or "sensor") URL: ``low``, ``high``
    or seconds in (0, :data:`MAX_LATENCY_S`].

    Raises:
        ConfigError: anything else.
    """
    if isinstance(text, int | float):
        value = float(text)
    elif str(text).strip().lower() in ("low", "high"):
        return str(text).strip().lower()
    else:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
    if not (math.isfinite(value) and 0.0 < value <= MAX_LATENCY_S):
        raise ConfigError(f"option 'latency' of {kind} URL {url!r} must be low, high or "
                          f"seconds in (0, {MAX_LATENCY_S:g}], got {text!r}")
    return value


# -- devices ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class AudioDevice:
    """One PortAudio device with channels in one ``direction``: ``output`` (an audio
    belt's) or ``input`` (an audio sensor's)."""

    index: int
    name: str
    hostapi: str
    channels: int
    samplerate: float
    direction: str = "output"

    def label(self) -> str:
        return (f"{self.index} {self.name!r} ({self.hostapi}, {self.channels} {self.direction} "
                f"channels, {self.samplerate:g} Hz)")


#: Who needs sounddevice, by direction (for the message when it is missing).
_USERS: Final = {"output": "audio belts", "input": "audio sensors"}


def list_devices(direction: str = "output") -> list[AudioDevice]:
    """Every PortAudio device with at least one channel in ``direction``."""
    sd = portaudio(_USERS[direction])
    apis = sd.query_hostapis()
    key = f"max_{direction}_channels"
    return [AudioDevice(int(d["index"]), str(d["name"]), str(apis[d["hostapi"]]["name"]),
                        int(d[key]), float(d["default_samplerate"]), direction)
            for d in sd.query_devices() if d[key] > 0]


def _offers(devices: list[AudioDevice]) -> str:
    return "; ".join(o.label() for o in devices) or "none (is the sound server running?)"


def find_device(target: str, direction: str = "output") -> AudioDevice:
    """The device named by ``target``: an index, ``default``, or words that all appear
    (case-insensitive) in exactly one ``direction`` device's ``name, host API``.

    Raises:
        DeviceError: no such device, or several match (the message lists the devices).
    """
    sd = portaudio(_USERS[direction])
    devices = list_devices(direction)
    text = target.strip()
    where = f"audio device {text!r}" if direction == "output" else f"audio input {text!r}"
    if text.lower() in ("", "default"):
        slot = sd.default.device[0 if direction == "input" else 1]
        index = -1 if slot is None else int(slot)
        if index < 0:
            index = int(sd.query_hostapis(sd.default.hostapi)[f"default_{direction}_device"])
        match = [o for o in devices if o.index == index]
        if not match:
            raise DeviceError(f"there is no default audio {direction}; {direction}s: "
                              f"{_offers(devices)}")
        return match[0]
    if text.isdigit():
        match = [o for o in devices if o.index == int(text)]
    else:
        words = text.lower().split()
        match = [o for o in devices if all(w in f"{o.name}, {o.hostapi}".lower() for w in words)]
        exact = [o for o in match if o.name.lower() == text.lower()]
        match = exact if len(exact) == 1 else match
    if not match:
        raise DeviceError(f"{where} not found; {direction}s: {_offers(devices)}")
    if len(match) > 1:
        raise DeviceError(f"{where} matches several {direction}s: {_offers(match)}; "
                          "give its index (audio:N)")
    return match[0]


def discover(timeout_s: float = 5.0, probe_all: bool = False) -> Discovery:
    """Audio outputs and their channel counts (for ``tactorbelt devices``)."""
    del timeout_s, probe_all
    try:
        outputs = list_devices()
    except DeviceError as exc:
        return Discovery([], str(exc))
    except Exception as exc:  # PortAudio failing to start is a note, not an error
        return Discovery([], f"audio outputs cannot be listed here ({exc})")
    rows = [Found("audio", str(o.index), f"{o.name} ({o.hostapi})",
                  f"audio:{o.index}?channels={o.channels}",
                  note=f"{o.channels} output channels at {o.samplerate:g} Hz "
                       f"-> --belt audio:{o.index}?channels={o.channels}")
            for o in outputs]
    return Discovery(rows, None, "no audio output")


# -- what the callback plays -------------------------------------------------------------------
class _Program:
    """What the callback outputs from some frame on: an envelope (calibrated levels,
    one column per tactor) as a function of the absolute frame index."""

    def envelope(self, idx: NDArray[np.int64]) -> FloatArray:
        raise NotImplementedError

    def start(self, frame: int) -> None:
        """Called by the callback at the frame the program begins."""


class _Levels(_Program):
    def __init__(self, levels: FloatArray) -> None:
        self.levels = levels

    def envelope(self, idx: NDArray[np.int64]) -> FloatArray:
        return np.broadcast_to(self.levels, (idx.shape[0], self.levels.shape[0]))


class _Render(_Program):
    """A stimulus from its onset frame, for ``n_frames`` (None: until replaced); the last
    ``ramp`` frames fade out, so the end is ramped too. A static stimulus's amplitudes do
    not change in time: they are computed once."""

    def __init__(self, stimulus: Stimulus, calibration: Calibration, rate: float,
                 n_frames: int | None, ramp: int) -> None:
        self.stimulus = stimulus
        self.calibration = None if calibration.is_identity else calibration
        self.rate = rate
        self.n_frames = n_frames
        self.ramp = ramp
        self.onset = 0
        self.constant = None if stimulus.is_dynamic else self._levels(np.zeros(1))[0]
        self._cache_start = 0
        self._cache: FloatArray | None = None

    def _levels(self, t: FloatArray) -> FloatArray:
        a = self.stimulus.amplitudes(t)
        return a if self.calibration is None else self.calibration.apply(a)

    def start(self, frame: int) -> None:
        self.onset = frame

    def _chunk(self, k0: int, n: int) -> FloatArray:
        """Levels of samples k0 .. k0+n-1 since onset, computed ``_CHUNK`` samples at a
        time (one vectorised call of the stimulus per chunk, not per callback)."""
        cache = self._cache
        if cache is None or not (self._cache_start <= k0
                                 and k0 + n <= self._cache_start + cache.shape[0]):
            k = np.arange(k0, k0 + max(n, _CHUNK), dtype=np.int64)
            cache = self._cache = self._levels(k / self.rate)
            self._cache_start = k0
        return cache[k0 - self._cache_start:k0 - self._cache_start + n]

    def envelope(self, idx: NDArray[np.int64]) -> FloatArray:
        k = idx - self.onset
        if self.constant is not None:
            env = np.broadcast_to(self.constant, (k.shape[0], self.constant.shape[0]))
        else:
            env = self._chunk(int(k[0]), k.shape[0])
        if self.n_frames is not None and self.n_frames - int(k[-1]) < self.ramp:
            left = (self.n_frames - k).astype(float)
            env = env * np.clip(left / self.ramp, 0.0, 1.0)[:, None]
        return env


# -- the belt ------------------------------------------------------------------------------
class AudioBelt(Belt):
    """A belt whose tactors are the output channels of a sound card (see the module doc).

    Attributes:
        device: the PortAudio output.
        channels: output channels opened; ``mapping[k]`` is tactor k's channel.
        carrier_hz, samplerate, blocksize: as opened (``blocksize`` 0: PortAudio's choice).
        latency_s: PortAudio's reported output latency of the open stream (0 where it
            reports no latency: :func:`checked_latency`).
        output_gain: per tactor, the frequency-response correction at the carrier.
        underruns: output underflows PortAudio reported since the belt was opened.
    """

    #: the callback renders through the calibration (gain, response, channel map)
    renders_calibrated = True
    renders_profiles = True

    @property
    def uses_sound_output(self) -> bool:
        return True

    def __init__(self, url: str, device: AudioDevice, layout: Layout,
                 calibration: Calibration | None, channels: int, mapping: tuple[int, ...],
                 carrier_hz: float, samplerate: float, latency: float | str, blocksize: int,
                 ramp_ms: float, name: str | None = None) -> None:
        super().__init__(url, name or f"audio belt on {device.name} ({device.hostapi})",
                         layout, None, calibration)
        self.device = device
        self.channels = channels
        self.mapping = mapping
        self.carrier_hz = carrier_hz
        self.samplerate = samplerate
        self.blocksize = blocksize
        self.ramp_frames = max(1, round(ramp_ms * samplerate / 1000.0))
        self.output_gain = np.array([response_gain(t.response, carrier_hz)
                                     for t in self.calibration.tactors])
        self.underruns = 0
        self._underruns_reported = 0
        self._callback_error: BaseException | None = None
        # the hand-off to the callback: (generation, program), replaced as one reference
        self._next: tuple[int, _Program] = (0, _Levels(np.zeros(layout.n)))
        self._generation = 0
        # the callback's own state
        self._playing_gen = -1
        self._settled_gen = -1
        self._program: _Program = self._next[1]
        self._fade_from = np.zeros(layout.n)
        self._fade_start = 0
        self._fading = False
        self._last_env = np.zeros(layout.n)
        self._frame = 0
        self._phase = 0.0
        self._step = carrier_hz / samplerate
        self._map = np.asarray(mapping, dtype=np.intp)
        self._direct = mapping == tuple(range(channels))
        self._gain = None if np.all(self.output_gain == 1.0) else self.output_gain
        self._ar = np.arange(8192, dtype=np.int64)
        self._busy_ns = 0
        sd = portaudio()
        try:
            self._stream = sd.OutputStream(
                device=device.index, channels=channels, samplerate=samplerate,
                dtype="float32", latency=latency, blocksize=blocksize,
                callback=self._callback)
            self._stream.start()
        except Exception as exc:
            with contextlib.suppress(Exception):
                self._stream.close()
            self._closed = True
            raise DeviceError(f"cannot open audio device {device.label()}: {exc}") from None
        self.latency_s = checked_latency(self._stream.latency, "output", device.label())

    # -- the audio callback (PortAudio's thread) ---------------------------------------------
    def _callback(self, outdata: Any, frames: int, time_info: Any, status: Any) -> None:
        t0 = time.thread_time_ns()
        if status.output_underflow:
            self.underruns += 1
        try:
            self._render(outdata, frames)
        except BaseException as exc:  # silence, stop the stream, tell the next caller
            outdata.fill(0)
            self._callback_error = exc
            raise portaudio().CallbackAbort from None
        self._busy_ns += time.thread_time_ns() - t0

    def _render(self, outdata: Any, frames: int) -> None:
        gen, program = self._next
        if gen != self._playing_gen:  # a new program: fade from what was last output
            program.start(self._frame)
            self._program, self._playing_gen = program, gen
            self._fade_from = self._last_env
            self._fade_start = self._frame
            self._fading = True
        if frames > self._ar.shape[0]:
            self._ar = np.arange(frames, dtype=np.int64)
        ar = self._ar[:frames]
        idx = self._frame + ar
        env = self._program.envelope(idx)
        if self._fading:
            w = np.clip((idx - self._fade_start + 1) / self.ramp_frames, 0.0, 1.0)[:, None]
            env = self._fade_from + (env - self._fade_from) * w
            self._fading = bool(w[-1, 0] < 1.0)
        self._last_env = np.array(env[-1], dtype=float)
        if not self._fading:
            self._settled_gen = gen
        carrier = np.sin((2.0 * math.pi) * (self._phase + ar * self._step))
        out = env * carrier[:, None]
        if self._gain is not None:
            out *= self._gain
        np.clip(out, -1.0, 1.0, out=out)
        if self._direct:
            outdata[:] = out
        else:
            outdata.fill(0)
            outdata[:, self._map] = out
        self._frame += frames
        self._phase = (self._phase + frames * self._step) % 1.0

    # -- what the base class calls -------------------------------------------------------------
    def _send(self, program: _Program) -> None:
        err = self._callback_error
        if err is not None:
            raise DeviceError(f"the audio stream of {self.url!r} stopped: {err}")
        if not self._stream.active:
            raise DeviceError(f"the audio stream of {self.url!r} stopped (did the sound "
                              f"server or the device {self.device.name!r} go away?)")
        self._generation += 1
        self._next = (self._generation, program)  # one reference: the callback sees all or none

    def _write_levels(self, levels: FloatArray) -> None:
        self._send(_Levels(np.array(levels, dtype=float)))

    def _write_stop(self) -> None:
        if self._callback_error is None and self._stream.active:
            self._send(_Levels(np.zeros(self.n_tactors)))
        self._report_underruns()

    def _device_renders(self, stimulus: Stimulus | None) -> bool:
        return True

    def _write_play(self, stimulus: Stimulus, duration_s: float | None) -> None:
        n = None if duration_s is None else max(1, round(float(duration_s) * self.samplerate))
        self._send(_Render(stimulus, self.calibration, self.samplerate, n, self.ramp_frames))

    def _close(self) -> None:
        try:
            self.settle()  # the ramp to silence has been output
        finally:
            with contextlib.suppress(Exception):
                self._stream.stop()
            with contextlib.suppress(Exception):
                self._stream.close()
            self._report_underruns()

    # -- public ------------------------------------------------------------------------------
    @property
    def active(self) -> bool:
        """True while the audio stream runs."""
        return bool(self._stream.active)

    def settle(self, timeout_s: float | None = None) -> bool:
        """Wait until the callback has output the last command completely (its ramp is
        over). Returns False on timeout or when the stream does not run."""
        if timeout_s is None:
            timeout_s = (self.ramp_frames / self.samplerate + 2 * self.latency_s
                         + _SETTLE_SLACK_S)
        end = time.monotonic() + timeout_s
        while self._settled_gen != self._generation:
            if self._callback_error is not None or not self._stream.active:
                return False
            if time.monotonic() > end:
                return False
            time.sleep(0.001)
        return True

    def dropouts(self) -> int:
        """Output underflows PortAudio reported since the belt was opened."""
        return self.underruns

    def _report_underruns(self) -> None:
        new = self.underruns - self._underruns_reported
        if new > 0:
            self._underruns_reported = self.underruns
            log.warning("%s: %d audio underrun(s) (blocks output before the callback filled "
                        "them; raise latency= or blocksize=)", self.url, new)


# -- opening ---------------------------------------------------------------------------------
def _parse_map(text: str, url: str) -> tuple[int, ...]:
    try:
        chans = tuple(int(p) for p in text.replace(" ", "").split(",") if p != "")
    except ValueError:
        raise ConfigError(f"option 'map' of belt URL {url!r} must be output channels "
                          f"separated by commas (map=0,1,2,3,4,5), got {text!r}") from None
    if not chans or min(chans) < 0:
        raise ConfigError(f"option 'map' of belt URL {url!r} must list channels 0, 1, ..., "
                          f"got {text!r}")
    if len(set(chans)) != len(chans):
        raise ConfigError(f"option 'map' of belt URL {url!r} names a channel twice: {text!r}")
    return chans


def open_audio(target: str, **options: Any) -> AudioBelt:
    """Open ``audio:DEVICE`` (see the module docstring and docs/audio.md).

    Args:
        target: a device index, words of its name, or ``default``.
        **options: ``channels`` (output channels opened; default: what the map needs),
            ``carrier_hz`` (250), ``map`` (``"0,1,2,3,4,5"``: tactor k's output channel),
            ``samplerate`` (the device's default), ``latency`` (``low``, ``high`` or
            seconds; default ``low``), ``blocksize`` (frames per callback; 0 = PortAudio's
            choice), ``ramp_ms`` (5), ``layout``, ``calibration``, ``name``, ``clock``
            (ignored: the belt runs on the sound card's clock).

    Raises:
        ConfigError: an unknown option, a bad map, a carrier above the Nyquist frequency.
        DeviceError: no such device, too few channels, a refused sample rate, no PortAudio.
    """
    url = f"audio:{target}"
    check_options(options, OPTIONS, url)
    options.pop("clock", None)
    layout: Layout | None = options.get("layout")
    calibration: Calibration | None = options.get("calibration")
    url_map = options.get("map")
    mapping = _parse_map(url_map, url) if url_map is not None else None
    cal_map = calibration.channels if calibration is not None else None
    if mapping is not None and cal_map is not None and mapping != cal_map:
        raise ConfigError(f"belt URL {url!r} maps the tactors to channels {list(mapping)} but "
                          f"the calibration file to {list(cal_map)}; give the map once")
    mapping = mapping or cal_map
    asked = options.get("channels")
    if layout is not None:
        n = layout.n
    elif mapping is not None:
        n = len(mapping)
    elif calibration is not None:
        n = calibration.n
    else:
        n = int(asked) if asked is not None else 6
    if mapping is None:
        mapping = tuple(range(n))
    if len(mapping) != n:
        raise ConfigError(f"belt {url!r} has {n} tactors but the channel map names "
                          f"{len(mapping)} channels: {list(mapping)}")
    channels = int(asked) if asked is not None else max(mapping) + 1
    if max(mapping) >= channels:
        raise ConfigError(f"belt URL {url!r}: the channel map uses channel {max(mapping)} but "
                          f"only {channels} channels are opened (channels={channels})")
    carrier = float(options.get("carrier_hz", DEFAULT_CARRIER_HZ))
    if not (math.isfinite(carrier) and carrier > 0):
        raise ConfigError(f"carrier_hz must be a positive number of Hz, got {carrier!r}")
    latency = parse_latency(options.get("latency", "low"), url)
    blocksize = int(options.get("blocksize", 0))
    ramp_ms = float(options.get("ramp_ms", DEFAULT_RAMP_MS))
    if not (math.isfinite(ramp_ms) and 0.1 <= ramp_ms <= 100.0):
        raise ConfigError(f"ramp_ms must be in 0.1..100, got {ramp_ms!r}")

    sd = portaudio()
    device = find_device(target)
    if device.channels < channels:
        raise DeviceError(f"audio device {device.label()} has {device.channels} output "
                          f"channels; belt {url!r} needs {channels} ({n} tactors on channels "
                          f"{list(mapping)})")
    rate = float(options.get("samplerate") or device.samplerate)
    try:
        sd.check_output_settings(device.index, channels, "float32", None, rate)
    except Exception as exc:
        offered = []
        for common in _COMMON_RATES:
            with contextlib.suppress(Exception):
                sd.check_output_settings(device.index, channels, "float32", None, common)
                offered.append(common)
        raise DeviceError(f"audio device {device.label()} refuses {rate:g} Hz ({exc}); it "
                          f"offers {', '.join(f'{r} Hz' for r in offered) or 'no common rate'}"
                          ) from None
    if carrier >= rate / 2:
        raise ConfigError(f"carrier_hz={carrier:g} is at or above the Nyquist frequency "
                          f"({rate / 2:g} Hz) of audio device {device.label()}")
    low, high = TACTOR_BAND_HZ
    if not low <= carrier <= high:
        log.warning("%s: a %g Hz carrier is outside the band voice-coil tactors and LRAs "
                    "render and the skin feels best (%g..%g Hz)", url, carrier, low, high)
    if calibration is not None:
        peak = max(t.ceiling * response_gain(t.response, carrier) for t in calibration.tactors)
        if peak > 1.0:
            log.warning("%s: the calibration's response gain at %g Hz drives an output past "
                        "full scale (x%.2f); the carrier clips", url, carrier, peak)
    return AudioBelt(url, device, layout or Layout.even(n), calibration, channels, mapping,
                     carrier, rate, latency, blocksize, ramp_ms, options.get("name"))

