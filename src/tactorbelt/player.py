"""The player: plays a stimulus on a belt, on absolute deadlines.

Two ways to play:

- **Device rendering**: a belt that renders a stimulus itself
  (``belt.can_render(stimulus)``: the sim belt, firmware with PLAY_TARGET for the laws
  and modes it knows) gets the whole stimulus once (``belt.play``) and keeps its own
  1 kHz timing. The default when the belt can render and its calibration is the
  identity (the device does not know the host's calibration); a stimulus the device
  cannot render is streamed instead.
- **Streaming**: the player writes one frame per period (default 1 kHz; a belt may
  declare ``stream_rate_hz``, e.g. 40 Hz over BLE). Frame i is due at
  ``deadline_i = onset + floor(i * 1e9 / rate)`` ns (:class:`~tactorbelt.clock.Deadlines`),
  computed from integers, never accumulated, so there is no drift however long it plays.
  The wall clock sleeps most of the way to a deadline and spins the last stretch
  (``WallClock.sleep_until_ns``).
  On the wall clock frames are written by a background thread; on a simulated clock
  (``clock.simulated``) nothing runs by itself: :meth:`Player.pump` writes every frame
  due up to a time.

Frame i shows ``stimulus.amplitudes(i / rate)`` (time since onset); on a belt whose
drive is shaped, ``stimulus.amplitudes(i / rate + lead)`` and off within ``lead`` of the
end: the shaper's preview (3 ms, ``devices.erm.LEAD_TICKS``), as a device previews what
it renders (a constant frame's last 3 ms are off: the brake starts then). A frame
is *missed* when it was woken up so late that the next deadline had already passed: the player
then skips straight to the frame due now (it never writes a burst of stale frames) and
counts the skipped ones as missed. The *deadline error* of a written frame is the
clock time just before the write minus its deadline.

If the belt raises in the background thread, the player stops, turns the motors off
(best effort) and re-raises the error from the next :meth:`Player.stop`,
:meth:`Player.pump` or :meth:`Player.stats`.

Imports NumPy, the standard library and tactorbelt (clock, devices.base, stimuli types).
"""

from __future__ import annotations

import collections
import contextlib
import math
import threading
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Final, Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

from ._errors import ConfigError, TactorbeltError
from .clock import SPIN_NS, Clock, Deadlines, WallClock
from .stimuli import Stimulus

if TYPE_CHECKING:
    from .devices.base import Belt
    from .geometry import Layout

__all__ = ["DEFAULT_RATE_HZ", "Player", "PlayerStats"]

#: The streaming rate when neither the caller nor the belt says otherwise.
DEFAULT_RATE_HZ: Final = 1000.0
#: Frames computed at once (one vectorised call of ``stimulus.amplitudes``).
_CHUNK: Final = 250
#: Deadline errors kept; beyond this, percentiles cover the most recent ones.
_MAX_ERRORS: Final = 1 << 21


@dataclass(frozen=True)
class PlayerStats:
    """Timing of one playback.

    Attributes:
        frames: frames written (0 when the device renders).
        missed: frames skipped because their time had passed.
        deadline_error_p50_ms, deadline_error_p99_ms, deadline_error_max_ms: the
            deadline error (write time minus deadline) of the written frames, median,
            99th percentile (NumPy's linear interpolation) and maximum; 0.0 when no
            frame was written. Percentiles cover the last 2,097,152 frames (35 min
            at 1 kHz); counts and the maximum cover everything.
        onset_ns: when the playback started (the first deadline), or None; on a shaped
            belt its pre-roll later (``Belt.preroll_ns``), as :meth:`Player.start` says.
        underruns: when the device renders, the output blocks it could not fill in time
            during the playback (an audio belt's underruns, :meth:`Belt.dropouts`): its
            missed frames; 0 when streaming or when the device cannot tell.
        stopped_ns: a stream played to its end: when its stop took effect, the clock
            midway through the belt's stop (a firmware belt returns once the device
            acknowledged it, so the device stopped within the call); the onset plus the
            duration only when the computer kept time; like ``onset_ns``, plus the pre-roll
            on a shaped belt. None when the device renders, when the playback was stopped
            before its end, or while it plays.
    """

    frames: int
    missed: int
    deadline_error_p50_ms: float
    deadline_error_p99_ms: float
    deadline_error_max_ms: float
    onset_ns: int | None
    underruns: int = 0
    stopped_ns: int | None = None

    def to_dict(self) -> dict[str, float | int | None]:
        """The statistics as a plain dict (for JSON)."""
        return asdict(self)


