"""FirmwareBelt (the host side of protocol v1) against a fake device, in memory.

:class:`~support.belts.FakeFirmware` plays the device with tactorbelt.devices.wire.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest

from support import wire_device
from support.belts import FakeFirmware, LoopTransport, open_fake, wait_for
from support.laws import rotated
from tactorbelt import ConfigError, DeviceError, Layout, ProtocolError, TactorbeltError
from tactorbelt.devices import wire
from tactorbelt.devices._firmware import FirmwareBelt
from tactorbelt.devices.calibration import Calibration, TactorCalibration
from tactorbelt.stimuli import make_stimulus

# --- opening ------------------------------------------------------------------------


def test_open_reads_layout_version_and_capabilities_from_info() -> None:
    belt, _, _ = open_fake()
    with belt:
        assert belt.n_tactors == 6
        assert belt.layout == Layout.even(6)
        assert belt.firmware_version == "1.2.3"
        assert belt.can_render()
        assert belt.heartbeat_ms == 250
        assert "loop0" in belt.name


def test_uneven_device_layout_is_used_and_even_layouts_snap_to_exact_angles() -> None:
    belt, _, _ = open_fake(FakeFirmware(tactors=4, angles_deg=(0.0, 80.0, 180.0, 250.5)))
    with belt:
        assert belt.tactor_angles_deg == (0.0, 80.0, 180.0, 250.5)
    # 180/7 comes back from the device as 25.71 deg: still the default 7-tactor layout
    belt, _, _ = open_fake(FakeFirmware(tactors=7))
    with belt:
        assert belt.layout == Layout.even(7)


def test_protocol_version_other_than_1_is_refused_and_the_link_released() -> None:
    with pytest.raises(ProtocolError, match=r"loop0 speaks protocol version 2"):
        open_fake(FakeFirmware(protocol_version=2))
    device = FakeFirmware(protocol_version=2)
    transport = LoopTransport(device)
    with pytest.raises(ProtocolError):
        FirmwareBelt(transport, "loop:x", keepalive=False)
    assert transport.closed


def test_a_device_that_never_answers_gives_a_device_error_naming_the_port() -> None:
    with pytest.raises(DeviceError, match="loop0"):
        open_fake(FakeFirmware(silent=True), timeout_s=0.02)


def test_no_capability_bit_means_no_device_rendering() -> None:
    belt, _, _ = open_fake(FakeFirmware(capabilities=0))
    with belt:
        assert not belt.can_render()
        with pytest.raises(TactorbeltError, match="cannot render"):
            belt.play(make_stimulus(belt.layout, 45.0))


def test_a_layout_override_with_other_angles_disables_device_rendering() -> None:
    other = rotated(Layout.even(6), 10.0)
    belt, _, _ = open_fake(layout=other)
    with belt:
        assert belt.layout == other
        assert not belt.can_render()
    with pytest.raises(ConfigError, match="4 tactors"):
        open_fake(layout=Layout.even(4))


def test_unknown_heartbeat_is_refused_before_sending() -> None:
    with pytest.raises(ConfigError, match=r"50\.\.2000"):
        open_fake(heartbeat_ms=20)


# --- streaming, playing, stopping -----------------------------------------------------


def test_set_amplitudes_sends_calibrated_levels() -> None:
    cal = Calibration((TactorCalibration(start=0.2),) + (TactorCalibration(),) * 5)
    belt, device, _ = open_fake(calibration=cal)
    with belt:
        belt.set_amplitudes([0.5, 1.0, 0.0, 0.25, 0.0, 1e-9])
        (req,) = device.of_type(wire_device.SetAmplitudes)
        assert isinstance(req, wire_device.SetAmplitudes)
        expected = [wire.amplitude_to_level(v) for v in (0.6, 1.0, 0.0, 0.25, 0.0, 1e-9)]
        assert list(req.levels) == expected
        assert device.state == wire.State.STREAMING


def test_every_packet_takes_the_next_sequence_number_mod_256() -> None:
    belt, device, _ = open_fake()
    with belt:
        for _ in range(300):
            belt.set_amplitudes(np.zeros(6))
        belt.status()
    steps = np.diff(np.array(device.seqs)) % 256
    assert np.all(steps == 1)
    # GET_INFO, GET_DIAG (the extension probe), frames, GET_STATUS, STOP_ALL
    assert len(device.seqs) == 1 + 1 + 300 + 1 + 1


def test_play_sends_play_target_with_the_stimulus_parameters() -> None:
    belt, device, _ = open_fake()
    with belt:
        stim = make_stimulus(belt.layout, 45.0, mode="dynamic", law="energy",
                             falloff_deg=12.5, period_s=0.8, transit_s=0.05)
        belt.play(stim, 2.5)
        belt.play(make_stimulus(belt.layout, 359.995), None)
    first, second = device.of_type(wire_device.PlayTarget)
    assert first == wire_device.PlayTarget(4500, 1, 2, 1250, 800, 50, 2500)
    assert second == wire_device.PlayTarget(0, 0, 0, 1500, 1000, 100, 0)  # 0 = until stopped


def test_play_rejects_values_the_wire_cannot_carry() -> None:
    belt, _, _ = open_fake()
    with belt:
        stim = make_stimulus(belt.layout, 45.0, period_s=70.0)
        with pytest.raises(ConfigError, match="period"):
            belt.play(stim)


def test_stop_waits_for_the_ack_and_close_stops_the_motors() -> None:
    belt, device, transport = open_fake()
    with belt:
        belt.set_amplitudes([1.0] * 6)
        belt.stop()
        assert device.levels == [0] * 6
        belt.set_amplitudes([1.0] * 6)
    assert device.levels == [0] * 6
    assert isinstance(device.requests[-1], wire_device.StopAll)
    assert transport.closed
    with pytest.raises(TactorbeltError, match="closed"):
        belt.set_amplitudes([0.0] * 6)


# --- requests --------------------------------------------------------------------------


def test_ping_status_and_set_config() -> None:
    belt, device, _ = open_fake()
    with belt:
        assert 0.0 < belt.ping() < 1.0
        belt.set_amplitudes([0.0, 0.5, 0.0, 0.0, 0.0, 1.0])
        status = belt.status()
        assert status.state == wire.State.STREAMING
        assert status.levels == (0, 32768, 0, 0, 0, 65535)
        belt.set_config(500)
        assert belt.heartbeat_ms == 500
        assert device.heartbeat_ms == 500
        with pytest.raises(ConfigError, match=r"50\.\.2000"):
            belt.set_config(10)


def test_a_nak_for_a_request_becomes_a_clear_error() -> None:
    device = FakeFirmware()
    belt, _, _ = open_fake(device)

    with belt:
        device._answer = lambda seq, req: wire.Nak(seq, wire.NakCode.OUT_OF_RANGE)  # type: ignore[method-assign]
        with pytest.raises(ConfigError, match="out of range"):
            belt.play(make_stimulus(belt.layout, 45.0))
        device._answer = lambda seq, req: wire.Nak(seq, wire.NakCode.UNKNOWN_TYPE)  # type: ignore[method-assign]
        with pytest.raises(ProtocolError, match="refused the status request"):
            belt.status()
        del device._answer


def test_bad_and_stale_replies_are_counted_and_skipped() -> None:
    device = FakeFirmware()
    belt, _, _ = open_fake(device)

    def junk(packet: wire.Packet) -> list[wire.Packet]:
        return [
            wire.Packet(0x99, packet.seq, b"\x01"),  # unknown type
            wire.Packet(wire.MsgType.PONG, packet.seq, b"\x00"),  # wrong length
            wire_device.encode_reply((packet.seq + 17) % 256, wire.Ack(0)),  # nobody waits for it
        ]

    with belt:
        device.extra_replies = junk
        status = belt.status()
        assert status.state == wire.State.IDLE
        assert belt.bad_replies == 2
        assert belt.unmatched_replies == 1
        device.extra_replies = None


# --- losing the device ----------------------------------------------------------------


def test_a_lost_link_makes_the_next_call_raise_naming_the_port() -> None:
    belt, _, transport = open_fake()
    transport.kill()
    with pytest.raises(DeviceError, match=r"loop0.*end of file"):
        belt.set_amplitudes([0.0] * 6)
    with pytest.raises(DeviceError, match="loop0"):
        belt.status()


def test_closing_a_dead_belt_logs_instead_of_raising(caplog: pytest.LogCaptureFixture) -> None:
    belt, device, transport = open_fake(timeout_s=0.02)
    device.silent = True
    with caplog.at_level(logging.WARNING, logger="tactorbelt.devices"), belt:
        pass
    assert belt.closed and transport.closed
    assert "could not stop the motors" in caplog.text and "loop0" in caplog.text
    belt2, _, transport2 = open_fake()
    transport2.kill()
    belt2.close()  # no exception
    assert belt2.closed


def test_a_request_without_reply_times_out_naming_the_port() -> None:
    belt, device, _ = open_fake(timeout_s=0.02)
    device.silent = True
    with pytest.raises(DeviceError, match=r"loop0 did not answer the status request within 20 ms"):
        belt.status()
    belt.close()


def test_keepalive_writes_while_open_and_detects_a_silent_device() -> None:
    device = FakeFirmware(heartbeat_ms=60)
    belt, _, _ = open_fake(device, keepalive=True)
    try:
        assert belt.keepalive_running
        # nothing else is sent, yet the device keeps hearing from the host
        assert wait_for(lambda: len(device.seqs) >= 4)
        kinds = {type(r) for r in device.requests[1:4]}
        assert kinds <= {wire_device.Ping, wire_device.Heartbeat}
        device.silent = True
        assert wait_for(lambda: belt.lost is not None)
        with pytest.raises(DeviceError, match=r"loop0 stopped answering: no reply"):
            belt.set_amplitudes([0.0] * 6)
    finally:
        belt.close()
    assert not belt.keepalive_running


class _StarvedReader(LoopTransport):
    """A link whose device is silent to the reader while ``unread`` bytes wait in the
    port: the host's reading thread starved of CPU, not a belt that stopped."""

    unread = 0

    def unread_bytes(self) -> int:
        return self.unread


