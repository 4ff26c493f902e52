"""The serial belt over a pseudo-terminal, against a Python fake device (FakeFirmware).

The fake device runs in a thread on the master side of a pty; the belt opens the
slave side with pyserial exactly as it opens /dev/ttyACM0.
"""

from __future__ import annotations

import os
import select
import threading
import tty
from collections.abc import Iterator
from types import SimpleNamespace

import numpy as np
import pytest

from tactorbelt import DeviceError, Layout, ProtocolError
from tactorbelt.devices import open_belt, wire
from tactorbelt.devices import serial as serial_backend
from tactorbelt.devices._firmware import FirmwareBelt
from test_firmware_belt import FakeFirmware, wait_for


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
    assert isinstance(pty_device.firmware.requests[-1], wire.StopAll)


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


def test_a_device_that_goes_silent_raises_naming_the_port(pty_device: PtyDevice) -> None:
    pty_device.firmware.heartbeat_ms = 60
    with open_belt(f"serial:{pty_device.path}") as belt:
        assert isinstance(belt, FirmwareBelt)
        pty_device.firmware.silent = True
        assert wait_for(lambda: belt.lost is not None)
        with pytest.raises(DeviceError, match=f"{pty_device.path} stopped answering"):
            belt.set_amplitudes([0.0] * 6)


def test_a_device_that_vanishes_raises_naming_the_port(pty_device: PtyDevice) -> None:
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


def _comports(*ports: SimpleNamespace) -> object:
    return lambda: list(ports)


def _port(device: str, description: str, vid: int | None = None) -> SimpleNamespace:
    return SimpleNamespace(device=device, description=description, vid=vid,
                           pid=0x805A if vid else None, product=None, manufacturer=None)


def test_serial_auto_picks_the_first_arduino_port_that_answers(
    monkeypatch: pytest.MonkeyPatch, pty_device: PtyDevice
) -> None:
    from serial.tools import list_ports

    silent = PtyDevice(FakeFirmware(silent=True))
    try:
        monkeypatch.setattr(list_ports, "comports", _comports(
            _port("/dev/ttyS0", "ttyS0"),
            _port(silent.path, "Nano 33 BLE", 0x2341),
            _port(pty_device.path, "Arduino Nano 33 BLE", 0x2341),
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
        monkeypatch.setattr(list_ports, "comports", _comports(
            _port(silent.path, "Nano 33 BLE", 0x2341),
            _port("/dev/tactorbelt-gone", "Arduino", 0x2341),
        ))
        with pytest.raises(DeviceError) as err:
            open_belt("serial:auto", timeout_s=0.05)
        text = str(err.value)
        assert silent.path in text and "/dev/tactorbelt-gone" in text
        assert "no candidate port answered" in text
        monkeypatch.setattr(list_ports, "comports", _comports(_port("/dev/ttyS0", "ttyS0")))
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
    assert isinstance(pty_device.firmware.requests[-1], wire.StopAll)
    assert pty_device.firmware.levels == [0] * 6