@runtime_checkable
class Playable(Protocol):
    """What the player streams: a layout and ``amplitudes(t_s) -> (len(t), N)``.

    A :class:`~tactorbelt.stimuli.Stimulus` is one (and the only kind a belt renders on
    the device); a constant test frame may be another.
    """

    layout: Layout

    def amplitudes(self, t: NDArray[np.float64]) -> NDArray[np.float64]: ...


class Player(contextlib.AbstractContextManager["Player"]):
    """Plays stimuli on one belt (see the module docstring).

    Args:
        belt: the belt.
        clock: the clock deadlines are kept on (default: ``belt.clock`` if the belt has
            one, else a new WallClock).
        rate_hz: frames per second when streaming (default: ``belt.stream_rate_hz`` if
            the belt declares one, else 1000).
        device_render: True to hand stimuli to the belt (``belt.play``), False to
            stream; default: the belt can render and its calibration is the identity.
            A stimulus made for another layout than the belt's is always streamed.

    Raises:
        ConfigError: a bad rate or clock, or ``device_render=True`` on a belt that
            cannot render.
    """

    def __init__(
        self,
        belt: Belt,
        clock: Clock | None = None,
        rate_hz: float | None = None,
        device_render: bool | None = None,
    ) -> None:
        self.belt = belt
        clock_is_ours = clock is None and belt.clock is None
        if clock is None:
            clock = belt.clock or WallClock()
        if not isinstance(clock, Clock):
            raise ConfigError(f"clock must be a Clock (now_ns, sleep_until_ns), got {clock!r}")
        self.clock: Clock = clock
        rate = belt.stream_rate_hz if rate_hz is None else rate_hz
        try:
            rate_f = float(rate)
        except (TypeError, ValueError):
            raise ConfigError(f"rate must be a positive number of Hz, got {rate!r}") from None
        if not (math.isfinite(rate_f) and 0 < rate_f <= 100_000):
            raise ConfigError(f"rate must be a number of Hz in (0, 100000], got {rate!r}")
        self.rate_hz = rate_f
        period_ns = Deadlines(self.clock, rate_f, onset_ns=0).period_ns
        if isinstance(self.clock, WallClock) and clock_is_ours:
            # Spin at most a quarter of a frame: a thread spinning the whole 1 ms period
            # holds the interpreter lock so long that the serial reader and keep-alive
            # threads starve (pings went unanswered for 300+ ms at 1 kHz).
            self.clock = WallClock(spin_ns=min(SPIN_NS, period_ns // 4))
        if device_render and not belt.can_render():
            raise ConfigError(f"belt {belt.url!r} cannot render stimuli on the device")
        if device_render is None:
            device_render = belt.renders_with_calibration()
        self.device_render = bool(device_render)

        self._lock = threading.Lock()
        self._halt = threading.Event()
        self._thread: threading.Thread | None = None
        self._error: BaseException | None = None
        self._reset(None, None, False)

    # -- state --------------------------------------------------------------------------
    def _reset(self, stimulus: Stimulus | None, onset_ns: int | None, device: bool) -> None:
        self._stimulus = stimulus
        self._onset: int | None = onset_ns
        self._dl = Deadlines(self.clock, self.rate_hz, onset_ns=onset_ns or 0)
        self._device = device
        self._dropouts0 = self.belt.dropouts() if device else 0
        self._active = stimulus is not None
        self._end: int | None = None
        self._stopped: int | None = None
        self._n_frames: int | None = None
        self._frames = 0
        #: the deadline errors (ns) of the latest frames written, and the largest of all
        self._errors: collections.deque[int] = collections.deque(maxlen=_MAX_ERRORS)
        self._max_error = 0
        self._cache_start = 0
        self._cache: NDArray[np.float64] | None = None
        #: the preview of a streamed stimulus (s): frames lead it on a shaped belt
        self._lead_s = 0.0
        #: the belt's pre-roll (ns): the stimulus's onset is this long after the command
        self._preroll = 0

    def _check_error(self) -> None:
        err = self._error
        if err is not None:
            self._error = None
            raise err

    def _check_stimulus(self, stimulus: Stimulus) -> None:
        # a protocol check is slow; most are a Stimulus
        if not isinstance(stimulus, Stimulus) and not isinstance(stimulus, Playable):
            raise ConfigError(f"expected a Stimulus, got {type(stimulus).__name__}")
        layout = stimulus.layout
        if layout.n != self.belt.n_tactors:
            raise ConfigError(f"the stimulus has {layout.n} tactors but the belt has "
                              f"{self.belt.n_tactors}")

    # -- public -----------------------------------------------------------------------------
    @property
    def playing(self) -> bool:
        """True while a stimulus is being played."""
        if not self._active:
            return False
        if self._thread is not None:
            return self._thread.is_alive()
        if self._device and self._end is not None:
            return self.clock.now_ns() < self._end
        return True

    @property
    def pumped(self) -> bool:
        """True while :meth:`pump` writes frames: a streamed playback on a simulated clock
        (a device-rendered one, or one written by the background thread, needs no pump)."""
        return self._active and not self._device and self._thread is None

    def renders_on_device(self, stimulus: Stimulus) -> bool:
        """True when :meth:`start` hands ``stimulus`` to the belt (else it streams it)."""
        return (self.device_render and isinstance(stimulus, Stimulus)
                and self.belt.can_render(stimulus))

    def start(self, stimulus: Stimulus, duration_s: float | None = None) -> int:
        """Start playing ``stimulus`` now, for ``duration_s`` seconds (None: until stopped).

        A playback already running is replaced (without turning the motors off).

        Returns:
            The onset: the clock time of the first frame's deadline (integer ns), plus the
            belt's pre-roll on a shaped belt (``Belt.preroll_ns``: the drive starts this
            long before the onset, so the kick from rest precedes it).
        """
        self._check_error()
        self._check_stimulus(stimulus)
        if duration_s is not None:
            try:
                d = float(duration_s)
            except (TypeError, ValueError):
                d = float("nan")
            if not (math.isfinite(d) and d > 0):
                raise ConfigError(f"duration must be a positive number of seconds, "
                                  f"got {duration_s!r}")
        self._join()
        self._halt.clear()
        device = self.renders_on_device(stimulus)
        onset = int(self.clock.now_ns())
        with self._lock:
            self._reset(stimulus, onset, device)
            self._preroll = self.belt.preroll_ns
            if not device and self.belt.drive == "shaped":
                # a streamed stimulus is known ahead: each frame shows it the shaper's
                # preview later, as the device's renderer previews what it plays
                # (docs/belts.md "Drive shaping")
                from .devices.erm import LEAD_TICKS, RENDER_TICK_NS

                self._lead_s = LEAD_TICKS * RENDER_TICK_NS * 1e-9
            if duration_s is not None:
                self._n_frames = max(1, round(float(duration_s) * self.rate_hz))
                self._end = (onset + round(float(duration_s) * 1e9) if device
                             else self._dl.deadline(self._n_frames))
        threaded = not device and not self.clock.simulated
        try:
            if device:
                self.belt.play(stimulus, duration_s)
            elif threaded:
                # frame 0 is due now: write it here, so the motors are on when start
                # returns (a caller that stops at once still played its first frame)
                self._step(None)
        except BaseException:
            self._active = False
            self._stop_motors()
            raise
        if threaded:
            self._thread = threading.Thread(target=self._run, name="tactorbelt-player",
                                            daemon=True)
            self._thread.start()
        return onset + self._preroll

    def device_onset(self, timeout_s: float = 0.1) -> tuple[int, int] | None:
        """The device-true onset of the last start, ``(host_ns, uncertainty_ns)``: the
        belt's :meth:`~tactorbelt.devices.base.Belt.last_onset` (when its outputs changed)
        plus the pre-roll, as :meth:`start` returns the onset; None where the belt cannot
        tell (``last_onset`` is None then)."""
        got = self.belt.last_onset(timeout_s)
        return None if got is None else (int(got[0]) + self._preroll, int(got[1]))

    def switch(self, stimulus: Stimulus) -> None:
        """Play ``stimulus`` from the next frame on, without a gap.

        Streaming keeps the time since onset (the phase of a dynamic stimulus runs on).
        A device-rendered playback restarts on the device with the new stimulus (the
        device cannot keep the phase), for what is left of the duration.
        """
        self._check_error()
        self._check_stimulus(stimulus)
        if not self.playing:
            raise TactorbeltError("nothing is playing: call start() before switch()")
        if self._device:
            if stimulus.layout != self.belt.layout:
                raise ConfigError("the stimulus was made for another layout than the belt's")
            remaining: float | None = None
            if self._end is not None:
                remaining = (self._end - self.clock.now_ns()) / 1e9
                if remaining <= 0:
                    return
            with self._lock:
                self._stimulus = stimulus
            self.belt.play(stimulus, remaining)
            return
        with self._lock:
            self._stimulus = stimulus
            self._cache = None

    def pump(self, until_ns: int) -> None:
        """On a simulated clock: write every frame due at or before ``until_ns``.

        Moves the clock to each frame's deadline (plus its jitter). A no-op when the
        device renders, when frames come from the background thread, or when nothing
        plays.
        """
        self._check_error()
        if not self._active or self._device or self._thread is not None:
            return
        try:
            while self._step(int(until_ns)):
                pass
        except BaseException:
            self._active = False
            self._stop_motors()
            raise

    def stop(self) -> PlayerStats:
        """Turn the motors off now and end the playback (joins the thread).

        Returns:
            The statistics of the playback.
        """
        self._join()
        self._active = False
        if self._error is not None:
            self._stop_motors()
            self._check_error()
        self.belt.stop()
        return self._stats()

    def play(self, stimulus: Stimulus, duration_s: float) -> PlayerStats:
        """Play ``stimulus`` for ``duration_s`` and return when it is over (motors off).

        On the wall clock this waits; on a simulated clock it pumps every frame and
        leaves the clock at the end.
        """
        if duration_s is None:
            raise ConfigError("play() needs a duration; use start() to play until stopped")
        self.start(stimulus, duration_s)
        try:
            assert self._end is not None
            if self._device:
                self.clock.sleep_until_ns(self._end)
            elif self._thread is None:
                self.pump(self._end)
            else:
                while self._thread.is_alive():
                    self._thread.join(0.05)
        except BaseException:
            self._halt.set()
            self._join()
            self._active = False
            self._stop_motors()
            raise
        return self.stop()

    def stats(self) -> PlayerStats:
        """The statistics so far (re-raises an error from the background thread)."""
        self._check_error()
        return self._stats()

    def __exit__(self, *exc: object) -> None:
        if self._active or self._thread is not None:
            self._halt.set()
            self._join()
            self._active = False
            self._stop_motors()

    # -- internals ----------------------------------------------------------------------------
    def _stats(self) -> PlayerStats:
        with self._lock:
            errs = np.fromiter(self._errors, dtype=np.int64, count=len(self._errors))
            p50, p99 = np.percentile(errs, [50.0, 99.0]) if errs.size else (0.0, 0.0)
            under = self.belt.dropouts() - self._dropouts0 if self._device else 0
            onset, stopped = (None if t is None else t + self._preroll
                              for t in (self._onset, self._stopped))
            return PlayerStats(self._frames, self._dl.missed, float(p50) / 1e6, float(p99) / 1e6,
                               self._max_error / 1e6, onset, under, stopped)

    def _stop_motors(self) -> None:
        with contextlib.suppress(Exception):  # best effort: the original error matters more
            self.belt.stop()

    def _join(self) -> None:
        t = self._thread
        if t is not None:
            self._halt.set()
            if t is not threading.current_thread():
                t.join()
            self._thread = None

    def _frame(self, i: int) -> NDArray[np.float64]:
        """Amplitudes of frame i (computed in vectorised chunks)."""
        with self._lock:
            cache = self._cache
            if cache is None or not (self._cache_start <= i < self._cache_start + len(cache)):
                assert self._stimulus is not None and self._onset is not None
                idx = np.arange(i, i + _CHUNK, dtype=np.int64)
                if self._n_frames is not None:
                    idx = idx[idx < max(self._n_frames, i + 1)]
                t = np.array([self._dl.time_s(int(k)) for k in idx])
                if self._lead_s:  # a shaped belt's frames lead by the shaper's preview
                    t += self._lead_s
                cache = np.asarray(self._stimulus.amplitudes(t), dtype=float)
                if self._lead_s and self._n_frames is not None:
                    cache[t >= self._dl.time_s(self._n_frames)] = 0.0
                self._cache, self._cache_start = cache, i
            return np.asarray(cache[i - self._cache_start])

    def _step(self, limit_ns: int | None) -> bool:
        """Wait for and write the next frame (or end the playback).

        Returns False when the playback is over or the next deadline is after
        ``limit_ns``.
        """
        dl = self._dl
        i = dl.next_index
        n = self._n_frames
        if n is not None and i >= n:
            end = dl.deadline(n)
            if limit_ns is not None and end > limit_ns:
                return False
            self.clock.sleep_until_ns(end)
            t0 = int(self.clock.now_ns())
            self.belt.stop()
            self._stopped = (t0 + int(self.clock.now_ns())) // 2
            self._active = False
            return False
        if limit_ns is not None and dl.deadline(i) > limit_ns:
            return False
        frame = self._frame(i)
        missed = dl.missed
        j, now = dl.wait(limit=n)
        if self._halt.is_set():  # stopped while waiting: this frame never happened
            dl.missed, dl.next_index = missed, i
            return False
        if n is not None and j >= n:  # woke up after the end: everything left is missed
            return True
        if j > i:
            frame = self._frame(j)
        self.belt.set_amplitudes(frame)
        err = now - dl.deadline(j)
        with self._lock:
            self._frames += 1
            self._errors.append(err)
            self._max_error = err if self._frames == 1 else max(self._max_error, err)
        return True

    def _run(self) -> None:
        try:
            while not self._halt.is_set() and self._step(None):
                pass
        except BaseException as exc:  # re-raised from stop()/pump()/stats()
            self._error = exc
            self._active = False
            self._stop_motors()