def test_keepalive_does_not_give_up_while_the_device_s_bytes_wait_unread() -> None:
    import time

    device = FakeFirmware(heartbeat_ms=60)
    transport = _StarvedReader(device)
    belt = FirmwareBelt(transport, "loop:loop0", keepalive=True)
    try:
        assert wait_for(lambda: len(device.seqs) >= 2)
        transport.unread = 24  # replies are in the port; the reader has not taken them
        device.silent = True
        time.sleep(0.5)  # eight heartbeat timeouts of the device's silence
        assert belt.lost is None
        transport.unread = 0  # nothing waiting: the belt really is silent
        assert wait_for(lambda: belt.lost is not None)
    finally:
        belt.close()


def test_stop_keepalive_lets_the_host_go_quiet() -> None:
    device = FakeFirmware(heartbeat_ms=60)
    belt, _, _ = open_fake(device, keepalive=True)
    with belt:
        belt.stop_keepalive()
        assert not belt.keepalive_running
        n = len(device.seqs)
        belt.start_keepalive()
        assert wait_for(lambda: len(device.seqs) > n)


def test_unknown_options_are_refused_by_open_belt() -> None:
    from tactorbelt.devices import open_belt

    with pytest.raises(ConfigError, match="unknown option"):
        open_belt("serial:/dev/null-does-not-exist", tactors=6)


