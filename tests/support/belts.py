"""Belt fakes shared by the tests: a fake firmware device, its in-memory transport, a
fake bleak client, a pseudo-terminal device, fake serial port listings, and one factory
per registered belt backend for the contract suite (tests/test_belt_contract.py).
"""

from __future__ import annotations

import asyncio
import os
import select
import threading
import time
import tty
from collections.abc import Callable
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

import numpy as np

from support import wire_device
from tactorbelt import Layout, ProtocolError
from tactorbelt.devices import ble, wire
from tactorbelt.devices._firmware import FirmwareBelt, PacketSink, Transport


@dataclass
class FakeFirmware:
    """A protocol v1 device in Python: answers requests, records what it got.

    Attributes:
        silent: drop every request without an answer (a hung device).
        protocol_version, capabilities, heartbeat_ms, angles_deg: what INFO reports.
        requests: every valid request, parsed, in order of arrival.
        seqs: their sequence numbers.
        extra_replies: a function of the request packet giving packets to send
            before the real reply (garbage, stale replies, ...).
        extensions: firmware 1.1 (GET_DIAG, ONSET events, SET_CONFIG flags); without,
            a plain 1.0.0 device that NAKs GET_DIAG with code 2.
        reset_flags: what DIAG reports as the cause of the last reset.
        flags: the SET_CONFIG flags in force (per connection).
        onset_times_us: the device time of every ONSET sent, by request seq.
        sense: SENSE_START (firmware 1.2): a function of the request, its seq and the
            device time giving the SENSE_DATA batches sent at once after the ACK (the
            whole session, its last batch included); None: no SENSE (NAK 2, firmware
            1.1). INFO's capability bit 1 is the test's to set (``capabilities``).
        sense_unavailable: SENSE_START is NAKed with code 6 (the IMU did not start).
    """

    tactors: int = 6
    protocol_version: int = 1
    capabilities: int = 1
    heartbeat_ms: int = 250
    angles_deg: tuple[float, ...] | None = None
    silent: bool = False
    requests: list[wire_device.Request] = field(default_factory=list)
    seqs: list[int] = field(default_factory=list)
    levels: list[int] = field(default_factory=list)
    state: wire.State = wire.State.IDLE
    extra_replies: Callable[[wire.Packet], list[wire.Packet]] | None = None
    got_request: threading.Event = field(default_factory=threading.Event)
    extensions: bool = False
    reset_flags: int = 0
    flags: int = 0
    max_on_ms: int = 30000
    onset_times_us: dict[int, int] = field(default_factory=dict)
    sense: Callable[[wire_device.SenseStart, int, int], list[wire.SenseData]] | None = None
    sense_unavailable: bool = False

    #: what INFO reports as the firmware version
    fw_version: tuple[int, int, int] = (1, 2, 3)

    def now_us(self) -> int:
        """The device clock: microseconds of time.perf_counter_ns (offset by an hour)."""
        return time.perf_counter_ns() // 1000 + 3_600_000_000

    def __post_init__(self) -> None:
        if self.angles_deg is None:
            self.angles_deg = Layout.even(self.tactors).angles_deg
        self.levels = [0] * self.tactors
        self._lock = threading.Lock()

    def of_type(self, kind: type) -> list[wire_device.Request]:
        with self._lock:
            return [r for r in self.requests if isinstance(r, kind)]

    def handle(self, packet: wire.Packet) -> list[wire.Packet]:
        """The replies to one request packet."""
        if self.silent:
            return []
        if packet.type == wire.MsgType.GET_DIAG and not self.extensions:
            with self._lock:
                self.seqs.append(packet.seq)  # NAKed, but a valid packet for seq tracking
            return [wire_device.encode_reply(packet.seq, wire.Nak(packet.seq,
                                                           wire.NakCode.UNKNOWN_TYPE))]
        if (packet.type == wire.MsgType.SET_CONFIG and len(packet.payload) == 7
                and not self.extensions):
            return [wire_device.encode_reply(packet.seq,
                                             wire.Nak(packet.seq, wire.NakCode.BAD_LENGTH))]
        if (packet.type in (wire.MsgType.SENSE_START, wire.MsgType.SENSE_STOP)
                and self.sense is None and not self.sense_unavailable):
            with self._lock:
                self.seqs.append(packet.seq)
            return [wire_device.encode_reply(packet.seq, wire.Nak(packet.seq,
                                                           wire.NakCode.UNKNOWN_TYPE))]
        try:
            req = wire_device.parse_request(packet)
        except ProtocolError:
            code = (wire.NakCode.UNKNOWN_TYPE if packet.type not in set(wire.MsgType)
                    else wire.NakCode.BAD_LENGTH)
            return [wire_device.encode_reply(packet.seq, wire.Nak(packet.seq, code))]
        with self._lock:
            self.requests.append(req)
            self.seqs.append(packet.seq)
        self.got_request.set()
        out = list(self.extra_replies(packet)) if self.extra_replies else []
        before = self.state
        t_us = self.now_us()
        reply = self._answer(packet.seq, req)
        if reply is not None:
            out.append(wire_device.encode_reply(packet.seq, reply))
        if isinstance(req, wire_device.SenseStart) and isinstance(reply, wire.Ack):
            assert self.sense is not None
            out += [wire_device.encode_reply(packet.seq, b)
                    for b in self.sense(req, packet.seq, t_us)]
        starts = isinstance(req, wire_device.PlayTarget) or (
            isinstance(req, wire_device.SetAmplitudes) and before != wire.State.STREAMING)
        if starts and self.flags & wire.ConfigFlag.ONSET_EVENTS:
            self.onset_times_us[packet.seq] = t_us
            out.append(wire_device.encode_reply(packet.seq,
                                                wire.Onset(packet.seq, packet.type, t_us)))
        return out

    def link_closed(self) -> None:
        """The connection ends: flags cleared (and the outputs off)."""
        self.flags = 0
        self.levels = [0] * self.tactors
        self.state = wire.State.IDLE

    def _answer(self, seq: int, req: wire_device.Request) -> wire.Reply | None:
        ack = wire.Ack(seq, 0)
        if isinstance(req, wire_device.Ping):
            return wire.Pong(req.nonce, self.now_us() & 0xFFFFFFFF)
        if isinstance(req, wire_device.GetDiag):
            return wire.Diag(self.now_us(), self.reset_flags, 0, 0)
        if isinstance(req, wire_device.GetInfo):
            assert self.angles_deg is not None
            caps = self.capabilities
            if self.extensions and self.reset_flags & wire.ResetFlag.WATCHDOG:
                caps |= wire.Capability.WATCHDOG_RESET
            return wire.Info(self.protocol_version, *self.fw_version, len(self.angles_deg),
                             65535, self.heartbeat_ms, caps, tuple(self.angles_deg))
        if isinstance(req, wire_device.SetAmplitudes):
            self.levels = list(req.levels)
            self.state = wire.State.STREAMING
            return None
        if isinstance(req, wire_device.StopAll):
            self.levels = [0] * self.tactors
            self.state = wire.State.IDLE
            return ack
        if isinstance(req, wire_device.PlayTarget):
            self.state = wire.State.PLAYING
            return ack
        if isinstance(req, wire_device.SetConfig):
            if not 50 <= req.heartbeat_ms <= 2000 or (
                    req.flags is not None and req.flags & ~0x03):
                return wire.Nak(seq, wire.NakCode.OUT_OF_RANGE)
            self.heartbeat_ms = req.heartbeat_ms
            if req.max_on_ms is not None:
                self.max_on_ms = req.max_on_ms
            if req.flags is not None:
                self.flags = req.flags
            return ack
        if isinstance(req, wire_device.GetStatus):
            return wire.Status(self.state, 0, 0, 0, 0, tuple(self.levels))
        if isinstance(req, wire_device.SenseStart):
            if self.sense_unavailable:
                return wire.Nak(seq, wire.NakCode.UNAVAILABLE)
            if not 1 <= req.duration_ms <= wire.SENSE_MAX_DURATION_MS or (
                    req.tactor != wire.SENSE_ANY_TACTOR and req.tactor >= self.tactors):
                return wire.Nak(seq, wire.NakCode.OUT_OF_RANGE)
            return ack
        if isinstance(req, wire_device.SenseStop):
            return ack
        return None  # HEARTBEAT


