"""A naviBelt emulated on a pseudo-terminal, speaking the USB serial protocol as pybelt
1.2.4 (feelSpace's Python library, Apache-2.0) defines it, so that pybelt's own
``BeltController`` connects to it, sends and receives (the ``navibelt:emulator`` belt).

The protocol, read from pybelt's source (``_communication_interface.py``,
``_gatt_profile.py``, ``belt_controller.py``): the naviBelt's GATT characteristics
carried over a 115200-baud serial line as packets ``[attribute handle, length, data...]``
(length at most 22; 0 for a read request). The host writes a value handle to write a
characteristic, ``[handle, 0]`` to read one, and ``[configuration handle, 2, 1, 0]`` to
enable its notifications; the belt answers reads and sends notifications as
``[value handle, length, data...]``. Handles (pybelt's USB profile): firmware info 31,
keep-alive 33/34, vibration command 36, button press 38/39, parameter request 41,
parameter notification 43/44, battery 51/52, orientation 60/61.

What the emulation does, and which of it is inferred (pybelt shows what the host sends
and what it accepts back, not what the belt does with it; docs/belts.md):

- parameters: belt mode (``01 01``, set ``01 81 m``), default intensity (``01 02``, set
  ``01 82 i 00 f``), heading offset (``01 03``), the inaccurate-orientation signal state
  (``10 01 03``, set ``11 03 s v``), answered on the parameter notification
  characteristic as pybelt expects;
- vibration commands ``[channel 0-5, pattern, intensity (2 bytes, 0xAAAA: the default),
  0, 0, orientation type, orientation (2 bytes), 0, 0, iterations, period (2), start
  (2), exclusive, clear others]`` and stops ``[0x30, channel or 0xFF]``, honoured in app
  mode only (inferred: the docs say other modes take only short signals on channel 1);
  a continuous channel drives its motors (a motor index, a 16-bit binary mask, or the
  motor nearest an angle: inferred) at its intensity; motors shared by channels take the
  strongest (inferred). Pulse commands (``0x40``) are accepted and treated as
  continuous (inferred, simplified);
- a keep-alive request every ``keepalive_s`` (``[0x01, mode]`` on the keep-alive
  characteristic; pybelt answers ``01``); a belt whose host has answered none for
  ``keepalive_timeout_s`` (10 s), or whose link drops, leaves app mode for wait mode and
  stops vibrating (inferred, the timeout too: the docs say an unexpected disconnection in
  app mode goes to wait mode; pybelt's answers come from its listener thread, which a
  loaded machine can hold back for seconds);
- battery notifications every ``battery_s`` (9 bytes: status, charge x 256, time to
  empty / 5.625, mA, mV, as pybelt parses them); a button press on demand
  (:meth:`press_button`: ``[button, 0, 0, previous mode, new mode]``); the
  inaccurate-orientation signal on demand (:meth:`orientation_warning`: it takes channel
  0, as the docs say, on the flank motors 4 and 12);
- :meth:`hang_up` closes the line (the host reads an error: a lost connection).

Imports the standard library only.
"""

from __future__ import annotations

import contextlib
import os
import select
import struct
import threading
import time
import tty
from dataclasses import dataclass
from typing import Final

__all__ = ["MOTORS", "NaviBeltEmulation"]

#: Motors on a naviBelt: index 0 at the navel, clockwise, 22.5 degrees apart.
MOTORS: Final = 16

# pybelt's USB GATT profile: value handles and configuration (notification) handles
FIRMWARE_INFO: Final = 31
KEEP_ALIVE, KEEP_ALIVE_CFG = 33, 34
VIBRATION: Final = 36
BUTTON, BUTTON_CFG = 38, 39
PARAM_REQUEST: Final = 41
PARAM_NOTIFY, PARAM_NOTIFY_CFG = 43, 44
BATTERY, BATTERY_CFG = 51, 52
SENSOR_CMD: Final = 55
ORIENTATION, ORIENTATION_CFG = 60, 61
_CONFIG_OF: Final = {KEEP_ALIVE_CFG: KEEP_ALIVE, BUTTON_CFG: BUTTON,
                     PARAM_NOTIFY_CFG: PARAM_NOTIFY, BATTERY_CFG: BATTERY,
                     ORIENTATION_CFG: ORIENTATION, 58: 57, 78: 77}
