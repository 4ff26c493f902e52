"""The host side of protocol v1: a Belt that talks to tactorbelt firmware over a transport.

:class:`FirmwareBelt` is shared by the ``serial``, ``emulator`` and ``ble`` backends;
they differ only in their :class:`Transport` (how packets become bytes and travel).

What the belt does while open:

- On open, GET_INFO (retried): it refuses a protocol version other than 1 with a
  :class:`~tactorbelt.ProtocolError`, takes the layout from the device's tactor
  angles, the firmware version, ``can_render()`` from capability bit 0 and the device's
  heartbeat timeout.
- Every packet gets the next sequence number (mod 256), in the order it is written,
  so the device's ``seq_gaps`` counter stays 0. Requests that have a reply (PING,
  GET_INFO, GET_STATUS, STOP_ALL, PLAY_TARGET, SET_CONFIG) wait for the reply with
  the same sequence number, with a timeout.
- A keep-alive thread writes every third of the device's heartbeat timeout: a PING
  when nothing has been heard from the device for that long, else a HEARTBEAT. When
  the device has been silent for a whole heartbeat timeout (and at least two PINGs
  went unanswered), or the transport reports an error or end of file, the belt is
  *lost*: every later call raises :class:`~tactorbelt.DeviceError` naming the port.
- Extensions (docs/protocol.md, "Extensions"): on open, after GET_INFO, the belt sends
  GET_DIAG. A DIAG means a firmware with the extensions (1.1): the belt keeps the
  DIAG as ``diagnostics``, warns (``log.warning``, printed by the CLI) when the device
  was last reset by its watchdog (INFO capability bit 7 or DIAG reset flag bit 1),
  and turns ONSET events on (SET_CONFIG with the flags byte; flags belong to the
  connection, so this happens on every open and again after a reset it notices).
  NAK 2 means plain v1 (firmware 1.0): no extensions, behaviour as before.
- Clock mapping: every PING/PONG and GET_DIAG/DIAG round trip is a sample for
  :class:`~tactorbelt.devices._clocksync.ClockSync` (device time to host
  ``perf_counter_ns``, with its uncertainty); with extensions, the keep-alive sends a
  GET_DIAG every :data:`SYNC_INTERVAL_S`. ONSET frames go to an onset table (never to
  ``unmatched_replies``), and :meth:`FirmwareBelt.last_onset` maps the one of the last
  stimulus start (a PLAY_TARGET, or the first SET_AMPLITUDES when not streaming) to
  host time.
- The board's accelerometer (firmware 1.2, INFO capability bit 1): :meth:`FirmwareBelt.sense`
  sends SENSE_START and returns a :class:`SenseRecording`, which collects the SENSE_DATA
  batches (routed by the SENSE_START's seq, never to ``unmatched_replies``) and maps their
  device time stamps to host time with the same clock fit as the onsets.
- BLE with an ATT MTU below 67 (``Transport.reply_limit``): GET_DIAG first, then
  SET_CONFIG with the framed-replies flag before GET_INFO, so that replies come as
  COBS frames in MTU-sized pieces; NAK 5 (reply too long for the MTU) is reported as
  a DeviceError that says so.
- Corrupted frames and garbage from the device are counted (``host_crc_errors``,
  ``host_framing_errors``, ``bad_replies``) and skipped.
- ``close()`` sends STOP_ALL and waits briefly for its ACK; on a dead device it logs
  a warning instead of raising (the device's own failsafe turns the motors off).
  Belts still open at interpreter exit are closed by an ``atexit`` hook.

Imports the standard library, NumPy (through Belt) and tactorbelt.devices.wire; never
pyserial or bleak (those live in the transports).
"""

from __future__ import annotations

import contextlib
import functools
import itertools
import logging
import math
import random
import threading
import time
import weakref
from abc import ABC, abstractmethod
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Final

import numpy as np
from numpy.typing import NDArray

from .._errors import ConfigError, DeviceError, ProtocolError, TactorbeltError
from .._registry import check_option
from ..geometry import Layout
from . import wire
from ._clocksync import ClockFit, ClockSync
from .base import Belt, close_at_exit, closed_before_exit
from .calibration import Calibration
from .erm import ErmParams

if TYPE_CHECKING:
    from ..stimuli import Stimulus
    from .registry import Found

__all__ = [
    "DEFAULT_TIMEOUT_S",
    "FIRMWARE_OPTIONS",
    "FirmwareBelt",
    "PacketSink",
    "SenseRecording",
    "Transport",
    "layout_from_info",
]

log = logging.getLogger("tactorbelt.devices")

#: How long a request waits for its reply by default.
DEFAULT_TIMEOUT_S: Final = 0.5
#: The shortest wait for the ACK of STOP_ALL (the request timeout if longer).
STOP_TIMEOUT_S: Final = 0.25
#: GET_INFO attempts on open (the first bytes after opening a port may be lost).
INFO_ATTEMPTS: Final = 3
#: With extensions, the keep-alive sends a GET_DIAG (a clock sample) this often.
SYNC_INTERVAL_S: Final = 0.5
#: GET_DIAG round trips on open, to start the clock mapping.
SYNC_BURST: Final = 8
#: The continuous-on limit a device has at power-up (SET_CONFIG with flags must carry one).
DEFAULT_MAX_ON_MS: Final = 30_000
#: The heartbeat timeout a device has at power-up.
DEFAULT_HEARTBEAT_MS: Final = 250
#: Requests need an ATT MTU of this much (64-byte packets, 3 bytes of ATT header).
BLE_MIN_MTU: Final = 67
#: The keyword options of every firmware belt (:class:`FirmwareBelt`'s); a link adds its own.
FIRMWARE_OPTIONS: Final = frozenset({"timeout_s", "heartbeat_ms", "calibration", "layout",
                                     "keepalive", "clock", "supply_v", "kick_ms"})
#: ONSET frames kept (by request seq).
_ONSETS_KEPT: Final = 64
#: Tactor angles within this of the default layout's are taken as the default layout.
_EVEN_LAYOUT_TOLERANCE_DEG: Final = 0.0051
#: How long :meth:`FirmwareBelt.sense` waits for the first samples after the ACK.
SENSE_FIRST_TIMEOUT_S: Final = 1.0
#: How long :meth:`SenseRecording.stop` waits for the session's last batch after the ACK.
SENSE_LAST_TIMEOUT_S: Final = 1.0

_LAW_CODES: Final = {law.name.lower(): law for law in wire.Law}
_MODE_CODES: Final = {mode.name.lower(): mode for mode in wire.Mode}
_REPLY_TYPES: Final = frozenset(t for t in wire.MsgType if t >= 0x80)  # replies from 0x80
_SYNC_TYPES: Final = frozenset({wire.MsgType.PING, wire.MsgType.GET_DIAG})


class PacketSink(ABC):
    """Where a transport delivers what it reads (called from the transport's thread)."""

    @abstractmethod
    def packet_received(self, packet: wire.Packet) -> None:
        """A packet with a valid CRC arrived."""

    @abstractmethod
    def link_lost(self, reason: str) -> None:
        """The link ended (end of file, I/O error, disconnect); ``reason`` says how."""


