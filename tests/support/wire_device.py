"""The device's side of protocol v1, with which tests and scripts play the device: each
request as a frozen dataclass (:func:`parse_request`), and replies built from theirs
(:func:`encode_reply`, the inverse of :func:`tactorbelt.devices.wire.parse_reply`)."""

from __future__ import annotations

import struct
from dataclasses import asdict, dataclass
from typing import Any

from tactorbelt import ConfigError, ProtocolError
from tactorbelt.devices.wire import (
    _DIAG,
    _INFO_HEAD,
    _ONSET,
    _PLAY_TARGET,
    _SENSE_HEAD,
    _SENSE_SAMPLES,
    _SENSE_START,
    _STATUS_HEAD,
    SENSE_ANY_TACTOR,
    SENSE_MAX_SAMPLES,
    Ack,
    Diag,
    Info,
    MsgType,
    Nak,
    Onset,
    Packet,
    Pong,
    Reply,
    SenseData,
    Status,
    _expect_len,
    _pack,
    _uint,
    _unpack_fixed,
    angle_to_cdeg,
)

# --- requests, as the device reads them -----------------------------------------------


@dataclass(frozen=True)
class Ping:
    nonce: int


@dataclass(frozen=True)
class GetInfo:
    pass


@dataclass(frozen=True)
class SetAmplitudes:
    levels: tuple[int, ...]


@dataclass(frozen=True)
class StopAll:
    pass


@dataclass(frozen=True)
class PlayTarget:
    angle_cdeg: int
    mode: int
    law: int
    falloff_cdeg: int
    period_ms: int
    transit_ms: int
    duration_ms: int


@dataclass(frozen=True)
class Heartbeat:
    pass


@dataclass(frozen=True)
class SetConfig:
    heartbeat_ms: int
    max_on_ms: int | None = None
    flags: int | None = None


@dataclass(frozen=True)
class GetStatus:
    pass


@dataclass(frozen=True)
class GetDiag:
    pass


@dataclass(frozen=True)
class SenseStart:
    """SENSE_START: stream the board's accelerometer (firmware 1.2).

    Attributes:
        rate_hz: the rate asked for; 0 = the sensor's highest. The device samples at the
            highest rate it can at or below it (period ``ceil(1e6 / rate_hz)`` us, at
            least the sensor's shortest, at most 65535 us).
        duration_ms: how long (1..3600000); SENSE_STOP ends it sooner.
        tactor: the tactor the board is on (the emulator simulates that one), or
            :data:`SENSE_ANY_TACTOR`.
    """

    rate_hz: int
    duration_ms: int
    tactor: int = SENSE_ANY_TACTOR


@dataclass(frozen=True)
class SenseStop:
    pass


Request = (Ping | GetInfo | SetAmplitudes | StopAll | PlayTarget | Heartbeat | SetConfig
           | GetStatus | GetDiag | SenseStart | SenseStop)


_NO_PAYLOAD = struct.Struct("")
#: The requests whose payload is one struct: type -> (class, struct).
_FIXED_REQUESTS: dict[int, tuple[type[Any], struct.Struct]] = {
    MsgType.PING: (Ping, struct.Struct("<I")), MsgType.GET_INFO: (GetInfo, _NO_PAYLOAD),
    MsgType.STOP_ALL: (StopAll, _NO_PAYLOAD), MsgType.PLAY_TARGET: (PlayTarget, _PLAY_TARGET),
    MsgType.HEARTBEAT: (Heartbeat, _NO_PAYLOAD), MsgType.GET_STATUS: (GetStatus, _NO_PAYLOAD),
    MsgType.GET_DIAG: (GetDiag, _NO_PAYLOAD), MsgType.SENSE_START: (SenseStart, _SENSE_START),
    MsgType.SENSE_STOP: (SenseStop, _NO_PAYLOAD)}


def parse_request(p: Packet) -> Request:
    """A host-to-device packet as a dataclass (for tests that play the device).

    Raises:
        ProtocolError: an unknown type or a payload of the wrong length.
    """
    t = p.type
    fixed = _FIXED_REQUESTS.get(t)
    if fixed is not None:
        return _unpack_fixed(p, *fixed)
    if t == MsgType.SET_AMPLITUDES:
        if len(p.payload) % 2:
            raise ProtocolError(f"SET_AMPLITUDES: odd payload of {len(p.payload)} bytes")
        n = len(p.payload) // 2
        return SetAmplitudes(struct.unpack(f"<{n}H", p.payload))
    if t == MsgType.SET_CONFIG:
        _expect_len(p, "SET_CONFIG", 2, 6, 7)
        fmt = {2: "<H", 6: "<HI", 7: "<HIB"}[len(p.payload)]
        return SetConfig(*struct.unpack(fmt, p.payload))
    raise ProtocolError(f"unknown request type 0x{t:02X}")


#: The replies whose payload is one struct: class -> (type, struct).
_FIXED_REPLIES: dict[type[Any], tuple[MsgType, struct.Struct]] = {
    Pong: (MsgType.PONG, struct.Struct("<II")), Diag: (MsgType.DIAG, _DIAG),
    Onset: (MsgType.ONSET, _ONSET), Ack: (MsgType.ACK, struct.Struct("<BB"))}


def encode_reply(seq: int, reply: Reply) -> Packet:
    """Build a device reply (the inverse of :func:`parse_reply`; for tests and tools)."""
    for kind, (t, layout) in _FIXED_REPLIES.items():
        if isinstance(reply, kind):
            return Packet(t, seq, _pack(layout, asdict(reply)))
    if isinstance(reply, Info):
        if reply.channels != len(reply.tactor_angles_deg):
            raise ConfigError(
                f"INFO: {reply.channels} channels but {len(reply.tactor_angles_deg)} angles"
            )
        payload = _pack(_INFO_HEAD, asdict(reply)) + b"".join(
            struct.pack("<H", angle_to_cdeg(a)) for a in reply.tactor_angles_deg)
        return Packet(MsgType.INFO, seq, payload)
    if isinstance(reply, Status):
        payload = _pack(_STATUS_HEAD, asdict(reply)) + b"".join(
            struct.pack("<H", _uint("level", v, 16)) for v in reply.levels)
        return Packet(MsgType.STATUS, seq, payload)
    if isinstance(reply, SenseData):
        if len(reply.samples) % 3 or len(reply.samples) > 3 * SENSE_MAX_SAMPLES:
            raise ConfigError(f"SENSE_DATA: {len(reply.samples)} values; 3 per sample, at most "
                              f"{SENSE_MAX_SAMPLES} samples")
        for v in reply.samples:
            if isinstance(v, bool) or not isinstance(v, int) or not -32768 <= v <= 32767:
                raise ConfigError(f"SENSE_DATA: sample value {v!r} is not an int16")
        payload = _pack(_SENSE_HEAD, asdict(reply)) + _SENSE_SAMPLES[
            len(reply.samples) // 3].pack(*reply.samples)
        return Packet(MsgType.SENSE_DATA, seq, payload)
    if isinstance(reply, Nak):
        return Packet(MsgType.NAK, seq, _pack(struct.Struct("<BB"), asdict(reply)))
    raise ConfigError(f"not a reply: {reply!r}")
