"""The Belt interface: the one seam between tactorbelt and vibration hardware.

Every backend (``sim``, ``emulator``, ``serial``, ``ble``) subclasses :class:`Belt`
and implements the four ``_``-methods. The base class validates amplitudes, applies
the calibration, and guarantees that every motor is off when the ``with`` block
ends, whether normally, on an exception or on Ctrl-C (KeyboardInterrupt).

Callers never need to know which backend they have:

- ``set_amplitudes(values)`` streams one frame (one value per tactor, in [0, 1]);
- ``play(stimulus, duration_s)`` hands a whole stimulus to a belt that renders it on
  the device (``can_render(stimulus)``), which then keeps its own 1 kHz timing;
- ``stop()`` turns every motor off.

Every capability a caller may use is declared here, with a default, so callers never
probe a belt with ``getattr``/``hasattr``:

- ``clock``: the belt's own clock (the sim belt's), or None (wall time);
- ``stream_rate_hz``: the rate a Player streams at (1000; 40 over BLE);
- ``can_render(stimulus)``: True when the device renders that stimulus itself (a law or
  mode the firmware lacks, or a wearer profile the device cannot apply
  (``renders_profiles``), is streamed instead); ``can_render()``: renders any at all;
- ``levels``: the drive levels last written (calibrated), or None when not known (a
  device rendering a stimulus);
- ``models_vibration`` and ``vibration(t0_ns, t1_ns, rate_hz)``: the modelled vibration
  (the sim belt's motor model); other belts raise TactorbeltError.
- ``reports_onsets`` and ``last_onset()``: the device-true onset of the last stimulus
  start, mapped to host time with its uncertainty, ``(host_ns, uncertainty_ns)``
  (firmware 1.1 with ONSET events); None for belts that cannot tell.
- ``vibration_channels`` and ``reserved_channels``: a device that keeps a few vibrations at
  once, each one intensity on a set of tactors (the naviBelt's channels, less the one it
  keeps for its own signals), rather than a level per tactor; None (every other belt):
  every tactor on its own. A frame needing more distinct intensities is refused.
- ``senses_vibration`` and ``sense(duration_s, rate_hz=, tactor=)``: the belt's own board
  records its accelerometer (firmware 1.2 with an IMU that started), a
  :class:`Recording` with host-clock times (the firmware's
  :class:`~tactorbelt.devices._firmware.SenseRecording`); other belts raise DeviceError.
- ``can_shape``, ``can_brake``, ``drive`` and ``set_drive(drive)``: drive shaping
  (:class:`~tactorbelt.devices.erm.Shaper`, docs/belts.md "Drive shaping"): a belt that
  can shape plays every level change as an overdrive kick or a brake pulse when its
  ``drive`` is ``shaped``; ``can_brake``: it can reverse-drive its motors (both H-bridge
  inputs); ``session_url``: the URL with the drive a session stores.

The :class:`tactorbelt.player.Player` picks between streaming and device-side
rendering, so runners simply use a Player.
"""

from __future__ import annotations

import atexit
import contextlib
import math
import threading
import weakref
from abc import ABC, abstractmethod
from collections.abc import Sequence
from types import TracebackType
from typing import TYPE_CHECKING, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._errors import ConfigError, DeviceError, TactorbeltError
from ..clock import Clock
from ..geometry import Layout
from .calibration import Calibration

if TYPE_CHECKING:
    from ..stimuli import Stimulus

__all__ = ["DEFAULT_STREAM_RATE_HZ", "Belt", "Recording", "check_amplitudes", "close_at_exit",
           "closed_before_exit"]

#: The streaming rate of a belt that does not declare another.
DEFAULT_STREAM_RATE_HZ = 1000.0


#: ``a.min()`` and ``a.max()`` without ndarray's Python wrappers (NaN reaches both).
_MIN, _MAX = np.minimum.reduce, np.maximum.reduce


def check_amplitudes(values: ArrayLike, n: int) -> NDArray[np.float64]:
    """Validate one frame: exactly ``n`` finite values in [0, 1].

    Raises:
        ConfigError: wrong count, NaN or infinite values, values outside [0, 1].
    """
    try:
        a = np.asarray(values, dtype=float)
    except (TypeError, ValueError):
        raise ConfigError(f"amplitudes must be {n} numbers in [0, 1], got {values!r}") from None
    if a.ndim != 1:
        raise ConfigError(f"amplitudes must be one flat list of {n} numbers, got shape {a.shape}")
    if a.size != n:
        raise ConfigError(f"expected {n} amplitudes (one per tactor), got {a.size}")
    if a.size and _MIN(a) >= 0.0 and _MAX(a) <= 1.0:  # the usual frame: two reductions
        return a
    if not np.all(np.isfinite(a)):
        raise ConfigError("amplitudes must be finite numbers in [0, 1]; got NaN or infinity")
    if np.any(a < 0.0) or np.any(a > 1.0):
        bad = a[(a < 0.0) | (a > 1.0)][0]
        raise ConfigError(f"amplitudes must be in [0, 1], got {bad:g}")
    return a


