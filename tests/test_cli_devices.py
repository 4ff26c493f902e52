"""``tactorbelt devices``: ports and BLE devices, which answer as belts, and clear notes."""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import pytest
from click.testing import CliRunner

from support import wire_device
from support.belts import FakeBle, FakeFirmware, PtyDevice, comports, port_info
from tactorbelt.cli import cli
from tactorbelt.devices import ble


@pytest.fixture
def pty_belt() -> Iterator[PtyDevice]:
    dev = PtyDevice(FakeFirmware(tactors=8))
    yield dev
    dev.close()


def _no_ble(monkeypatch: pytest.MonkeyPatch) -> None:
    def unavailable(timeout_s: float = 5.0) -> list[ble.BleBeltInfo]:
        raise ble.BleUnavailableError("BLE is not available on this machine: no adapter")

    monkeypatch.setattr(ble, "discover_belts", unavailable)


def test_lists_the_serial_belt_and_leaves_other_ports_alone(
    monkeypatch: pytest.MonkeyPatch, pty_belt: PtyDevice
) -> None:
    from serial.tools import list_ports

    monkeypatch.setattr(list_ports, "comports", comports(
        port_info("/dev/ttyS0", "ttyS0"), port_info(pty_belt.path, "Nano 33 BLE", 0x2341)))
    result = CliRunner().invoke(cli, ["devices", "--no-ble"])
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    (belt_line,) = [ln for ln in lines if ln.lstrip().startswith(pty_belt.path)]
    assert "firmware 1.2.3, 8 tactors" in belt_line
    assert f"--belt serial:{pty_belt.path}" in belt_line
    (other,) = [ln for ln in lines if "/dev/ttyS0" in ln]
    assert "not probed" in other
    assert "1 belt(s) found." in result.output
    # the probe closed the belt: it stopped the motors and released the port
    assert isinstance(pty_belt.firmware.requests[-1], wire_device.StopAll)


def test_says_clearly_when_there_is_nothing_and_ble_is_unavailable(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from serial.tools import list_ports

    monkeypatch.setattr(list_ports, "comports", comports())
    _no_ble(monkeypatch)
    result = CliRunner().invoke(cli, ["devices", "--timeout", "0.2"])
    assert result.exit_code == 0, result.output
    assert "Serial ports:\n  none" in result.output
    assert "note: BLE is not available on this machine: no adapter" in result.output
    assert "No belts found." in result.output
    assert "Traceback" not in result.output


@pytest.mark.parametrize(("capabilities", "says"), [
    (0x01, "plain drive only"),
    (0x05, "shapes its drive, cannot brake (IN2 to ground)"),
    (0x0D, "shapes its drive and brakes"),
])
def test_says_what_the_belts_drive_can_do(monkeypatch: pytest.MonkeyPatch, capabilities: int,
                                          says: str) -> None:
    """Firmware 1.3's INFO bits SHAPE (0x04) and BRAKE (0x08): a board wired the old way
    (IN2 to ground) shapes but cannot brake (docs/hardware.md)."""
    from serial.tools import list_ports

    dev = PtyDevice(FakeFirmware(tactors=6, extensions=True, fw_version=(1, 3, 0),
                                 capabilities=capabilities))
    try:
        monkeypatch.setattr(list_ports, "comports", comports(
            port_info(dev.path, "Nano 33 BLE", 0x2341)))
        result = CliRunner().invoke(cli, ["devices", "--no-ble"])
    finally:
        dev.close()
    assert result.exit_code == 0, result.output
    assert f"drive: {says}" in result.output


def test_lists_ble_belts_that_answer(monkeypatch: pytest.MonkeyPatch) -> None:
    from serial.tools import list_ports

    monkeypatch.setattr(list_ports, "comports", comports())
    monkeypatch.setattr(ble, "discover_belts", lambda timeout_s=5.0: [
        ble.BleBeltInfo("AA:BB:CC:DD:EE:FF", "tactorbelt", -60)])
    real_open = ble.open_ble
    fake = FakeBle(FakeFirmware(tactors=6))

    def open_fake(target: str, **options: Any) -> Any:
        return real_open(target, client_factory=fake, **options)

    monkeypatch.setattr(ble, "open_ble", open_fake)
    result = CliRunner().invoke(cli, ["devices", "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["belts"] == ["ble:AA:BB:CC:DD:EE:FF"]
    (row,) = data["ble"]
    assert row["firmware_version"] == "1.2.3" and row["tactors"] == 6
    assert row["description"] == "tactorbelt, -60 dBm"
    assert fake.client is not None and fake.client.disconnects == 1


def test_a_port_that_does_not_answer_is_listed_with_the_reason(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from serial.tools import list_ports

    monkeypatch.setattr(list_ports, "comports", comports(
        port_info("/dev/tactorbelt-gone", "Arduino Nano 33 BLE", 0x2341)))
    result = CliRunner().invoke(cli, ["devices", "--no-ble"])
    assert result.exit_code == 0, result.output
    assert "cannot open serial port /dev/tactorbelt-gone" in result.output
    assert "No belts found." in result.output


def test_lists_joysticks_for_the_run_command(monkeypatch: pytest.MonkeyPatch) -> None:
    from serial.tools import list_ports

    from tactorbelt.inputs import joystick

    monkeypatch.setattr(list_ports, "comports", comports())
    _no_ble(monkeypatch)
    stick = {"index": 0, "name": "Thrustmaster HOTAS Warthog Joystick", "guid": "x",
             "axes": 2, "buttons": 19, "hats": 1}
    monkeypatch.setattr(joystick, "list_joysticks", lambda: [stick])
    result = CliRunner().invoke(cli, ["devices", "--timeout", "0.2"])
    assert "0  Thrustmaster HOTAS Warthog Joystick  (2 axes, 19 buttons)" in result.output
    result = CliRunner().invoke(cli, ["devices", "--timeout", "0.2", "--json"])
    assert json.loads(result.output)["joysticks"] == [stick]


def test_skipped_links_are_not_scanned_and_say_so(monkeypatch: pytest.MonkeyPatch) -> None:
    from serial.tools import list_ports

    def never(*_: Any, **__: Any) -> Any:
        raise AssertionError("a skipped link was scanned")

    monkeypatch.setattr(list_ports, "comports", never)
    monkeypatch.setattr(ble, "discover_belts", never)
    result = CliRunner().invoke(cli, ["devices", "--skip", "serial", "--no-ble", "--json"])
    assert result.exit_code == 0, result.output
    data = json.loads(result.output)
    assert data["serial"] == [] and data["serial_note"] == "not scanned (--skip serial)"
    assert data["ble"] == [] and data["ble_note"] == "not scanned (--no-ble)"
    assert data["belts"] == []


def test_help_lists_every_registered_backend_and_its_url_options() -> None:
    from tactorbelt.devices.registry import BACKENDS

    result = CliRunner().invoke(cli, ["devices", "--help"])
    assert result.exit_code == 0
    for backend in BACKENDS.values():
        assert all(example in result.output for example in backend.examples)
        assert all(f"{backend.scheme}: {o.name} " in result.output for o in backend.options)
