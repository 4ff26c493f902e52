"""The firmware never lets a link or a hang keep the motors on: the emulator, byte level.

The emulator (``firmware/build/emulator``) runs the board's core with the board's reply
path: replies go into a bounded TX ring of whole frames that is drained without blocking,
and a frame that does not fit is dropped and counted (GET_DIAG). These tests talk to its
pseudo-terminal directly, with raw bytes (no belt class), and read its levels log, so the
times are device times:

- a host that holds the port open but stops reading, after a SET_AMPLITUDES or a
  PLAY_TARGET, while it floods requests and then goes quiet: the 1 kHz tick keeps
  running (a dynamic PLAY_TARGET keeps changing the levels) and the heartbeat failsafe
  turns every output off one timeout after the last request; the replies that did not
  fit were dropped and counted, never waited for;
- a loop that hangs (DEBUG_HANG, emulator only): no tick, so no failsafe; the watchdog
  (``--watchdog-ms``) resets the core, every output off, and the next INFO and GET_DIAG
  report the watchdog reset.

Skipped when g++ or make is missing.
"""

from __future__ import annotations

import os
import struct
import subprocess
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from tactorbelt.devices import wire

pytestmark = pytest.mark.emulator

GET_DIAG = 0x17
DIAG = 0x84
ONSET = 0x85
DEBUG_HANG = 0x7E
RESET_WATCHDOG = 0x02
CAP_WATCHDOG_RESET = 0x80
HEARTBEAT_MS = 100



