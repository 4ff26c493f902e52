"""Protocol v1 on the wire: packets, CRC, COBS framing, and every message of it
(the extensions too: GET_DIAG/DIAG, ONSET, the SET_CONFIG flags, NAK 5, and the
board's accelerometer: SENSE_START, SENSE_STOP, SENSE_DATA, NAK 6).

The contract is ``docs/protocol.md``; the firmware (``firmware/``) implements the
same contract in C++ and shares nothing with this module but that document and the
test vectors in ``firmware/test/vectors.json``.

- A packet is ``type u8, seq u8, payload, crc u16 LE`` (at most 64 bytes), the CRC
  being CRC-16/CCITT-FALSE over type, seq and payload.
- Serial: each packet is COBS-encoded and followed by one 0x00
  (:func:`encode_frame`, :class:`FrameDecoder`). BLE: the packet goes unframed
  (:func:`encode_packet`, :func:`decode_packet`).
- Builders (:func:`ping`, :func:`set_amplitudes`, ...) return a :class:`Packet`;
  :func:`parse_reply` turns a Packet into a frozen dataclass. The device's side (parse a
  request, encode a reply), with which tests play the device, is
  ``tests/support/wire_device.py``.

Builders check that each value fits its field (u8, u16, u32) and raise
:class:`~tactorbelt.ConfigError` otherwise; they do not check the ranges the device
enforces (mode, law, heartbeat timeout), so that those NAKs can be tested. Bytes that
break the protocol raise :class:`~tactorbelt.ProtocolError`.

Pure: imports only the standard library and tactorbelt._errors.
"""

from __future__ import annotations

import enum
import functools
import math
import struct
from binascii import crc_hqx as _crc_hqx
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from typing import Any

from .._errors import ConfigError, ProtocolError

__all__ = [
    "MAX_ENCODED_PACKET",
    "MAX_PACKET",
    "MAX_PAYLOAD",
    "MIN_PACKET",
    "PROTOCOL_VERSION",
    "SENSE_ANY_TACTOR",
    "SENSE_MAX_DURATION_MS",
    "SENSE_MAX_SAMPLES",
    "Ack",
    "Capability",
    "ConfigFlag",
    "Diag",
    "DriveConstants",
    "DriveMode",
    "FrameDecoder",
    "Info",
    "Law",
    "Mode",
    "MsgType",
    "Nak",
    "NakCode",
    "Onset",
    "Packet",
    "Pong",
    "Reply",
    "ResetFlag",
    "SenseData",
    "SenseFlag",
    "State",
    "Status",
    "amplitude_to_level",
    "angle_to_cdeg",
    "cobs_decode",
    "cobs_encode",
    "crc16_ccitt_false",
    "decode_packet",
    "encode_frame",
    "encode_packet",
    "get_diag",
    "get_info",
    "get_status",
    "heartbeat",
    "parse_reply",
    "ping",
    "play_target",
    "sense_start",
    "sense_stop",
    "set_amplitudes",
    "set_config",
    "set_drive",
    "stop_all",
]

PROTOCOL_VERSION = 1
#: Longest packet (type, seq, payload, crc) before framing.
MAX_PACKET = 64
#: Shortest packet: type, seq and crc.
MIN_PACKET = 4
MAX_PAYLOAD = MAX_PACKET - MIN_PACKET
#: Longest COBS encoding of a packet (the 0x00 delimiter not counted).
MAX_ENCODED_PACKET = MAX_PACKET + MAX_PACKET // 254 + 1
#: SENSE_START's tactor when the host does not say which tactor the board is on.
SENSE_ANY_TACTOR = 0xFF
#: The longest SENSE_START duration (one hour).
SENSE_MAX_DURATION_MS = 3_600_000
#: SENSE_DATA header: session seq, flags, first index u32, t0 u64, period u16, full scale u16.
SENSE_DATA_HEADER = 18
#: Samples (x, y, z int16) in one SENSE_DATA: as many as fit a 64-byte packet.
SENSE_MAX_SAMPLES = (MAX_PAYLOAD - SENSE_DATA_HEADER) // 6


