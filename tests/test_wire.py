"""Protocol v1 codec (tactorbelt.devices.wire): what backends and other tools rely on.

The byte layouts here are the contract of docs/protocol.md; the firmware checks the
same bytes through firmware/test/vectors.json.
"""

from __future__ import annotations

import struct
from collections.abc import Callable

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from support import wire_device
from support import wire_reference as ref
from tactorbelt import ConfigError, ProtocolError
from tactorbelt.devices import wire
from tactorbelt.devices.wire import (
    Ack,
    Info,
    MsgType,
    Nak,
    NakCode,
    Packet,
    Pong,
    State,
    Status,
)

u8 = st.integers(0, 0xFF)
u16 = st.integers(0, 0xFFFF)
u32 = st.integers(0, 0xFFFFFFFF)
payloads = st.binary(max_size=wire.MAX_PAYLOAD)
packets = st.builds(Packet, u8, u8, payloads)


# --- CRC and COBS --------------------------------------------------------------------


def test_crc_check_value() -> None:
    assert wire.crc16_ccitt_false(b"123456789") == 0x29B1
    assert wire.crc16_ccitt_false(b"") == 0xFFFF


@pytest.mark.parametrize(
    ("data", "encoded"),
    [
        (b"", b"\x01"),
        (b"\x00", b"\x01\x01"),
        (b"\x00\x00", b"\x01\x01\x01"),
        (b"\x11\x22\x00\x33", b"\x03\x11\x22\x02\x33"),
        (b"\x11\x22\x33\x44", b"\x05\x11\x22\x33\x44"),
        (b"\x11\x00\x00\x00", b"\x02\x11\x01\x01\x01"),
        (bytes(range(1, 255)), b"\xff" + bytes(range(1, 255))),
        (bytes(range(1, 256)), b"\xff" + bytes(range(1, 255)) + b"\x02\xff"),
    ],
)
def test_cobs_known_encodings(data: bytes, encoded: bytes) -> None:
    assert wire.cobs_encode(data) == encoded
    assert wire.cobs_decode(encoded) == data


@given(st.binary(max_size=700))
def test_cobs_round_trip_and_no_zero(data: bytes) -> None:
    encoded = wire.cobs_encode(data)
    assert 0 not in encoded
    assert len(encoded) <= len(data) + len(data) // 254 + 1
    assert wire.cobs_decode(encoded) == data


@pytest.mark.parametrize("bad", [b"\x00", b"\x02\x00", b"\x05\x01\x02", b"\x03\x01"])
def test_cobs_decode_rejects_malformed(bad: bytes) -> None:
    with pytest.raises(ProtocolError):
        wire.cobs_decode(bad)


# --- the fast codec against the per-byte reference ------------------------------------
#
# crc16_ccitt_false, cobs_encode, cobs_decode and FrameDecoder run per packet in C
# (binascii, bytes methods); the *_reference functions are the per-byte definitions.

#: Bytes with long non-zero runs (COBS's 254-byte blocks) as well as zeros.
runs = st.lists(st.one_of(st.binary(min_size=1, max_size=3),
                          st.binary(min_size=250, max_size=520).map(
                              lambda b: b.replace(b"\x00", b"\x07"))),
                max_size=4).map(b"".join)


@given(st.one_of(st.binary(max_size=300), runs))
def test_fast_crc_and_cobs_equal_the_reference(data: bytes) -> None:
    assert wire.crc16_ccitt_false(data) == ref.crc16_ccitt_false_reference(data)
    encoded = wire.cobs_encode(data)
    assert encoded == ref.cobs_encode_reference(data)
    assert wire.cobs_decode(encoded) == ref.cobs_decode_reference(encoded) == data


def _decode_or_error(decode: Callable[[bytes], bytes], data: bytes) -> bytes | str:
    try:
        return decode(data)
    except ProtocolError as exc:
        return str(exc)


