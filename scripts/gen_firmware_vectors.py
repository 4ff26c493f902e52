#!/usr/bin/env python3
"""Write firmware/test/vectors.json and vectors_ext.json: what the Python package says
the firmware must do.

The C++ host tests (``make -C firmware test``) read the files and check, byte for byte,
CRCs, COBS encodings, frames of every message and the frame decoder's verdicts on
damaged streams; a scripted exchange with the controller (replies byte for byte);
and rendered amplitudes (within 2/65535) for targets, modes, laws and times on the
default 6-tactor layout, an 8-tactor layout and an uneven layout.

``vectors_ext.json`` holds the protocol extensions (docs/protocol.md, "Extensions"):
GET_DIAG/DIAG, ONSET, the SET_CONFIG flags byte, NAK 5, a scripted exchange with
ONSET events, and the BLE reply paths (refused, unframed, framed in MTU pieces); the
board's accelerometer (firmware 1.2): SENSE_START/SENSE_STOP/SENSE_DATA and NAK 6, a
scripted sensing session with a fake accelerometer (every SENSE_DATA byte for byte), and
the ERM motor model of the emulator's IMU against ``tactorbelt.devices.erm``.

The sources of truth are ``tactorbelt.devices.wire``, ``tactorbelt.devices.erm`` and
``tactorbelt.stimuli``.
``tests/test_firmware_vectors.py`` fails when the committed file no longer matches.

Usage:
    python scripts/gen_firmware_vectors.py            # rewrite both files
    python scripts/gen_firmware_vectors.py --check    # exit 1 when either is stale
"""

from __future__ import annotations

import argparse
import json
import math
import random
import sys
from pathlib import Path
from typing import Any

import numpy as np

from tactorbelt.devices import wire
from tactorbelt.devices.erm import ErmParams, erm_speed, shape_tick
from tactorbelt.devices.wire import (
    Ack,
    ConfigFlag,
    Diag,
    Info,
    MsgType,
    Nak,
    NakCode,
    Onset,
    Packet,
    Pong,
    ResetFlag,
    SenseData,
    SenseFlag,
    State,
    Status,
)
from tactorbelt.geometry import Layout
from tactorbelt.stimuli import make_stimulus

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from support import wire_device  # the device's side of the protocol

ROOT = Path(__file__).resolve().parents[1]
VECTORS = ROOT / "firmware" / "test" / "vectors.json"
EXT_NAME = "vectors_ext.json"
FORMAT = 1
DECIMALS = 9

MODES = ("static", "dynamic")
LAWS = ("paper", "linear", "energy")

# What the firmware reports for itself (firmware/tactorbelt/src/core/protocol.h) and
# what the exchange below runs against (6 tactors, default layout, 800 PWM steps).
FW_VERSION = (1, 3, 0)
EXCHANGE_PWM_STEPS = 800


def _hex(data: bytes) -> str:
    return data.hex()


def _frame_entry(name: str, p: Packet) -> dict[str, Any]:
    return {
        "name": name,
        "type": int(p.type),
        "seq": p.seq,
        "payload": _hex(p.payload),
        "packet": _hex(wire.encode_packet(p)),
        "frame": _hex(wire.encode_frame(p)),
    }


def crc_vectors() -> list[dict[str, Any]]:
    rng = random.Random(1)
    datas = [b"123456789", b"", b"\x00", b"\xff" * 4, bytes(range(64))]
    datas += [bytes(rng.randrange(256) for _ in range(rng.randrange(1, 70))) for _ in range(5)]
    return [{"data": _hex(d), "crc": wire.crc16_ccitt_false(d)} for d in datas]


def cobs_vectors() -> list[dict[str, Any]]:
    rng = random.Random(2)
    datas = [
        b"",
        b"\x00",
        b"\x00\x00",
        b"\x11\x22\x00\x33",
        b"\x11\x22\x33\x44",
        b"\x11\x00\x00\x00",
        bytes(range(1, 255)),  # 254 non-zero bytes: one full block, nothing after
        bytes(range(1, 256)),  # 255 non-zero bytes: a full block and one more
        bytes(range(256)),
        b"\x01" * 300,
    ]
    datas += [
        bytes(rng.choice((0, rng.randrange(256))) for _ in range(rng.randrange(1, 80)))
        for _ in range(6)
    ]
    return [{"data": _hex(d), "encoded": _hex(wire.cobs_encode(d))} for d in datas]


def default_info(channels: int = 6, heartbeat_ms: int = 250, capabilities: int = 1) -> Info:
    layout = Layout.even(channels)
    return Info(
        wire.PROTOCOL_VERSION,
        *FW_VERSION,
        channels,
        EXCHANGE_PWM_STEPS,
        heartbeat_ms,
        capabilities,
        tuple(wire.angle_to_cdeg(a) / 100.0 for a in layout.angles_deg),
    )