class MsgType(enum.IntEnum):
    """Packet types: host-to-device requests below 0x80, replies from 0x80."""

    PING = 0x01
    GET_INFO = 0x02
    SET_AMPLITUDES = 0x10
    STOP_ALL = 0x11
    PLAY_TARGET = 0x12
    HEARTBEAT = 0x14
    SET_CONFIG = 0x15
    GET_STATUS = 0x16
    GET_DIAG = 0x17
    SENSE_START = 0x18
    SENSE_STOP = 0x19
    SET_DRIVE = 0x1A
    ACK = 0x80
    PONG = 0x81
    INFO = 0x82
    STATUS = 0x83
    DIAG = 0x84
    ONSET = 0x85
    SENSE_DATA = 0x86
    NAK = 0x8F


class NakCode(enum.IntEnum):
    """Why the device refused a request."""

    UNKNOWN_TYPE = 2
    BAD_LENGTH = 3
    OUT_OF_RANGE = 4
    #: BLE only: the reply does not fit the ATT MTU (the request was carried out).
    REPLY_TOO_LONG = 5
    #: The device knows the request but its hardware did not start (SENSE_START on a
    #: board whose IMU did not answer).
    UNAVAILABLE = 6


class State(enum.IntEnum):
    """The device state reported in STATUS."""

    IDLE = 0
    STREAMING = 1
    PLAYING = 2
    FAILSAFE = 3


class Mode(enum.IntEnum):
    """PLAY_TARGET mode."""

    STATIC = 0
    DYNAMIC = 1


class Law(enum.IntEnum):
    """PLAY_TARGET amplitude law."""

    PAPER = 0
    LINEAR = 1
    ENERGY = 2


class Capability(enum.IntFlag):
    """INFO capability bits. WATCHDOG_RESET is a status bit: the last reset was the
    watchdog's (extensions). SENSE (firmware 1.2): the board's accelerometer started and
    SENSE_START streams it."""

    PLAY_TARGET = 0x01
    SENSE = 0x02
    #: firmware 1.3: SET_DRIVE shapes the drive on the device (overdrive kicks).
    SHAPE = 0x04
    #: firmware 1.3: both H-bridge inputs are wired, so a shaped fall brakes.
    BRAKE = 0x08
    WATCHDOG_RESET = 0x80


class ConfigFlag(enum.IntFlag):
    """SET_CONFIG flags (the optional 7th byte; extensions). Cleared when the link closes."""

    ONSET_EVENTS = 0x01
    BLE_FRAMED = 0x02


class DriveMode(enum.IntFlag):
    """SET_DRIVE mode bits (firmware 1.3); 0 is the plain drive, the device's default
    after power-up and after every link close."""

    SHAPED = 0x01
    #: shaped, but a fall coasts instead of braking
    NO_BRAKE = 0x02


class SenseFlag(enum.IntFlag):
    """SENSE_DATA flags."""

    #: The session ended with this batch (its duration passed, or SENSE_STOP).
    LAST = 0x01
    #: Samples before this batch were lost on the device (its queue was full, a read
    #: failed); their indices are skipped.
    DROPPED = 0x02


class ResetFlag(enum.IntFlag):
    """DIAG ``reset_flags``: why the device last reset (0 after power-on)."""

    PIN = 0x01
    WATCHDOG = 0x02
    SOFTWARE = 0x04
    LOCKUP = 0x08
    OTHER = 0x80