def test_fake_firmware_replies_roundtrip_through_wire() -> None:
    """Guard for the fake itself: its INFO parses as the real firmware's would."""
    info = wire.parse_reply(FakeFirmware().handle(wire.get_info(5))[0])
    assert isinstance(info, wire.Info)
    assert info.channels == 6 and info.can_play_target


# --- extensions (firmware 1.1): GET_DIAG probe, watchdog report, ONSET events --------------

#: FakeFirmware's device clock runs this far ahead of time.perf_counter_ns (in us).
_FAKE_EPOCH_US = 3_600_000_000


def test_firmware_1_0_devices_work_without_extensions() -> None:
    """A 1.0.0 device NAKs GET_DIAG with code 2: no flags, no onsets, behaviour as v1."""
    belt, device, _ = open_fake(FakeFirmware(fw_version=(1, 0, 0)))
    with belt:
        assert belt.firmware_version == "1.0.0"
        assert not belt.extensions and not belt.reports_onsets
        assert belt.diagnostics is None
        belt.play(make_stimulus(belt.layout, 45.0, mode="dynamic"), 1.0)
        assert belt.last_onset() is None
        belt.set_amplitudes([0.5] * 6)
        assert belt.status().levels == (32768,) * 6
        with pytest.raises(TactorbeltError, match=r"1\.1"):
            belt.diag()
    assert not any(isinstance(r, wire_device.SetConfig) and r.flags is not None
                   for r in device.requests)
    assert belt.unsolicited_naks == 0 and belt.unmatched_replies == 0