class LoopTransport(Transport):
    """An in-memory link: each write is one packet, answered at once by the fake."""

    def __init__(self, device: FakeFirmware, port: str = "loop0") -> None:
        self.device = device
        self.port = port
        self.sink: PacketSink | None = None
        self.dead = False
        self.closed = False

    def encode(self, packet: wire.Packet) -> bytes:
        return wire.encode_packet(packet)

    def write(self, data: bytes) -> None:
        if self.dead:
            raise OSError(5, "Input/output error")
        assert self.sink is not None
        for reply in self.device.handle(wire.decode_packet(data)):
            self.sink.packet_received(reply)

    def start(self, sink: PacketSink) -> None:
        self.sink = sink

    def close(self) -> None:
        self.closed = True

    def kill(self) -> None:
        """The link ends (a cable pulled): the reader reports it, writes fail."""
        self.dead = True
        assert self.sink is not None
        self.sink.link_lost("end of file")


def write_raw(belt: FirmwareBelt, data: bytes) -> None:
    """Write bytes to the belt's link as they are, between packets: the device counts what
    it cannot decode and skips it; a serial device resynchronises at the next 0x00."""
    with belt._tx_lock:
        belt._write(data)


def hang(belt: FirmwareBelt) -> None:
    """Send the emulator's DEBUG_HANG (0x7E): an emulator started with ``debug_frames`` ACKs
    it, then its loop stops (no tick, no failsafe) until its watchdog resets it; any other
    firmware NAKs it (code 2: a ProtocolError)."""
    belt._request(lambda seq: wire.Packet(0x7E, seq), "DEBUG_HANG", expect=wire.Ack)