#: Belts that hold a link open (firmware belts, naviBelts), closed at interpreter exit
#: (motors stopped) if their owner has not closed them by then.
_OPEN_AT_EXIT: weakref.WeakSet[Belt] = weakref.WeakSet()


def close_at_exit(belt: Belt) -> None:
    """Close ``belt`` (motors stopped) at interpreter exit if it is still open then."""
    _OPEN_AT_EXIT.add(belt)


def closed_before_exit(belt: Belt) -> None:
    """``belt`` was closed: nothing is left for the exit hook to do."""
    _OPEN_AT_EXIT.discard(belt)


@atexit.register
def _close_open_belts() -> None:
    for belt in list(_OPEN_AT_EXIT):
        with contextlib.suppress(Exception):
            belt.close()


class Recording(Protocol):
    """What :meth:`Belt.sense` returns: the samples of the belt's own accelerometer, with
    host-clock times, as they come in (a context manager that stops it)."""

    @property
    def rate_hz(self) -> float: ...
    @property
    def interrupted(self) -> str | None: ...
    def samples(self, t0_ns: int | None = None, t1_ns: int | None = None
                ) -> tuple[NDArray[np.int64], NDArray[np.float64]]: ...
    def problem(self, t0_ns: int | None = None, t1_ns: int | None = None) -> str | None: ...
    def wait_for(self, t_ns: int, timeout_s: float = 2.0) -> bool: ...
    def stop(self) -> None: ...
    def __enter__(self) -> Recording: ...
    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None: ...