def frame_vectors() -> list[dict[str, Any]]:
    entries = [
        ("ping", wire.ping(0, 0)),
        ("ping", wire.ping(7, 0xDEADBEEF)),
        ("get_info", wire.get_info(1)),
        ("set_amplitudes", wire.set_amplitudes(2, [0, 65535, 1, 256, 32768, 12345])),
        ("set_amplitudes", wire.set_amplitudes(3, [0] * 8)),
        ("stop_all", wire.stop_all(4)),
        ("play_target", wire.play_target(5, 4500, 1, 0, 1500, 1000, 100, 0)),
        ("play_target", wire.play_target(255, 35999, 0, 2, 1, 65535, 32767, 0xFFFFFFFF)),
        ("heartbeat", wire.heartbeat(6)),
        ("set_config", wire.set_config(7, 250)),
        ("set_config", wire.set_config(8, 2000, 30000)),
        ("get_status", wire.get_status(0)),
        ("ack", wire_device.encode_reply(4, Ack(4))),
        ("nak", wire_device.encode_reply(9, Nak(9, NakCode.OUT_OF_RANGE))),
        ("pong", wire_device.encode_reply(0, Pong(0xDEADBEEF, 123456789))),
        ("info", wire_device.encode_reply(1, default_info())),
        ("status", wire_device.encode_reply(2, Status(State.FAILSAFE, 1, 2, 3, 4,
                                                      (0, 1, 2, 3, 4, 5)))),
        ("get_diag", wire.get_diag(5)),
        ("set_config", wire.set_config(9, 250, 30000, ConfigFlag.ONSET_EVENTS)),
        ("diag", wire_device.encode_reply(5, Diag(0x123456789, ResetFlag.WATCHDOG, 3, 1))),
        ("onset", wire_device.encode_reply(7, Onset(7, MsgType.PLAY_TARGET, 4_000_000))),
        ("nak", wire_device.encode_reply(9, Nak(9, NakCode.REPLY_TOO_LONG))),
        ("unknown", Packet(0x7F, 0x00, b"\x00\x00\x00")),
        ("max_payload", Packet(0x10, 0x00, bytes(range(60)))),
    ]
    return [_frame_entry(name, p) for name, p in entries]


def _stream(name: str, data: bytes) -> dict[str, Any]:
    dec = wire.FrameDecoder()
    packets = dec.feed(data)
    return {
        "name": name,
        "input": _hex(data),
        "packets": [
            {"type": int(p.type), "seq": p.seq, "payload": _hex(p.payload)} for p in packets
        ],
        "crc_errors": dec.crc_errors,
        "framing_errors": dec.framing_errors,
    }


def stream_vectors() -> list[dict[str, Any]]:
    good = [
        wire.encode_frame(wire.ping(1, 0x01020304)),
        wire.encode_frame(wire.set_amplitudes(2, [0, 1000, 0, 65535, 0, 7])),
        wire.encode_frame(wire.get_status(3)),
        wire.encode_frame(wire.play_target(4, 1500, 1, 0, 1500, 1000, 100, 0)),
    ]
    bad_crc = bytearray(wire.encode_packet(wire.ping(5, 42)))
    bad_crc[-1] ^= 0x01
    short = wire.cobs_encode(b"\x01\x02\x03") + b"\x00"
    bad_cobs = b"\x05\x01\x02\x00"  # code 5 promises 4 bytes, 2 follow
    streams = [
        _stream("good frames back to back", b"".join(good)),
        _stream("leading zeros and empty frames", b"\x00\x00" + good[0] + b"\x00\x00" + good[2]),
        _stream("garbage then a frame", b"\x13\x37\xff\xfe" + b"\x00" + good[1]),
        _stream("garbage without a delimiter glued to a frame", b"\x13\x37" + good[1] + good[2]),
        _stream("bad crc", wire.cobs_encode(bytes(bad_crc)) + b"\x00" + good[0]),
        _stream("too short", short + good[2]),
        _stream("bad cobs", bad_cobs + good[3]),
        _stream("overlong frame", b"\x01" * 200 + b"\x00" + good[0]),
        _stream("exactly the longest frame", wire.encode_frame(Packet(0x10, 9, bytes(60)))),
        _stream("one byte too long", b"\x02" + wire.encode_frame(Packet(0x10, 9, bytes(60)))),
        _stream("truncated frame then resync", good[3][:7] + b"\x00" + good[3]),
    ]
    rng = random.Random(3)
    for i in range(12):
        parts: list[bytes] = []
        for _ in range(rng.randrange(2, 8)):
            kind = rng.randrange(4)
            frame = bytearray(rng.choice(good))
            if kind == 1:  # flip one bit
                pos = rng.randrange(len(frame))
                frame[pos] ^= 1 << rng.randrange(8)
            elif kind == 2:  # random noise
                frame = bytearray(rng.randrange(256) for _ in range(rng.randrange(1, 90)))
            elif kind == 3:  # cut short
                frame = frame[: rng.randrange(1, len(frame))]
            parts.append(bytes(frame))
        streams.append(_stream(f"random mix {i}", b"".join(parts)))
    return streams


