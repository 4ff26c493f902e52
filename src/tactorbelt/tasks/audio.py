"""Secondary-task sounds through SDL's audio output, each one starting at its onset.

:class:`SdlTaskAudio` opens an SDL audio device (``pygame._sdl2.audio.AudioDevice``,
mono float32, 48 kHz, blocks of 480 frames = 10 ms) whose callback, in SDL's audio
thread, mixes the scheduled sounds into each block. A sound is scheduled with the onset
it must have on the runner's clock (:meth:`TaskAudio.schedule`, at least
``TASK_LEAD_NS`` = 100 ms ahead); the callback places its first sample on the frame
that is output at that instant, so the onset is sample-accurate whatever Python's
main thread is doing (drawing a frame, writing the store).

The stream's timeline: at each callback, the clock is read; the block's first frame is
output ``latency_s`` later (the output latency: by default 0 for SDL's ``disk`` and
``dummy`` drivers, which write a block as soon as it is filled, and one block for a
sound card, whose driver plays a block after the one playing). A sound card's callbacks
may run late (the thread woke late) while the card plays on its own clock, so for a
sound card the estimate follows a late callback only slowly (``follow`` 0.2: a lower
envelope of the callback times) and an early one at once; the ``disk`` and ``dummy``
drivers follow every callback (``follow`` 1). A sound whose onset has already passed
when its block is filled starts at once, and is listed in :attr:`TaskAudio.late` when
it starts more than 1 ms late.

Silence and closing: :meth:`TaskAudio.stop` fades whatever sounds out over 5 ms;
:meth:`TaskAudio.close` (also the context manager's exit, on every exit path) outputs
silence and closes the device. SDL runs the callback holding the device's lock, and
the callback needs Python's GIL, so pausing or closing the device from Python while
holding the GIL can deadlock; the device is paused and closed through ``ctypes`` (which
releases the GIL) on the same SDL library pygame loaded. Where ctypes cannot reach that
library the output is refused before it opens (a ``DeviceError``): closing it through
pygame, which keeps the GIL, can hang a session (a hang seen under load).

:class:`SilentTaskAudio` schedules nothing and records the same placements (a simulated
clock has no time to play sound in; tests and the model participant use it).
:func:`open_task_audio` picks one.

I/O: imports pygame (SDL audio) only in :class:`SdlTaskAudio`; NumPy.
"""

from __future__ import annotations

import collections
import contextlib
import ctypes
import ctypes.util
import logging
import math
import os
import sys
import time
import weakref
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Final, Self

import numpy as np
from numpy.typing import NDArray

from .._errors import ConfigError, DeviceError
from .sounds import RATE

if TYPE_CHECKING:
    from ..clock import Clock

__all__ = [
    "BLOCK_FRAMES",
    "DEVICE_ENV",
    "LATENCY_ENV",
    "LATE_NS",
    "Placement",
    "SdlTaskAudio",
    "SilentTaskAudio",
    "TaskAudio",
    "open_task_audio",
]

log = logging.getLogger("tactorbelt.tasks")

#: Frames per callback block (10 ms at 48 kHz).
BLOCK_FRAMES: Final = 480
#: Fade when stopping (s).
STOP_RAMP_S: Final = 0.005
#: Drivers that write a block out as soon as the callback filled it.
IMMEDIATE_DRIVERS: Final = ("disk", "dummy")
#: Seconds :meth:`SdlTaskAudio.close` waits for the callback to output silence.
CLOSE_WAIT_S: Final = 0.5
#: A sound that starts more than this after its onset counts as late (ns): a stream
#: slower than the clock (SDL's disk driver) leaves gaps of a fraction of a millisecond.
LATE_NS: Final = 1_000_000
#: The environment variable naming the task sounds' output (words of an SDL output's name).
DEVICE_ENV: Final = "TACTORBELT_TASK_AUDIO"
#: The environment variable giving a sound card's output latency in ms (measured).
LATENCY_ENV: Final = "TACTORBELT_TASK_AUDIO_LATENCY_MS"
#: Callback blocks remembered in :attr:`SdlTaskAudio.blocks` (the last minute).
BLOCKS_KEPT: Final = 6000

FloatArray = NDArray[np.float32]

# devices closed through ctypes: kept alive so that pygame never closes their id again
_RETIRED: list[Any] = []


@dataclass(frozen=True)
class Placement:
    """Where a scheduled sound went.

    Attributes:
        label: what the caller called it (the item's stimulus).
        onset_ns: the onset asked for (runner clock).
        frame: the stream frame of its first sample (None: not played, silent output).
        start_ns: when that frame is output, by the stream's timeline (runner clock).
        late_ns: how much later than ``onset_ns`` it started (0 when on time).
    """

    label: str
    onset_ns: int
    frame: int | None
    start_ns: int
    late_ns: int