def wait_for(predicate: Callable[[], object], timeout_s: float = 5.0) -> bool:
    """Poll a condition another thread makes true (for keep-alive behaviour)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.005)
    return bool(predicate())


def open_fake(device: FakeFirmware | None = None, **options: object
              ) -> tuple[FirmwareBelt, FakeFirmware, LoopTransport]:
    device = device or FakeFirmware()
    transport = LoopTransport(device)
    options.setdefault("keepalive", False)
    belt = FirmwareBelt(transport, "loop:loop0", **options)  # type: ignore[arg-type]
    return belt, device, transport




class FakeBleClient:
    """A bleak-like client connected to a FakeFirmware.

    Attributes:
        writes: every (characteristic, data, response) written.
        corrupt: notify a corrupted and a truncated packet before each reply.
        fail_connect: connect() raises like an out-of-range device.
    """

    def __init__(self, firmware: FakeFirmware, on_disconnect: Callable[[Any], None],
                 mtu: int = 247) -> None:
        self.firmware = firmware
        self.mtu_size = mtu
        self.notifications: list[bytes] = []
        self.on_disconnect = on_disconnect
        self.address = "AA:BB:CC:DD:EE:FF"
        self.connected = False
        self.disconnects = 0
        self.writes: list[tuple[str, bytes, bool]] = []
        self.notify: Callable[[Any, bytearray], None] | None = None
        self.corrupt = False
        self.fail_connect = False

    @property
    def is_connected(self) -> bool:
        return self.connected

    async def connect(self) -> None:
        if self.fail_connect:
            raise TimeoutError("device out of range")
        self.connected = True

    async def disconnect(self) -> None:
        if self.connected:
            self.firmware.link_closed()
        self.connected = False
        self.disconnects += 1

    async def start_notify(self, char: str, callback: Callable[[Any, bytearray], None]) -> None:
        assert char == ble.TX_CHAR_UUID
        self.notify = callback

    async def write_gatt_char(self, char: str, data: bytes, response: bool) -> None:
        if not self.connected:
            raise OSError("not connected")
        self.writes.append((char, bytes(data), response))
        if len(data) > self.mtu_size - 3:
            raise OSError(f"write of {len(data)} bytes exceeds the MTU")
        loop = asyncio.get_running_loop()
        limit = self.mtu_size - 3
        for reply in self.firmware.handle(wire.decode_packet(bytes(data))):
            raw = wire.encode_packet(reply)
            if self.firmware.flags & wire.ConfigFlag.BLE_FRAMED:  # a byte stream in pieces
                frame = wire.encode_frame(reply)
                for i in range(0, len(frame), limit):
                    self._notify(loop, frame[i:i + limit])
                continue
            if len(raw) > limit:  # the firmware never sends what the stack would cut
                if not self.firmware.extensions:
                    self._notify(loop, raw[:limit])  # plain v1: cut short by the stack
                    continue
                raw = wire.encode_packet(wire_device.encode_reply(
                    reply.seq, wire.Nak(reply.seq, wire.NakCode.REPLY_TOO_LONG)))
            if self.corrupt:
                bad = bytearray(raw)
                bad[2] ^= 0x55
                loop.call_soon(self.notify, None, bad)  # type: ignore[arg-type]
                loop.call_soon(self.notify, None, bytearray(raw[:3]))  # type: ignore[arg-type]
            self._notify(loop, raw)

    def _notify(self, loop: asyncio.AbstractEventLoop, data: bytes) -> None:
        self.notifications.append(bytes(data))
        loop.call_soon(self.notify, None, bytearray(data))  # type: ignore[arg-type]

    def drop(self) -> None:
        """The device disconnects (out of range, powered off)."""
        self.connected = False
        self.firmware.link_closed()
        self.on_disconnect(self)


class FakeBle:
    """A client_factory that hands out FakeBleClients for one FakeFirmware."""

    def __init__(self, firmware: FakeFirmware | None = None, mtu: int = 247) -> None:
        self.firmware = firmware or FakeFirmware()
        self.mtu = mtu
        self.client: FakeBleClient | None = None
        self.targets: list[str] = []
        self.fail_connect = False

    async def __call__(self, target: str, on_disconnect: Callable[[Any], None],
                       scan_timeout_s: float) -> FakeBleClient:
        self.targets.append(target)
        self.client = FakeBleClient(self.firmware, on_disconnect, self.mtu)
        self.client.fail_connect = self.fail_connect
        return self.client




class PtyDevice:
    """A FakeFirmware served on a pseudo-terminal (``path`` is what the host opens).

    Attributes:
        garbage: before each reply, also send random bytes and a frame with a bad CRC.
        bytes_in: every byte the host wrote.
    """

    def __init__(self, firmware: FakeFirmware, seed: int = 1) -> None:
        self.firmware = firmware
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.path = os.ttyname(self._slave)
        self.garbage = False
        self.garbage_sent = 0
        self.bytes_in = bytearray()
        self._rng = np.random.default_rng(seed)
        self._decoder = wire.FrameDecoder()
        self._stop_r, self._stop_w = os.pipe()
        self._thread = threading.Thread(target=self._serve, daemon=True)
        self._thread.start()

    def _serve(self) -> None:
        while True:
            ready, _, _ = select.select([self.master, self._stop_r], [], [])
            if self._stop_r in ready:
                return
            try:
                data = os.read(self.master, 4096)
            except OSError:
                return
            self.bytes_in += data
            for packet in self._decoder.feed(data):
                for reply in self.firmware.handle(packet):
                    out = b""
                    if self.garbage:
                        noise = self._rng.integers(0, 256, 40, dtype=np.uint8).tobytes()
                        bad = bytearray(wire.encode_packet(reply))
                        bad[-1] ^= 0xFF
                        out += noise + b"\x00" + wire.cobs_encode(bytes(bad)) + b"\x00"
                        self.garbage_sent += 1
                    os.write(self.master, out + wire.encode_frame(reply))

    def hang_up(self) -> None:
        """The device vanishes: the master side closes (the host reads EIO)."""
        os.write(self._stop_w, b"x")
        self._thread.join()
        os.close(self.master)
        self.master = -1

    def close(self) -> None:
        if self.master >= 0:
            self.hang_up()
        os.close(self._slave)
        os.close(self._stop_r)
        os.close(self._stop_w)




def comports(*ports: SimpleNamespace) -> object:
    return lambda: list(ports)


def port_info(device: str, description: str, vid: int | None = None) -> SimpleNamespace:
    return SimpleNamespace(device=device, description=description, vid=vid,
                           pid=0x805A if vid else None, product=None, manufacturer=None)




# --- one factory per registered backend, for tests/test_belt_contract.py -----------------


@dataclass
class Harness:
    """An open belt of one backend and a way to read what its device outputs.

    Attributes:
        belt: the open belt.
        device_levels: the levels the device outputs now (0..1 per tactor), read on the
            device side (after ``belt.close()`` too).
        cleanup: releases the fake device (after the belt is closed).
    """

    belt: Any
    device_levels: Callable[[], list[float]]
    cleanup: Callable[[], None] = lambda: None


def _synced(belt: FirmwareBelt, read: Callable[[], list[int]]) -> Callable[[], list[float]]:
    """Device levels after every packet sent so far has arrived (a PING round trip)."""

    def levels() -> list[float]:
        if not belt.closed:
            belt.ping()
        return [v / 65535.0 for v in read()]

    return levels


def _skip(reason: str) -> None:
    import pytest

    pytest.skip(reason)


def sim_harness(**options: Any) -> Harness:
    from tactorbelt.clock import SimClock
    from tactorbelt.devices import open_belt

    clock = SimClock()
    belt = open_belt("sim", clock=clock, **options)
    return Harness(belt, lambda: [float(v) for v in belt.levels])


def emulator_harness(tmp_dir: str | None = None, **options: Any) -> Harness:
    import shutil
    import tempfile
    from pathlib import Path

    from tactorbelt import DeviceError
    from tactorbelt.devices import open_belt
    from tactorbelt.devices.emulator import build_emulator, firmware_dir

    missing = [t for t in ("g++", "make") if shutil.which(t) is None]
    if missing:
        _skip(f"the firmware emulator needs {' and '.join(missing)} to build")
    try:
        build_emulator(firmware_dir())
    except DeviceError as exc:
        _skip(f"the firmware emulator cannot be built here: {exc}")
    folder = Path(tmp_dir or tempfile.mkdtemp(prefix="tactorbelt-contract-"))
    log = folder / "levels.csv"
    belt = open_belt("emulator", build=False, levels_log=log, **options)

    def device_levels() -> list[float]:
        if not belt.closed:
            return [v / 65535.0 for v in belt.status().levels]
        assert wait_for(lambda: belt.process.poll() is not None)
        last = log.read_text().strip().splitlines()[-1].split(",")
        return [int(v) / 65535.0 for v in last[2:]]

    return Harness(belt, device_levels)


def serial_harness(**options: Any) -> Harness:
    from tactorbelt.devices import open_belt

    dev = PtyDevice(FakeFirmware())
    try:
        belt = open_belt(f"serial:{dev.path}", **options)
    except BaseException:
        dev.close()
        raise
    return Harness(belt, _synced(belt, lambda: dev.firmware.levels), dev.close)


def ble_harness(**options: Any) -> Harness:
    from tactorbelt.devices import open_belt

    fake = FakeBle()
    belt = open_belt("ble:tactorbelt", client_factory=fake, **options)
    return Harness(belt, _synced(belt, lambda: fake.firmware.levels))


def audio_harness(**options: Any) -> Harness:
    """A 6-tactor audio belt on a real JACK server (dummy backend), skipped without JACK;
    the device side is what the audio callback last wrote to the sound card's buffer."""
    from support.audio import DEVICE, ensure_jack
    from tactorbelt.devices import open_belt

    ensure_jack()
    belt = open_belt(f"audio:{DEVICE}?channels=6", **options)
    return Harness(belt, lambda: audio_output_levels(belt))