def exchange_vectors() -> dict[str, Any]:
    """A scripted session with a fresh 6-tactor controller: requests and exact replies."""
    steps: list[dict[str, Any]] = []

    def step(t_us: int, data: bytes, replies: list[Packet]) -> None:
        steps.append(
            {
                "t_us": t_us,
                "input": _hex(data),
                "output": _hex(b"".join(wire.encode_frame(r) for r in replies)),
            }
        )

    def frame(p: Packet) -> bytes:
        return wire.encode_frame(p)

    levels = (0, 1000, 65535, 0, 7, 0)
    step(1_000, frame(wire.get_info(0)), [wire_device.encode_reply(0, default_info())])
    step(2_000, frame(wire.ping(1, 0xCAFEF00D)),
         [wire_device.encode_reply(1, Pong(0xCAFEF00D, 2_000))])
    step(3_000, frame(wire.set_amplitudes(2, levels)), [])
    step(
        4_000,
        frame(wire.get_status(3)),
        [wire_device.encode_reply(3, Status(State.STREAMING, 0, 0, 0, 0, levels))],
    )
    bad = bytearray(wire.encode_packet(wire.stop_all(4)))
    bad[2] ^= 0xFF
    step(5_000, wire.cobs_encode(bytes(bad)) + b"\x00" + b"\x07\x00", [])
    step(6_000, frame(Packet(wire.MsgType.HEARTBEAT, 4, b"\x00")),
         [wire_device.encode_reply(4, Nak(4, NakCode.BAD_LENGTH))])
    step(7_000, frame(Packet(0x7F, 5)), [wire_device.encode_reply(5, Nak(5, NakCode.UNKNOWN_TYPE))])
    step(8_000, frame(wire.play_target(6, 4500, 2, 0, 1500, 1000, 100, 0)),
         [wire_device.encode_reply(6, Nak(6, NakCode.OUT_OF_RANGE))])
    step(9_000, frame(wire.play_target(7, 4500, 1, 3, 1500, 1000, 100, 0)),
         [wire_device.encode_reply(7, Nak(7, NakCode.OUT_OF_RANGE))])
    step(10_000, frame(wire.set_config(8, 49)),
         [wire_device.encode_reply(8, Nak(8, NakCode.OUT_OF_RANGE))])
    step(11_000, frame(wire.set_config(9, 2001)),
         [wire_device.encode_reply(9, Nak(9, NakCode.OUT_OF_RANGE))])
    step(12_000, frame(wire.set_config(10, 250, 99)),
         [wire_device.encode_reply(10, Nak(10, NakCode.OUT_OF_RANGE))])
    step(13_000, frame(wire.set_config(11, 300, 20000)), [wire_device.encode_reply(11, Ack(11))])
    step(14_000, frame(wire.set_amplitudes(12, (1, 2, 3))),
         [wire_device.encode_reply(12, Nak(12, NakCode.BAD_LENGTH))])
    # seq 13 skipped on purpose: one sequence gap
    step(
        15_000,
        frame(wire.get_status(14)),
        [wire_device.encode_reply(14, Status(State.STREAMING, 0, 1, 1, 1, levels))],
    )
    step(16_000, frame(wire.stop_all(15)), [wire_device.encode_reply(15, Ack(15))])
    step(
        17_000,
        frame(wire.get_status(16)) + frame(wire.get_info(17)),
        [
            wire_device.encode_reply(16, Status(State.IDLE, 0, 1, 1, 1, (0,) * 6)),
            wire_device.encode_reply(17, default_info(heartbeat_ms=300)),
        ],
    )
    # the heartbeat is now 300 ms: silence for longer trips the failsafe
    step(18_000, frame(wire.set_amplitudes(18, levels)), [])
    step(
        318_000,
        frame(wire.get_status(19)),
        [wire_device.encode_reply(19, Status(State.FAILSAFE, 1, 1, 1, 1, (0,) * 6))],
    )
    return {"tactors": 6, "pwm_steps": EXCHANGE_PWM_STEPS, "steps": steps}


def _render_case(
    layout: Layout,
    angle_cdeg: int,
    mode: str,
    law: str,
    t_us: list[int],
    falloff_cdeg: int = 1500,
    period_ms: int = 1000,
    transit_ms: int = 100,
) -> dict[str, Any]:
    stim = make_stimulus(
        layout,
        angle_cdeg / 100.0,
        mode,
        law,
        falloff_deg=falloff_cdeg / 100.0,
        period_s=period_ms / 1000.0,
        transit_s=transit_ms / 1000.0,
    )
    amps = stim.amplitudes(np.asarray(t_us, dtype=float) / 1e6)
    return {
        "tactor_angles_deg": list(layout.angles_deg),
        "angle_cdeg": angle_cdeg,
        "mode": MODES.index(mode),
        "law": LAWS.index(law),
        "falloff_cdeg": falloff_cdeg,
        "period_ms": period_ms,
        "transit_ms": transit_ms,
        "t_us": t_us,
        "amplitudes": [[_num(a) for a in row] for row in amps],
    }


