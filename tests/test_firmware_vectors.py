"""The firmware's shared test vectors, and the emulator's command-line contract.

``firmware/test/vectors.json`` is written by ``scripts/gen_firmware_vectors.py`` from
``tactorbelt.devices.wire`` and ``tactorbelt.stimuli``; the C++ host tests
(``make -C firmware test``) check the firmware against it. When the Python side
changes, this test fails until the file is regenerated, so the firmware can never
be checked against a stale contract.

The emulator tests (marker ``emulator``) run ``firmware/build/emulator`` directly and
check what docs/protocol.md promises about it: the first stdout line, the levels log,
the exit rules; they take about 3.5 s of wall time and skip without g++ or make.
"""

from __future__ import annotations

import importlib.util
import itertools
import json
import math
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np
import pytest

from tactorbelt.devices import wire

REPO = Path(__file__).resolve().parents[1]
SCRIPT = REPO / "scripts" / "gen_firmware_vectors.py"
VECTORS = REPO / "firmware" / "test" / "vectors.json"

#: Amplitudes are written with 9 decimals; another libm may round the last one apart.
AMPLITUDE_TOLERANCE = 2e-9


def _load_script() -> ModuleType:
    spec = importlib.util.spec_from_file_location("gen_firmware_vectors", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def gen() -> ModuleType:
    return _load_script()


@pytest.fixture(scope="module")
def committed() -> dict[str, Any]:
    data: dict[str, Any] = json.loads(VECTORS.read_text())
    return data


@pytest.fixture(scope="module")
def fresh(gen: ModuleType) -> dict[str, Any]:
    data: dict[str, Any] = gen.build_vectors()
    return data


def _assert_same(a: Any, b: Any, path: str = "") -> None:
    """Exact equality, except floats within AMPLITUDE_TOLERANCE."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and a.keys() == b.keys(), f"keys differ at {path}"
        for k in a:
            _assert_same(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), f"lengths differ at {path}"
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            _assert_same(x, y, f"{path}[{i}]")
    elif isinstance(a, float) or isinstance(b, float):
        assert math.isclose(a, b, rel_tol=0, abs_tol=AMPLITUDE_TOLERANCE), f"{path}: {a} != {b}"
    else:
        assert a == b, f"{path}: {a!r} != {b!r}"


def test_committed_vectors_match_the_package(
    committed: dict[str, Any], fresh: dict[str, Any]
) -> None:
    """Regenerate with: python scripts/gen_firmware_vectors.py"""
    # a JSON round trip turns tuples into lists, as in the committed file
    _assert_same(committed, json.loads(json.dumps(fresh)))


def test_committed_extension_vectors_match_the_package(gen: ModuleType) -> None:
    """vectors_ext.json (GET_DIAG, ONSET, flags, NAK 5, BLE pieces, SENSE, the ERM model)
    comes from the script too, with the firmware version of INFO (1.3.0) that protocol.h
    reports."""
    committed = json.loads((VECTORS.parent / "vectors_ext.json").read_text())
    _assert_same(committed, json.loads(json.dumps(gen.build_ext_vectors())))
    header = (REPO / "firmware" / "tactorbelt" / "src" / "core" / "protocol.h").read_text()
    version = tuple(
        int(header.split(f"kFirmware{part} = ")[1].split(";")[0])
        for part in ("Major", "Minor", "Patch"))
    assert version == gen.FW_VERSION == (1, 3, 0)


def test_extension_vectors_cover_sensing_and_the_erm_model(gen: ModuleType) -> None:
    """The SENSE session and the ERM trace the firmware host tests replay: the session
    streams whole batches, ends one by its duration, one by SENSE_STOP and one by a new
    SENSE_START, and NAKs bad requests; the ERM trace rises, falls and sits in the dead
    zone."""
    ext = json.loads((VECTORS.parent / "vectors_ext.json").read_text())
    frames = b"".join(bytes.fromhex(s["output"]) for s in ext["sense"]["steps"])
    replies = [wire.parse_reply(p) for p in wire.FrameDecoder().feed(frames)]
    batches = [r for r in replies if isinstance(r, wire.SenseData)]
    assert {b.n_samples for b in batches} >= {wire.SENSE_MAX_SAMPLES, 1}
    assert sum(b.last for b in batches) == 4  # one per session
    assert {b.period_us for b in batches} == {1000, 2500}
    naks = {r.code for r in replies if isinstance(r, wire.Nak)}
    assert naks == {wire.NakCode.OUT_OF_RANGE, wire.NakCode.BAD_LENGTH}
    info = next(r for r in replies if isinstance(r, wire.Info))
    assert info.can_sense and info.firmware_version == "1.3.0"
    speed = np.array([s["speed"] for s in ext["erm"]["steps"]])
    assert speed.max() > 0.99 and speed[-1, 0] < 0.05  # up to full speed, and down again
    # 0.24 from 420 ms is in the dead zone: the motor falls from its 0.26
    t = np.array([s["t_us"] for s in ext["erm"]["steps"]])
    dead = (t > 421_000) & (t < 430_000)
    assert np.all(np.diff(speed[dead, 0]) < 0)


def test_the_generator_is_deterministic(gen: ModuleType, fresh: dict[str, Any]) -> None:
    assert gen.dumps(fresh) == gen.dumps(gen.build_vectors())


def test_vectors_cover_the_contract(committed: dict[str, Any]) -> None:
    assert committed["format"] == 1
    assert {"data": b"123456789".hex(), "crc": 0x29B1} in committed["crc"]
    names = {f["name"] for f in committed["frames"]}
    assert names >= {"ping", "get_info", "set_amplitudes", "stop_all", "play_target",
                     "heartbeat", "set_config", "get_status", "ack", "nak", "pong", "info",
                     "status"}
    streams = committed["streams"]
    assert sum(s["crc_errors"] for s in streams) > 0
    assert sum(s["framing_errors"] for s in streams) > 0
    render = committed["render"]
    layouts = {len(c["tactor_angles_deg"]) for c in render}
    assert layouts == {5, 6, 8}
    assert {c["mode"] for c in render} == {0, 1}
    assert {c["law"] for c in render} == {0, 1, 2}
    one_khz = [c for c in render if len(c["t_us"]) == 1000]
    assert one_khz and one_khz[0]["t_us"][:3] == [0, 1000, 2000]


def test_frames_decode_to_what_they_say(committed: dict[str, Any]) -> None:
    for f in committed["frames"]:
        p = wire.Packet(f["type"], f["seq"], bytes.fromhex(f["payload"]))
        assert wire.decode_packet(bytes.fromhex(f["packet"])) == p
        assert wire.FrameDecoder().feed(bytes.fromhex(f["frame"])) == [p]


def test_quarter_point_vector_dwells_600_and_200_ms(committed: dict[str, Any]) -> None:
    """The 1 kHz case is the paper's quarter point: 600 ms on tactor 0, 200 ms on 5."""
    case = next(c for c in committed["render"] if len(c["t_us"]) == 1000)
    assert case["angle_cdeg"] == 1500 and case["mode"] == 1
    amps = case["amplitudes"]
    near_only = sum(1 for a in amps if a[0] > 0 and a[5] == 0)
    far_only = sum(1 for a in amps if a[5] > 0 and a[0] == 0)
    assert near_only == 601  # t = 0..600 ms: the transit starts after 600 ms
    assert far_only == 201  # t = 700..900 ms


def test_check_mode_reports_a_stale_file(gen: ModuleType, tmp_path: Path) -> None:
    out = tmp_path / "vectors.json"
    assert gen.main(["-o", str(out)]) == 0
    assert gen.main(["--check", "-o", str(out)]) == 0
    out.write_text(out.read_text().replace('"format": 1', '"format": 0'))
    assert gen.main(["--check", "-o", str(out)]) == 1


# --- the emulator: the same core on a pseudo-terminal (its command-line contract) ---------


@pytest.fixture(scope="module")
def emulator_exe() -> Path:
    missing = [t for t in ("g++", "make") if shutil.which(t) is None]
    if missing:
        pytest.skip(f"the firmware emulator needs {' and '.join(missing)} to build")
    from tactorbelt.devices.emulator import build_emulator

    return build_emulator(REPO / "firmware")


def _start(exe: Path, *args: str, stdin: Any = subprocess.PIPE) -> tuple[subprocess.Popen[bytes],
                                                                          str]:
    proc = subprocess.Popen([str(exe), *args], stdin=stdin, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE)
    assert proc.stdout is not None
    line = proc.stdout.readline().decode().strip()
    return proc, line


def _read_log(path: Path) -> tuple[list[str], list[list[int]]]:
    lines = path.read_text().splitlines()
    return lines[0].split(","), [[int(v) for v in row.split(",")] for row in lines[1:]]


def _segments(rows: list[list[int]], t0: int, t1: int) -> list[tuple[int, list[int]]]:
    """(duration_us, row) for every logged row that starts in [t0, t1)."""
    out = []
    for a, b in itertools.pairwise(rows):
        if t0 <= a[0] < t1:
            out.append((min(b[0], t1) - a[0], a))
    return out


@pytest.mark.emulator
def test_emulator_cli_contract(emulator_exe: Path, tmp_path: Path) -> None:
    """First line, levels log, dwell pattern, failsafe timing, port close, exit on EOF."""
    import serial

    log = tmp_path / "levels.csv"
    # a 300 ms heartbeat sent every 30 ms: a loaded machine may stall this process
    # for a while without the failsafe tripping during the two periods measured
    proc, pty = _start(emulator_exe, "--tactors", "6", "--heartbeat-ms", "300",
                       "--levels-log", str(log))
    try:
        assert pty.startswith("/dev/")
        port = serial.Serial(pty, timeout=1.0)
        dec = wire.FrameDecoder()

        def request(p: wire.Packet) -> wire.Reply:
            port.write(wire.encode_frame(p))
            deadline = time.monotonic() + 5.0
            while time.monotonic() < deadline:
                got = dec.feed(port.read(port.in_waiting or 1))
                if got:
                    return wire.parse_reply(got[0])
            raise AssertionError("no reply")

        info = request(wire.get_info(0))
        assert isinstance(info, wire.Info) and info.heartbeat_ms == 300
        ack = request(wire.play_target(1, 4500, 1, 0, 1500, 1000, 100, 0))
        assert ack == wire.Ack(1)
        seq = 2
        t_end = time.monotonic() + 2.0
        while time.monotonic() < t_end:  # keep it alive for two periods
            port.write(wire.encode_frame(wire.heartbeat(seq)))
            seq += 1
            time.sleep(0.03)
        time.sleep(0.7)  # silence: the failsafe trips 300 ms after the last heartbeat
        status = request(wire.get_status(seq))
        assert isinstance(status, wire.Status) and status.state == wire.State.FAILSAFE
        port.write(wire.encode_frame(wire.set_amplitudes(seq + 1, [1000] * 6)))
        time.sleep(0.05)
        port.close()  # like the USB port closing: outputs off
        time.sleep(0.05)
        assert proc.stdin is not None
        proc.stdin.close()  # end of file on stdin: the emulator exits
        assert proc.wait(2.0) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()

    header, rows = _read_log(log)
    assert header == ["t_us", "state"] + [f"level_{k}" for k in range(6)]
    assert rows[0] == [0, 0, 0, 0, 0, 0, 0, 0]
    play_start = next(r[0] for r in rows if r[1] == wire.State.PLAYING)
    segs = _segments(rows, play_start, play_start + 2_000_000)
    near_only = sum(d for d, r in segs if r[2] > 0 and r[3] == 0) / 2
    far_only = sum(d for d, r in segs if r[3] > 60000 and r[2] == 0) / 2
    # per period, in microseconds; 20 ms leaves room for a stalled emulator and still
    # tells 600/200 from an even 400/400
    assert abs(near_only - 600_000) < 20_000
    assert abs(far_only - 200_000) < 20_000
    failsafe = next(r for r in rows if r[1] == wire.State.FAILSAFE)
    assert failsafe[2:] == [0] * 6
    streaming = [r for r in rows if r[1] == wire.State.STREAMING]
    assert streaming and streaming[0][2:] == [1000] * 6
    after = rows[rows.index(streaming[-1]) + 1]
    assert after[1] == wire.State.IDLE and after[2:] == [0] * 6  # the port closed
    assert rows[-1][1] == wire.State.IDLE and rows[-1][2:] == [0] * 6  # the exit line


@pytest.mark.emulator
def test_emulator_ignores_dev_null_stdin_and_ends_on_sigterm(emulator_exe: Path) -> None:
    proc, pty = _start(emulator_exe, stdin=subprocess.DEVNULL)
    try:
        assert pty.startswith("/dev/")
        time.sleep(0.3)
        assert proc.poll() is None  # still serving
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(2.0) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@pytest.mark.emulator
@pytest.mark.parametrize(
    "args", [["--tactors", "1"], ["--heartbeat-ms", "49"], ["--tactor-angles", "10,10"],
             ["--bogus", "1"], ["--imu", "bmx160"], ["--imu"]]
)
def test_emulator_rejects_bad_arguments(emulator_exe: Path, args: list[str]) -> None:
    proc = subprocess.run([str(emulator_exe), *args], capture_output=True, timeout=5,
                          stdin=subprocess.DEVNULL, check=False)
    assert proc.returncode == 2
    assert proc.stdout == b""
    assert b"emulator: error:" in proc.stderr


def test_shape_vectors_kick_brake_and_stay_within_the_full_duty() -> None:
    """The drive-shaping trace the firmware's shaper must reproduce (test/test_drive.cpp):
    with braking it reverse-drives some ticks, without it never; no drive passes the full
    duty (the firmware's overdrive bound) and the predicted speed never passes 1."""
    ext = json.loads((VECTORS.parent / "vectors_ext.json").read_text())
    cases = {c["brake"]: c for c in ext["shape"]["cases"]}
    assert sum(cases[True]["reverse"]) > 10 and not any(cases[False]["reverse"])
    for c in cases.values():
        assert max(c["drive"]) == 1.0 and min(c["drive"]) >= 0.0
        assert max(c["speed"]) <= 1.0 + 1e-9 and min(c["speed"]) >= -1e-9