class TaskAudio:
    """What the window uses to play task sounds (see :class:`SdlTaskAudio`).

    Attributes:
        rate: the sample rate sounds must have (Hz).
        played: every sound placed so far, in order (:class:`Placement`).
        late: the placements that started more than :data:`LATE_NS` (1 ms) after their
            onset.
        plays_sound: whether anything is heard (False: :class:`SilentTaskAudio`).
    """

    rate: int = RATE
    plays_sound: bool = False

    def __init__(self) -> None:
        self.played: list[Placement] = []

    @property
    def late(self) -> list[Placement]:
        return [p for p in self.played if p.late_ns > LATE_NS]

    def schedule(self, sound: FloatArray, onset_ns: int, label: str = "") -> None:
        """Play ``sound`` (mono float32 at :attr:`rate`) from ``onset_ns`` on."""
        raise NotImplementedError

    def stop(self) -> None:
        """Silence now: fade out what plays, drop what is scheduled."""

    def close(self) -> None:
        """Silence and release the output (idempotent)."""

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class SilentTaskAudio(TaskAudio):
    """Records each sound as placed at its onset; plays nothing. As an output that plays,
    :meth:`stop` drops the sounds whose onset ``clock`` has not reached (a task run that
    ends before an item it announced: the item is never heard)."""

    def __init__(self, clock: Clock) -> None:
        super().__init__()
        self.clock = clock

    def schedule(self, sound: FloatArray, onset_ns: int, label: str = "") -> None:
        self.played.append(Placement(label, int(onset_ns), None, int(onset_ns), 0))

    def stop(self) -> None:
        now = int(self.clock.now_ns())
        self.played = [p for p in self.played if p.onset_ns <= now]


@dataclass(slots=True, eq=False)
class _Sound:
    """A scheduled sound; ``gen``: the stops asked before it was scheduled (a later
    stop silences it, an earlier one does not); ``start``: its first frame, once placed."""

    label: str
    onset_ns: int
    samples: FloatArray
    gen: int
    start: int | None = None


class _Trampoline:
    """What SDL calls: forwards to the output while it lives (a weak reference, so a
    closed device kept in ``_RETIRED`` does not keep the output and its buffers)."""

    def __init__(self, target: SdlTaskAudio) -> None:
        self._target = weakref.ref(target)

    def __call__(self, device: Any, stream: Any) -> None:
        target = self._target()
        if target is None:
            np.asarray(stream).fill(0)
        else:
            target._callback(device, stream)


def _find_output(words: str, sdl_audio: Any) -> str:
    """The one SDL output whose name holds every word of ``words`` (DeviceError)."""
    names = [str(n) for n in sdl_audio.get_audio_device_names(False)]
    want = words.lower().split()
    match = [n for n in names if all(w in n.lower() for w in want)]
    exact = [n for n in match if n.lower() == words.strip().lower()]
    match = exact or match
    offers = "; ".join(repr(n) for n in names) or "none"
    if len(match) != 1:
        what = "matches no" if not match else "matches several"
        raise DeviceError(f"the task sound output {words!r} ({DEVICE_ENV}) {what} SDL "
                          f"output; outputs: {offers}")
    return match[0]


def _sdl_library() -> Any:
    """The SDL2 library pygame loaded, through ctypes (None when it cannot be found)."""
    paths: list[str] = []
    if sys.platform.startswith("linux"):
        with contextlib.suppress(OSError), open("/proc/self/maps", encoding="utf-8") as f:
            for line in f:
                path = line.rsplit(" ", 1)[-1].strip()
                name = os.path.basename(path)
                if name.startswith("libSDL2-") or name.startswith("libSDL2.so"):
                    paths.append(path)
    else:
        import pygame

        here = os.path.dirname(pygame.__file__)
        for sub in ("", ".dylibs"):
            folder = os.path.join(here, sub)
            with contextlib.suppress(OSError):
                paths += [os.path.join(folder, n) for n in os.listdir(folder)
                          if n in ("SDL2.dll",) or n.startswith("libSDL2-2.0")]
    found = ctypes.util.find_library("SDL2")
    if found:
        paths.append(found)
    for path in paths:
        with contextlib.suppress(OSError, AttributeError):
            lib = ctypes.CDLL(path)
            lib.SDL_PauseAudioDevice.argtypes = [ctypes.c_uint32, ctypes.c_int]
            lib.SDL_PauseAudioDevice.restype = None
            lib.SDL_CloseAudioDevice.argtypes = [ctypes.c_uint32]
            lib.SDL_CloseAudioDevice.restype = None
            return lib
    return None