class Emu:
    """The emulator process, its pseudo-terminal (opened raw, non-blocking) and its log."""

    def __init__(self, exe: Path, log: Path, *args: str) -> None:
        self.log = log
        self.proc = subprocess.Popen(
            [str(exe), "--levels-log", str(log), "--heartbeat-ms", str(HEARTBEAT_MS), *args],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        )
        assert self.proc.stdout is not None
        self.pty = self.proc.stdout.readline().decode().strip()
        self.fd = os.open(self.pty, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        self.seq = 0
        self.decoder = wire.FrameDecoder()

    def send(self, packet_type: int, payload: bytes = b"") -> int:
        seq = self.seq
        self.seq = (self.seq + 1) % 256
        frame = wire.encode_frame(wire.Packet(packet_type, seq, payload))
        done = 0
        while done < len(frame):
            try:
                done += os.write(self.fd, frame[done:])
            except BlockingIOError:
                time.sleep(0.001)
        return seq

    def read_packets(self, timeout_s: float = 0.5, until_type: int | None = None
                     ) -> list[wire.Packet]:
        """Everything the device sent, read until quiet (or until a packet of a type)."""
        out: list[wire.Packet] = []
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            try:
                data = os.read(self.fd, 65536)
            except BlockingIOError:
                time.sleep(0.005)
                continue
            out += self.decoder.feed(data)
            if until_type is not None and any(p.type == until_type for p in out):
                break
        return out

    def rows(self) -> list[list[int]]:
        lines = self.log.read_text().splitlines()[1:]
        return [[int(v) for v in line.split(",")] for line in lines if line.count(",") >= 2]

    def close(self) -> None:
        os.close(self.fd)
        self.proc.terminate()
        try:
            self.proc.wait(timeout=3)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


StartEmu = Callable[..., Emu]


@pytest.fixture
def start_emu(emulator_exe: Path, tmp_path: Path) -> Iterator[StartEmu]:
    started: list[Emu] = []

    def start(*args: str) -> Emu:
        emu = Emu(emulator_exe, tmp_path / f"levels{len(started)}.csv", *args)
        started.append(emu)
        return emu

    yield start
    for emu in started:
        emu.close()


def _play_dynamic() -> bytes:
    # 45 degrees, dynamic, paper law, 15 degrees, 1000 ms period, 100 ms transit, forever
    return struct.pack("<HBBHHHI", 4500, 1, 0, 1500, 1000, 100, 0)


def _diag(emu: Emu) -> tuple[int, int, int, int]:
    emu.read_packets(0.2)  # whatever is still queued
    seq = emu.send(GET_DIAG)
    for p in emu.read_packets(2.0, until_type=DIAG):
        if p.type == DIAG and p.seq == seq:
            device_us, reset_flags, tx_dropped, ble_refused = struct.unpack("<QBHH", p.payload)
            return device_us, reset_flags, tx_dropped, ble_refused
    raise AssertionError("no DIAG reply")


@pytest.mark.parametrize("start", ["set_amplitudes", "play_target"])
def test_a_host_that_stops_reading_cannot_stall_the_tick(start_emu: StartEmu, start: str) -> None:
    emu = start_emu()
    if start == "set_amplitudes":
        emu.send(wire.MsgType.SET_AMPLITUDES, struct.pack("<6H", 30000, 0, 0, 0, 0, 50000))
    else:
        emu.send(wire.MsgType.PLAY_TARGET, _play_dynamic())
    time.sleep(0.05)
    # Flood requests whose replies nobody reads, for 1.5 s: the pseudo-terminal fills,
    # then the TX ring, then replies are dropped. Each request keeps the heartbeat alive.
    t_flood = time.monotonic()
    while time.monotonic() - t_flood < 1.5:
        for _ in range(50):
            emu.send(wire.MsgType.GET_STATUS)
        time.sleep(0.005)
    last_request = time.monotonic()
    # Quiet now, and still not reading: the failsafe must fire one timeout later.
    failsafe: list[list[int]] = []
    while not failsafe and time.monotonic() - last_request < 2.0:
        time.sleep(0.01)
        failsafe = [r for r in emu.rows() if r[1] == 3]
    seen_after_s = time.monotonic() - last_request
    assert failsafe, "no failsafe while the host neither read nor wrote"
    assert all(v == 0 for v in failsafe[0][2:])
    # wall clock: the timeout plus the log's polling and a loaded machine's slack
    assert seen_after_s < HEARTBEAT_MS / 1000 + 0.5
    rows = emu.rows()
    on = [r for r in rows if r[1] in (1, 2)]
    # device time: the outputs stayed on through the flood (the requests kept the
    # heartbeat alive, and nothing waited on the full buffer)
    assert failsafe[0][0] - on[0][0] > 1_400_000
    if start == "play_target":
        # the tick ran all along: the dynamic pattern kept changing the levels
        t_changes = [r[0] for r in on]
        assert len(t_changes) > 10
        assert t_changes[-1] - t_changes[0] > 1_000_000, "the tick stalled"
        gap_ms = (failsafe[0][0] - t_changes[-1]) / 1e3
        assert gap_ms <= HEARTBEAT_MS + 60, f"failsafe {gap_ms:.0f} ms after the last change"
    # Reading again: the device answers, and counts what it had to drop.
    _, reset_flags, tx_dropped, _ = _diag(emu)
    assert tx_dropped > 0
    assert reset_flags == 0


def test_replies_resume_after_the_host_reads_again(start_emu: StartEmu) -> None:
    emu = start_emu()
    for _ in range(3000):
        emu.send(wire.MsgType.GET_STATUS)
    time.sleep(0.2)
    got = emu.read_packets(1.0)
    # whole frames only: every frame that arrived decodes, none is cut
    assert got and all(p.type == wire.MsgType.STATUS for p in got)
    assert emu.decoder.crc_errors == 0 and emu.decoder.framing_errors == 0
    seq = emu.send(wire.MsgType.PING, struct.pack("<I", 7))
    pongs = [p for p in emu.read_packets(1.0, until_type=wire.MsgType.PONG)
             if p.type == wire.MsgType.PONG]
    assert pongs and pongs[-1].seq == seq


def test_the_watchdog_resets_a_hung_loop(start_emu: StartEmu) -> None:
    emu = start_emu("--watchdog-ms", "300", "--debug-frames")
    emu.send(wire.MsgType.SET_AMPLITUDES, struct.pack("<6H", 40000, 0, 0, 0, 0, 0))
    time.sleep(0.05)
    seq = emu.send(DEBUG_HANG)
    acks = [p for p in emu.read_packets(1.0, until_type=wire.MsgType.ACK)
            if p.type == wire.MsgType.ACK]
    assert acks and acks[0].seq == seq
    time.sleep(0.8)
    rows = emu.rows()
    on = [r for r in rows if r[2] == 40000]
    assert on, "the outputs never came on"
    after = [r for r in rows if r[0] > on[-1][0]]
    assert after and all(v == 0 for v in after[0][2:]), "the hang kept the outputs on"
    hung_ms = (after[0][0] - on[-1][0]) / 1e3
    # no tick during the hang, so no failsafe: it is the watchdog, 300 ms after the last feed
    assert after[0][1] == 0
    assert 250 <= hung_ms <= 300 + 200, f"outputs off {hung_ms:.0f} ms after the last tick"
    # the core booted again and says why
    seq = emu.send(wire.MsgType.GET_INFO)
    infos = [p for p in emu.read_packets(1.0, until_type=wire.MsgType.INFO)
             if p.type == wire.MsgType.INFO]
    assert infos
    info = wire.parse_reply(infos[-1])
    assert isinstance(info, wire.Info)
    assert info.capabilities & CAP_WATCHDOG_RESET
    assert info.capabilities & wire.Capability.PLAY_TARGET
    _, reset_flags, _, _ = _diag(emu)
    assert reset_flags & RESET_WATCHDOG


def test_without_the_debug_flag_a_hang_request_is_refused(start_emu: StartEmu) -> None:
    emu = start_emu("--watchdog-ms", "300")
    seq = emu.send(DEBUG_HANG)
    naks = [p for p in emu.read_packets(1.0, until_type=wire.MsgType.NAK)
            if p.type == wire.MsgType.NAK]
    assert naks and naks[0].payload == bytes([seq, wire.NakCode.UNKNOWN_TYPE])


def test_onset_events_are_opt_in(start_emu: StartEmu) -> None:
    emu = start_emu()
    # plain v1: no ONSET
    emu.send(wire.MsgType.PLAY_TARGET, _play_dynamic())
    assert all(p.type != ONSET for p in emu.read_packets(0.3))
    emu.send(wire.MsgType.STOP_ALL)
    # SET_CONFIG with the flags byte: heartbeat 100 ms, max_on 30 s, onset events on
    emu.send(wire.MsgType.SET_CONFIG, struct.pack("<HIB", HEARTBEAT_MS, 30000, 1))
    emu.read_packets(0.2)
    t_before, _, _, _ = _diag(emu)
    seq = emu.send(wire.MsgType.PLAY_TARGET, _play_dynamic())
    got = emu.read_packets(1.0, until_type=ONSET)
    kinds = [p.type for p in got]
    assert wire.MsgType.ACK in kinds and ONSET in kinds
    assert kinds.index(wire.MsgType.ACK) < kinds.index(ONSET)
    onset = next(p for p in got if p.type == ONSET)
    req_seq, req_type, t_us = struct.unpack("<BBQ", onset.payload)
    assert (onset.seq, req_seq, req_type) == (seq, seq, wire.MsgType.PLAY_TARGET)
    assert t_before < t_us < t_before + 2_000_000
    # the level log agrees: the outputs changed at that device time (same clock)
    starts = [r for r in emu.rows() if r[1] == 2 and r[0] >= t_before]
    assert starts and abs(starts[0][0] - t_us) <= 1000