class Transport(ABC):
    """How packets travel: encode, write bytes, read packets in a thread, close.

    Attributes:
        port: names the link in messages (``/dev/ttyACM0``, ``BLE AA:BB:...``).
        crc_errors: incoming frames dropped for a bad CRC.
        framing_errors: incoming frames dropped for bad framing or length.
    """

    port: str = "?"

    @property
    def reply_limit(self) -> int | None:
        """The longest reply the link carries in one piece (BLE: ATT MTU - 3), or None
        (no limit: serial)."""
        return None

    @property
    def usb_port(self) -> str | None:
        """The serial port the board's firmware can be uploaded through (serial links),
        or None (BLE, where the board must be connected by USB to update it)."""
        return None

    def silence_hint(self) -> str:
        """Why the device may not be answering, as far as the link can tell (serial: the
        DTR line low), or "" when it cannot tell."""
        return ""

    def unread_bytes(self) -> int:
        """Bytes the device sent that the reading thread has not taken yet (serial: the
        port's input buffer), 0 where the link cannot tell (BLE pushes notifications)."""
        return 0

    def use_framed_replies(self) -> None:  # noqa: B027 - only BLE needs it
        """From now on, replies arrive as COBS frames split across notifications (BLE)."""

    #: the decoder of framed replies (serial; BLE with framed replies), and the frames the
    #: transport itself dropped (BLE's unframed packets)
    _decoder: wire.FrameDecoder | None = None
    _crc_errors = _framing_errors = 0

    @property
    def crc_errors(self) -> int:
        return self._crc_errors + (self._decoder.crc_errors if self._decoder else 0)

    @property
    def framing_errors(self) -> int:
        return self._framing_errors + (self._decoder.framing_errors if self._decoder else 0)

    def deliver(self, sink: PacketSink, packets: list[wire.Packet]) -> None:
        """Hand packets to ``sink``; a handler's error is logged, never kills the reader."""
        for packet in packets:
            try:
                sink.packet_received(packet)
            except Exception:
                log.exception("%s: error handling a packet", self.port)

    @abstractmethod
    def encode(self, packet: wire.Packet) -> bytes:
        """The bytes of one packet on this link (framed for serial, raw for BLE)."""

    @abstractmethod
    def write(self, data: bytes) -> None:
        """Write bytes. Raises DeviceError (or OSError) when the link is gone."""

    @abstractmethod
    def start(self, sink: PacketSink) -> None:
        """Start delivering incoming packets (and the end of the link) to ``sink``."""

    @abstractmethod
    def close(self) -> None:
        """Stop reading and release the link. Safe to call twice; never raises."""


@dataclass
class _Waiter:
    """One request waiting for its reply."""

    seq: int
    event: threading.Event = field(default_factory=threading.Event)
    reply: wire.Reply | None = None


def layout_from_info(info: wire.Info) -> Layout:
    """The device's tactor layout; the default layout when the angles match it.

    The device reports centidegrees, so ``180/7`` comes back as 25.71: snapping to
    :meth:`Layout.even` keeps ``belt.layout == Layout.even(n)`` for stimuli built on it.

    Raises:
        ProtocolError: no tactors, or angles that do not form a layout.
    """
    angles = info.tactor_angles_deg
    if info.channels != len(angles) or info.channels < 2:
        raise ProtocolError(
            f"INFO reports {info.channels} channels and {len(angles)} tactor angles; "
            "a belt needs at least 2"
        )
    even = Layout.even(info.channels)
    diffs = np.abs((np.asarray(angles) - even.angles + 180.0) % 360.0 - 180.0)
    if np.all(diffs <= _EVEN_LAYOUT_TOLERANCE_DEG):
        return even
    try:
        return Layout.from_angles(angles)
    except ConfigError as exc:
        raise ProtocolError(f"INFO tactor angles {list(angles)} are not a layout: {exc}") from None


def _ms(value_s: float, what: str, lo: int, hi: int) -> int:
    ms = round(value_s * 1000.0)
    if not lo <= ms <= hi:
        raise ConfigError(
            f"{what} {value_s:g} s does not fit the device: "
            f"allowed {lo / 1000:g} to {hi / 1000:g} s"
        )
    return ms


def _rounded(value: Any, scale: float) -> int:
    """``round(value * scale)`` of a finite number, else -1."""
    try:
        v = float(value) * scale
    except (TypeError, ValueError):
        return -1
    return round(v) if math.isfinite(v) else -1


def checked_int(name: str, value: Any, lo: int, hi: int) -> int:
    """``value`` when it is an integer (not a bool) in ``lo..hi``, else a ConfigError."""
    if isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi:
        raise ConfigError(f"{name} must be an integer in {lo}..{hi}, got {value!r}")
    return value


def _play_args(stimulus: Stimulus, duration_s: float | None) -> tuple[int, ...]:
    """PLAY_TARGET's fields for ``stimulus`` (after the seq).

    Raises:
        ConfigError: a law or mode the firmware lacks, or a value that does not fit.
    """
    if stimulus.law not in _LAW_CODES:
        raise ConfigError(
            f"the firmware cannot render law {stimulus.law!r}; allowed: {', '.join(_LAW_CODES)}"
        )
    check_option("stimulus mode for the firmware", stimulus.mode, _MODE_CODES)
    falloff_cdeg = round(stimulus.falloff_deg * 100.0)
    if not 1 <= falloff_cdeg <= 0xFFFF:
        raise ConfigError(
            f"falloff {stimulus.falloff_deg:g} deg does not fit the device: "
            "allowed 0.01 to 655.35 deg"
        )
    return (wire.angle_to_cdeg(stimulus.target_deg), int(_MODE_CODES[stimulus.mode]),
            int(_LAW_CODES[stimulus.law]), falloff_cdeg,
            _ms(stimulus.period_s, "period", 1, 0xFFFF),
            _ms(stimulus.transit_s, "transit", 1, 0xFFFF),
            0 if duration_s is None else _ms(duration_s, "duration", 1, 0xFFFFFFFF))