def _num(a: float) -> float | int:
    r = round(float(a), DECIMALS)
    return 0 if r == 0 else r


def _us(t_ms: list[int], offset_us: int = 0) -> list[int]:
    return [t * 1000 + offset_us for t in t_ms]


def render_vectors() -> list[dict[str, Any]]:
    static_t = _us([0, 1234])
    period_ms = [*range(0, 1000, 25), 599, 601, 613, 650, 699, 701, 899, 901, 937, 999, 1605, 12345]
    period_t = _us(period_ms)
    cases: list[dict[str, Any]] = []

    six = Layout.even(6)
    six_targets = [k * 1500 for k in range(24)] + [750, 1234, 35950, 35999]
    for law in LAWS:
        for cdeg in six_targets:
            cases.append(_render_case(six, cdeg, "static", law, static_t))
    for cdeg in six_targets:
        cases.append(_render_case(six, cdeg, "dynamic", "paper", period_t))
    for law in ("linear", "energy"):
        for cdeg in (750, 1500, 3000, 6000, 1234):
            cases.append(_render_case(six, cdeg, "dynamic", law, period_t))
    # one period at 1 kHz, as the golden reference
    cases.append(_render_case(six, 1500, "dynamic", "paper", _us(list(range(1000)))))
    # other falloff, period and transit
    cases.append(_render_case(six, 1500, "dynamic", "paper", _us(list(range(0, 1600, 7))),
                              falloff_cdeg=1000, period_ms=1500, transit_ms=200))
    cases.append(_render_case(six, 11000, "dynamic", "paper", _us(list(range(0, 700, 3))),
                              falloff_cdeg=2500, period_ms=600, transit_ms=50))
    cases.append(_render_case(six, 1250, "static", "paper", static_t, falloff_cdeg=100))

    eight = Layout.even(8)
    for cdeg in (0, 1125, 2250, 4500, 5000, 9000, 20000, 33750):
        for law in LAWS:
            cases.append(_render_case(eight, cdeg, "static", law, static_t))
        cases.append(_render_case(eight, cdeg, "dynamic", "paper", period_t))

    # On an uneven layout the law jumps where the location arrives on a tactor from
    # its counter-clockwise side (s switches to the clockwise gap), and which side a
    # sample at that very instant sees is float noise. Sample half a millisecond off.
    uneven = Layout.from_angles([10, 70, 150, 200, 290])
    for cdeg in (0, 4000, 10000, 18000, 25000, 7000):
        for law in LAWS:
            cases.append(_render_case(uneven, cdeg, "static", law, static_t))
            cases.append(_render_case(uneven, cdeg, "dynamic", law, _us(period_ms, 500)))
    return cases


# --- the extensions (vectors_ext.json) ------------------------------------------------------


def ext_packet_vectors() -> list[dict[str, Any]]:
    flags = ConfigFlag.ONSET_EVENTS | ConfigFlag.BLE_FRAMED
    entries = [
        ("GET_DIAG seq 5", wire.get_diag(5)),
        ("DIAG seq 5: device time 0x0000000123456789 us, reset watchdog, 3 TX dropped, "
         "1 BLE refused", wire_device.encode_reply(5, Diag(0x123456789, ResetFlag.WATCHDOG, 3, 1))),
        ("ONSET seq 7 of PLAY_TARGET at 4000000 us",
         wire_device.encode_reply(7, Onset(7, MsgType.PLAY_TARGET, 4_000_000))),
        ("SET_CONFIG seq 8: 250 ms, 30000 ms, flags 0x03 (onset events, BLE framed)",
         wire.set_config(8, 250, 30000, flags)),
        ("NAK seq 9 code 5 (reply too long for the BLE MTU)",
         wire_device.encode_reply(9, Nak(9, NakCode.REPLY_TOO_LONG))),
        ("SENSE_START seq 10: highest rate, 2000 ms, any tactor",
         wire.sense_start(10, 0, 2000)),
        ("SENSE_START seq 11: 400 Hz, 3600000 ms, tactor 5",
         wire.sense_start(11, 400, 3_600_000, 5)),
        ("SENSE_STOP seq 12", wire.sense_stop(12)),
        ("SENSE_DATA of seq 10: 7 samples from index 0x01020304 at 0x123456789 us, 625 us "
         "apart, +-8 g, the last", wire_device.encode_reply(10, SenseData(
             10, SenseFlag.LAST, 0x01020304, 0x123456789, 625, 8000,
             (0, 1, -1, 32767, -32768, 256, 4096, -4096, 8192, 1, 2, 3, -3, -2, -1,
              0x1234, -0x1234, 0, 100, 200, 300)))),
        ("SENSE_DATA of seq 10: no sample, the last, samples dropped before it",
         wire_device.encode_reply(10, SenseData(10, SenseFlag.LAST | SenseFlag.DROPPED, 9, 5000,
                                         1051, 8000, ()))),
        ("NAK seq 13 code 6 (the IMU did not start)",
         wire_device.encode_reply(13, Nak(13, NakCode.UNAVAILABLE))),
    ]
    return [_frame_entry(name, p) for name, p in entries]