class SdlTaskAudio(TaskAudio):
    """Task sounds through an SDL audio device, sample-accurate (see the module doc).

    Args:
        clock: the runner's clock (a wall clock: the callback reads it).
        latency_s: output latency after a callback (None: 0 for the ``disk`` and
            ``dummy`` drivers, one block otherwise).
        device: words of an SDL output's name (case-insensitive; None: the default
            output).

    Attributes:
        follow: how fast the timeline follows a late callback, 0..1 (1 for the ``disk``
            and ``dummy`` drivers, 0.2 otherwise).
        frames: frames output so far.
        blocks: per callback of the last minute, ``(first frame, its output time,
            callback time)`` (ns).
        error: an exception the callback caught (it then outputs silence), or None.

    Raises:
        DeviceError: SDL cannot open the output (no sound card, no sound server).
    """

    plays_sound = True

    def __init__(self, clock: Clock, *, latency_s: float | None = None,
                 device: str | None = None) -> None:
        super().__init__()
        os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
        import pygame._sdl2.audio as sdl_audio
        import pygame._sdl2.sdl2 as sdl

        self.clock = clock
        # SDL's audio driver as the environment asks for it (first of a list), or ''
        self.driver = os.environ.get("SDL_AUDIODRIVER", "").split(",")[0].strip().lower()
        immediate = self.driver in IMMEDIATE_DRIVERS
        self.follow = 1.0 if immediate else 0.2
        self._inbox: collections.deque[_Sound] = collections.deque()
        self._pending: list[_Sound] = []
        self._active: list[_Sound] = []
        self._stop_asked = 0
        self._closing = False
        self._silent_blocks = 0
        self.frames = 0
        self._base_ns: int | None = None
        self._prev_n = 0
        self.blocks: collections.deque[tuple[int, int, int]] = collections.deque(
            maxlen=BLOCKS_KEPT)
        self.error: BaseException | None = None
        self._ramp = max(1, round(STOP_RAMP_S * self.rate))
        self._closed = False
        try:
            sdl.init_subsystem(sdl.INIT_AUDIO)
            self._lib = _sdl_library()  # the SDL pygame loaded, to close without the GIL
            if self._lib is None:
                raise DeviceError(
                    "cannot reach the SDL2 library pygame loaded through ctypes, so the "
                    "sound output for the auditory task could not be closed safely (closing "
                    "it through pygame can hang); install pygame from its wheel (it bundles "
                    "SDL2) or make libSDL2 findable, or use a visual task")
            name = None if device is None else _find_output(device, sdl_audio)
            self._dev = sdl_audio.AudioDevice(name, False, self.rate, sdl_audio.AUDIO_F32,
                                              1, BLOCK_FRAMES, 0, _Trampoline(self))
        except DeviceError:
            self._closed = True
            raise
        except Exception as exc:
            self._closed = True
            raise DeviceError(
                f"cannot open the sound output for the auditory task ({exc}); check the "
                "sound card or the sound server, or set SDL_AUDIODRIVER=dummy to run "
                "without sound") from None
        self.block = int(self._dev.chunksize)
        lat = latency_s if latency_s is not None else (
            0.0 if immediate else self.block / self.rate)
        self.latency_ns = round(float(lat) * 1e9)
        self._dev.pause(0)  # safe here: the device opened paused, no callback runs yet

    # -- the callback (SDL's audio thread) -------------------------------------------------
    def _callback(self, device: Any, stream: Any) -> None:
        t_cb = self.clock.now_ns()
        out = np.asarray(stream).view(np.float32)
        try:
            self._fill(out, t_cb)
        except BaseException as exc:  # never raise into SDL: silence, remember why
            out.fill(0.0)
            if self.error is None:
                self.error = exc

    def _timeline(self, t_cb: int, n: int) -> int:
        """The output time of this block's first frame (runner clock, ns)."""
        raw = t_cb + self.latency_ns
        base = self._base_ns
        if base is None:
            est = raw
        else:
            nominal = base + round(self._prev_n * 1e9 / self.rate)
            est = raw if raw <= nominal else nominal + round(self.follow * (raw - nominal))
        self._base_ns = est
        self._prev_n = n
        return est

    def _fill(self, out: FloatArray, t_cb: int) -> None:
        n = out.shape[0]
        frame = self.frames
        base = self._timeline(t_cb, n)
        self.blocks.append((frame, base, t_cb))
        out.fill(0.0)
        if self._closing or self.error is not None:
            self._pending.clear()
            self._active.clear()
            self._silent_blocks += 1
            self.frames = frame + n
            return
        stop = self._stop_asked
        while self._inbox:
            self._pending.append(self._inbox.popleft())
        # a stop drops what was scheduled before it (not what came after it)
        self._pending = [p for p in self._pending if p.gen >= stop]
        # place what starts in this block (or should have started already)
        end = frame + n
        keep: list[_Sound] = []
        for s in self._pending:
            start = frame + round((s.onset_ns - base) * self.rate / 1e9)
            if start >= end:
                keep.append(s)
                continue
            late = 0
            if start < frame:
                late = round((frame - start) * 1e9 / self.rate)
                start = frame
            s.start = start
            start_ns = base + round((start - frame) * 1e9 / self.rate)
            self.played.append(Placement(s.label, s.onset_ns, start, start_ns, late))
            self._active.append(s)
        self._pending = keep
        # mix; sounds a stop silences fade out over the ramp, then end
        alive: list[_Sound] = []
        fading: FloatArray | None = None
        for s in self._active:
            assert s.start is not None
            stopped = s.gen < stop
            if stopped and fading is None:
                fading = np.zeros(n, dtype=np.float32)
            dest = fading if stopped and fading is not None else out
            o0 = max(s.start - frame, 0)
            i0 = max(frame - s.start, 0)
            k = min(n - o0, s.samples.shape[0] - i0)
            if k > 0:
                dest[o0:o0 + k] += s.samples[i0:i0 + k]
            if i0 + k < s.samples.shape[0] and not stopped:
                alive.append(s)
        self._active = alive
        if fading is not None:
            r = min(self._ramp, n)
            fading[:r] *= np.linspace(1.0, 0.0, r, dtype=np.float32)
            out[:r] += fading[:r]
        np.clip(out, -1.0, 1.0, out=out)
        self.frames = end

    # -- the main thread -----------------------------------------------------------------
    def schedule(self, sound: FloatArray, onset_ns: int, label: str = "") -> None:
        """Play ``sound`` from ``onset_ns`` (runner clock) on.

        Raises:
            DeviceError: the output stopped (the callback failed) or is closed.
        """
        if self.error is not None:
            raise DeviceError(f"the sound output of the auditory task stopped: {self.error}")
        if self._closed:
            raise DeviceError("the sound output of the auditory task is closed")
        samples = np.ascontiguousarray(sound, dtype=np.float32).reshape(-1)
        self._inbox.append(_Sound(label, int(onset_ns), samples, self._stop_asked))

    def stop(self) -> None:
        self._stop_asked += 1  # sounds scheduled from now on are not silenced

    def close(self) -> None:
        """Output silence, then close the device (idempotent; never raises)."""
        if self._closed:
            return
        self._closed = True
        self._closing = True
        late = self.late
        if late:
            log.warning("%d of %d task sounds started more than 1 ms after their onset "
                        "(at worst %.1f ms): the audio thread did not get the CPU in time",
                        len(late), len(self.played), max(p.late_ns for p in late) / 1e6)
        self._inbox.clear()
        end = time.monotonic() + CLOSE_WAIT_S
        while self._silent_blocks == 0 and time.monotonic() < end:
            time.sleep(0.001)
        dev = self._dev
        with contextlib.suppress(Exception):
            devid = int(dev.deviceid)
            self._lib.SDL_PauseAudioDevice(devid, 1)  # ctypes releases the GIL
            self._lib.SDL_CloseAudioDevice(devid)
            _RETIRED.append(dev)  # pygame must not close this id again


def open_task_audio(clock: Clock) -> TaskAudio:
    """A task-sound output for ``clock``: SDL's (sound card, or SDL_AUDIODRIVER's
    driver) on a wall clock, else a :class:`SilentTaskAudio`. The output is
    ``$TACTORBELT_TASK_AUDIO`` (words of an SDL output's name), else SDL's default; its
    latency ``$TACTORBELT_TASK_AUDIO_LATENCY_MS``, else the driver's default (see the
    module doc).

    Raises:
        DeviceError: the sound output cannot be opened, or the one named is not there.
        ConfigError: a latency that is not a number of ms in 0..1000.
    """
    if clock.simulated:
        return SilentTaskAudio(clock)
    text = os.environ.get(LATENCY_ENV, "").strip()
    latency_s = None
    if text:
        try:
            ms = float(text)
        except ValueError:
            ms = math.nan
        if not (math.isfinite(ms) and 0 <= ms <= 1000):
            raise ConfigError(f"{LATENCY_ENV} must be the output latency in ms (0..1000), "
                              f"got {text!r}")
        latency_s = ms / 1000.0
    return SdlTaskAudio(clock, latency_s=latency_s,
                        device=os.environ.get(DEVICE_ENV, "").strip() or None)