@given(st.one_of(st.binary(max_size=80), runs))
def test_fast_cobs_decode_equals_the_reference_on_any_bytes(data: bytes) -> None:
    # malformed input too: the same error, in the same words
    assert (_decode_or_error(wire.cobs_decode, data)
            == _decode_or_error(ref.cobs_decode_reference, data))


class ReferenceFrameDecoder:
    """The per-byte decoder (round 1's FrameDecoder over the reference functions)."""

    def __init__(self) -> None:
        self.crc_errors = 0
        self.framing_errors = 0
        self.buf = bytearray()
        self.overflow = False

    def feed(self, data: bytes) -> list[Packet]:
        packets = []
        for byte in data:
            if byte:
                if len(self.buf) >= wire.MAX_ENCODED_PACKET:
                    self.overflow = True
                elif not self.overflow:
                    self.buf.append(byte)
                continue
            frame, overflow = bytes(self.buf), self.overflow
            self.buf.clear()
            self.overflow = False
            if overflow:
                self.framing_errors += 1
            elif frame:
                try:
                    raw = ref.cobs_decode_reference(frame)
                except ProtocolError:
                    self.framing_errors += 1
                    continue
                if not wire.MIN_PACKET <= len(raw) <= wire.MAX_PACKET:
                    self.framing_errors += 1
                elif (struct.unpack("<H", raw[-2:])[0]
                      != ref.crc16_ccitt_false_reference(raw[:-2])):
                    self.crc_errors += 1
                else:
                    packets.append(Packet(raw[0], raw[1], raw[2:-2]))
        return packets


#: A serial stream: good frames, damaged frames, garbage and lone delimiters.
streams = st.lists(st.one_of(
    packets.map(wire.encode_frame),
    st.tuples(packets, st.integers(0, 80), st.integers(0, 255)).map(
        lambda t: (lambda f: f[:t[1] % len(f)] + bytes([t[2]]) + f[t[1] % len(f) + 1:])(
            wire.encode_frame(t[0]))),
    st.binary(max_size=90),
    st.just(b"\x00"),
), max_size=8).map(b"".join)


@given(streams, st.lists(st.integers(1, 40), max_size=12))
def test_frame_decoder_equals_the_reference_decoder(stream: bytes, cuts: list[int]) -> None:
    # the same packets and counters however the stream is cut into reads
    fast, ref = wire.FrameDecoder(), ReferenceFrameDecoder()
    got: list[Packet] = []
    at = 0
    for n in [*cuts, len(stream)]:
        got += fast.feed(stream[at:at + n])
        at += n
    assert got == ref.feed(stream)
    assert (fast.crc_errors, fast.framing_errors) == (ref.crc_errors, ref.framing_errors)


@given(u8, st.lists(st.one_of(u16, st.integers(-3, 70000), st.booleans(), st.floats(0, 9)),
                    max_size=31))
def test_set_amplitudes_takes_only_u16_levels(seq: int, levels: list[object]) -> None:
    valid = len(levels) <= 30 and all(
        type(v) is int and 0 <= v <= 0xFFFF for v in levels)  # type: ignore[operator]
    if valid:
        p = wire.set_amplitudes(seq, levels)  # type: ignore[arg-type]
        assert p == Packet(MsgType.SET_AMPLITUDES, seq, struct.pack(f"<{len(levels)}H", *levels))
        assert wire_device.parse_request(p) == wire_device.SetAmplitudes(tuple(levels))  # type: ignore[arg-type]
    else:
        with pytest.raises(ConfigError):
            wire.set_amplitudes(seq, levels)  # type: ignore[arg-type]


# --- packets and frames -----------------------------------------------------------------


def test_packet_layout_is_type_seq_payload_crc_le() -> None:
    raw = wire.encode_packet(Packet(0x12, 0x34, b"\xab\xcd"))
    crc = wire.crc16_ccitt_false(b"\x12\x34\xab\xcd")
    assert raw == b"\x12\x34\xab\xcd" + struct.pack("<H", crc)
    assert wire.encode_frame(Packet(0x12, 0x34, b"\xab\xcd")) == wire.cobs_encode(raw) + b"\x00"


