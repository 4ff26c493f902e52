"""The naviBelt's BLE path (``navibelt:ble:NAME``) without a Bluetooth adapter: the URL, and
the error when pybelt's scanner (bleak, BlueZ over D-Bus) cannot run, through bleak's own
code against a private D-Bus daemon: no system bus, no BlueZ, a BlueZ with no adapter."""

from __future__ import annotations

import shutil
import subprocess
import sys
import textwrap
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tactorbelt import ConfigError, DeviceError
from tactorbelt.devices import open_belt

pytest.importorskip("pybelt", reason="pip install 'tactorbelt[navibelt]'")

_BUS_CONF = """\
<!DOCTYPE busconfig PUBLIC "-//freedesktop//DTD D-Bus Bus Configuration 1.0//EN"
 "http://www.freedesktop.org/standards/dbus/1.0/busconfig.dtd">
<busconfig>
  <type>session</type>
  <listen>unix:path={sock}</listen>
  <auth>EXTERNAL</auth>
  <policy context="default">
    <allow send_destination="*" eavesdrop="true"/><allow eavesdrop="true"/><allow own="*"/>
  </policy>
</busconfig>
"""

#: BlueZ as bleak sees it with no adapter: org.bluez owned, no objects managed
_FAKE_BLUEZ = textwrap.dedent("""\
    import asyncio, sys
    from dbus_fast.aio import MessageBus
    from dbus_fast.service import ServiceInterface, method

    class ObjectManager(ServiceInterface):
        def __init__(self):
            super().__init__("org.freedesktop.DBus.ObjectManager")

        @method()
        def GetManagedObjects(self) -> "a{oa{sa{sv}}}":
            return {}

    async def main(address):
        bus = await MessageBus(bus_address=address).connect()
        bus.export("/", ObjectManager())
        await bus.request_name("org.bluez")
        print("ready", flush=True)
        await asyncio.Event().wait()

    asyncio.run(main(sys.argv[1]))
    """)


@pytest.mark.parametrize("url", ["navibelt:ble:", "navibelt:bluetooth:belt",
                                 "navibelt:ble:belt?speed=3"])
def test_a_bad_ble_url_is_a_config_error(url: str) -> None:
    with pytest.raises(ConfigError, match="navibelt"):
        open_belt(url)


def _scan_error(monkeypatch: pytest.MonkeyPatch, address: str) -> str:
    monkeypatch.setenv("DBUS_SYSTEM_BUS_ADDRESS", address)
    with pytest.raises(DeviceError) as info:
        open_belt("navibelt:ble:naviBelt_4A2F")
    return str(info.value)


def test_without_a_dbus_system_bus_the_error_says_so(monkeypatch: pytest.MonkeyPatch,
                                                     tmp_path: Path) -> None:
    msg = _scan_error(monkeypatch, f"unix:path={tmp_path / 'no-bus'}")
    assert msg.startswith("cannot scan for naviBelts over BLE for 'navibelt:ble:naviBelt_4A2F': "
                          "no D-Bus system bus to reach BlueZ"), msg
    assert "navibelt:serial:PORT" in msg


@pytest.fixture
def bus(tmp_path: Path) -> Iterator[str]:
    """A private D-Bus daemon standing in for the system bus; its address."""
    if shutil.which("dbus-daemon") is None:
        pytest.skip("dbus-daemon not installed (apt-get install dbus)")
    sock = tmp_path / "bus.sock"
    conf = tmp_path / "bus.conf"
    conf.write_text(_BUS_CONF.format(sock=sock))
    proc = subprocess.Popen(["dbus-daemon", f"--config-file={conf}", "--nofork"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 30
        while not sock.exists():
            assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
            assert time.monotonic() < deadline, "dbus-daemon did not start"
            time.sleep(0.05)
        yield f"unix:path={sock}"
    finally:
        proc.terminate()
        proc.wait(10)


def test_without_bluez_the_error_says_so(monkeypatch: pytest.MonkeyPatch, bus: str) -> None:
    msg = _scan_error(monkeypatch, bus)
    assert "BlueZ is not running (no org.bluez on the D-Bus system bus" in msg, msg


def test_with_bluez_but_no_adapter_the_error_says_so(monkeypatch: pytest.MonkeyPatch,
                                                      bus: str) -> None:
    bluez = subprocess.Popen([sys.executable, "-c", _FAKE_BLUEZ, bus], stdout=subprocess.PIPE,
                             text=True)
    try:
        assert bluez.stdout is not None and bluez.stdout.readline().strip() == "ready"
        msg = _scan_error(monkeypatch, bus)
        assert msg == ("cannot scan for naviBelts over BLE for 'navibelt:ble:naviBelt_4A2F': "
                       "no Bluetooth adapter (BlueZ lists none); a naviBelt on USB: "
                       "navibelt:serial:PORT")
        # tactorbelt devices: a note, not an error
        from tactorbelt.devices.navibelt import discover

        found = discover()
        assert found.note is not None and "no BLE scan for naviBelts: no Bluetooth adapter" \
            in found.note
    finally:
        bluez.terminate()
        bluez.wait(10)