def _uint(name: str, value: int, bits: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise ConfigError(f"{name} must be an integer, got {value!r}")
    if not 0 <= value < (1 << bits):
        raise ConfigError(f"{name} must be in 0..{(1 << bits) - 1} (u{bits}), got {value}")
    return value


#: The bits of a struct field, by its format character.
_BITS = {"B": 8, "H": 16, "I": 32, "Q": 64}


def _pack(layout: struct.Struct, values: Mapping[str, int]) -> bytes:
    """The first of ``values`` (name: value, in order) packed by ``layout``, each checked
    to fit its field (u8 to u64)."""
    return layout.pack(*[_uint(name, v, _BITS[c]) for (name, v), c in
                         zip(values.items(), layout.format[1:], strict=False)])


@dataclass(frozen=True)
class Packet:
    """One protocol packet: type, sequence number and payload (the CRC is implicit)."""

    type: int
    seq: int
    payload: bytes = b""

    def __post_init__(self) -> None:
        _uint("packet type", self.type, 8)
        _uint("packet seq", self.seq, 8)
        if not isinstance(self.payload, bytes | bytearray | memoryview):
            raise ConfigError(f"packet payload must be bytes, got {type(self.payload).__name__}")
        object.__setattr__(self, "payload", bytes(self.payload))
        if len(self.payload) > MAX_PAYLOAD:
            raise ConfigError(
                f"packet payload is {len(self.payload)} bytes; at most {MAX_PAYLOAD} fit"
            )


# --- CRC and COBS -------------------------------------------------------------------
#
# The functions the host uses run per packet in C (binascii.crc_hqx, bytes.split,
# bytes.join); tests/support/wire_reference.py holds the per-byte definitions the tests
# compare them with (tests/test_wire.py).


def crc16_ccitt_false(data: bytes) -> int:
    """CRC-16/CCITT-FALSE: poly 0x1021, init 0xFFFF, no reflection, no final xor
    (computed in C by :func:`binascii.crc_hqx`)."""
    return _crc_hqx(data, 0xFFFF)


#: ``_CODE[n]`` is the COBS code byte of a block of ``n`` data bytes.
_CODE = tuple(bytes((n + 1,)) for n in range(255))


def cobs_encode(data: bytes) -> bytes:
    """COBS-encode ``data`` (the result holds no 0x00; the delimiter is not added).

    A run of 254 non-zero bytes that ends the data is not followed by an empty block.
    """
    runs = bytes(data).split(b"\x00")
    if len(runs) == 1 and len(runs[0]) < 0xFF - 1:  # no 0x00, short: one block
        return _CODE[len(data)] + data
    out: list[bytes] = []
    last = len(runs) - 1
    for k, run in enumerate(runs):
        n = len(run)
        start = 0
        while n - start >= 0xFE:
            out.append(b"\xff")
            out.append(run[start:start + 0xFE])
            start += 0xFE
        if start and start == n and k == last:
            break  # a full block ends the data: no empty block after it
        out.append(_CODE[n - start])
        out.append(run[start:])
    return b"".join(out)


def cobs_decode(data: bytes) -> bytes:
    """Decode one COBS block sequence (without the 0x00 delimiter).

    Raises:
        ProtocolError: a 0x00 inside the data, or a code that runs past the end.
    """
    data = bytes(data)
    n = len(data)
    if n and data[0] == n and 0 not in data:  # one block, no 0x00 in the packet
        return data[1:]
    zeros = 0 in data
    parts: list[bytes] = []
    i = 0
    while i < n:
        code = data[i]
        if code == 0:
            raise ProtocolError(f"COBS: unexpected 0x00 at byte {i}")
        end = i + code
        if end > n:
            raise ProtocolError(f"COBS: block at byte {i} runs past the end ({n} bytes)")
        block = data[i + 1:end]
        if zeros and 0 in block:
            raise ProtocolError(f"COBS: unexpected 0x00 at byte {i + 1 + block.index(0)}")
        parts.append(block)
        i = end
        if code != 0xFF and i < n:
            parts.append(b"\x00")
    return b"".join(parts)


# --- packets and frames -------------------------------------------------------------

_CRC = struct.Struct("<H")

_new_packet = object.__new__
_set = object.__setattr__


def _packet(type_: int, seq: int, payload: bytes) -> Packet:
    """A Packet from fields already known to fit (u8, u8, bytes of at most 60)."""
    p = _new_packet(Packet)
    _set(p, "__dict__", {"type": type_, "seq": seq, "payload": payload})
    return p


def encode_packet(p: Packet) -> bytes:
    """``type, seq, payload, crc16 LE``: the unframed packet (one BLE write)."""
    body = bytes((p.type, p.seq)) + p.payload
    return body + _CRC.pack(_crc_hqx(body, 0xFFFF))


def decode_packet(raw: bytes) -> Packet:
    """Check the length and CRC of an unframed packet.

    Raises:
        ProtocolError: fewer than 4 or more than 64 bytes, or a CRC mismatch.
    """
    raw = bytes(raw)
    if not MIN_PACKET <= len(raw) <= MAX_PACKET:
        raise ProtocolError(
            f"packet of {len(raw)} bytes; a packet has {MIN_PACKET} to {MAX_PACKET} bytes"
        )
    expected = _crc_hqx(raw[:-2], 0xFFFF)
    (crc,) = _CRC.unpack_from(raw, len(raw) - 2)
    if crc != expected:
        raise ProtocolError(f"bad CRC: got 0x{crc:04X}, computed 0x{expected:04X}")
    return _packet(raw[0], raw[1], raw[2:-2])


def encode_frame(p: Packet) -> bytes:
    """``COBS(encode_packet(p)) + b"\\x00"``: one packet on the serial link."""
    body = bytes((p.type, p.seq)) + p.payload
    raw = body + _CRC.pack(_crc_hqx(body, 0xFFFF))
    if 0 in raw:
        return cobs_encode(raw) + b"\x00"
    return _CODE[len(raw)] + raw + b"\x00"  # no 0x00 (and at most 64 bytes): one block


class FrameDecoder:
    """Incremental decoder for the serial link: feed bytes, get packets.

    A frame is everything up to a 0x00. Empty frames are ignored (a host may send a
    0x00 to flush). A frame longer than :data:`MAX_ENCODED_PACKET` bytes, not valid
    COBS, or shorter than 4 bytes counts as a framing error; a bad CRC as a CRC
    error. Errors are counted, never raised, and the decoder resynchronises at the
    next 0x00. The firmware decoder follows the same rules.

    Attributes:
        crc_errors: frames dropped for a bad CRC.
        framing_errors: frames dropped for bad framing or length.
    """

    def __init__(self) -> None:
        self.crc_errors = 0
        self.framing_errors = 0
        self._buf = b""
        self._overflow = False

    def feed(self, data: bytes) -> list[Packet]:
        """Consume bytes; return the packets completed by them, in order."""
        if type(data) is not bytes:
            data = bytes(data)
        frames = data.split(b"\x00")
        # frames[:-1] end with a 0x00; frames[-1] is the start of the next frame
        tail = frames.pop()
        packets: list[Packet] = []
        if frames:
            if self._buf or self._overflow:
                if self._overflow:
                    frames[0] = b""
                    self.framing_errors += 1
                else:
                    frames[0] = self._buf + frames[0]
                self._buf, self._overflow = b"", False
            for frame in frames:
                n = len(frame)
                if not n:
                    continue  # an empty frame: a flush
                if n > MAX_ENCODED_PACKET:
                    self.framing_errors += 1
                    continue
                if frame[0] == n:  # one COBS block: the packet holds no 0x00
                    body = frame[1:-2]
                    crc = frame[-2:]
                else:
                    try:
                        raw = cobs_decode(frame)
                    except ProtocolError:
                        self.framing_errors += 1
                        continue
                    body = raw[:-2]
                    crc = raw[-2:]
                if not MIN_PACKET - 2 <= len(body) <= MAX_PACKET - 2:
                    self.framing_errors += 1
                elif _CRC.pack(_crc_hqx(body, 0xFFFF)) != crc:
                    self.crc_errors += 1
                else:
                    packets.append(_packet(body[0], body[1], body[2:]))
        if tail and not self._overflow:
            if len(self._buf) + len(tail) > MAX_ENCODED_PACKET:
                self._buf, self._overflow = b"", True
            else:
                self._buf += tail
        return packets


# --- values ---------------------------------------------------------------------------


def amplitude_to_level(a: float) -> int:
    """Amplitude in [0, 1] to a drive level 0..65535: ``floor(a*65535 + 0.5)``, clamped.

    Raises:
        ConfigError: NaN (a ValueError; hiding it as 0 would hide a bug).
    """
    a = float(a)
    if math.isnan(a):
        raise ConfigError("amplitude is NaN; expected a number in [0, 1]")
    if a <= 0.0:
        return 0
    if a >= 1.0:
        return 65535
    return math.floor(a * 65535.0 + 0.5)


def angle_to_cdeg(angle_deg: float) -> int:
    """Degrees to centidegrees in 0..35999 (rounded, normalised).

    Raises:
        ConfigError: a non-finite angle.
    """
    a = float(angle_deg)
    if not math.isfinite(a):
        raise ConfigError(f"angle must be a finite number of degrees, got {angle_deg!r}")
    return round(a * 100.0) % 36000


# --- requests (host to device) --------------------------------------------------------

_PLAY_TARGET = struct.Struct("<HBBHHHI")
_SENSE_START = struct.Struct("<HIB")
#: ``_LEVELS[n]`` packs the payload of SET_AMPLITUDES with ``n`` levels.
_LEVELS = tuple(struct.Struct(f"<{n}H") for n in range(MAX_PAYLOAD // 2 + 1))
_SET_AMPLITUDES = MsgType.SET_AMPLITUDES


def ping(seq: int, nonce: int) -> Packet:
    """PING: the device answers PONG with the nonce and its clock."""
    return Packet(MsgType.PING, seq, struct.pack("<I", _uint("nonce", nonce, 32)))


# The requests without a payload: ``get_info(seq)`` is ``Packet(MsgType.GET_INFO, seq)``.
#: GET_INFO: the device answers INFO.
get_info = functools.partial(Packet, MsgType.GET_INFO)
#: STOP_ALL: every output off, state idle; the device answers ACK.
stop_all = functools.partial(Packet, MsgType.STOP_ALL)
#: HEARTBEAT: pushes the failsafe deadline; no reply.
heartbeat = functools.partial(Packet, MsgType.HEARTBEAT)
#: GET_STATUS: the device answers STATUS.
get_status = functools.partial(Packet, MsgType.GET_STATUS)
#: GET_DIAG (extensions): the device answers DIAG; a plain v1 device NAKs code 2.
get_diag = functools.partial(Packet, MsgType.GET_DIAG)
#: SENSE_STOP (firmware 1.2): the session ends now (its last batch comes with
#: :attr:`SenseFlag.LAST`); ACK, also when none runs.
sense_stop = functools.partial(Packet, MsgType.SENSE_STOP)


def set_amplitudes(seq: int, levels: Sequence[int]) -> Packet:
    """SET_AMPLITUDES: one level per channel, 0 (off) to 65535 (full). No reply."""
    n = len(levels)
    if n <= MAX_PAYLOAD // 2 and type(seq) is int and 0 <= seq <= 0xFF:
        for v in levels:
            if type(v) is not int:  # bool, float, NumPy: the checks below word the error
                break
        else:
            try:
                return _packet(_SET_AMPLITUDES, seq, _LEVELS[n].pack(*levels))
            except struct.error:
                pass  # a level out of range: the checks below word the error
    values = [_uint(f"level {k}", v, 16) for k, v in enumerate(levels)]
    if 2 * len(values) > MAX_PAYLOAD:
        raise ConfigError(f"{len(values)} levels do not fit in one packet (at most 30)")
    return Packet(MsgType.SET_AMPLITUDES, seq, struct.pack(f"<{len(values)}H", *values))


def play_target(
    seq: int,
    angle_cdeg: int,
    mode: int,
    law: int,
    falloff_cdeg: int,
    period_ms: int,
    transit_ms: int,
    duration_ms: int,
) -> Packet:
    """PLAY_TARGET: the device renders the stimulus itself at 1 kHz; answers ACK."""
    return Packet(MsgType.PLAY_TARGET, seq, _pack(_PLAY_TARGET, dict(
        angle_cdeg=angle_cdeg, mode=mode, law=law, falloff_cdeg=falloff_cdeg,
        period_ms=period_ms, transit_ms=transit_ms, duration_ms=duration_ms)))


def set_config(seq: int, heartbeat_ms: int, max_on_ms: int | None = None,
               flags: int | None = None) -> Packet:
    """SET_CONFIG: heartbeat timeout (50..2000 ms) and, optionally, the longest
    continuous-on time per channel (100..600000 ms) and the flags byte (extensions:
    :class:`ConfigFlag`; needs ``max_on_ms``). ACK, or NAK when out of range."""
    if flags is not None and max_on_ms is None:
        raise ConfigError("SET_CONFIG flags need max_on_ms (the flags are the 7th byte)")
    given = {k: v for k, v in (("heartbeat_ms", heartbeat_ms), ("max_on_ms", max_on_ms),
                               ("flags", flags)) if v is not None}  # the first 2, 6 or 7 bytes
    return Packet(MsgType.SET_CONFIG, seq, _pack(struct.Struct("<HIB"[:1 + len(given)]), given))


def sense_start(seq: int, rate_hz: int, duration_ms: int,
                tactor: int = SENSE_ANY_TACTOR) -> Packet:
    """SENSE_START (firmware 1.2): ACK, then SENSE_DATA batches until ``duration_ms`` has
    passed or SENSE_STOP; NAK 2 from a firmware without it, NAK 6 when the board's IMU did
    not start, NAK 4 for a duration of 0 or above an hour or a tactor the belt lacks."""
    return Packet(MsgType.SENSE_START, seq, _pack(_SENSE_START, dict(
        rate_hz=rate_hz, duration_ms=duration_ms, tactor=tactor)))


#: SET_DRIVE's motor constants: tactor, start and rated levels, rise, fall and brake
#: time constants (units of 100 us).
_SET_DRIVE_CONSTANTS = struct.Struct("<BHHHHH")
#: SET_DRIVE's tactor that names every tactor at once.
DRIVE_ALL_TACTORS = 0xFF
#: The time constants SET_DRIVE carries (units of 100 us): 1 ms .. 6 s.
DRIVE_TAU_RANGE = (10, 60_000)


@dataclass(frozen=True)
class DriveConstants:
    """One SET_DRIVE vector: a tactor's motor constants for the device's shaper.

    ``start`` and ``rated`` are levels (65535 = full duty): the dead zone and the duty of
    the motor's rated voltage (a shaped level is held at most there; only a kick, at most
    ``rise_tau * ln(1 / (1 - rated))`` plus a tick, goes above it). The time constants are
    in units of 100 us. ``tactor`` 0xFF (:data:`DRIVE_ALL_TACTORS`): every tactor."""

    tactor: int
    start: int
    rated: int
    rise_tau: int
    fall_tau: int
    brake_tau: int

    def pack(self) -> bytes:
        lo, hi = DRIVE_TAU_RANGE
        for name in ("rise_tau", "fall_tau", "brake_tau"):
            v = getattr(self, name)
            if not (isinstance(v, int) and lo <= v <= hi):
                raise ConfigError(f"SET_DRIVE {name} must be {lo}..{hi} (100 us), got {v!r}")
        if not 0 <= self.start < self.rated:
            raise ConfigError(f"SET_DRIVE start ({self.start}) must be below rated "
                              f"({self.rated})")
        return _pack(_SET_DRIVE_CONSTANTS, asdict(self))


def set_drive(seq: int, mode: int, constants: DriveConstants | None = None) -> Packet:
    """SET_DRIVE (firmware 1.3): the mode byte (:class:`DriveMode`) alone (the device keeps
    its motor constants), or with one tactor's constants (or every tactor's: tactor 0xFF;
    docs/protocol.md, "SET_DRIVE"). ACK; NAK 2 from a firmware without shaping (INFO
    without :attr:`Capability.SHAPE`), NAK 4 for a tactor the belt lacks."""
    payload = bytes([_uint("mode", mode, 8)])
    if constants is not None:
        payload += constants.pack()
    return Packet(MsgType.SET_DRIVE, seq, payload)


def _expect_len(p: Packet, name: str, *sizes: int) -> None:
    if len(p.payload) not in sizes:
        want = " or ".join(str(s) for s in sizes)
        raise ProtocolError(f"{name}: payload of {len(p.payload)} bytes, expected {want}")


def _counted(p: Packet, name: str, head: int, size: int) -> int:
    """How many items of ``size`` bytes follow the ``head`` bytes of a packet's payload."""
    n, odd = divmod(len(p.payload) - head, size)
    if len(p.payload) < head or odd:
        raise ProtocolError(f"{name}: payload of {len(p.payload)} bytes, expected {head} + "
                            f"{size}*N")
    return n


def _unpack_fixed(p: Packet, kind: type[Any], layout: struct.Struct) -> Any:
    """A packet whose payload is one struct, as ``kind`` of its fields."""
    _expect_len(p, MsgType(p.type).name, layout.size)
    return kind(*layout.unpack(p.payload))


# --- replies (device to host) ---------------------------------------------------------


@dataclass(frozen=True)
class Pong:
    nonce: int
    device_time_us: int


@dataclass(frozen=True)
class Info:
    """What GET_INFO tells: versions, channels, PWM resolution, timeout, tactor angles."""

    protocol_version: int
    fw_major: int
    fw_minor: int
    fw_patch: int
    channels: int
    pwm_steps: int
    heartbeat_ms: int
    capabilities: int
    tactor_angles_deg: tuple[float, ...]

    @property
    def firmware_version(self) -> str:
        """``"major.minor.patch"``."""
        return f"{self.fw_major}.{self.fw_minor}.{self.fw_patch}"

    @property
    def can_play_target(self) -> bool:
        """True when the device renders PLAY_TARGET itself."""
        return bool(self.capabilities & Capability.PLAY_TARGET)

    @property
    def can_sense(self) -> bool:
        """True when SENSE_START streams the board's accelerometer (firmware 1.2, its IMU
        started)."""
        return bool(self.capabilities & Capability.SENSE)

    @property
    def can_shape(self) -> bool:
        """True when SET_DRIVE shapes the drive on the device (firmware 1.3)."""
        return bool(self.capabilities & Capability.SHAPE)

    @property
    def can_brake(self) -> bool:
        """True when the board has both H-bridge inputs wired (a shaped fall brakes)."""
        return bool(self.capabilities & Capability.BRAKE)


@dataclass(frozen=True)
class Status:
    """What GET_STATUS tells: state, error counters and each channel's output level."""

    state: State
    failsafe_count: int
    crc_errors: int
    framing_errors: int
    seq_gaps: int
    levels: tuple[int, ...]


@dataclass(frozen=True)
class Diag:
    """What GET_DIAG tells (extensions): the 64-bit device clock, the cause of the last
    reset (:class:`ResetFlag`) and the link counters."""

    device_time_us: int
    reset_flags: int
    tx_dropped: int
    ble_refused: int

    @property
    def watchdog_reset(self) -> bool:
        """True when the device's last reset was its watchdog's."""
        return bool(self.reset_flags & ResetFlag.WATCHDOG)


@dataclass(frozen=True)
class Onset:
    """ONSET (extensions): the device time at which a request changed the outputs."""

    seq: int
    request_type: int
    device_time_us: int


@dataclass(frozen=True)
class SenseData:
    """SENSE_DATA (firmware 1.2): consecutive accelerometer samples of one session.

    Sample ``i`` was taken at device time ``t0_us + i * period_us`` (read at most half a
    period after it); ``samples`` holds x, y, z of each in turn (int16, ``full_scale_mg``
    milli-g at 32768).

    Attributes:
        session_seq: the seq of the SENSE_START that began the session (also the header's).
        flags: :class:`SenseFlag` bits.
        first_index: the index of the first sample within the session (a gap in the
            indices is samples lost).
        t0_us: the device time of the first sample (us, the clock of DIAG and ONSET).
        period_us: the sampling period.
        full_scale_mg: the acceleration a raw 32768 stands for (milli-g).
        samples: ``x0, y0, z0, x1, ...`` (3 per sample, at most :data:`SENSE_MAX_SAMPLES`).
    """

    session_seq: int
    flags: int
    first_index: int
    t0_us: int
    period_us: int
    full_scale_mg: int
    samples: tuple[int, ...] = ()

    @property
    def n_samples(self) -> int:
        return len(self.samples) // 3

    @property
    def last(self) -> bool:
        """True when the session ended with this batch."""
        return bool(self.flags & SenseFlag.LAST)


@dataclass(frozen=True)
class Ack:
    seq: int
    code: int = 0


@dataclass(frozen=True)
class Nak:
    seq: int
    code: int


Reply = Pong | Info | Status | Diag | Onset | SenseData | Ack | Nak

_INFO_HEAD = struct.Struct("<BBBBBHHB")
_STATUS_HEAD = struct.Struct("<BHHHH")
_DIAG = struct.Struct("<QBHH")
_ONSET = struct.Struct("<BBQ")
_SENSE_HEAD = struct.Struct("<BBIQHH")
#: ``_SENSE_SAMPLES[n]`` unpacks n samples (3n int16).
_SENSE_SAMPLES = tuple(struct.Struct(f"<{3 * n}h") for n in range(SENSE_MAX_SAMPLES + 1))
#: The replies whose payload is one struct: type -> (class, struct).
_FIXED_REPLIES: dict[int, tuple[type[Any], struct.Struct]] = {
    MsgType.PONG: (Pong, struct.Struct("<II")), MsgType.DIAG: (Diag, _DIAG),
    MsgType.ONSET: (Onset, _ONSET), MsgType.ACK: (Ack, struct.Struct("<BB"))}


def parse_reply(p: Packet) -> Reply:
    """A device-to-host packet as a dataclass.

    Raises:
        ProtocolError: an unknown type, a payload of the wrong length, an unknown state.
    """
    t, payload = p.type, p.payload
    if t in _FIXED_REPLIES:
        return _unpack_fixed(p, *_FIXED_REPLIES[t])
    if t == MsgType.INFO:
        _counted(p, "INFO", _INFO_HEAD.size, 2)
        version, major, minor, patch, channels, steps, hb_ms, caps = _INFO_HEAD.unpack_from(
            payload)
        if len(payload) != _INFO_HEAD.size + 2 * channels:
            raise ProtocolError(f"INFO: {channels} channels need {_INFO_HEAD.size + 2 * channels}"
                                f" bytes, got {len(payload)}")
        cdeg = struct.unpack_from(f"<{channels}H", payload, _INFO_HEAD.size)
        return Info(version, major, minor, patch, channels, steps, hb_ms, caps,
                    tuple(c / 100.0 for c in cdeg))
    if t == MsgType.STATUS:
        n = _counted(p, "STATUS", _STATUS_HEAD.size, 2)
        state, failsafe, crc_errors, framing_errors, gaps = _STATUS_HEAD.unpack_from(payload)
        try:
            st = State(state)
        except ValueError:
            raise ProtocolError(f"STATUS: unknown state {state}") from None
        return Status(st, failsafe, crc_errors, framing_errors, gaps,
                      struct.unpack_from(f"<{n}H", payload, _STATUS_HEAD.size))
    if t == MsgType.SENSE_DATA:
        n = _counted(p, "SENSE_DATA", _SENSE_HEAD.size, 6)
        seq, flags, index, t0, period, fs = _SENSE_HEAD.unpack_from(payload)
        if period == 0:
            raise ProtocolError("SENSE_DATA: a sampling period of 0 us")
        return SenseData(seq, flags, index, t0, period, fs,
                         _SENSE_SAMPLES[n].unpack_from(payload, _SENSE_HEAD.size))
    if t == MsgType.NAK:
        _expect_len(p, "NAK", 2)
        seq, code = payload
        try:
            return Nak(seq, NakCode(code))
        except ValueError:
            return Nak(seq, code)
    raise ProtocolError(f"unknown reply type 0x{t:02X}")