def ext_exchange_vectors() -> dict[str, Any]:
    """A scripted session with ONSET events on, off, and the extension NAKs."""
    steps: list[dict[str, Any]] = []

    def step(t_us: int, note: str, request: Packet, replies: list[Packet]) -> None:
        steps.append({
            "t_us": t_us,
            "note": note,
            "input": _hex(wire.encode_frame(request)),
            "output": _hex(b"".join(wire.encode_frame(r) for r in replies)),
        })

    def ack(seq: int) -> Packet:
        return wire_device.encode_reply(seq, Ack(seq))

    def nak(seq: int, code: NakCode) -> Packet:
        return wire_device.encode_reply(seq, Nak(seq, code))

    def onset(seq: int, kind: MsgType, t_us: int) -> Packet:
        return wire_device.encode_reply(seq, Onset(seq, kind, t_us))

    levels = (1000, 0, 0, 0, 0, 2000)
    play = (4500, 1, 0, 1500, 1000, 100, 0)
    on = ConfigFlag.ONSET_EVENTS
    step(1_000, "SET_CONFIG with flags: onset events on", wire.set_config(0, 250, 30000, on),
         [ack(0)])
    step(2_000, "first SET_AMPLITUDES after idle: ONSET", wire.set_amplitudes(1, levels),
         [onset(1, MsgType.SET_AMPLITUDES, 2_000)])
    step(3_000, "SET_AMPLITUDES while streaming: no ONSET", wire.set_amplitudes(2, levels), [])
    step(4_000, "PLAY_TARGET: ACK, then ONSET", wire.play_target(3, *play),
         [ack(3), onset(3, MsgType.PLAY_TARGET, 4_000)])
    step(5_000, "GET_DIAG", wire.get_diag(4),
         [wire_device.encode_reply(4, Diag(5_000, 0, 0, 0))])
    step(6_000, "an unknown flag: NAK 4, nothing changes", wire.set_config(5, 250, 30000, 0x04),
         [nak(5, NakCode.OUT_OF_RANGE)])
    step(7_000, "GET_DIAG with a payload: NAK 3", Packet(MsgType.GET_DIAG, 6, b"\x00"),
         [nak(6, NakCode.BAD_LENGTH)])
    step(8_000, "DEBUG_HANG without a debug hook: NAK 2", Packet(0x7E, 7),
         [nak(7, NakCode.UNKNOWN_TYPE)])
    step(9_000, "STOP_ALL", wire.stop_all(8), [ack(8)])
    step(10_000, "SET_AMPLITUDES after STOP_ALL: ONSET again", wire.set_amplitudes(9, levels),
         [onset(9, MsgType.SET_AMPLITUDES, 10_000)])
    step(11_000, "flags off", wire.set_config(10, 250, 30000, 0), [ack(10)])
    step(12_000, "STOP_ALL", wire.stop_all(11), [ack(11)])
    step(13_000, "PLAY_TARGET without the flag: ACK only", wire.play_target(12, *play),
         [ack(12)])
    step(14_000, "SENSE_START without an accelerometer (firmware 1.1): NAK 2",
         wire.sense_start(13, 0, 1000), [nak(13, NakCode.UNKNOWN_TYPE)])
    step(15_000, "SENSE_STOP without an accelerometer: NAK 2", wire.sense_stop(14),
         [nak(14, NakCode.UNKNOWN_TYPE)])
    return {"tactors": 6, "pwm_steps": EXCHANGE_PWM_STEPS, "steps": steps}


def ext_ble_vectors() -> dict[str, Any]:
    """GET_INFO on BLE: refused (NAK 5) at MTU 23, whole at MTU 33, framed in pieces."""
    info = wire_device.encode_reply(1, default_info())
    framed = wire.encode_frame(info)
    chunk = 23 - 3
    return {
        "note": "GET_INFO (seq 1) on BLE, 6 tactors: the INFO packet is "
                f"{len(wire.encode_packet(info))} bytes",
        "request": _hex(wire.encode_packet(wire.get_info(1))),
        "info_packet": _hex(wire.encode_packet(info)),
        "mtu_23_unframed": [_hex(wire.encode_packet(
            wire_device.encode_reply(1, Nak(1, NakCode.REPLY_TOO_LONG))))],
        "mtu_33_unframed": [_hex(wire.encode_packet(info))],
        "mtu_23_framed": [_hex(framed[i:i + chunk]) for i in range(0, len(framed), chunk)],
    }


# --- the board's accelerometer (firmware 1.2) -------------------------------------------------