_HANDLES: Final = frozenset({30, 31, 32, 33, 34, 35, 36, 37, 38, 39, 40, 41, 42, 43, 44, 50,
                             51, 52, 54, 55, 56, 57, 58, 59, 60, 61, 74, 75, 76, 77, 78})

# belt modes (pybelt's BeltMode)
STANDBY, WAIT, COMPASS, APP_MODE, PAUSE = 0, 1, 2, 3, 4
# orientation types (pybelt's BeltOrientationType)
BINARY_MASK, MOTOR_INDEX, ANGLE, MAGNETIC_BEARING = 0, 1, 2, 3


@dataclass(frozen=True)
class Channel:
    """What one vibration channel drives: an intensity (0-100) on a set of motors."""

    intensity: int
    motors: frozenset[int]


class NaviBeltEmulation:
    """A naviBelt on a pseudo-terminal (``path`` is the port the host opens).

    Args:
        firmware_version: what the firmware-info characteristic reports.
        default_intensity: the belt's default intensity (0-100).
        keepalive_s: seconds between keep-alive requests (None: none).
        keepalive_timeout_s: seconds without an answer after which the belt drops the
            host (leaves app mode).
        battery_s: seconds between battery notifications (None: none).
        battery_percent: the charge reported.
    """

    def __init__(self, firmware_version: int = 52, default_intensity: int = 50,
                 keepalive_s: float | None = 1.0, keepalive_timeout_s: float = 10.0,
                 battery_s: float | None = 2.0,
                 battery_percent: float = 80.0) -> None:
        self.firmware_version = firmware_version
        self.default_intensity = default_intensity
        self.keepalive_s = keepalive_s
        self.keepalive_timeout_s = keepalive_timeout_s
        self._answered_at = time.monotonic()
        self.battery_s = battery_s
        self.battery_percent = battery_percent
        self.mode = WAIT
        self.heading_offset = 0
        self.signal_state = 3  # the inaccurate-orientation signal: on in app and compass modes
        self.channels: dict[int, Channel] = {}
        self.notify: set[int] = set()
        self.keepalives_sent = 0
        self.keepalives_answered = 0
        self.commands: list[bytes] = []  # every vibration command, in order
        #: each motor's intensity (0..1) when the link was lost, before the belt stopped
        #: its motors itself (None: not lost)
        self.levels_at_link_loss: list[float] | None = None
        #: ``(time.perf_counter_ns(), motor intensities 0..1)`` at every change, from rest
        self.timeline: list[tuple[int, tuple[float, ...]]] = [(time.perf_counter_ns(),
                                                               (0.0,) * MOTORS)]
        self._lock = threading.Lock()
        self.master, self._slave = os.openpty()
        tty.setraw(self._slave)
        self.path = os.ttyname(self._slave)
        self._stop_r, self._stop_w = os.pipe()
        self._closed = False
        self._thread = threading.Thread(target=self._serve, name="navibelt-emulation",
                                        daemon=True)
        self._thread.start()

    # -- what the motors do ------------------------------------------------------------------
    def motor_levels(self) -> list[float]:
        """Each motor's intensity now, 0..1 (the strongest channel driving it)."""
        with self._lock:
            return list(self._levels())

    def _levels(self) -> tuple[float, ...]:
        out = [0] * MOTORS
        for ch in self.channels.values():
            for m in ch.motors:
                out[m] = max(out[m], ch.intensity)
        return tuple(v / 100.0 for v in out)

    def _changed(self) -> None:
        levels = self._levels()
        if levels != self.timeline[-1][1]:
            self.timeline.append((time.perf_counter_ns(), levels))

    # -- the wearer and the belt's own signals --------------------------------------------------
    def press_button(self, button: int, new_mode: int) -> None:
        """The wearer presses ``button`` (1-4) and the belt goes to ``new_mode``."""
        with self._lock:
            previous = self.mode
            self._set_mode(new_mode)
        self._send(BUTTON, bytes([button, 0, 0, previous, new_mode]))

    def orientation_warning(self) -> None:
        """The inaccurate-orientation signal starts: it takes channel 0 (the flanks)."""
        with self._lock:
            if self.signal_state & 2 and self.mode == APP_MODE:
                self.channels[0] = Channel(self.default_intensity, frozenset({4, 12}))
                self._changed()

    # -- the link ------------------------------------------------------------------------------
    def hang_up(self) -> None:
        """The belt vanishes (unplugged, powered off): the line closes."""
        if self._closed:
            return
        self._closed = True
        os.write(self._stop_w, b"x")
        self._thread.join(2.0)
        with contextlib.suppress(OSError):
            os.close(self.master)
        with self._lock:
            self._link_lost()

    def close(self) -> None:
        self.hang_up()
        for fd in (self._slave, self._stop_r, self._stop_w):
            with contextlib.suppress(OSError):
                os.close(fd)

    # -- internals -----------------------------------------------------------------------------
    def _set_mode(self, mode: int) -> None:
        if mode != APP_MODE:
            self.channels.clear()  # leaving app mode stops the app's vibration
            self._changed()
        self.mode = mode

    def _link_lost(self) -> None:
        if self.levels_at_link_loss is None:
            self.levels_at_link_loss = list(self._levels())
        if self.mode == APP_MODE:
            self._set_mode(WAIT)

    def _send(self, handle: int, data: bytes) -> None:
        if self._closed or (handle != FIRMWARE_INFO and handle not in self.notify):
            return  # a read is answered; anything else only when notifications are on
        with contextlib.suppress(OSError):
            os.write(self.master, bytes([handle, len(data)]) + data)

    def _serve(self) -> None:
        buf = bytearray()
        now = time.monotonic()
        next_keepalive = now + (self.keepalive_s or 1e9)
        next_battery = now + (self.battery_s or 1e9)
        while True:
            timeout = max(0.0, min(next_keepalive, next_battery) - time.monotonic())
            ready, _, _ = select.select([self.master, self._stop_r], [], [], timeout)
            if self._stop_r in ready:  # what the host wrote before the line closed still counts
                with contextlib.suppress(OSError):
                    while select.select([self.master], [], [], 0)[0]:
                        data = os.read(self.master, 4096)
                        if not data:
                            break
                        buf = self._packets(buf + data)
                return
            if self.master in ready:
                try:
                    data = os.read(self.master, 4096)
                except OSError:
                    with self._lock:
                        self._link_lost()
                    return
                buf += data
                buf = self._packets(buf)
            now = time.monotonic()
            if self.keepalive_s and now >= next_keepalive:
                next_keepalive = now + self.keepalive_s
                self._keepalive()
            if self.battery_s and now >= next_battery:
                next_battery = now + self.battery_s
                self._battery()

    def _keepalive(self) -> None:
        with self._lock:
            if KEEP_ALIVE not in self.notify:
                return
            waiting = self.keepalives_sent > self.keepalives_answered
            if waiting and time.monotonic() - self._answered_at > self.keepalive_timeout_s:
                self._link_lost()  # the host stopped answering
            self.keepalives_sent += 1
            mode = self.mode
        self._send(KEEP_ALIVE, bytes([0x01, mode]))

    def _battery(self) -> None:
        self._send(BATTERY, struct.pack("<BHHhH", 2, round(self.battery_percent * 256), 1600,
                                        -150, 3900))

    def _packets(self, buf: bytearray) -> bytearray:
        while len(buf) >= 2:
            handle, size = buf[0], buf[1]
            if handle not in _HANDLES:  # out of step: drop a byte, as pybelt's reader does
                del buf[0]
                continue
            if len(buf) < 2 + size:
                break
            data = bytes(buf[2:2 + size])
            del buf[:2 + size]
            self._handle(handle, data)
        return buf

    def _handle(self, handle: int, data: bytes) -> None:
        if handle in _CONFIG_OF and len(data) == 2:
            with self._lock:
                (self.notify.add if data[0] & 1 else self.notify.discard)(_CONFIG_OF[handle])
        elif handle == FIRMWARE_INFO and not data:
            self._send(FIRMWARE_INFO, self.firmware_version.to_bytes(2, "little") + b"\x00\x00")
        elif handle == KEEP_ALIVE and data[:1] == b"\x01":
            with self._lock:
                self.keepalives_answered = self.keepalives_sent
                self._answered_at = time.monotonic()
        elif handle == PARAM_REQUEST:
            self._parameter(data)
        elif handle == VIBRATION:
            with self._lock:
                self.commands.append(data)
                self._vibration(data)
                self._changed()

    def _parameter(self, data: bytes) -> None:
        if data == b"\x01\x01":
            self._send(PARAM_NOTIFY, bytes([0x01, 0x01, self.mode]))
        elif data[:2] == b"\x01\x81" and len(data) >= 3:
            with self._lock:
                self._set_mode(data[2])
            self._send(PARAM_NOTIFY, bytes([0x01, 0x01, self.mode]))
        elif data == b"\x01\x02":
            self._send(PARAM_NOTIFY, bytes([0x01, 0x02, self.default_intensity, 0x00]))
        elif data[:2] == b"\x01\x82" and len(data) >= 3:
            self.default_intensity = max(5, min(100, data[2]))
            self._send(PARAM_NOTIFY, bytes([0x01, 0x02, self.default_intensity, 0x00]))
        elif data == b"\x01\x03":
            offset = self.heading_offset.to_bytes(2, "little")
            self._send(PARAM_NOTIFY, bytes([0x01, 0x03]) + offset)
        elif data == b"\x10\x01\x03":
            self._send(PARAM_NOTIFY, bytes([0x10, 0x03, self.signal_state]))
        elif data[:2] == b"\x11\x03" and len(data) >= 4:
            self.signal_state = data[3]
            self._send(PARAM_NOTIFY, bytes([0x10, 0x03, self.signal_state]))

    def _vibration(self, data: bytes) -> None:
        if self.mode != APP_MODE:
            return
        if data[:1] == b"\x30" and len(data) == 2:
            if data[1] == 0xFF:
                self.channels.clear()
            else:
                self.channels.pop(data[1], None)
            return
        if data[:1] == b"\x40" and len(data) >= 6:  # a pulse command: taken as continuous
            channel, kind, orient, intensity = struct.unpack_from("<BBHB", data, 1)
            intensity = self.default_intensity if intensity == 0xAA else intensity
        elif len(data) == 18 and data[0] <= 5:
            channel, pattern, intensity, kind, orient = struct.unpack_from("<BBH2xBH", data)
            intensity = self.default_intensity if intensity == 0xAAAA else intensity
            if pattern == 0:
                self.channels.pop(channel, None)
                return
        else:
            return
        if channel > 5:
            return
        if kind == BINARY_MASK:
            motors = frozenset(m for m in range(MOTORS) if orient >> m & 1)
        elif kind == MOTOR_INDEX:
            motors = frozenset({orient % MOTORS})
        else:
            motors = frozenset({round(orient / (360.0 / MOTORS)) % MOTORS})
        if data[-1:] == b"\x01" and data[0] != 0x40:  # clear the other channels
            self.channels.clear()
        self.channels[channel] = Channel(min(100, intensity), motors)