class SenseRecording(contextlib.AbstractContextManager["SenseRecording"]):
    """Samples of the accelerometer on a firmware belt's own board, with host-clock times.

    Made by :meth:`FirmwareBelt.sense`, which returns once the first samples arrived; the
    device goes on sampling until the duration has passed or :meth:`stop`. A context
    manager: ``with belt.sense(10.0) as rec: ...`` stops it on exit.

    The device samples on its own microsecond clock, every ``period_us`` (sample k of a
    batch at ``t0 + k * period``, each read within half a period after its stamp); the
    times :meth:`samples` gives are those stamps mapped to ``time.perf_counter_ns`` (the
    WallClock, as :meth:`FirmwareBelt.last_onset`) with the belt's clock fit as it is when
    asked (so later calls use more round trips), give or take :attr:`uncertainty_ns`. The
    IMU's own delays (the age of its last conversion, at most one of its periods, and its
    filter's) are not taken off.

    Samples the device or the link lost show as gaps in the batches' indices:
    :meth:`lost` counts them, :meth:`problem` says so for an interval. Thread-safe: the
    belt's reader thread adds batches while callers read.

    Attributes:
        tactor: the tactor the board was said to be on (None: not said).
        rate_hz: the sampling rate, ``1e6 / period_us``.
        period_us: the sampling period (us).
        full_scale_g: the acceleration of a raw value of 32768 (g).
        duration_s: how long the device was asked to sense.
    """

    def __init__(self, belt: FirmwareBelt, tactor: int | None, duration_s: float) -> None:
        self._belt = belt
        self.tactor = tactor
        self.duration_s = duration_s
        self.seq = -1
        self.period_us = 0
        self.rate_hz = 0.0
        self.full_scale_g = 0.0
        self._cond = threading.Condition()
        self._chunks_t: list[NDArray[np.int64]] = []
        self._chunks_a: list[NDArray[np.int16]] = []
        self._t_us: NDArray[np.int64] = np.zeros(0, dtype=np.int64)
        self._acc: NDArray[np.int16] = np.zeros((0, 3), dtype=np.int16)
        self._next_index = 0
        self._last_t_us: int | None = None
        self._gaps: list[tuple[int, int, int]] = []  # (after device us, before device us, n)
        self._first = False
        self.finished = False
        self._broken: str | None = None
        self._fit: ClockFit | None = None

    # -- the reader thread -----------------------------------------------------------
    def _add(self, batch: wire.SenseData) -> None:
        n = batch.n_samples
        with self._cond:
            if not self._first:
                self._first = True
                self.period_us = batch.period_us
                self.rate_hz = 1e6 / batch.period_us
                self.full_scale_g = batch.full_scale_mg / 1000.0
            if batch.first_index > self._next_index:
                after = self._last_t_us if self._last_t_us is not None else batch.t0_us
                self._gaps.append((after, batch.t0_us, batch.first_index - self._next_index))
            if n:
                t = batch.t0_us + batch.period_us * np.arange(n, dtype=np.int64)
                self._chunks_t.append(t)
                self._chunks_a.append(np.asarray(batch.samples, dtype=np.int16).reshape(n, 3))
                self._last_t_us = int(t[-1])
            self._next_index = max(self._next_index, batch.first_index + n)
            if batch.last:
                self.finished = True
            self._cond.notify_all()

    def _end(self, reason: str, fit: ClockFit | None = None) -> None:
        """The recording stops here (the belt closed, was lost or restarted); with ``fit``,
        its times stay mapped with that fit (the device clock it was taken on)."""
        with self._cond:
            if fit is not None and self._fit is None:
                self._fit = fit
            if not self.finished and self._broken is None:
                self._broken = reason
            self._cond.notify_all()

    # -- the caller's side -------------------------------------------------------------
    @property
    def active(self) -> bool:
        """True while the device may still send samples of this recording."""
        with self._cond:
            return not self.finished and self._broken is None

    @property
    def interrupted(self) -> str | None:
        """Why the recording ended before its time (the belt closed, lost, restarted), or
        None."""
        with self._cond:
            return self._broken

    def __len__(self) -> int:
        with self._cond:
            return int(self._t_us.shape[0]) + sum(c.shape[0] for c in self._chunks_t)

    def _consolidate(self) -> tuple[NDArray[np.int64], NDArray[np.int16]]:
        with self._cond:
            if self._chunks_t:
                self._t_us = np.concatenate([self._t_us, *self._chunks_t])
                self._acc = np.concatenate([self._acc, *self._chunks_a])
                self._chunks_t, self._chunks_a = [], []
            return self._t_us, self._acc

    def _current_fit(self) -> ClockFit:
        fit = self._fit or self._belt.clock_sync.fit()
        if fit is None:  # pragma: no cover - the belt syncs before sense() returns
            raise DeviceError(f"the belt on {self._belt.port} has no clock mapping yet")
        return fit

    def samples(self, t0_ns: int | None = None, t1_ns: int | None = None
                ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """The samples taken in [t0, t1) (host ns; None: from the first, to the last).

        Returns:
            ``(t_ns, acc)``: host times (int64 ns on ``time.perf_counter_ns``, increasing
            within a batch; a late read starts a new batch), and acceleration (float64,
            shape (n, 3): x, y, z of the board in g).
        """
        t_us, acc = self._consolidate()
        fit = self._current_fit()
        lo = 0 if t0_ns is None else int(np.searchsorted(
            t_us, math.ceil(fit.device_us(t0_ns) - 1.0), "left"))
        hi = t_us.shape[0] if t1_ns is None else int(np.searchsorted(
            t_us, math.floor(fit.device_us(t1_ns) + 1.0), "right"))
        t_ns = np.rint(fit.host_ns(t_us[lo:hi].astype(np.float64))).astype(np.int64)
        keep = np.ones(t_ns.shape[0], dtype=bool)
        if t0_ns is not None:
            keep &= t_ns >= t0_ns
        if t1_ns is not None:
            keep &= t_ns < t1_ns
        g = acc[lo:hi][keep].astype(np.float64) * (self.full_scale_g / 32768.0)
        return np.asarray(t_ns[keep]), g

    @property
    def uncertainty_ns(self) -> int:
        """How far off the mapped times may be: half the fastest round trips, the fit's
        error (at the middle of the recording) and the device clock's resolution."""
        t_us, _ = self._consolidate()
        mid = int(t_us[t_us.shape[0] // 2]) if t_us.shape[0] else 0
        return self._current_fit().to_host(mid)[1]

    def lost(self, t0_ns: int | None = None, t1_ns: int | None = None) -> int:
        """Samples lost (on the device or the link) in [t0, t1) (host ns; None: all): each
        gap in the indices counts whole when it overlaps the interval."""
        with self._cond:
            gaps = list(self._gaps)
        if not gaps:
            return 0
        fit = self._current_fit()
        lo = -math.inf if t0_ns is None else fit.device_us(t0_ns)
        hi = math.inf if t1_ns is None else fit.device_us(t1_ns)
        return sum(n for after, before, n in gaps if before > lo and after < hi)

    def problem(self, t0_ns: int | None = None, t1_ns: int | None = None) -> str | None:
        """Why [t0, t1) cannot be used as it is (samples lost in it, the recording ended
        before its end), or None."""
        n = self.lost(t0_ns, t1_ns)
        if n:
            return (f"{n} sample{'s' if n != 1 else ''} of the board's IMU were lost in the "
                    "interval (the link did not keep up, or the IMU did not answer)")
        with self._cond:
            broken = self._broken
            last = self._last_t_us
        if broken is not None and t1_ns is not None and (
                last is None or self._current_fit().to_host(last)[0] < t1_ns):
            return f"the recording ended early: {broken}"
        return None

    def wait_for(self, t_ns: int, timeout_s: float = 2.0) -> bool:
        """Wait until samples at or after host time ``t_ns`` have arrived. False when the
        recording ends before it or ``timeout_s`` passes."""
        deadline = time.monotonic() + timeout_s
        while True:
            with self._cond:
                last = self._last_t_us
                ended = self.finished or self._broken is not None
            if last is not None and self._current_fit().to_host(last)[0] >= t_ns:
                return True
            left = deadline - time.monotonic()
            if ended or left <= 0:
                return False
            with self._cond:
                self._cond.wait(min(left, 0.05))

    def forget_before(self, t_ns: int) -> None:
        """Drop the samples before host time ``t_ns`` (a long recording need not keep them)."""
        t_us, _ = self._consolidate()
        cut = int(np.searchsorted(t_us, math.floor(self._current_fit().device_us(t_ns)),
                                  "left"))
        with self._cond:
            self._t_us = self._t_us[cut:]
            self._acc = self._acc[cut:]

    def stop(self) -> None:
        """End the recording now (SENSE_STOP) and wait for its last samples. Safe to call
        twice, and after the belt closed.

        Raises:
            DeviceError: the belt stopped answering.
        """
        if not self.active:
            return
        self._belt._stop_sensing(self)
        with self._cond:
            self._cond.wait_for(lambda: self.finished or self._broken is not None,
                                SENSE_LAST_TIMEOUT_S)
            if not self.finished and self._broken is None:
                self._broken = "its last samples did not arrive"
            self.finished = True

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: object) -> None:
        with contextlib.suppress(DeviceError):
            self.stop()

    def __repr__(self) -> str:
        state = "active" if self.active else "ended"
        return (f"<SenseRecording of {self._belt.port}: {len(self)} samples at "
                f"{self.rate_hz:g} Hz, {state}>")


class FirmwareBelt(Belt, PacketSink):
    """A belt running tactorbelt firmware (protocol v1), over any :class:`Transport`.

    Open one with ``open_belt("serial:...")``, ``open_belt("emulator")`` or
    ``open_belt("ble:...")`` rather than directly.

    Args:
        transport: the link; the belt starts it and closes it.
        url: how it was opened (``serial:/dev/ttyACM0``).
        stream_rate_hz: the frame rate :class:`~tactorbelt.player.Player` streams at.
        timeout_s: how long a request waits for its reply.
        heartbeat_ms: if given, set the device's heartbeat timeout (50..2000 ms) on open.
        calibration: drive mapping per tactor.
        layout: override the device's tactor angles (same tactor count). When they
            differ from the device's, the belt cannot render on the device
            (``can_render()`` is False), since the device renders with its own angles.
        keepalive: run the keep-alive thread (turn it off only to test the failsafe).
        clock: accepted for compatibility with the other backends and ignored
            (a real device runs on wall time).

    Attributes:
        info: what GET_INFO reported.
        port: the link's name.
        heartbeat_ms: the device's heartbeat timeout in use.
        max_on_ms: the continuous-on limit this belt last set (30000 until it sets one).
        stream_rate_hz: the streaming rate for this link.
        extensions: the firmware answered GET_DIAG (1.1: DIAG, ONSET, SET_CONFIG flags).
        diagnostics: the last DIAG (None without extensions).
        watchdog_reset: the device was reset by its watchdog (before or while open).
        onset_events: ONSET events are on (see :meth:`last_onset`).
        stray_sense_batches: SENSE_DATA of no recording of this belt (an earlier
            connection's, or one that came after its recording ended).
        framed_replies: BLE replies come as COBS frames (an MTU below 67).
        clock_sync: the device-to-host clock mapping (:class:`ClockSync`).

    Raises:
        ProtocolError: the device speaks another protocol version, or garbles INFO.
        DeviceError: no answer to GET_INFO.
    """

    def __init__(
        self,
        transport: Transport,
        url: str,
        *,
        stream_rate_hz: float = 1000.0,
        timeout_s: float = DEFAULT_TIMEOUT_S,
        heartbeat_ms: int | None = None,
        calibration: Calibration | None = None,
        layout: Layout | None = None,
        keepalive: bool = True,
        clock: object | None = None,
        supply_v: float | None = None,
        kick_ms: float = 0.0,
    ) -> None:
        del clock
        #: the motor supply (V) and how long a kick may apply it above the motor's maximum
        #: voltage (ms): the constants SET_DRIVE sends (None: the device's defaults)
        self._supply_v = supply_v
        self._kick_ms = kick_ms
        self._transport = transport
        self.port = transport.port
        self.stream_rate_hz = float(stream_rate_hz)
        self._seq = itertools.count()
        self._tx_lock = threading.Lock()
        self._pending: dict[int, _Waiter] = {}
        self._pending_lock = threading.Lock()
        self._lost: str | None = None
        self._last_rx_ns = time.monotonic_ns()
        self._unanswered_pings = 0
        self._first_ping_ns = 0
        self._keepalive_stop = threading.Event()
        self._keepalive_kick = threading.Event()
        self._keepalive_thread: threading.Thread | None = None
        self.bad_replies = 0
        self.unmatched_replies = 0
        self.unsolicited_naks = 0
        self.frames_sent = 0
        self.heartbeat_ms = 0
        self.max_on_ms = DEFAULT_MAX_ON_MS
        self._can_play_target = False
        self.extensions = False
        self.framed_replies = False
        self.onset_events = False
        self.diagnostics: wire.Diag | None = None
        self.watchdog_reset = False
        self.clock_sync = ClockSync()
        self._sync_sent: dict[int, int] = {}
        self._last_sync_ns = 0
        self._onsets: dict[int, wire.Onset] = {}
        self._onset_cond = threading.Condition()
        self._onset_seq: int | None = None
        self._streaming = False
        self._reset_seen = False
        self._sense_lock = threading.Lock()
        self._recordings: dict[int, SenseRecording] = {}  # by SENSE_START seq, until ended
        self._all_recordings: weakref.WeakSet[SenseRecording] = weakref.WeakSet()
        self._sensing: SenseRecording | None = None  # the device's current session
        self.stray_sense_batches = 0
        # Belt.__init__ sets _closed; until it runs, __del__ must see a closed belt.
        self._closed = True
        try:  # the transport is closed whatever fails here: the openers need not
            if not (isinstance(timeout_s, int | float) and math.isfinite(timeout_s)
                    and timeout_s > 0):
                raise ConfigError(
                    f"timeout_s must be a positive number of seconds, got {timeout_s!r}")
            self.timeout_s = float(timeout_s)
            transport.start(self)
            limit = transport.reply_limit
            if limit is not None and limit < wire.MAX_PACKET:
                self._start_framing(limit, heartbeat_ms)
            info = self._handshake()
            from ..firmware import version_note

            note = version_note(info.firmware_version, transport.usb_port)
            if note:
                log.warning("%s: %s", self.port, note)
            dev_layout = layout_from_info(info)
            use_layout = dev_layout if layout is None else layout
            if use_layout.n != dev_layout.n:
                raise ConfigError(f"layout has {use_layout.n} tactors but the belt on "
                                  f"{self.port} has {dev_layout.n}")
            self.info = info
            self.heartbeat_ms = info.heartbeat_ms
            self._can_play_target = info.can_play_target and use_layout == dev_layout
            super().__init__(
                url,
                f"tactorbelt firmware {info.firmware_version} on {self.port}",
                use_layout,
                firmware_version=info.firmware_version,
                calibration=calibration,
            )
            if heartbeat_ms is not None:
                self.set_config(heartbeat_ms)
            if not self.extensions:
                self._probe_extensions()
            if self.extensions:
                diag = self.diagnostics
                if info.capabilities & wire.Capability.WATCHDOG_RESET or (
                        diag is not None and diag.watchdog_reset):
                    self._warn_watchdog("was last reset by its watchdog")
                self._enable_flags()
                self._sync_burst()
        except BaseException:
            self._closed = True
            transport.close()
            raise
        close_at_exit(self)
        if keepalive:
            self.start_keepalive()

    # -- packets in (transport thread) ------------------------------------------
    def packet_received(self, packet: wire.Packet) -> None:
        recv_ns = time.perf_counter_ns()
        self._last_rx_ns = time.monotonic_ns()
        self._unanswered_pings = 0
        if packet.type not in _REPLY_TYPES:
            self.bad_replies += 1
            log.debug("%s: ignoring packet type 0x%02X from the device", self.port, packet.type)
            return
        try:
            reply = wire.parse_reply(packet)
        except ProtocolError as exc:
            self.bad_replies += 1
            log.debug("%s: ignoring a bad reply: %s", self.port, exc)
            return
        if isinstance(reply, wire.SenseData):  # the header's seq is the SENSE_START's
            with self._sense_lock:
                rec = self._recordings.get(reply.session_seq)
                if rec is not None and reply.last:
                    del self._recordings[reply.session_seq]
            if rec is None:
                self.stray_sense_batches += 1
            else:
                rec._add(reply)
            return
        if isinstance(reply, wire.Onset):  # follows the ACK of the same seq: no waiter
            with self._onset_cond:
                self._onsets[reply.seq] = reply
                while len(self._onsets) > _ONSETS_KEPT:
                    del self._onsets[next(iter(self._onsets))]
                self._onset_cond.notify_all()
            return
        if isinstance(reply, wire.Pong | wire.Diag):
            self._clock_sample(packet.seq, reply, recv_ns)
        with self._pending_lock:
            waiter = self._pending.pop(packet.seq, None)
        if waiter is None:
            if isinstance(reply, wire.Nak):
                self.unsolicited_naks += 1
                log.warning("%s: the device refused packet seq %d (NAK code %s)",
                            self.port, packet.seq, reply.code)
            elif not isinstance(reply, wire.Pong):  # keep-alive PONGs have no waiter
                self.unmatched_replies += 1
            return
        waiter.reply = reply
        waiter.event.set()

    def link_lost(self, reason: str) -> None:
        self._mark_lost(f"belt on {self.port} stopped answering: {reason}")

    def _end_recordings(self, reason: str, fit: ClockFit | None = None) -> None:
        """Every recording of this belt ends (``fit``: the clock fit their times keep)."""
        with self._sense_lock:
            recordings = list(self._all_recordings)
            self._recordings.clear()
            self._sensing = None
        for rec in recordings:
            rec._end(reason, fit)

    def _mark_lost(self, message: str) -> None:
        if self._lost is None:
            self._lost = message
            if not self._closing and not self._closed:
                log.warning("%s", message)
            self._end_recordings(message)
        with self._pending_lock:
            waiters = list(self._pending.values())
            self._pending.clear()
        for w in waiters:
            w.event.set()

    # -- packets out -------------------------------------------------------------
    def _check_alive(self) -> None:
        if self._lost is not None:
            raise DeviceError(self._lost)

    def _send(self, build: Callable[[int], wire.Packet], wait: bool = False,
              onset: bool = False) -> _Waiter | None:
        """Build a packet with the next seq and write it; register a waiter first (``wait``).

        ``onset``: the request starts a stimulus; its ONSET (if any) is the one
        :meth:`last_onset` reports.
        """
        self._check_alive()
        with self._tx_lock:
            seq = next(self._seq) & 0xFF
            packet = build(seq)
            waiter = None
            if wait:
                waiter = _Waiter(seq)
                with self._pending_lock:
                    self._pending[seq] = waiter
            if onset:
                with self._onset_cond:
                    self._onsets.pop(seq, None)
                    self._onset_seq = seq
            data = self._transport.encode(packet)
            if packet.type in _SYNC_TYPES:
                self._sync_sent[seq] = time.perf_counter_ns()
            self._write(data)
            self.frames_sent += 1
        return waiter

    def _write(self, data: bytes) -> None:
        """Write to the link (holding the write lock); a failed write loses the belt."""
        try:
            self._transport.write(data)
        except (OSError, DeviceError) as exc:
            self._mark_lost(f"belt on {self.port} stopped answering: write failed: {exc}")
            raise DeviceError(self._lost) from None

    def _request(self, build: Callable[[int], wire.Packet], name: str,
                 timeout_s: float | None = None, expect: type | None = None,
                 onset: bool = False) -> Any:
        """Send a request and wait for the reply with its sequence number (``expect``: a
        reply of that kind, else an error, :meth:`_expect`; ``onset``: as for
        :meth:`_send`)."""
        waiter = self._send(build, True, onset)
        assert waiter is not None
        timeout = self.timeout_s if timeout_s is None else timeout_s
        if not waiter.event.wait(timeout):
            with self._pending_lock:
                self._pending.pop(waiter.seq, None)
            self._check_alive()
            raise DeviceError(
                f"belt on {self.port} did not answer {name} within {timeout * 1000:.0f} ms"
            )
        if waiter.reply is None:  # woken by the link ending
            self._check_alive()
            raise DeviceError(f"belt on {self.port} stopped answering")
        return waiter.reply if expect is None else self._expect(waiter.reply, expect, name)

    def _expect(self, reply: wire.Reply, kind: type, name: str) -> Any:
        if isinstance(reply, wire.Nak):
            if reply.code == wire.NakCode.REPLY_TOO_LONG:
                raise DeviceError(
                    f"the belt on {self.port} could not send its answer to {name}: it does "
                    f"not fit the BLE link's MTU ({self._mtu_text()}) and framed replies "
                    "are off; let the adapter negotiate an MTU of at least "
                    f"{BLE_MIN_MTU}, or update the firmware to 1.1 (framed replies)"
                )
            if reply.code == wire.NakCode.OUT_OF_RANGE:
                raise ConfigError(
                    f"the belt on {self.port} refused {name}: a value is out of range"
                )
            raise ProtocolError(
                f"the belt on {self.port} refused {name} (NAK code {int(reply.code)}); "
                "host and firmware disagree on protocol v1"
            )
        if not isinstance(reply, kind):
            raise ProtocolError(
                f"the belt on {self.port} answered {name} with {type(reply).__name__}"
            )
        return reply

    def _handshake(self) -> wire.Info:
        last: DeviceError | None = None
        for _ in range(INFO_ATTEMPTS):
            try:
                reply = self._request(wire.get_info, "the version request")
            except DeviceError as exc:
                if self._lost is not None:
                    raise
                last = exc
                continue
            info: wire.Info = self._expect(reply, wire.Info, "the version request")
            if info.protocol_version != wire.PROTOCOL_VERSION:
                from ..firmware import update_command

                fix = (update_command(self._transport.usb_port)
                       if info.protocol_version < wire.PROTOCOL_VERSION else
                       "update tactorbelt (pip install -U tactorbelt), or put this "
                       f"tactorbelt's firmware on it: {update_command(self._transport.usb_port)}")
                raise ProtocolError(
                    f"the device on {self.port} speaks protocol version {info.protocol_version} "
                    f"(firmware {info.firmware_version}); this tactorbelt speaks version "
                    f"{wire.PROTOCOL_VERSION}: {fix}"
                )
            return info
        hint = self._transport.silence_hint()
        raise DeviceError(
            f"no tactorbelt firmware answered on {self.port} "
            f"(asked {INFO_ATTEMPTS} times for its version, {self.timeout_s * 1000:.0f} ms each)"
            + (f": {hint}" if hint else "")
        ) from last

    # -- extensions ----------------------------------------------------------------
    def _mtu_text(self) -> str:
        limit = self._transport.reply_limit
        return "unknown" if limit is None else f"ATT MTU {limit + 3}"

    def _start_framing(self, limit: int, heartbeat_ms: int | None) -> None:
        """BLE with a small MTU: probe the extensions, then ask for framed replies.

        The ACK of the SET_CONFIG that turns framing on already comes framed.
        """
        if not self._probe_extensions():
            log.warning(
                "%s: the BLE link's %s is below %d and the firmware has no framed "
                "replies (plain v1): replies longer than %d bytes (INFO, STATUS of 6 "
                "tactors) cannot arrive", self.port, self._mtu_text(), BLE_MIN_MTU, limit)
            return
        hb = DEFAULT_HEARTBEAT_MS if heartbeat_ms is None else heartbeat_ms
        self._transport.use_framed_replies()
        self.framed_replies = True
        self._request(
            lambda seq: wire.set_config(seq, hb, self.max_on_ms, wire.ConfigFlag.BLE_FRAMED),
            "the switch to framed replies", expect=wire.Ack)
        log.info("%s: %s below %d: replies come framed", self.port, self._mtu_text(),
                 BLE_MIN_MTU)

    def _probe_extensions(self) -> bool:
        """GET_DIAG: True (and ``diagnostics`` set) on a device with the extensions."""
        try:
            reply = self._request(wire.get_diag, "the diagnostics request")
        except DeviceError:
            if self._lost is not None:
                raise
            log.debug("%s: no answer to GET_DIAG; taking the device as plain v1", self.port)
            return False
        if isinstance(reply, wire.Nak) and reply.code == wire.NakCode.UNKNOWN_TYPE:
            return False
        diag: wire.Diag = self._expect(reply, wire.Diag, "the diagnostics request")
        self.diagnostics = diag
        self.extensions = True
        return True

    def _warn_watchdog(self, what: str) -> None:
        self.watchdog_reset = True
        log.warning("the belt on %s %s (its firmware stopped for 300 ms and every motor "
                    "went off); look for a firmware hang or a brown-out", self.port, what)

    def _enable_flags(self) -> None:
        """SET_CONFIG with the flags byte: ONSET events (and framed BLE replies)."""
        flags = wire.ConfigFlag.ONSET_EVENTS | (
            wire.ConfigFlag.BLE_FRAMED if self.framed_replies else 0)
        hb, max_on = self.heartbeat_ms, self.max_on_ms
        self._request(lambda seq: wire.set_config(seq, hb, max_on, flags),
                      "the onset-report setting", expect=wire.Ack)
        self.onset_events = True

    def _sync_burst(self) -> None:
        for _ in range(SYNC_BURST):
            # spaced, so that a device reading its clock once per loop over waiting
            # input (the emulator) stamps each request when it arrived
            time.sleep(0.001)
            self._request(wire.get_diag, "the diagnostics request")

    def _clock_sample(self, seq: int, reply: wire.Pong | wire.Diag, recv_ns: int) -> None:
        send_ns = self._sync_sent.pop(seq, None)
        if send_ns is None:
            return
        self._last_sync_ns = recv_ns
        if isinstance(reply, wire.Diag):
            fit = self.clock_sync.fit()
            old = self.diagnostics
            if fit is not None and reply.device_time_us * 1000 + fit.offset_ns < send_ns - 1e9:
                # the device clock went back: the device restarted; recordings keep the
                # fit of the clock they were taken on
                self._end_recordings("the belt restarted", fit)
                self.clock_sync.reset()
                self._device_restarted(reply)
            elif (old is not None and reply.watchdog_reset and not old.watchdog_reset):
                self._end_recordings("the belt restarted", fit)
                self._device_restarted(reply)
            self.diagnostics = reply
            self.clock_sync.add(send_ns, recv_ns, reply.device_time_us)
        else:
            device_us = self.clock_sync.unwrap32(reply.device_time_us, send_ns, recv_ns)
            self.clock_sync.add(send_ns, recv_ns, device_us)

    def _device_restarted(self, diag: wire.Diag) -> None:
        """Seen from the transport thread: the keep-alive sets the flags again."""
        if diag.watchdog_reset:
            self._warn_watchdog("was reset by its watchdog while open")
        else:
            log.warning("the belt on %s restarted while open (reset flags 0x%02X)",
                        self.port, diag.reset_flags)
        self.onset_events = False
        self._reset_seen = True
        self._keepalive_kick.set()

    def diag(self) -> wire.Diag:
        """Ask the device for GET_DIAG now (a clock sample too); also noticing a reset.

        Raises:
            TactorbeltError: the firmware has no extensions (1.0).
        """
        self._check_open()
        if not self.extensions:
            raise TactorbeltError(f"the firmware on {self.port} ({self.firmware_version}) "
                                  "cannot report diagnostics (needs firmware 1.1)")
        diag: wire.Diag = self._request(wire.get_diag, "the diagnostics request",
                                        expect=wire.Diag)
        if self._reset_seen:
            self._restore_after_reset()
        return diag

    def _restore_after_reset(self) -> None:
        self._reset_seen = False
        with contextlib.suppress(DeviceError, ProtocolError, ConfigError):
            self._enable_flags()

    @property
    def reports_onsets(self) -> bool:
        """True while the device sends ONSET events (firmware 1.1, turned on at open)."""
        return self.onset_events

    def last_onset(self, timeout_s: float = 0.1) -> tuple[int, int] | None:
        """The device-true onset of the last stimulus start, on the host's clock.

        The start is the last PLAY_TARGET (``play``) or the first SET_AMPLITUDES while
        not streaming (after open, ``stop`` or ``play``). The device's ONSET time is
        mapped with the clock fit: ``(host_ns, uncertainty_ns)`` on
        ``time.perf_counter_ns`` (the WallClock). Waits up to ``timeout_s`` for an
        ONSET still on its way. None without ONSET events (firmware 1.0), before any
        start, or when the ONSET did not come.
        """
        with self._onset_cond:
            seq = self._onset_seq
            if seq is None or not self.onset_events:
                return None
            self._onset_cond.wait_for(lambda: seq in self._onsets or self._lost is not None,
                                      timeout_s)
            got = self._onsets.get(seq)
        if got is None:
            return None
        return self.clock_sync.to_host(got.device_time_us)

    # -- drive shaping (firmware 1.3) -----------------------------------------------------
    @property
    def can_shape(self) -> bool:
        """True when the firmware shapes the drive in its renderer (INFO capability bit 2,
        SET_DRIVE): every board with firmware 1.3 or later."""
        return self.extensions and self.info.can_shape

    @property
    def can_brake(self) -> bool:
        """True when the board reports both H-bridge inputs wired (INFO capability bit 3):
        a shaped fall reverse-drives and short-brakes; else it coasts."""
        return self.can_shape and self.info.can_brake

    @property
    def drive_summary(self) -> str:
        """What ``tactorbelt devices`` says of the drive: shaped with braking, shaped
        without (IN2 to ground), or plain only (firmware before 1.3)."""
        if not self.can_shape:
            return "plain drive only (firmware before 1.3)"
        if self.can_brake:
            return "shapes its drive and brakes (both bridge inputs wired)"
        return "shapes its drive, cannot brake (IN2 to ground)"

    def _set_drive(self, drive: str) -> None:
        """SET_DRIVE: the device shapes every level change from now on (frames and
        PLAY_TARGET alike), with its motor constants (docs/protocol.md, "SET_DRIVE")."""
        mode = int(wire.DriveMode.SHAPED if drive == "shaped" else 0)
        vectors = drive_constants(self.n_tactors, self.calibration.shaping_taus(),
                                  self._supply_v, self._kick_ms) if drive == "shaped" else None
        for v in vectors or (None,):  # None: the mode alone (the device keeps its constants)
            self._request(functools.partial(wire.set_drive, mode=mode, constants=v),
                          "SET_DRIVE", expect=wire.Ack)

    # -- the board's accelerometer (firmware 1.2) -----------------------------------------
    @property
    def senses_vibration(self) -> bool:
        """True when :meth:`sense` records the board's own accelerometer: firmware 1.2 (or
        later) whose IMU started (INFO capability bit 1)."""
        return self.extensions and self.info.can_sense

    def _no_sense_message(self, imu_failed: bool = False) -> str:
        if imu_failed:
            return (f"the IMU of the board on {self.port} (firmware {self.firmware_version}) did "
                    "not start: a Nano 33 BLE Rev1 (LSM9DS1) needs the firmware built with "
                    "TACTORBELT_IMU_LSM9DS1, a Rev2 (BMI270) the default build "
                    "(docs/hardware.md, \"The IMU\")")
        from ..firmware import update_command

        return (f"this board's firmware ({self.firmware_version} on {self.port}) cannot stream "
                f"its IMU: {update_command(self._transport.usb_port)}")

    def sense(self, duration_s: float | None = None, *, rate_hz: float | None = None,
              tactor: int | None = None) -> SenseRecording:
        """Record the board's accelerometer (SENSE_START): returns once the first samples
        arrived; the device samples until ``duration_s`` has passed or
        :meth:`SenseRecording.stop`.

        Args:
            duration_s: how long, up to an hour (None: an hour; stop it when done).
            rate_hz: the sampling rate to ask for (None: the IMU's highest, 1600 Hz on a
                Rev2 board, 952 on a Rev1); the device takes the highest it can at or
                below it. Over BLE, a lower rate keeps the link from falling behind.
            tactor: the tactor the board is on (the emulator simulates that one; a real
                board senses whatever is under it). None: not said.

        Raises:
            DeviceError: the firmware cannot stream its IMU (older than 1.2: the message
                names the upload command), the IMU did not start, or no samples came.
            ConfigError: a duration, rate or tactor out of range.
        """
        self._check_open()
        if not self.senses_vibration and (
                not self.extensions or (self.info.fw_major, self.info.fw_minor) < (1, 2)):
            raise DeviceError(self._no_sense_message())  # known without asking
        duration_ms = (wire.SENSE_MAX_DURATION_MS if duration_s is None
                       else _rounded(duration_s, 1000.0))
        if not 1 <= duration_ms <= wire.SENSE_MAX_DURATION_MS:
            raise ConfigError(f"duration_s must be 0.001 to "
                              f"{wire.SENSE_MAX_DURATION_MS // 1000} s, got {duration_s!r}")
        rate = 0 if rate_hz is None else _rounded(rate_hz, 1.0)
        if rate_hz is not None and not 1 <= rate <= 0xFFFF:
            raise ConfigError(f"rate_hz must be 1 to 65535 Hz, got {rate_hz!r}")
        if tactor is not None and (isinstance(tactor, bool) or not isinstance(tactor, int)
                                   or not 0 <= tactor < self.n_tactors):
            raise ConfigError(f"tactor must be an index 0..{self.n_tactors - 1}, got {tactor!r}")
        rec = SenseRecording(self, tactor, duration_ms / 1000.0)
        t = wire.SENSE_ANY_TACTOR if tactor is None else tactor

        def build(seq: int) -> wire.Packet:
            rec.seq = seq
            with self._sense_lock:
                self._recordings[seq] = rec
                self._all_recordings.add(rec)
            return wire.sense_start(seq, rate, duration_ms, t)

        what = "the sensing request"
        try:
            # without the capability bit, a firmware 1.2 says why: NAK 6 (its IMU did not
            # start) or NAK 2 (a build without SENSE)
            reply = self._request(build, what)
            if isinstance(reply, wire.Nak) and reply.code == wire.NakCode.UNKNOWN_TYPE:
                raise DeviceError(self._no_sense_message())
            if isinstance(reply, wire.Nak) and reply.code == wire.NakCode.UNAVAILABLE:
                raise DeviceError(self._no_sense_message(imu_failed=True))
            self._expect(reply, wire.Ack, what)
        except BaseException:
            with self._sense_lock:
                self._recordings.pop(rec.seq, None)
            raise
        with self._sense_lock:
            # a recording running before ends on the device now (its last batch comes)
            self._sensing = rec
        with rec._cond:
            got = rec._cond.wait_for(lambda: rec._first or rec._broken is not None,
                                     SENSE_FIRST_TIMEOUT_S)
        if not got or not rec._first:
            rec._end("no samples came")
            raise DeviceError(f"the belt on {self.port} accepted the sensing request but sent "
                              f"no samples within {SENSE_FIRST_TIMEOUT_S:g} s")
        return rec

    def _stop_sensing(self, rec: SenseRecording) -> None:
        """SENSE_STOP for ``rec`` when it is the device's current session (a newer one has
        already ended it on the device)."""
        with self._sense_lock:
            current = self._sensing is rec
        if not current or self._closed or self._lost is not None:
            return
        self._request(wire.sense_stop, "the end of sensing", expect=wire.Ack)
        with self._sense_lock:
            if self._sensing is rec:
                self._sensing = None

    # -- keep-alive --------------------------------------------------------------
    @property
    def keepalive_running(self) -> bool:
        """True while the keep-alive thread runs."""
        t = self._keepalive_thread
        return t is not None and t.is_alive()

    def start_keepalive(self) -> None:
        """Start the keep-alive thread (it starts on open unless ``keepalive=False``)."""
        if self.keepalive_running:
            return
        self._keepalive_stop = threading.Event()
        self._keepalive_kick = threading.Event()
        self._last_rx_ns = time.monotonic_ns()
        self._unanswered_pings = 0
        self._first_ping_ns = 0
        t = threading.Thread(
            target=self._keepalive_loop, args=(self._keepalive_stop, self._keepalive_kick),
            name=f"tactorbelt-keepalive {self.port}", daemon=True,
        )
        self._keepalive_thread = t
        t.start()

    def stop_keepalive(self) -> None:
        """Stop the keep-alive thread: the device's failsafe fires unless frames keep coming.

        Meant for tests and diagnostics of the failsafe.
        """
        self._keepalive_stop.set()
        self._keepalive_kick.set()
        t = self._keepalive_thread
        if t is not None and t is not threading.current_thread():
            t.join()
        self._keepalive_thread = None

    def _transport_has_unread(self) -> bool:
        try:
            return self._transport.unread_bytes() > 0
        except Exception:  # a link that cannot say (a closed port): it decides nothing
            return False

    def _keepalive_loop(self, stop: threading.Event, kick: threading.Event) -> None:
        while True:
            hb_s = self.heartbeat_ms / 1000.0
            kick.wait(hb_s / 3.0)  # set_config kicks it: a shorter timeout applies at once
            kick.clear()
            if stop.is_set() or self._lost is not None:
                return
            now_ns = time.monotonic_ns()
            silent_s = (now_ns - self._last_rx_ns) / 1e9
            # Lost only when pings that really went out (not ones still waiting behind a
            # 1 kHz stream for the write lock, or a host that was itself starved of CPU)
            # have gone unanswered for a whole heartbeat timeout.
            pinged_s = (now_ns - self._first_ping_ns) / 1e9 if self._unanswered_pings else 0.0
            # Nor while the device's bytes wait unread: the host's reader was starved,
            # the belt answered.
            if silent_s >= hb_s and self._unanswered_pings >= 2 and pinged_s >= hb_s \
                    and not self._transport_has_unread():
                self._mark_lost(
                    f"belt on {self.port} stopped answering: no reply for "
                    f"{silent_s * 1000:.0f} ms (heartbeat timeout {self.heartbeat_ms} ms)"
                )
                return
            try:
                if self._reset_seen:
                    self._restore_after_reset()
                    continue
                if silent_s >= hb_s / 3.0:
                    self._send(functools.partial(wire.ping, nonce=self._unanswered_pings + 1))
                    if self._unanswered_pings == 0:
                        self._first_ping_ns = time.monotonic_ns()
                    self._unanswered_pings += 1
                elif self.extensions and (
                        time.perf_counter_ns() - self._last_sync_ns >= SYNC_INTERVAL_S * 1e9):
                    self._send(wire.get_diag)
                else:
                    self._send(wire.heartbeat)
            except DeviceError:
                return

    # -- Belt backend --------------------------------------------------------------
    def _write_levels(self, levels: NDArray[np.float64]) -> None:
        # wire.amplitude_to_level value by value: on a frame of a few tactors, plain floats
        # cost less than NumPy's calls on the whole frame (which gave the same levels)
        lv = [wire.amplitude_to_level(a) for a in np.asarray(levels, dtype=float).tolist()]
        starts = not self._streaming
        self._send(lambda seq: wire.set_amplitudes(seq, lv), onset=starts)
        self._streaming = True

    def _write_stop(self) -> None:
        try:
            self._streaming = False
            self._request(wire.stop_all, "the stop", max(STOP_TIMEOUT_S, self.timeout_s),
                          wire.Ack)
        except DeviceError as exc:
            if not self._closing:
                raise
            if self._lost is not None:  # the port may still be open: one last try, no wait
                with contextlib.suppress(Exception), self._tx_lock:
                    seq = next(self._seq) & 0xFF
                    self._transport.write(self._transport.encode(wire.stop_all(seq)))
            log.warning("could not stop the motors of the belt on %s: %s "
                        "(its failsafe turns them off within %d ms)",
                        self.port, exc, self.heartbeat_ms)

    def _device_renders(self, stimulus: Stimulus | None) -> bool:
        if not self._can_play_target:
            return False
        if stimulus is not None:
            try:  # what PLAY_TARGET can carry: a known law and mode, timings that fit
                _play_args(stimulus, None)
            except ConfigError:
                return False
        return True

    def _write_play(self, stimulus: Stimulus, duration_s: float | None) -> None:
        args = _play_args(stimulus, duration_s)
        self._streaming = False
        self._request(lambda seq: wire.play_target(seq, *args), "the play command",
                      expect=wire.Ack, onset=True)

    def _close(self) -> None:
        closed_before_exit(self)
        self._end_recordings("the belt was closed", self.clock_sync.fit())
        self.stop_keepalive()
        self._transport.close()
        self._mark_lost(f"belt on {self.port} is closed")

    # -- device-level requests -------------------------------------------------------
    def ping(self) -> float:
        """Round trip of a PING to the device, in seconds.

        Raises:
            DeviceError: no PONG within the timeout, or the belt is lost.
        """
        self._check_open()
        nonce = random.getrandbits(32)
        t0 = time.perf_counter()
        reply = self._request(lambda seq: wire.ping(seq, nonce), "a ping")
        rtt = time.perf_counter() - t0
        pong: wire.Pong = self._expect(reply, wire.Pong, "a ping")
        if pong.nonce != nonce:
            raise ProtocolError(f"the belt on {self.port} answered a ping with the wrong number")
        return rtt

    def status(self) -> wire.Status:
        """The device's state, error counters and output levels (GET_STATUS)."""
        self._check_open()
        status: wire.Status = self._request(wire.get_status, "the status request",
                                            expect=wire.Status)
        return status

    def set_config(self, heartbeat_ms: int, max_on_ms: int | None = None) -> None:
        """Set the device's heartbeat timeout and, optionally, its continuous-on limit.

        Args:
            heartbeat_ms: 50..2000 ms without a valid packet before the device turns
                every output off (the failsafe).
            max_on_ms: 100..600000 ms a channel may stay on without a break.

        Raises:
            ConfigError: a value out of range (checked here and by the device).
        """
        checked_int("heartbeat_ms", heartbeat_ms, 50, 2000)
        if max_on_ms is not None:
            checked_int("max_on_ms", max_on_ms, 100, 600_000)
        self._check_open()
        self._request(lambda seq: wire.set_config(seq, heartbeat_ms, max_on_ms),
                      "the new settings (heartbeat, longest on-time)", expect=wire.Ack)
        self.heartbeat_ms = heartbeat_ms
        if max_on_ms is not None:
            self.max_on_ms = max_on_ms
        self._keepalive_kick.set()

    @property
    def lost(self) -> str | None:
        """Why the belt was lost (None while it answers)."""
        return self._lost

    @property
    def host_crc_errors(self) -> int:
        """Frames from the device dropped for a bad CRC."""
        return self._transport.crc_errors

    @property
    def host_framing_errors(self) -> int:
        """Frames from the device dropped for bad framing or length."""
        return self._transport.framing_errors


def drive_constants(n: int, taus: tuple[tuple[float, ...], tuple[float, ...],
                                        tuple[float, ...]] | None,
                    supply_v: float | None, kick_ms: float = 0.0
                    ) -> list[wire.DriveConstants] | None:
    """The SET_DRIVE vectors that give a board's shaper the host's motor constants: the
    time constants ``validate onsets --tune`` fitted (``taus``: the calibration's
    :meth:`~tactorbelt.devices.calibration.Calibration.shaping_taus`) and the rated level
    of a motor supply ``supply_v`` (the rated voltage over it; its kick, at the full duty,
    bounded by :meth:`~tactorbelt.devices.erm.ErmParams.kick_overdrive`). One vector for
    every tactor (0xFF) when they share their constants, else one per tactor; None when
    nothing differs from the device's defaults (neither given).

    Raises:
        ConfigError: a supply above the motor's maximum voltage without a ``kick_ms`` that
            covers a kick at it (the board kicks at its full duty: the supply).
    """
    if taus is None and supply_v is None:
        return None
    p = ErmParams()
    rise, fall, brake = taus if taus is not None else (
        (p.rise_tau_s,) * n, (p.fall_tau_s,) * n, (p.brake_tau_s,) * n)
    rated = 1.0
    if supply_v is not None:
        k = p.kick_overdrive(float(supply_v), kick_ms, rise)
        if float(supply_v) > k * p.rated_voltage_v * (1 + 1e-9):
            raise ConfigError(
                f"a board kicks at its full duty, the {supply_v:g} V supply, above the motor's "
                f"maximum {p.max_voltage_v:g} V: give kick_ms (how long a kick may apply it) "
                "or a supply at most the maximum")
        rated = min(1.0, p.rated_voltage_v / float(supply_v))
    lo, hi = wire.DRIVE_TAU_RANGE

    def tau(x: float) -> int:
        return min(hi, max(lo, round(x * 1e4)))

    rated_lv = max(1, min(65535, round(rated * 65535)))
    start_lv = min(rated_lv - 1, round(p.start_level * rated * 65535))
    rows = [(tau(r), tau(f), tau(b)) for r, f, b in zip(rise, fall, brake, strict=True)]
    if len(rows) != n:
        raise ConfigError(f"the shaping has time constants for {len(rows)} tactors, the "
                          f"belt {n}")
    targets = [(wire.DRIVE_ALL_TACTORS, rows[0])] if len(set(rows)) == 1 else list(
        enumerate(rows))
    return [wire.DriveConstants(t, start_lv, rated_lv, *row) for t, row in targets]


def probe(row: Found, open_: Callable[[], FirmwareBelt]) -> None:
    """Open a belt, note its version, tactor count, version note and what its drive can
    do in ``row`` (``tactorbelt devices``), close it; the error in ``row.note`` when it
    does not open. Never raises."""
    from ..firmware import version_note

    try:
        belt = open_()
    except TactorbeltError as exc:
        row.note = str(exc)
        return
    with belt:
        row.firmware_version, row.tactors = belt.firmware_version, belt.n_tactors
        row.note = version_note(belt.firmware_version, belt._transport.usb_port)
        row.drive = belt.drive_summary