#: The fake accelerometer of the sensing exchange: its shortest period and full scale.
FAKE_PERIOD_US = 1000
FAKE_FULL_SCALE_MG = 8000


def fake_sample(stamp_us: int) -> tuple[int, int, int]:
    """What the exchange's fake accelerometer reads for a sample stamped ``stamp_us``."""
    k = stamp_us // 1000
    return (k & 0x3FFF, -(k & 0x3FFF), 4096 + (k & 0xF))


class _SenseModel:
    """The device's sampling (firmware/tactorbelt/src/core/sense.cpp) in Python, for the
    exchange: what SENSE_DATA it sends, and when. Its link never lacks room."""

    def __init__(self, min_period_us: int, full_scale_mg: int) -> None:
        self.min_period = min_period_us
        self.full_scale = full_scale_mg
        self.active = False
        self.out: list[Packet] = []
        self.batch: list[tuple[int, int, int]] = []

    def start(self, seq: int, rate_hz: int, duration_ms: int, now: int) -> None:
        if self.active:
            self._finish()
        period = self.min_period
        if rate_hz:
            period = max(period, -(-1_000_000 // rate_hz))
        self.period = min(period, 0xFFFF)
        self.session, self.index, self.batch = seq, 0, []
        self.next, self.end, self.active = now, now + duration_ms * 1000, True

    def stop(self) -> None:
        if self.active:
            self._finish()

    def poll(self, now: int) -> None:
        if self.active and now >= self.next:
            stamp = self.next
            if stamp < self.end and now - stamp > self.period // 2:
                self._close(0)
                stamp = now
            if stamp >= self.end:
                self._finish()
                return
            if not self.batch:
                self.t0, self.first = stamp, self.index
            self.batch.append(fake_sample(stamp))
            if len(self.batch) == wire.SENSE_MAX_SAMPLES:
                self._close(0)
            self.index += 1
            self.next = stamp + self.period
        elif self.active and now >= self.end:
            self._finish()

    def _finish(self) -> None:
        self._close(SenseFlag.LAST)
        self.active = False

    def _close(self, flags: int) -> None:
        if not self.batch and not flags & SenseFlag.LAST:
            return
        if not self.batch:
            self.first, self.t0 = self.index, min(self.next, self.end)
        values = tuple(v for sample in self.batch for v in sample)
        self.out.append(wire_device.encode_reply(self.session, SenseData(
            self.session, int(flags), self.first, self.t0, self.period, self.full_scale,
            values)))
        self.batch = []


def sense_exchange_vectors() -> dict[str, Any]:
    """A scripted session with a 6-tactor controller whose fake accelerometer (shortest
    period 1000 us, +-8 g) reads :func:`fake_sample` of each sample's stamp. The runner
    ticks the controller every millisecond up to a step's time and polls the sensing after
    each tick, then hands it the step's input and polls once more (the order of the
    sketch's loop); a step's output is everything sent since the previous step, byte for
    byte."""
    steps: list[dict[str, Any]] = []
    model = _SenseModel(FAKE_PERIOD_US, FAKE_FULL_SCALE_MG)
    clock = [0]

    def take() -> list[Packet]:
        out, model.out = model.out, []
        return out

    def step(t_us: int, note: str, requests: list[Packet]) -> None:
        out: list[Packet] = []
        while clock[0] + 1000 <= t_us:
            clock[0] += 1000
            model.poll(clock[0])
        out += take()
        clock[0] = t_us
        for p in requests:
            out += answer(p, t_us)
        model.poll(t_us)
        out += take()
        steps.append({
            "t_us": t_us,
            "note": note,
            "input": _hex(b"".join(wire.encode_frame(p) for p in requests)),
            "output": _hex(b"".join(wire.encode_frame(p) for p in out)),
        })

    def answer(p: Packet, t_us: int) -> list[Packet]:
        seq = p.seq
        if p.type == MsgType.SENSE_START:
            if len(p.payload) != 7:
                return [wire_device.encode_reply(seq, Nak(seq, NakCode.BAD_LENGTH))]
            req = wire_device.parse_request(p)
            assert isinstance(req, wire_device.SenseStart)
            if not 1 <= req.duration_ms <= wire.SENSE_MAX_DURATION_MS or (
                    req.tactor != wire.SENSE_ANY_TACTOR and req.tactor >= 6):
                return [wire_device.encode_reply(seq, Nak(seq, NakCode.OUT_OF_RANGE))]
            model.start(seq, req.rate_hz, req.duration_ms, t_us)
            return [*take(), wire_device.encode_reply(seq, Ack(seq))]
        if p.type == MsgType.SENSE_STOP:
            model.stop()
            return [*take(), wire_device.encode_reply(seq, Ack(seq))]
        if p.type == MsgType.GET_INFO:
            caps = int(wire.Capability.PLAY_TARGET | wire.Capability.SENSE)
            return [wire_device.encode_reply(seq, default_info(capabilities=caps))]
        if p.type == MsgType.GET_STATUS:
            return [wire_device.encode_reply(seq, Status(State.IDLE, 0, 0, 0, 0, (0,) * 6))]
        if p.type == MsgType.GET_DIAG:
            return [wire_device.encode_reply(seq, Diag(t_us, 0, 0, 0))]
        raise AssertionError(f"no answer for {p}")

    step(1_000, "GET_INFO: capability bit 1, the accelerometer", [wire.get_info(0)])
    step(2_000, "SENSE_START at the highest rate (1000 us) for 20 ms: ACK; the first sample "
         "is read at once", [wire.sense_start(1, 0, 20)])
    step(10_000, "GET_STATUS while sensing: the first batch (7 samples) came before it",
         [wire.get_status(2)])
    step(30_000, "GET_DIAG: the second batch, and the third (6 samples, the last: 20 ms "
         "passed at 22000)", [wire.get_diag(3)])
    step(31_000, "SENSE_START at 400 Hz (2500 us; read on the 1 ms polls, up to 500 us "
         "late, stamped on time), tactor 2", [wire.sense_start(4, 400, 1000, 2)])
    step(50_000, "SENSE_STOP: the first batch came at 46000; the last (1 sample), then ACK",
         [wire.sense_stop(5)])
    step(51_000, "SENSE_STOP again: ACK only", [wire.sense_stop(6)])
    step(52_000, "SENSE_START for tactor 6 of 6, for 0 ms, for more than an hour: NAK 4",
         [wire.sense_start(7, 0, 1000, 6), wire.sense_start(8, 0, 0),
          wire.sense_start(9, 0, wire.SENSE_MAX_DURATION_MS + 1)])
    step(53_000, "SENSE_START with 6 bytes: NAK 3", [Packet(MsgType.SENSE_START, 10, bytes(6))])
    step(60_000, "SENSE_START for 100 ms", [wire.sense_start(11, 0, 100, 0)])
    step(62_000, "SENSE_START while sensing: the last batch of the old session (3 samples), "
         "the ACK, the new session's first sample", [wire.sense_start(12, 0, 100, 1)])
    step(63_000, "SENSE_STOP: the last batch (2 samples), then the ACK", [wire.sense_stop(13)])
    step(70_000, "GET_STATUS: nothing more", [wire.get_status(14)])
    return {"tactors": 6, "pwm_steps": EXCHANGE_PWM_STEPS, "accelerometer": {
        "min_period_us": FAKE_PERIOD_US, "full_scale_mg": FAKE_FULL_SCALE_MG,
        "sample": "k = stamp_us / 1000: x = k & 0x3FFF, y = -x, z = 4096 + (k & 0xF)"},
        "steps": steps}


def erm_vectors() -> dict[str, Any]:
    """The ERM model (tactorbelt.devices.erm) on a drive history of two motors: speeds and
    amplitudes every millisecond, from rest; the emulator's ErmBank must give the same."""
    params = ErmParams()
    t_ms = np.arange(0, 601)
    amps = np.zeros((t_ms.size, 2))
    for lo, hi, a in ((5, 150, 1.0), (150, 250, 0.5), (250, 300, 0.2), (300, 400, 0.8),
                      (400, 420, 0.26), (420, 430, 0.24)):
        amps[(t_ms >= lo) & (t_ms < hi), 0] = a
    for lo, hi, a in ((0, 100, 0.3), (200, 500, 1.0), (500, 503, 0.6)):
        amps[(t_ms >= lo) & (t_ms < hi), 1] = a
    levels = np.array([[wire.amplitude_to_level(a) for a in row] for row in amps], dtype=np.int64)
    speed = erm_speed(t_ms.astype(np.int64) * 1_000_000, levels / 65535.0, np.zeros(2), params)
    amplitude = params.amplitude(speed)
    return {
        "params": {"rise_tau_s": params.rise_tau_s, "fall_tau_s": params.fall_tau_s,
                   "start_level": params.start_level,
                   "amplitude_exponent": params.amplitude_exponent},
        "note": "each step: the levels that drive [t_us, the next step's t_us), and the "
                "speed and amplitude at t_us (erm_speed, from rest)",
        "steps": [
            {"t_us": int(t) * 1000, "levels": [int(v) for v in lv],
             "speed": [_num(v) for v in sp], "amplitude": [_num(v) for v in am]}
            for t, lv, sp, am in zip(t_ms, levels, speed, amplitude, strict=True)
        ],
    }


def shape_vectors() -> dict[str, Any]:
    """Drive shaping (firmware 1.3): erm.shape_tick's decision at every 1 ms tick for a
    history of levels, with and without braking, in the firmware's units (drive 1 = full
    duty, so the overdrive bound is 1); the firmware's shape_tick and drive_relax must give
    the same drives and predicted speeds (test/test_drive.cpp)."""
    params = ErmParams()
    levels: list[float] = [0.0] * 3
    for a, n in ((0.5, 80), (1.0, 150), (0.3, 80), (0.0, 100), (0.6, 60), (0.1, 60),
                 (0.8, 40), (0.0, 60)):
        levels += [a] * n
    levels += [i / 100.0 for i in range(100)] + [1.0 - i / 50.0 for i in range(51)]
    levels += [0.0] * 60
    cases = []
    for brake in (True, False):
        w = 0.0
        drives: list[float] = []
        reverse: list[bool] = []
        speeds: list[float] = []
        for a in levels:
            d, w = shape_tick(a, w, 1e-3, params.start_level, 1.0, brake, params.rise_tau_s,
                              params.fall_tau_s, params.brake_tau_s)
            drives.append(_num(abs(d)))
            reverse.append(math.copysign(1.0, d) < 0.0)
            speeds.append(_num(w))
        cases.append({"brake": brake, "drive": drives, "reverse": reverse, "speed": speeds})
    return {
        "params": {"rise_tau_s": params.rise_tau_s, "fall_tau_s": params.fall_tau_s,
                   "brake_tau_s": params.brake_tau_s, "start_level": params.start_level,
                   "overdrive": 1.0, "tick_s": 1e-3},
        "note": "levels[i] is commanded over tick i; drive[i] (reverse[i]: its sign) is the "
                "shaper's decision at its start and speed[i] the predicted speed at its end, "
                "from rest",
        "levels": [_num(a) for a in levels],
        "cases": cases,
    }


def build_ext_vectors() -> dict[str, Any]:
    """The extensions' vectors (firmware/test/vectors_ext.json)."""
    return {
        "format": FORMAT,
        "generated_by": "scripts/gen_firmware_vectors.py (do not edit by hand)",
        "about": "Protocol v1 extensions (docs/protocol.md, 'Extensions'): GET_DIAG/DIAG, "
                 "ONSET, the SET_CONFIG flags byte, NAK 5 and BLE chunking; SENSE_START, "
                 "SENSE_STOP, SENSE_DATA and NAK 6 (firmware 1.2), the ERM model of the "
                 "emulator's IMU, and drive shaping (firmware 1.3); checked by the firmware "
                 "host tests (test/test_extensions.cpp, test/test_sense.cpp).",
        "packets": ext_packet_vectors(),
        "exchange": ext_exchange_vectors(),
        "ble": ext_ble_vectors(),
        "sense": sense_exchange_vectors(),
        "erm": erm_vectors(),
        "shape": shape_vectors(),
    }


def build_vectors() -> dict[str, Any]:
    """Everything the firmware tests check, as plain JSON values."""
    return {
        "format": FORMAT,
        "generated_by": "scripts/gen_firmware_vectors.py (do not edit by hand)",
        "crc": crc_vectors(),
        "cobs": cobs_vectors(),
        "frames": frame_vectors(),
        "streams": stream_vectors(),
        "exchange": exchange_vectors(),
        "render": render_vectors(),
    }


def dumps(vectors: dict[str, Any]) -> str:
    """JSON with one list element per line, so that diffs stay readable."""
    lines = ["{"]
    keys = list(vectors)
    for i, key in enumerate(keys):
        value = vectors[key]
        comma = "," if i + 1 < len(keys) else ""
        if isinstance(value, list):
            lines.append(f"  {json.dumps(key)}: [")
            for j, item in enumerate(value):
                sep = "," if j + 1 < len(value) else ""
                lines.append("    " + json.dumps(item, separators=(",", ":")) + sep)
            lines.append(f"  ]{comma}")
        elif isinstance(value, dict) and "steps" in value:
            head = {k: v for k, v in value.items() if k != "steps"}
            lines.append(f"  {json.dumps(key)}: {{")
            for k, v in head.items():
                lines.append(f"    {json.dumps(k)}: {json.dumps(v)},")
            lines.append('    "steps": [')
            for j, item in enumerate(value["steps"]):
                sep = "," if j + 1 < len(value["steps"]) else ""
                lines.append("      " + json.dumps(item, separators=(",", ":")) + sep)
            lines.append("    ]")
            lines.append(f"  }}{comma}")
        else:
            lines.append(f"  {json.dumps(key)}: {json.dumps(value)}{comma}")
    lines.append("}")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", action="store_true", help="exit 1 when the file is stale")
    parser.add_argument("-o", "--output", type=Path, default=VECTORS,
                        help=f"vectors.json; {EXT_NAME} goes next to it")
    args = parser.parse_args(argv)
    files = [(args.output, dumps(build_vectors())),
             (args.output.with_name(EXT_NAME), dumps(build_ext_vectors()))]
    if args.check:
        stale = 0
        for path, text in files:
            current = path.read_text() if path.exists() else ""
            if current != text:
                print(f"{path} is stale; run scripts/gen_firmware_vectors.py", file=sys.stderr)
                stale = 1
        return stale
    for path, text in files:
        path.write_text(text)
        print(f"wrote {path} ({len(text)} bytes)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