class Belt(ABC):
    """A vibrotactile belt. Use it as a context manager: motors are off on exit.

    Attributes:
        url: how it was opened (``sim``, ``serial:/dev/ttyACM0``, ...).
        name: a human-readable name.
        firmware_version: ``"1.0.0"`` or None for a belt with no firmware.
        layout: the tactor angles.
        calibration: the drive mapping applied to every frame.
        clock: the belt's own clock, or None (the belt runs on wall time).
        stream_rate_hz: the frame rate a Player streams at by default.
    """

    clock: Clock | None = None
    stream_rate_hz: float = DEFAULT_STREAM_RATE_HZ
    #: how many vibrations the device keeps at once, each one intensity on any set of
    #: tactors (a naviBelt: 5), or None when every tactor is driven on its own
    vibration_channels: int | None = None
    #: the device's channels kept for its own signals, never used for stimuli (a
    #: naviBelt's channel 0, its inaccurate-orientation signal)
    reserved_channels: tuple[int, ...] = ()
    #: True from :meth:`close` on: a backend's ``_write_stop`` may then log what fails
    #: (a dead link) rather than raise it
    _closing = False

    def __init__(
        self,
        url: str,
        name: str,
        layout: Layout,
        firmware_version: str | None = None,
        calibration: Calibration | None = None,
    ) -> None:
        self.url = url
        self.name = name
        self.layout = layout
        self.firmware_version = firmware_version
        if calibration is not None and calibration.n != layout.n:
            raise ConfigError(
                f"calibration has {calibration.n} tactors but the belt has {layout.n}"
            )
        self.calibration = calibration or Calibration.identity(layout.n)
        self._closed = False
        self._lock = threading.RLock()
        self._levels: NDArray[np.float64] | None = np.zeros(layout.n)
        self._drive = "plain"

    # -- what backends implement ------------------------------------------------
    @abstractmethod
    def _write_levels(self, levels: NDArray[np.float64]) -> None:
        """Send one frame of drive levels (calibrated, each in [0, 1])."""

    @abstractmethod
    def _write_stop(self) -> None:
        """Turn every motor off now."""

    def _write_play(self, stimulus: Stimulus, duration_s: float | None) -> None:
        """Hand a stimulus to the device (only for what ``can_render`` accepts)."""
        raise TactorbeltError(f"belt {self.url!r} cannot render stimuli on the device")

    def _device_renders(self, stimulus: Stimulus | None) -> bool:
        """Backends that render on the device: True for what the device can render
        (``stimulus`` None: anything at all). The layout is checked by the caller."""
        return False

    def _close(self) -> None:  # noqa: B027 - optional hook
        """Release the connection (motors are already off)."""

    # -- the public interface ---------------------------------------------------
    @property
    def n_tactors(self) -> int:
        return self.layout.n

    @property
    def tactor_angles_deg(self) -> tuple[float, ...]:
        return self.layout.angles_deg

    @property
    def closed(self) -> bool:
        return self._closed

    # -- capabilities -------------------------------------------------------------
    def can_render(self, stimulus: Stimulus | None = None) -> bool:
        """True when :meth:`play` renders ``stimulus`` on the device.

        False for a stimulus made for another layout, or with a law, mode or timing
        the device lacks (stream it instead). Without a stimulus: True when the belt
        can render some stimulus on the device.
        """
        if stimulus is not None and stimulus.layout != self.layout:
            return False
        if (stimulus is not None and stimulus.profile is not None
                and not stimulus.profile.is_identity and not self.renders_profiles):
            return False  # the firmware knows no wearer profile: stream it
        return self._device_renders(stimulus)

    #: True when rendering on the device applies this belt's calibration (the audio
    #: belt renders in the host's audio callback, through the calibration). A firmware
    #: device knows nothing of the host's calibration, so a calibrated firmware belt (and
    #: the sim belt, which models one) streams instead.
    renders_calibrated: bool = False

    #: True when rendering on the device applies a stimulus's wearer profile
    #: (:mod:`tactorbelt.wearer`): the audio belt renders ``stimulus.amplitudes`` in the
    #: host. The firmware (PLAY_TARGET) carries no warp or gains, so a stimulus with a
    #: non-identity profile is streamed on every other belt, the sim belt included.
    renders_profiles: bool = False

    def renders_with_calibration(self, stimulus: Stimulus | None = None) -> bool:
        """True when :meth:`play` renders ``stimulus`` on the device *as calibrated*:
        the device can render it, and either the calibration is the identity or the
        device applies it. The player and the direction display render on the device
        by default exactly then."""
        return self.can_render(stimulus) and (self.calibration.is_identity
                                              or self.renders_calibrated)

    def channels_needed(self, levels: NDArray[np.float64]) -> NDArray[np.int64]:
        """How many of the device's :attr:`vibration_channels` each frame of drive levels
        (shape ``(n, N)``, calibrated) would take; zeros where every tactor is driven on its
        own (``vibration_channels`` None, the default)."""
        return np.zeros(np.shape(levels)[0], dtype=np.int64)

    @property
    def levels(self) -> NDArray[np.float64] | None:
        """The drive levels last written (calibrated, one per tactor; zeros after
        ``stop``), or None when not known (the device is rendering a stimulus)."""
        with self._lock:
            return None if self._levels is None else self._levels.copy()

    # -- drive shaping ----------------------------------------------------------
    @property
    def can_shape(self) -> bool:
        """True when the belt can play shaped drive (ERM motors it may overdrive)."""
        return False

    @property
    def can_brake(self) -> bool:
        """True when the belt can reverse-drive or short-brake its motors (both inputs of
        each H-bridge wired); a shaped fall then brakes, else it coasts."""
        return False

    @property
    def drive(self) -> str:
        """``plain`` or ``shaped`` (docs/belts.md, "Drive shaping")."""
        return self._drive

    @property
    def preroll_ns(self) -> int:
        """How long after the command a stimulus the player plays has its onset: 0 when
        plain; when shaped, :data:`~tactorbelt.devices.erm.PREROLL_NS`, so the kick from
        rest starts before the onset a session stores (docs/belts.md, "Pre-roll")."""
        if self._drive != "shaped":
            return 0
        from .erm import PREROLL_NS

        return PREROLL_NS

    def set_drive(self, drive: str) -> None:
        """Play ``plain`` or ``shaped`` from now on.

        Raises:
            ConfigError: an unknown drive, or ``shaped`` on a belt that cannot shape.
        """
        from .erm import DRIVES

        if drive not in DRIVES:
            raise ConfigError(f"drive must be one of {', '.join(DRIVES)}, got {drive!r}")
        if drive == "shaped" and not self.can_shape:
            raise ConfigError(f"belt {self.url!r} cannot shape its drive (no ERM motors "
                              "it may overdrive); use drive=plain")
        with self._lock:
            if drive != self._drive:
                self._set_drive(drive)
                self._drive = drive

    def _set_drive(self, drive: str) -> None:  # noqa: B027 - optional hook
        """Switch the device to ``drive`` (belts that can shape)."""

    @property
    def session_url(self) -> str:
        """The URL a session stores: :attr:`url` (without a ``drive`` option), with
        ``drive=shaped`` when shaped (a plain session's URL is as before)."""
        head, _, query = self.url.partition("?")
        items = [q for q in query.split("&") if q and not q.startswith("drive=")]
        if self._drive != "plain":
            items.append(f"drive={self._drive}")
        return head + ("?" + "&".join(items) if items else "")

    @property
    def models_vibration(self) -> bool:
        """True when :meth:`vibration` models the motors' vibration (the sim belt)."""
        return False

    @property
    def hardware(self) -> bool:
        """True when the belt drives real outputs a person may wear (every belt but the
        sim belt); a session on a simulated belt may batch its store commits."""
        return True

    @property
    def uses_sound_output(self) -> bool:
        """True when the tactors are driven through one of the computer's sound outputs
        (the audio belt): other sounds (a secondary task's) must not go to that output."""
        return False

    @property
    def reports_onsets(self) -> bool:
        """True when :meth:`last_onset` can give the device's own onset times."""
        return False

    def dropouts(self) -> int:
        """Output blocks the device could not fill in time since the belt was opened (an
        audio interface's underruns): 0 where the device cannot tell (the default)."""
        return 0

    def last_onset(self, timeout_s: float = 0.1) -> tuple[int, int] | None:
        """The device-true onset of the last stimulus start, on the host's clock.

        A start is a :meth:`play`, or the first :meth:`set_amplitudes` after the belt was
        idle (opened, stopped) or rendering. Returns ``(host_ns, uncertainty_ns)``: the
        moment the device changed its outputs, mapped from the device's clock to
        ``time.perf_counter_ns`` (the WallClock), and how far off that may be. None when
        the belt cannot tell (the default; firmware without ONSET events) or nothing
        has started. May wait up to ``timeout_s`` for the device's report.
        """
        return None

    @property
    def senses_vibration(self) -> bool:
        """True when :meth:`sense` records the vibration with a sensor of the belt's own
        (a firmware belt whose board's IMU streams: firmware 1.2)."""
        return False

    def sense(self, duration_s: float | None = None, *, rate_hz: float | None = None,
              tactor: int | None = None) -> Recording:
        """Start recording the belt's own accelerometer: samples (host ns, g) until
        ``duration_s`` passes or the recording's ``stop()``; see
        :meth:`tactorbelt.devices._firmware.FirmwareBelt.sense`.

        Raises:
            DeviceError: the belt has no sensor of its own (``senses_vibration`` False).
        """
        raise DeviceError("this belt has no sensor of its own; give --sense URL")

    def vibration(self, t0_ns: int, t1_ns: int, rate_hz: float = 1000.0
                  ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Modelled vibration over [t0, t1): ``(t_ns, amplitude (n, N))``.

        Raises:
            TactorbeltError: the belt models no vibration (``models_vibration`` False).
        """
        raise TactorbeltError(f"belt {self.url!r} models no vibration (only the sim belt does)")

    def _check_open(self) -> None:
        if self._closed:
            raise TactorbeltError(f"belt {self.url!r} is closed")

    def set_amplitudes(self, values: Sequence[float] | ArrayLike) -> None:
        """Set every tactor's amplitude (one value per tactor, in [0, 1]; 0 = off)."""
        a = check_amplitudes(values, self.n_tactors)
        with self._lock:
            self._check_open()
            levels = self.calibration.apply(a)
            self._write_levels(levels)
            self._levels = np.asarray(levels, dtype=float)

    def play(self, stimulus: Stimulus, duration_s: float | None = None) -> None:
        """Render ``stimulus`` on the device for ``duration_s`` (None: until stopped)."""
        if duration_s is not None:
            try:
                ok = math.isfinite(float(duration_s)) and float(duration_s) > 0
            except (TypeError, ValueError):
                ok = False
            if not ok:
                raise ConfigError(f"duration must be a positive, finite number of seconds, "
                                  f"got {duration_s!r}")
        if stimulus.layout != self.layout:
            raise ConfigError("the stimulus was made for another layout than this belt's")
        with self._lock:
            self._check_open()
            if not self.can_render():
                raise TactorbeltError(f"belt {self.url!r} cannot render stimuli on the device")
            self._write_play(stimulus, duration_s)
            self._levels = None

    def stop(self) -> None:
        """Turn every motor off."""
        with self._lock:
            if not self._closed:
                self._write_stop()
                self._levels = np.zeros(self.n_tactors)

    def close(self) -> None:
        """Turn every motor off (best effort) and release the belt. Safe to call twice."""
        with self._lock:
            if self._closed:
                return
            self._closing = True
            try:
                self._write_stop()
                self._levels = np.zeros(self.n_tactors)
            finally:
                self._closed = True
                self._close()

    def __enter__(self) -> Belt:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def __del__(self) -> None:  # last resort: never leave a motor running
        try:
            if not self.__dict__.get("_closed", True):  # __init__ may not have run
                self.close()
        except Exception:
            pass

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.url!r} {self.n_tactors} tactors>"
