"""The serial belt over a pseudo-terminal, against a Python fake device (FakeFirmware).

The fake device runs in a thread on the master side of a pty; the belt opens the
slave side with pyserial exactly as it opens /dev/ttyACM0.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from support import wire_device
from support.belts import FakeFirmware, PtyDevice, comports, port_info, wait_for
from tactorbelt import DeviceError, Layout, ProtocolError
from tactorbelt.devices import open_belt, wire
from tactorbelt.devices import serial as serial_backend
from tactorbelt.devices._firmware import FirmwareBelt


@pytest.fixture
def pty_device() -> Iterator[PtyDevice]:
    dev = PtyDevice(FakeFirmware())
    yield dev
    dev.close()


def test_open_belt_serial_talks_to_the_device(pty_device: PtyDevice) -> None:
    with open_belt(f"serial:{pty_device.path}") as belt:
        assert isinstance(belt, FirmwareBelt)
        assert belt.url == f"serial:{pty_device.path}"
        assert belt.stream_rate_hz == 1000.0
        assert belt.layout == Layout.even(6)
        assert belt.firmware_version == "1.2.3"
        belt.set_amplitudes([0.0, 0.25, 0.5, 0.75, 1.0, 0.0])
        assert belt.status().levels == (0, 16384, 32768, 49151, 65535, 0)
        assert belt.ping() > 0
    assert pty_device.firmware.levels == [0] * 6
    assert isinstance(pty_device.firmware.requests[-1], wire_device.StopAll)


def test_garbage_and_corrupted_frames_from_the_device_are_counted_and_skipped(
    pty_device: PtyDevice,
) -> None:
    with open_belt(f"serial:{pty_device.path}", keepalive=False) as belt:
        assert isinstance(belt, FirmwareBelt)
        pty_device.garbage = True
        for _ in range(5):
            assert belt.status().state == wire.State.IDLE
        assert belt.host_crc_errors >= 5
        assert belt.host_framing_errors + belt.host_crc_errors >= 10
        assert belt.lost is None


def test_a_device_that_goes_silent_raises_naming_theport_info(pty_device: PtyDevice) -> None:
    pty_device.firmware.heartbeat_ms = 60
    with open_belt(f"serial:{pty_device.path}") as belt:
        assert isinstance(belt, FirmwareBelt)
        pty_device.firmware.silent = True
        assert wait_for(lambda: belt.lost is not None)
        with pytest.raises(DeviceError, match=f"{pty_device.path} stopped answering"):
            belt.set_amplitudes([0.0] * 6)


def test_a_device_that_vanishes_raises_naming_theport_info(pty_device: PtyDevice) -> None:
    belt = open_belt(f"serial:{pty_device.path}", keepalive=False)
    assert isinstance(belt, FirmwareBelt)
    pty_device.hang_up()
    assert wait_for(lambda: belt.lost is not None)
    with pytest.raises(DeviceError, match=f"{pty_device.path} stopped answering"):
        belt.status()
    belt.close()  # logs, never raises


def test_protocol_version_2_is_refused_and_the_port_released() -> None:
    dev = PtyDevice(FakeFirmware(protocol_version=2))
    try:
        with pytest.raises(ProtocolError, match="protocol version 2"):
            open_belt(f"serial:{dev.path}")
        dev.firmware.protocol_version = 1
        with open_belt(f"serial:{dev.path}") as belt:  # exclusive lock was released
            assert belt.n_tactors == 6
    finally:
        dev.close()


def test_a_missing_port_is_a_device_error() -> None:
    with pytest.raises(DeviceError, match="cannot open serial port /dev/tactorbelt-nope"):
        open_belt("serial:/dev/tactorbelt-nope")


def test_serial_auto_picks_the_first_arduino_port_that_answers(
    monkeypatch: pytest.MonkeyPatch, pty_device: PtyDevice
) -> None:
    from serial.tools import list_ports

    silent = PtyDevice(FakeFirmware(silent=True))
    try:
        monkeypatch.setattr(list_ports, "comports", comports(
            port_info("/dev/ttyS0", "ttyS0"),
            port_info(silent.path, "Nano 33 BLE", 0x2341),
            port_info(pty_device.path, "Arduino Nano 33 BLE", 0x2341),
        ))
        ports = serial_backend.list_serial_ports()
        assert [p.device for p in ports] == [silent.path, pty_device.path, "/dev/ttyS0"]
        with open_belt("serial:auto", timeout_s=0.1) as belt:
            assert belt.url == f"serial:{pty_device.path}"
            assert isinstance(belt, FirmwareBelt)
            assert belt.timeout_s == 0.1
        assert silent.bytes_in  # the silent candidate was tried first
    finally:
        silent.close()


def test_serial_auto_lists_every_candidate_when_none_answers(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from serial.tools import list_ports

    silent = PtyDevice(FakeFirmware(silent=True))
    try:
        monkeypatch.setattr(list_ports, "comports", comports(
            port_info(silent.path, "Nano 33 BLE", 0x2341),
            port_info("/dev/tactorbelt-gone", "Arduino", 0x2341),
        ))
        with pytest.raises(DeviceError) as err:
            open_belt("serial:auto", timeout_s=0.05)
        text = str(err.value)
        assert silent.path in text and "/dev/tactorbelt-gone" in text
        assert "no candidate port answered" in text
        monkeypatch.setattr(list_ports, "comports", comports(port_info("/dev/ttyS0", "ttyS0")))
        with pytest.raises(DeviceError, match=r"no port that looks like.*ttyS0"):
            open_belt("serial:auto")
    finally:
        silent.close()


def test_a_program_that_forgets_to_close_stops_the_motors_at_exit(
    pty_device: PtyDevice,
) -> None:
    import subprocess
    import sys

    script = (
        "from tactorbelt.devices import open_belt\n"
        f"belt = open_belt('serial:{pty_device.path}')\n"
        "belt.set_amplitudes([1.0] * 6)\n"
    )
    subprocess.run([sys.executable, "-c", script], check=True, timeout=30)
    assert isinstance(pty_device.firmware.requests[-1], wire_device.StopAll)
    assert pty_device.firmware.levels == [0] * 6


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")
def test_writes_past_a_full_buffer_arrive_whole_and_in_order() -> None:
    """The transport writes a frame with one os.write when the port takes it, and hands
    the rest of a partial or refused write to pyserial, which waits for room: frames
    written much faster than the other end reads (a terminal's buffer holds a few KB)
    all arrive, byte for byte, in order."""
    import termios
    import threading
    import time

    controller, device = os.openpty()
    attrs = termios.tcgetattr(controller)
    attrs[3] &= ~(termios.ECHO | termios.ICANON)  # raw: bytes come through as written
    termios.tcsetattr(controller, termios.TCSANOW, attrs)
    transport = serial_backend.SerialTransport(os.ttyname(device), write_timeout_s=10.0)
    frames = [bytes([k & 0xFF]) * 19 + b"\x00" for k in range(20_000)]  # 400 KB
    got = bytearray()

    def read() -> None:
        time.sleep(0.3)  # let the writer fill the buffer first
        deadline = time.monotonic() + 20.0
        while len(got) < 20 * len(frames) and time.monotonic() < deadline:
            got.extend(os.read(controller, 65536))

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        for f in frames:
            transport.write(f)
        reader.join(25.0)
    finally:
        transport.close()
        os.close(device)
        os.close(controller)
    assert bytes(got) == b"".join(frames)


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")
def test_a_refused_or_partial_write_goes_on_through_pyserial(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """What os.write did not take (all of a frame the port refused, the tail of a
    partial write) is written by pyserial, which waits for room: nothing is lost or
    sent twice."""
    controller, device = os.openpty()
    transport = serial_backend.SerialTransport(os.ttyname(device))
    sent: list[bytes] = []
    answers = iter(["all", "refuse", 7, "all", 1])

    def fake_write(fd: int, data: bytes) -> int:
        how = next(answers)
        if how == "refuse":
            raise BlockingIOError
        n = len(data) if how == "all" else int(how)
        sent.append(bytes(data[:n]))
        return n

    monkeypatch.setattr(serial_backend.os, "write", fake_write)
    monkeypatch.setattr(transport._ser, "write", lambda data: sent.append(bytes(data)))
    frames = [bytes([k]) * 20 for k in range(1, 6)]
    try:
        for f in frames:
            transport.write(f)
    finally:
        monkeypatch.undo()
        transport.close()
        os.close(device)
        os.close(controller)
    assert b"".join(sent) == b"".join(frames)


@pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a pseudo-terminal")
def test_a_write_after_close_is_a_device_error_not_a_write_to_another_file(
        tmp_path: Path) -> None:
    """After close(), write() reports the port closed and touches no file descriptor,
    even one the closed port's number now belongs to."""
    controller, device = os.openpty()
    transport = serial_backend.SerialTransport(os.ttyname(device))
    transport.close()
    reused = os.open(tmp_path / "other", os.O_WRONLY | os.O_CREAT)  # may take the old number
    transport._closed = False  # as a writer that checked before close() went on would
    try:
        with pytest.raises(DeviceError, match="failed"):
            transport.write(b"frame")
    finally:
        os.close(reused)
        os.close(device)
        os.close(controller)
    assert (tmp_path / "other").read_bytes() == b""
