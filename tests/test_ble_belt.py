"""The BLE belt against a fake bleak client that plays the device (no adapter needed).

The fake client answers each write-without-response on the RX characteristic with
notifications on the TX characteristic, from the BLE event loop, as bleak does.
"""

from __future__ import annotations

import pytest

from support import wire_device
from support.belts import FakeBle, FakeFirmware, wait_for
from tactorbelt import DeviceError, Layout, ProtocolError
from tactorbelt.devices import ble, open_belt, wire
from tactorbelt.devices._firmware import FirmwareBelt
from tactorbelt.stimuli import make_stimulus


def test_ble_belt_streams_plays_and_stops_through_gatt() -> None:
    fake = FakeBle()
    with open_belt("ble:tactorbelt", client_factory=fake) as belt:
        assert isinstance(belt, FirmwareBelt)
        assert fake.targets == ["tactorbelt"]
        assert belt.url == "ble:tactorbelt"
        assert belt.stream_rate_hz == 40.0
        assert belt.layout == Layout.even(6)
        assert "BLE tactorbelt" in belt.name
        belt.set_amplitudes([1.0, 0.5, 0.0, 0.0, 0.0, 0.0])
        assert belt.status().levels == (65535, 32768, 0, 0, 0, 0)
        belt.play(make_stimulus(belt.layout, 45.0, mode="dynamic"), 1.0)
        assert fake.firmware.of_type(wire_device.PlayTarget)[-1] == wire_device.PlayTarget(
            4500, 1, 0, 1500, 1000, 100, 1000)
        assert belt.ping() > 0
    client = fake.client
    assert client is not None
    assert isinstance(fake.firmware.requests[-1], wire_device.StopAll)
    assert client.disconnects == 1
    # every packet went unframed, in one write without response, to RX
    for char, data, response in client.writes:
        assert char == ble.RX_CHAR_UUID and response is False
        assert len(data) <= wire.MAX_PACKET
        wire.decode_packet(data)


def test_corrupted_notifications_are_counted_and_skipped() -> None:
    fake = FakeBle()
    with open_belt("ble:tactorbelt", client_factory=fake, keepalive=False) as belt:
        assert isinstance(belt, FirmwareBelt) and fake.client is not None
        fake.client.corrupt = True
        for _ in range(3):
            assert belt.status().state == wire.State.IDLE
        assert wait_for(lambda: belt.host_crc_errors == 3 and belt.host_framing_errors == 3)


def test_a_disconnect_makes_the_next_call_raise_naming_the_device() -> None:
    fake = FakeBle()
    belt = open_belt("ble:tactorbelt", client_factory=fake)
    assert fake.client is not None
    fake.client.drop()
    with pytest.raises(DeviceError, match=r"BLE tactorbelt.*stopped answering: BLE disconnected"):
        belt.set_amplitudes([0.0] * 6)
    belt.close()  # logs, never raises


def test_protocol_version_2_is_refused_and_the_connection_closed() -> None:
    fake = FakeBle(FakeFirmware(protocol_version=2))
    with pytest.raises(ProtocolError, match="protocol version 2"):
        open_belt("ble:AA:BB:CC:DD:EE:FF", client_factory=fake)
    assert fake.client is not None and fake.client.disconnects == 1


def test_a_failed_connection_is_a_device_error() -> None:
    fake = FakeBle()
    fake.fail_connect = True
    msg = r"cannot connect to BLE tactorbelt \(AA:BB:CC:DD:EE:FF\): device out of range"
    with pytest.raises(DeviceError, match=msg):
        open_belt("ble:tactorbelt", client_factory=fake)


def test_without_an_adapter_ble_fails_with_a_device_error() -> None:
    # On this machine there is no adapter (or no belt in range): never a traceback.
    with pytest.raises(DeviceError):
        open_belt("ble:tactorbelt-not-here", scan_timeout_s=0.5)


def test_uuids_and_name_match_the_firmware_sketch() -> None:
    import re
    from pathlib import Path

    sketch = Path(__file__).resolve().parents[1] / "firmware" / "tactorbelt" / "tactorbelt.ino"
    if not sketch.is_file():
        pytest.skip("no firmware sketch in this tree")
    consts = dict(re.findall(r'const char (k\w+)\[\] = "([^"]+)";', sketch.read_text()))
    assert consts["kServiceUuid"] == ble.SERVICE_UUID
    assert consts["kRxUuid"] == ble.RX_CHAR_UUID
    assert consts["kTxUuid"] == ble.TX_CHAR_UUID
    assert consts["kDeviceName"] == ble.DEVICE_NAME


# --- the ATT MTU: framed replies below 67 (firmware 1.1) ------------------------------------


@pytest.mark.parametrize("mtu", [23, 247])
def test_ble_belt_works_at_any_mtu_with_firmware_1_1(mtu: int) -> None:
    fake = FakeBle(FakeFirmware(extensions=True), mtu=mtu)
    with open_belt("ble:tactorbelt", client_factory=fake) as belt:
        assert isinstance(belt, FirmwareBelt)
        assert belt.framed_replies == (mtu < 67)
        assert belt.layout == Layout.even(6)  # INFO (26 bytes) arrived
        assert belt.status().levels == (0,) * 6  # STATUS of 6 tactors (25 bytes)
        belt.play(make_stimulus(belt.layout, 45.0, mode="dynamic"), 1.0)
        assert belt.last_onset() is not None
        belt.set_amplitudes([0.5] * 6)
        assert belt.status().levels == (32768,) * 6
        assert belt.host_crc_errors == 0 and belt.host_framing_errors == 0
    client = fake.client
    assert client is not None
    assert all(len(n) <= mtu - 3 for n in client.notifications)
    if mtu < 67:  # framing asked for before GET_INFO, with the flags byte
        kinds = [type(r) for r in fake.firmware.requests]
        assert kinds[:3] == [wire_device.GetDiag, wire_device.SetConfig, wire_device.GetInfo]
        assert any(len(n) == mtu - 3 and 0 not in n for n in client.notifications)
    else:  # one unframed packet per notification
        assert all(wire.decode_packet(n) for n in client.notifications)


def test_ble_plain_v1_at_a_small_mtu_warns(caplog: pytest.LogCaptureFixture) -> None:
    import logging

    fake = FakeBle(FakeFirmware(tactors=3, fw_version=(1, 0, 0)), mtu=23)
    with caplog.at_level(logging.WARNING, logger="tactorbelt.devices"), open_belt(
            "ble:tactorbelt", client_factory=fake) as belt:
        assert not belt.framed_replies  # type: ignore[attr-defined]
        assert belt.n_tactors == 3  # INFO of 3 tactors fits 20 bytes
    assert any("MTU" in r.getMessage() for r in caplog.records)


def test_a_write_longer_than_the_mtu_fails_with_the_mtu_named() -> None:
    fake = FakeBle(FakeFirmware(tactors=10, extensions=True), mtu=23)
    with open_belt("ble:tactorbelt", client_factory=fake) as belt:
        assert belt.n_tactors == 10  # INFO of 10 tactors (34 bytes) came framed
        with pytest.raises(DeviceError, match="ATT MTU 23"):
            belt.set_amplitudes([0.5] * 10)  # 24 bytes: one write cannot carry it