def audio_output_levels(belt: Any) -> list[float]:
    """The envelope an audio belt's callback last wrote to the device, per tactor
    (calibrated levels, before the frequency-response correction), after any ramp is over."""
    if not belt.closed:
        belt.settle()
    return [float(v) for v in belt._last_env]


def navibelt_harness(**options: Any) -> Harness:
    """A 6-motor naviBelt on the emulation, through pybelt (skipped without pybelt); the
    device side is the emulated motors (after the link closes: as they were when it did,
    before the belt stopped them itself)."""
    import importlib.util

    from tactorbelt.devices import open_belt

    if importlib.util.find_spec("pybelt") is None:
        _skip("pybelt is not installed (pip install 'tactorbelt[navibelt]')")
    belt = open_belt("navibelt:emulator?motors=1,4,7,9,12,15", **options)
    em = belt.emulation

    def device_levels() -> list[float]:
        if not belt.closed:
            belt.ping()
            levels = em.motor_levels()
        else:
            levels = em.levels_at_link_loss or em.motor_levels()
        return [levels[m] for m in belt.motors]

    return Harness(belt, device_levels)


def loop_harness(**options: Any) -> Harness:
    """Not a registered scheme: FirmwareBelt over the in-memory loop transport."""
    options.setdefault("keepalive", False)
    belt, device, _ = open_fake(**options)
    return Harness(belt, _synced(belt, lambda: device.levels))


def url_harness(url: str, **options: Any) -> Harness:
    """A belt opened by its registered ``contract_url``; the device side is read as the
    belt's own ``levels`` (the backend declares no fake device to read instead)."""
    from tactorbelt.devices import open_belt

    belt = open_belt(url, **options)

    def levels() -> list[float]:
        lv = belt.levels
        return [0.0] * belt.n_tactors if lv is None else [float(v) for v in lv]

    return Harness(belt, levels)


#: scheme -> harness factory with a fake device. A registered scheme needs one unless
#: its Backend has a ``contract_url`` that opens without hardware (the contract suite
#: then opens that URL; tests/support/toy_belt.py); the suite fails for a scheme with
#: neither.
FACTORIES: dict[str, Callable[..., Harness]] = {
    "sim": sim_harness,
    "emulator": emulator_harness,
    "serial": serial_harness,
    "ble": ble_harness,
    "audio": audio_harness,
    "navibelt": navibelt_harness,
}
#: Further cases of the contract that are not URL schemes.
EXTRA_FACTORIES: dict[str, Callable[..., Harness]] = {
    "firmware-loop": loop_harness,
}