@pytest.mark.parametrize("version", [(1, 1, 0), (1, 1, 7)])
def test_firmware_1_1_turns_onset_events_on_and_reports_device_onsets(
        version: tuple[int, int, int]) -> None:
    belt, device, _ = open_fake(FakeFirmware(extensions=True, fw_version=version))
    with belt:
        assert belt.extensions and belt.reports_onsets
        assert device.flags == wire.ConfigFlag.ONSET_EVENTS
        assert isinstance(belt.diagnostics, wire.Diag) and not belt.watchdog_reset
        assert len(belt.clock_sync) >= 8  # the GET_DIAG burst on open
        stim = make_stimulus(belt.layout, 45.0, mode="dynamic")
        for start in ("play", "stream"):
            if start == "play":
                belt.play(stim, 1.0)
            else:
                belt.set_amplitudes([0.25] * 6)  # the first frame after stop: an ONSET
                belt.set_amplitudes([0.5] * 6)  # streaming on: none
            onset = belt.last_onset()
            assert onset is not None
            host_ns, uncertainty_ns = onset
            seq = device.seqs[-2] if start == "stream" else device.seqs[-1]
            true_ns = (device.onset_times_us[seq] - _FAKE_EPOCH_US) * 1000
            assert abs(host_ns - true_ns) <= max(uncertainty_ns, 50_000)
            assert 0 < uncertainty_ns < 5_000_000
            belt.stop()
        assert len(device.onset_times_us) == 2
    assert belt.unmatched_replies == 0 and belt.bad_replies == 0


def test_a_watchdog_reset_is_reported_on_open(caplog: pytest.LogCaptureFixture) -> None:
    with caplog.at_level(logging.WARNING, logger="tactorbelt.devices"):
        belt, _, _ = open_fake(FakeFirmware(extensions=True, reset_flags=0x02))
    with belt:
        assert belt.watchdog_reset
        assert belt.diagnostics is not None and belt.diagnostics.watchdog_reset
        assert belt.info.capabilities & wire.Capability.WATCHDOG_RESET
    assert any("watchdog" in r.getMessage() and r.levelno == logging.WARNING
               for r in caplog.records)


def test_a_watchdog_reset_while_open_is_reported_and_the_flags_set_again(
        caplog: pytest.LogCaptureFixture) -> None:
    belt, device, _ = open_fake(FakeFirmware(extensions=True))
    with belt, caplog.at_level(logging.WARNING, logger="tactorbelt.devices"):
        assert not belt.watchdog_reset
        device.reset_flags, device.flags = 0x02, 0  # the device rebooted: flags gone
        belt.diag()
        assert belt.watchdog_reset
        assert device.flags == wire.ConfigFlag.ONSET_EVENTS  # set again
        belt.play(make_stimulus(belt.layout, 45.0), 1.0)
        assert belt.last_onset() is not None
    assert any("watchdog" in r.getMessage() for r in caplog.records)


def test_a_reply_too_long_for_the_mtu_is_a_clear_error() -> None:
    class SmallMtu(FakeFirmware):
        def _answer(self, seq: int, req: wire_device.Request) -> wire.Reply | None:
            if isinstance(req, wire_device.GetStatus):
                return wire.Nak(seq, wire.NakCode.REPLY_TOO_LONG)
            return super()._answer(seq, req)

    belt, _, _ = open_fake(SmallMtu(extensions=True))
    with belt, pytest.raises(DeviceError, match="MTU"):
        belt.status()