@given(packets)
def test_packet_and_frame_round_trip(p: Packet) -> None:
    raw = wire.encode_packet(p)
    assert len(raw) <= wire.MAX_PACKET
    assert wire.decode_packet(raw) == p
    frame = wire.encode_frame(p)
    assert frame.endswith(b"\x00") and frame.count(0) == 1
    dec = wire.FrameDecoder()
    assert dec.feed(frame) == [p]
    assert (dec.crc_errors, dec.framing_errors) == (0, 0)


@pytest.mark.parametrize("size", [0, 1, 3, 65, 200])
def test_decode_packet_rejects_bad_lengths(size: int) -> None:
    with pytest.raises(ProtocolError, match="bytes"):
        wire.decode_packet(bytes(size))


@given(packets, st.data())
def test_decode_packet_rejects_any_single_bit_flip(p: Packet, data: st.DataObject) -> None:
    raw = bytearray(wire.encode_packet(p))
    bit = data.draw(st.integers(0, 8 * len(raw) - 1))
    raw[bit // 8] ^= 1 << (bit % 8)
    with pytest.raises(ProtocolError, match="CRC"):
        wire.decode_packet(bytes(raw))


def test_packet_fields_are_checked() -> None:
    with pytest.raises(ConfigError):
        Packet(256, 0)
    with pytest.raises(ConfigError):
        Packet(1, -1)
    with pytest.raises(ConfigError, match="at most 60"):
        Packet(1, 0, bytes(61))


# --- the frame decoder ---------------------------------------------------------------------


@given(st.lists(packets, max_size=8), st.integers(1, 20))
def test_decoder_handles_any_chunking(ps: list[Packet], chunk: int) -> None:
    stream = b"".join(wire.encode_frame(p) for p in ps)
    dec = wire.FrameDecoder()
    got: list[Packet] = []
    for i in range(0, len(stream), chunk):
        got += dec.feed(stream[i : i + chunk])
    assert got == ps


@settings(max_examples=300)
@given(st.binary(max_size=300), packets)
def test_decoder_never_raises_and_resynchronises(garbage: bytes, p: Packet) -> None:
    dec = wire.FrameDecoder()
    dec.feed(garbage)  # anything at all: counted, never raised
    got = dec.feed(b"\x00" + wire.encode_frame(p))
    assert got[-1] == p


@given(packets, st.data())
def test_decoder_counts_a_mutated_frame_and_decodes_the_next(
    p: Packet, data: st.DataObject
) -> None:
    frame = bytearray(wire.encode_frame(p))
    pos = data.draw(st.integers(0, len(frame) - 2))  # not the delimiter
    frame[pos] = data.draw(st.integers(1, 255).filter(lambda b: b != frame[pos]))
    good = Packet(MsgType.GET_STATUS, 7)
    dec = wire.FrameDecoder()
    got = dec.feed(bytes(frame) + wire.encode_frame(good))
    assert got[-1] == good
    # the damaged frame is counted as an error, or (when the damage happens to leave a
    # valid CRC, about 1 in 65536) decoded as some packet; never both, never lost
    assert dec.crc_errors + dec.framing_errors + len(got[:-1]) == 1


def test_decoder_error_kinds() -> None:
    dec = wire.FrameDecoder()
    bad_crc = bytearray(wire.encode_packet(wire.ping(1, 2)))
    bad_crc[-1] ^= 0xFF
    assert dec.feed(wire.cobs_encode(bytes(bad_crc)) + b"\x00") == []
    assert (dec.crc_errors, dec.framing_errors) == (1, 0)
    assert dec.feed(wire.cobs_encode(b"\x01\x02\x03") + b"\x00") == []  # 3 bytes: too short
    assert dec.feed(b"\x05\x01\x00") == []  # the code runs past the end
    assert dec.feed(b"\x01" * 100 + b"\x00") == []  # longer than any frame
    assert (dec.crc_errors, dec.framing_errors) == (1, 3)
    assert dec.feed(b"\x00\x00\x00") == []  # empty frames are not errors
    assert (dec.crc_errors, dec.framing_errors) == (1, 3)


def test_longest_frame_is_accepted_and_one_more_byte_is_not() -> None:
    longest = wire.encode_frame(Packet(0x10, 1, bytes(wire.MAX_PAYLOAD)))
    assert len(longest) == wire.MAX_ENCODED_PACKET + 1
    dec = wire.FrameDecoder()
    assert len(dec.feed(longest)) == 1
    assert dec.feed(b"\x02" + longest) == []
    assert dec.framing_errors == 1


# --- requests ---------------------------------------------------------------------------------


@given(u8, u32)
def test_ping_round_trip(seq: int, nonce: int) -> None:
    p = wire.ping(seq, nonce)
    assert (p.type, p.seq, p.payload) == (0x01, seq, struct.pack("<I", nonce))
    assert wire_device.parse_request(p) == wire_device.Ping(nonce)


@given(u8, st.lists(u16, min_size=1, max_size=30))
def test_set_amplitudes_round_trip(seq: int, levels: list[int]) -> None:
    p = wire.set_amplitudes(seq, levels)
    assert p.type == 0x10 and p.payload == struct.pack(f"<{len(levels)}H", *levels)
    assert wire_device.parse_request(p) == wire_device.SetAmplitudes(tuple(levels))


@given(u8, u16, u8, u8, u16, u16, u16, u32)
def test_play_target_round_trip(seq: int, angle: int, mode: int, law: int, falloff: int,
                                period: int, transit: int, duration: int) -> None:
    p = wire.play_target(seq, angle, mode, law, falloff, period, transit, duration)
    assert p.type == 0x12 and len(p.payload) == 14
    assert p.payload == struct.pack("<HBBHHHI", angle, mode, law, falloff, period, transit,
                                    duration)
    assert wire_device.parse_request(p) == wire_device.PlayTarget(
        angle, mode, law, falloff, period, transit, duration)


@given(u8, u16, st.one_of(st.none(), u32))
def test_set_config_round_trip(seq: int, heartbeat_ms: int, max_on_ms: int | None) -> None:
    p = wire.set_config(seq, heartbeat_ms, max_on_ms)
    assert p.type == 0x15
    assert len(p.payload) == (2 if max_on_ms is None else 6)
    assert wire_device.parse_request(p) == wire_device.SetConfig(heartbeat_ms, max_on_ms)


@pytest.mark.parametrize(
    ("build", "type_", "parsed"),
    [
        (wire.get_info, 0x02, wire_device.GetInfo()),
        (wire.stop_all, 0x11, wire_device.StopAll()),
        (wire.heartbeat, 0x14, wire_device.Heartbeat()),
        (wire.get_status, 0x16, wire_device.GetStatus()),
    ],
)
def test_empty_requests(build: Callable[[int], Packet], type_: int, parsed: object) -> None:
    p = build(9)
    assert (p.type, p.seq, p.payload) == (type_, 9, b"")
    assert wire_device.parse_request(p) == parsed


def test_builders_check_field_widths() -> None:
    with pytest.raises(ConfigError, match="nonce"):
        wire.ping(0, 1 << 32)
    with pytest.raises(ConfigError, match="level 1"):
        wire.set_amplitudes(0, [0, 65536])
    with pytest.raises(ConfigError, match="at most 30"):
        wire.set_amplitudes(0, [0] * 31)
    with pytest.raises(ConfigError, match="mode"):
        wire.play_target(0, 0, 256, 0, 1500, 1000, 100, 0)
    with pytest.raises(ConfigError, match="heartbeat_ms"):
        wire.set_config(0, -1)
    with pytest.raises(ConfigError, match="seq"):
        wire.get_info(256)
    # ranges the device enforces are not checked here, so that NAKs can be tested
    assert wire.set_config(0, 49).payload == b"\x31\x00"


@pytest.mark.parametrize(
    "p",
    [
        Packet(0x01, 0, b"\x00\x00\x00"),
        Packet(0x02, 0, b"\x00"),
        Packet(0x10, 0, b"\x00"),
        Packet(0x12, 0, bytes(13)),
        Packet(0x15, 0, bytes(4)),
        Packet(0x16, 0, b"\x00"),
    ],
)
def test_parse_request_rejects_bad_lengths(p: Packet) -> None:
    with pytest.raises(ProtocolError, match="payload"):
        wire_device.parse_request(p)


def test_parse_request_rejects_unknown_types() -> None:
    with pytest.raises(ProtocolError, match="0x7F"):
        wire_device.parse_request(Packet(0x7F, 0))
    with pytest.raises(ProtocolError, match="0x81"):
        wire_device.parse_request(Packet(0x81, 0, bytes(8)))


# --- replies -------------------------------------------------------------------------------------

infos = st.integers(0, 25).flatmap(
    lambda n: st.builds(
        Info, u8, u8, u8, u8, st.just(n), u16, u16, u8,
        st.lists(st.integers(0, 35999).map(lambda c: c / 100.0), min_size=n, max_size=n).map(
            tuple
        ),
    )
)
statuses = st.builds(
    Status, st.sampled_from(State), u16, u16, u16, u16,
    st.lists(u16, max_size=25).map(tuple),
)
replies = st.one_of(
    st.builds(Pong, u32, u32),
    infos,
    statuses,
    st.builds(Ack, u8, st.just(0)),
    st.builds(Nak, u8, st.sampled_from(NakCode)),
    st.builds(wire.Diag, st.integers(0, (1 << 64) - 1), u8, u16, u16),
    st.builds(wire.Onset, u8, u8, st.integers(0, (1 << 64) - 1)),
    st.builds(wire.SenseData, u8, u8, u32, st.integers(0, (1 << 64) - 1),
              st.integers(1, 0xFFFF), u16,
              st.integers(0, wire.SENSE_MAX_SAMPLES).flatmap(
                  lambda n: st.lists(st.integers(-32768, 32767), min_size=3 * n,
                                     max_size=3 * n).map(tuple))),
)


@given(u8, replies)
def test_reply_round_trip(seq: int, reply: wire.Reply) -> None:
    p = wire_device.encode_reply(seq, reply)
    assert p.seq == seq
    assert len(wire.encode_packet(p)) <= wire.MAX_PACKET
    assert wire.parse_reply(p) == reply


def test_info_layout() -> None:
    payload = bytes([1, 1, 2, 3, 6]) + struct.pack("<HHB", 800, 250, 1)
    payload += struct.pack("<6H", 3000, 9000, 15000, 21000, 27000, 33000)
    info = wire.parse_reply(Packet(0x82, 0, payload))
    assert isinstance(info, Info)
    assert info.protocol_version == 1
    assert info.firmware_version == "1.2.3"
    assert (info.channels, info.pwm_steps, info.heartbeat_ms) == (6, 800, 250)
    assert info.can_play_target
    assert info.tactor_angles_deg == (30.0, 90.0, 150.0, 210.0, 270.0, 330.0)


def test_status_layout() -> None:
    payload = struct.pack("<BHHHH", 3, 1, 2, 3, 4) + struct.pack("<2H", 0, 65535)
    status = wire.parse_reply(Packet(0x83, 0, payload))
    assert status == Status(State.FAILSAFE, 1, 2, 3, 4, (0, 65535))
    assert isinstance(status, Status) and status.state is State.FAILSAFE


def test_ack_nak_pong_layouts() -> None:
    assert wire.parse_reply(Packet(0x80, 5, b"\x05\x00")) == Ack(5, 0)
    nak = wire.parse_reply(Packet(0x8F, 5, b"\x05\x04"))
    assert nak == Nak(5, NakCode.OUT_OF_RANGE)
    assert wire.parse_reply(Packet(0x8F, 5, b"\x05\x09")) == Nak(5, 9)  # unknown code kept
    assert wire.parse_reply(Packet(0x81, 0, struct.pack("<II", 7, 8))) == Pong(7, 8)


@pytest.mark.parametrize(
    "p",
    [
        Packet(0x80, 0, b"\x00"),
        Packet(0x81, 0, bytes(7)),
        Packet(0x82, 0, bytes(9)),
        Packet(0x82, 0, bytes([1, 1, 0, 0, 6]) + bytes(5) + bytes(10)),  # 6 channels, 5 angles
        Packet(0x83, 0, bytes(10)),
        Packet(0x83, 0, b"\x07" + bytes(8)),  # unknown state
        Packet(0x8F, 0, b""),
        Packet(0x01, 0, bytes(4)),  # a request is not a reply
    ],
)
def test_parse_reply_rejects_malformed(p: Packet) -> None:
    with pytest.raises(ProtocolError):
        wire.parse_reply(p)


# --- values ---------------------------------------------------------------------------------------


def test_amplitude_to_level() -> None:
    assert wire.amplitude_to_level(0.0) == 0
    assert wire.amplitude_to_level(1.0) == 65535
    assert wire.amplitude_to_level(0.5) == 32768
    assert wire.amplitude_to_level(-0.1) == 0
    assert wire.amplitude_to_level(1.5) == 65535
    assert wire.amplitude_to_level(1 / 65535) == 1
    with pytest.raises(ValueError, match="NaN"):
        wire.amplitude_to_level(float("nan"))


@given(st.floats(0.0, 1.0))
def test_amplitude_to_level_is_monotonic_and_close(a: float) -> None:
    level = wire.amplitude_to_level(a)
    assert abs(level / 65535 - a) <= 0.5 / 65535 + 1e-12
    assert wire.amplitude_to_level(min(1.0, a + 1e-3)) >= level


def test_angle_to_cdeg() -> None:
    assert wire.angle_to_cdeg(30.0) == 3000
    assert wire.angle_to_cdeg(359.999) == 0
    assert wire.angle_to_cdeg(-15.0) == 34500
    assert wire.angle_to_cdeg(12.345) in (1234, 1235)
    with pytest.raises(ConfigError):
        wire.angle_to_cdeg(float("inf"))


def test_message_codes_are_the_contract() -> None:
    assert {m.name: m.value for m in MsgType} == {
        "PING": 0x01, "GET_INFO": 0x02, "SET_AMPLITUDES": 0x10, "STOP_ALL": 0x11,
        "PLAY_TARGET": 0x12, "HEARTBEAT": 0x14, "SET_CONFIG": 0x15, "GET_STATUS": 0x16,
        "GET_DIAG": 0x17, "SENSE_START": 0x18, "SENSE_STOP": 0x19, "SET_DRIVE": 0x1A,
        "ACK": 0x80, "PONG": 0x81,
        "INFO": 0x82, "STATUS": 0x83, "DIAG": 0x84, "ONSET": 0x85, "SENSE_DATA": 0x86,
        "NAK": 0x8F,
    }
    assert [c.value for c in NakCode] == [2, 3, 4, 5, 6]
    assert (wire.Capability.WATCHDOG_RESET, wire.ResetFlag.WATCHDOG) == (0x80, 0x02)
    assert (wire.Capability.SENSE, wire.SenseFlag.LAST, wire.SenseFlag.DROPPED) == (2, 1, 2)
    assert (wire.ConfigFlag.ONSET_EVENTS, wire.ConfigFlag.BLE_FRAMED) == (0x01, 0x02)
    assert (wire.Capability.SHAPE, wire.Capability.BRAKE) == (0x04, 0x08)
    assert (wire.DriveMode.SHAPED, wire.DriveMode.NO_BRAKE) == (0x01, 0x02)
    assert wire.encode_packet(wire.set_drive(7, wire.DriveMode.SHAPED))[:3] == b"\x1a\x07\x01"
    assert [s.value for s in State] == [0, 1, 2, 3]
    assert (wire.PROTOCOL_VERSION, wire.MAX_PACKET) == (1, 64)


# --- extensions (docs/protocol.md "Extensions"; firmware/test/vectors_ext.json) ------------


def _ext_vectors() -> dict[str, object]:
    import json
    from pathlib import Path

    path = Path(__file__).resolve().parents[1] / "firmware" / "test" / "vectors_ext.json"
    data: dict[str, object] = json.loads(path.read_text())
    return data


def test_extension_messages_match_the_firmware_vectors() -> None:
    """The hand-checked bytes of docs/protocol.md: GET_DIAG, DIAG, ONSET, flags, NAK 5."""
    assert wire.get_diag(5) == Packet(0x17, 5)
    assert wire.encode_frame(wire.get_diag(5)).hex() == "0517054ed700"
    flags = wire.ConfigFlag.ONSET_EVENTS | wire.ConfigFlag.BLE_FRAMED
    assert wire.encode_packet(wire.set_config(8, 250, 30000, flags)).hex() == (
        "1508fa003075000003f13c")
    diag = wire.parse_reply(wire.decode_packet(bytes.fromhex("840589674523010000000203000100c105")))
    assert diag == wire.Diag(0x123456789, 0x02, 3, 1)
    assert isinstance(diag, wire.Diag) and diag.watchdog_reset
    onset = wire.parse_reply(wire.decode_packet(bytes.fromhex("8507071200093d000000000024ca")))
    assert onset == wire.Onset(7, wire.MsgType.PLAY_TARGET, 4_000_000)
    nak = wire.parse_reply(wire.decode_packet(bytes.fromhex("8f090905baf9")))
    assert nak == Nak(9, NakCode.REPLY_TOO_LONG)
    vectors = _ext_vectors()
    packets = vectors["packets"]
    assert isinstance(packets, list)
    for v in packets:
        p = Packet(v["type"], v["seq"], bytes.fromhex(v["payload"]))
        assert wire.encode_packet(p).hex() == v["packet"], v["name"]
        assert wire.encode_frame(p).hex() == v["frame"], v["name"]


def test_set_config_flags_round_trip() -> None:
    p = wire.set_config(3, 300, 20000, wire.ConfigFlag.ONSET_EVENTS)
    assert p.payload == struct.pack("<HIB", 300, 20000, 1)
    assert wire_device.parse_request(p) == wire_device.SetConfig(300, 20000, 1)
    with pytest.raises(ConfigError, match="max_on_ms"):
        wire.set_config(3, 300, None, 1)
    with pytest.raises(ConfigError, match="flags"):
        wire.set_config(3, 300, 20000, 256)
    assert wire_device.parse_request(wire.get_diag(4)) == wire_device.GetDiag()
    with pytest.raises(ProtocolError, match="GET_DIAG"):
        wire_device.parse_request(Packet(0x17, 0, b"\x00"))
    with pytest.raises(ProtocolError, match="DIAG"):
        wire.parse_reply(Packet(0x84, 0, bytes(12)))
    with pytest.raises(ProtocolError, match="ONSET"):
        wire.parse_reply(Packet(0x85, 0, bytes(11)))


# --- the board's accelerometer (firmware 1.2) ------------------------------------------------


def test_sense_requests_layout_and_round_trip() -> None:
    p = wire.sense_start(4, 0, 2000)
    assert (p.type, p.payload) == (0x18, struct.pack("<HIB", 0, 2000, 0xFF))
    assert wire_device.parse_request(p) == wire_device.SenseStart(0, 2000, wire.SENSE_ANY_TACTOR)
    p = wire.sense_start(5, 400, wire.SENSE_MAX_DURATION_MS, 3)
    assert wire_device.parse_request(p) == wire_device.SenseStart(400, 3_600_000, 3)
    assert wire_device.parse_request(wire.sense_stop(6)) == wire_device.SenseStop()
    assert wire.sense_stop(6) == Packet(0x19, 6)
    with pytest.raises(ConfigError, match="rate_hz"):
        wire.sense_start(0, 70000, 1000)
    with pytest.raises(ConfigError, match="tactor"):
        wire.sense_start(0, 0, 1000, 256)
    with pytest.raises(ProtocolError, match="SENSE_START"):
        wire_device.parse_request(Packet(0x18, 0, bytes(6)))
    with pytest.raises(ProtocolError, match="SENSE_STOP"):
        wire_device.parse_request(Packet(0x19, 0, b"\x00"))


def test_sense_data_layout_fills_one_packet() -> None:
    """18 bytes of header and 7 samples of 3 int16: 60 bytes, the most a packet carries
    (one serial frame, one notification at an ATT MTU of 67 or framed below)."""
    assert wire.SENSE_MAX_SAMPLES == 7
    values = tuple(range(-10, 11))
    data = wire.SenseData(9, wire.SenseFlag.LAST, 0x01020304, 0x0102030405060708, 625, 8000,
                          values)
    p = wire_device.encode_reply(9, data)
    assert len(p.payload) == wire.MAX_PAYLOAD and len(wire.encode_packet(p)) == wire.MAX_PACKET
    assert p.payload[:18] == struct.pack("<BBIQHH", 9, 1, 0x01020304, 0x0102030405060708,
                                         625, 8000)
    assert p.payload[18:] == struct.pack("<21h", *values)
    back = wire.parse_reply(p)
    assert back == data and isinstance(back, wire.SenseData)
    assert back.n_samples == 7 and back.last
    empty = wire.parse_reply(wire_device.encode_reply(9, wire.SenseData(9, 0, 0, 0, 625, 8000)))
    assert isinstance(empty, wire.SenseData) and empty.n_samples == 0 and not empty.last


@pytest.mark.parametrize("p", [
    Packet(0x86, 0, bytes(17)),  # shorter than the header
    Packet(0x86, 0, bytes(18 + 5)),  # not whole samples
    Packet(0x86, 0, bytes(18)),  # a period of 0
])
def test_parse_sense_data_rejects_malformed(p: Packet) -> None:
    with pytest.raises(ProtocolError, match="SENSE_DATA"):
        wire.parse_reply(p)


def test_sense_data_builder_checks_its_samples() -> None:
    with pytest.raises(ConfigError, match="at most 7"):
        wire_device.encode_reply(0, wire.SenseData(0, 0, 0, 0, 625, 8000, (0,) * 24))
    with pytest.raises(ConfigError, match="3 per sample"):
        wire_device.encode_reply(0, wire.SenseData(0, 0, 0, 0, 625, 8000, (0, 0)))
    with pytest.raises(ConfigError, match="int16"):
        wire_device.encode_reply(0, wire.SenseData(0, 0, 0, 0, 625, 8000, (32768, 0, 0)))


def test_info_reports_the_sense_capability() -> None:
    payload = bytes([1, 1, 2, 0, 2]) + struct.pack("<HHB", 800, 250, 0x03) + bytes(4)
    info = wire.parse_reply(Packet(0x82, 0, payload))
    assert isinstance(info, Info) and info.can_sense and info.can_play_target
    other = wire.parse_reply(Packet(0x82, 0, payload[:9] + b"\x81" + bytes(4)))
    assert isinstance(other, Info) and not other.can_sense
