"""The ``serial`` belt: tactorbelt firmware over USB serial (COBS frames), with pyserial.

- ``serial:/dev/ttyACM0`` (or ``serial:COM3``) opens that port.
- ``serial:auto`` lists the serial ports, keeps those that look like an Arduino Nano
  33 BLE (USB vendor 0x2341, or "Nano 33 BLE"/"Arduino" in the description) and opens
  the first that answers GET_INFO; when none does, the error lists every candidate
  and why it failed.

The serial link streams at 1 kHz (``stream_rate_hz = 1000.0``). A reader thread
decodes frames; packets go to :class:`~tactorbelt.devices._firmware.FirmwareBelt`.

Imports pyserial; :func:`tactorbelt.devices.open_belt` imports this module only when a
``serial:`` or ``emulator`` belt is opened.
"""

from __future__ import annotations

import contextlib
import errno
import functools
import logging
import os
import threading
from dataclasses import dataclass
from typing import Any, Final

from .._errors import ConfigError, DeviceError, ProtocolError
from . import wire
from ._firmware import (
    DEFAULT_TIMEOUT_S,
    FIRMWARE_OPTIONS,
    FirmwareBelt,
    PacketSink,
    Transport,
    probe,
)
from .registry import Discovery, Found, check_options

__all__ = [
    "ARDUINO_VID",
    "SERIAL_STREAM_RATE_HZ",
    "SerialPortInfo",
    "SerialTransport",
    "discover",
    "list_serial_ports",
    "open_serial",
    "open_serial_port",
]

log = logging.getLogger("tactorbelt.devices")

#: USB vendor id of Arduino (the Nano 33 BLE enumerates with it).
ARDUINO_VID: Final = 0x2341
SERIAL_STREAM_RATE_HZ: Final = 1000.0
#: Per-request timeout while ``serial:auto`` probes candidate ports.
AUTO_PROBE_TIMEOUT_S: Final = 0.3

#: Options open_serial accepts (passed on to FirmwareBelt but ``baudrate``).
OPTIONS: Final = FIRMWARE_OPTIONS | {"baudrate", "dtr"}


class SerialTransport(Transport):
    """COBS frames over a pyserial port, read by a daemon thread.

    Args:
        port: the device path (``/dev/ttyACM0``, a pseudo-terminal, ``COM3``).
        baudrate: ignored by USB CDC and pseudo-terminals, kept for real UARTs.
        write_timeout_s: a write that blocks this long means the device is gone.
        dtr: assert DTR while the port is open (the default: the board's USB serial
            sends nothing without it); False only for adapters where DTR resets a board.

    Attributes:
        dtr_line: the DTR line as the OS reports it after open (None: no modem lines,
            as on a pseudo-terminal).

    Raises:
        DeviceError: the port cannot be opened (missing, busy, no permission).
    """

    def __init__(self, port: str, baudrate: int = 115200, write_timeout_s: float = 1.0,
                 dtr: bool = True) -> None:
        import serial

        self.port = port
        self._serial_exception = serial.SerialException
        self._dtr_asked = dtr
        try:
            # DTR set before open(): pyserial applies it while opening on every platform
            # (POSIX: TIOCMBIS; Windows: the DCB's fDtrControl), so the board's USB CDC
            # sees the terminal connected from the first byte (docs/devices.md, "DTR")
            self._ser = serial.Serial(
                None, baudrate=baudrate, timeout=None, write_timeout=write_timeout_s,
                exclusive=True, dsrdtr=False,
            )
            self._ser.dtr = dtr
            self._ser.port = port
            self._ser.open()
        except (serial.SerialException, OSError, ValueError) as exc:
            hint = ""
            text = str(exc).lower()
            if getattr(exc, "errno", None) == errno.ENOENT:
                raise DeviceError(
                    f"cannot open serial port {port}: no such port "
                    "('tactorbelt devices' lists the ports)"
                ) from None
            if "permission" in text:
                hint = " (on Linux, add yourself to the 'dialout' group and log in again)"
            elif "lock" in text or "busy" in text:
                hint = " (another program has it open: close the serial monitor)"
            raise DeviceError(f"cannot open serial port {port}: {exc}{hint}") from None
        # pyserial's write() follows every write with a select() for the timeout: on a
        # non-blocking POSIX port, one os.write() usually takes the whole frame, and only
        # the rest of a partial or refused write goes through pyserial (the timeout then)
        self._fd: int | None = None
        self._fd_lock = threading.Lock()  # close() never frees the fd under an os.write
        if os.name == "posix":
            with contextlib.suppress(AttributeError, OSError, ValueError):
                fd = self._ser.fileno()
                if not os.get_blocking(fd):
                    self._fd = fd
        self.dtr_line = _read_dtr(self._ser) if dtr else False
        self._decoder: wire.FrameDecoder = wire.FrameDecoder()
        self._stopping = False
        self._thread: threading.Thread | None = None
        self._sink: PacketSink | None = None
        self._closed = False

    @property
    def usb_port(self) -> str | None:
        return self.port

    def silence_hint(self) -> str:
        """Why the device may be mute: the DTR line low (the board's USB serial sends
        nothing until the host asserts DTR), or "" when DTR is high or the port has no
        modem lines (a pseudo-terminal)."""
        if not self._dtr_asked:
            return (f"DTR is low on {self.port} (the port was opened with dtr=0); the "
                    "Nano 33 BLE's USB serial sends nothing until the host asserts DTR: "
                    "open it without ?dtr=0")
        if self.dtr_line is False:
            return (f"DTR is low on {self.port} although tactorbelt asserted it (the "
                    "driver or another program lowered it); the Nano 33 BLE's USB serial "
                    "sends nothing until the host asserts DTR: close other programs using "
                    "the port and plug the board in again")
        return ""

    def encode(self, packet: wire.Packet) -> bytes:
        return wire.encode_frame(packet)

    def write(self, data: bytes) -> None:
        if self._closed:
            raise DeviceError(f"serial port {self.port} is closed")
        try:
            if self._fd is not None:
                with self._fd_lock:
                    fd = self._fd
                    try:
                        n = os.write(fd, data) if fd is not None else 0
                    except BlockingIOError:  # the device's buffer is full: wait in pyserial
                        n = 0
                if n == len(data):
                    return
                data = data[n:]
            self._ser.write(data)  # (after close(): pyserial's "port not open")
        except (self._serial_exception, OSError) as exc:
            raise DeviceError(f"write to serial port {self.port} failed: {exc}") from None

    def unread_bytes(self) -> int:
        return int(self._ser.in_waiting)

    def start(self, sink: PacketSink) -> None:
        self._sink = sink
        self._thread = threading.Thread(
            target=self._read_loop, name=f"tactorbelt-serial {self.port}", daemon=True
        )
        self._thread.start()

    def _read_loop(self) -> None:
        sink = self._sink
        assert sink is not None
        while not self._stopping:
            try:
                data = self._ser.read(max(1, self._ser.in_waiting))
            except Exception as exc:  # pyserial raises SerialException, OSError, TypeError
                if not self._stopping:
                    sink.link_lost(f"serial port {self.port} failed: {exc}")
                return
            if not data:
                continue  # cancelled read or timeout
            self.deliver(sink, self._decoder.feed(data))

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._stopping = True
        with self._fd_lock:
            self._fd = None
        with contextlib.suppress(Exception):
            self._ser.cancel_read()
        t = self._thread
        if t is not None and t is not threading.current_thread():
            t.join(timeout=2.0)
        try:
            self._ser.close()
        except Exception as exc:
            log.debug("closing %s: %s", self.port, exc)


def _read_dtr(ser: Any) -> bool | None:
    """The DTR line as the OS reports it after open: True or False, or None where the
    port has no modem lines (a pseudo-terminal) or the OS cannot say (then pyserial's
    own record on Windows, where the DCB set it)."""
    if os.name != "posix":
        return bool(ser.dtr)
    import fcntl
    import struct
    import termios

    try:
        bits = fcntl.ioctl(ser.fileno(), termios.TIOCMGET, struct.pack("I", 0))
    except (OSError, AttributeError, ValueError):
        return None
    return bool(struct.unpack("I", bits)[0] & termios.TIOCM_DTR)


def open_serial_port(port: str, url: str | None = None, **options: Any) -> FirmwareBelt:
    """Open the firmware belt on one serial port (no auto-detection).

    Args:
        port: the device path.
        url: recorded as ``belt.url`` (default ``serial:PORT``).
        **options: ``baudrate`` and the :class:`FirmwareBelt` options
            (``timeout_s``, ``heartbeat_ms``, ``calibration``, ``layout``, ``keepalive``).
    """
    url = url or f"serial:{port}"
    check_options(options, OPTIONS, url)
    baudrate = int(options.pop("baudrate", 115200))
    if baudrate == 1200:  # the mbed core's "1200 baud touch": the board resets into its
        raise ConfigError(  # bootloader when the port closes (docs/hardware.md)
            f"baudrate=1200 on {port} would reset a Nano 33 BLE into its bootloader when "
            "the port closes (the upload trigger); use any other rate (USB ignores it)")
    transport = SerialTransport(port, baudrate=baudrate, dtr=bool(options.pop("dtr", True)))
    return FirmwareBelt(transport, url, stream_rate_hz=SERIAL_STREAM_RATE_HZ, **options)


@dataclass(frozen=True)
class SerialPortInfo:
    """One serial port as the operating system lists it.

    Attributes:
        device: the path to open (``/dev/ttyACM0``).
        description: what the OS calls it.
        vid, pid: USB vendor and product ids (None for non-USB ports).
        looks_like_belt: USB VID 0x2341 or an Arduino / Nano 33 BLE description.
    """

    device: str
    description: str
    vid: int | None
    pid: int | None
    looks_like_belt: bool

    def label(self) -> str:
        ids = f" [{self.vid:04X}:{self.pid or 0:04X}]" if self.vid is not None else ""
        return f"{self.device} ({self.description}{ids})"


def list_serial_ports() -> list[SerialPortInfo]:
    """Every serial port the OS lists, Arduino-looking ones first (else in the OS's order)."""
    from serial.tools import list_ports

    ports = []
    for p in list_ports.comports():
        text = " ".join(str(x) for x in (p.description, p.product, p.manufacturer) if x).lower()
        ports.append(SerialPortInfo(
            device=p.device,
            description=str(p.description or p.device),
            vid=p.vid,
            pid=p.pid,
            looks_like_belt=p.vid == ARDUINO_VID or "nano 33 ble" in text or "arduino" in text,
        ))
    ports.sort(key=lambda p: not p.looks_like_belt)
    return ports


def open_serial(target: str, **options: Any) -> FirmwareBelt:
    """Open ``serial:PORT`` or ``serial:auto``.

    Args:
        target: a port path, or ``auto``.
        **options: ``baudrate``, ``timeout_s``, ``heartbeat_ms``, ``calibration``,
            ``layout``, ``keepalive``, ``clock`` (ignored).

    Raises:
        ConfigError: an unknown option.
        DeviceError: the port cannot be opened or does not answer; for ``auto``, no
            candidate answered (the message lists them).
        ProtocolError: the device speaks another protocol version.
    """
    url = f"serial:{target}"
    check_options(options, OPTIONS, url)
    if target.strip().lower() != "auto":
        return open_serial_port(target, url, **options)
    ports = list_serial_ports()
    candidates = [p for p in ports if p.looks_like_belt]
    if not candidates:
        seen = "; ".join(p.label() for p in ports) or "none"
        raise DeviceError(
            "serial:auto found no port that looks like an Arduino Nano 33 BLE "
            f"(USB vendor 0x{ARDUINO_VID:04X}); ports seen: {seen}. "
            "Plug the belt in, or name its port: --belt serial:/dev/ttyACM0"
        )
    failures = []
    probe = dict(options)
    probe.setdefault("timeout_s", AUTO_PROBE_TIMEOUT_S)
    for p in candidates:
        try:
            belt = open_serial_port(p.device, **probe)
        except (ProtocolError, DeviceError) as exc:
            failures.append(f"{p.label()}: {exc}")
            continue
        if "timeout_s" not in options:
            belt.timeout_s = DEFAULT_TIMEOUT_S
        log.info("serial:auto picked %s", p.device)
        return belt
    raise DeviceError(
        "serial:auto: no candidate port answered as a tactorbelt: " + "; ".join(failures)
    )


#: Longest wait for one device's answer while ``tactorbelt devices`` probes.
PROBE_TIMEOUT_S: Final = 0.5


def discover(timeout_s: float = 5.0, probe_all: bool = False) -> Discovery:
    """Every serial port; those that look like a belt (or all, with ``probe_all``) are
    asked GET_INFO (for ``tactorbelt devices``). Never raises for a port that fails."""
    rows = []
    for p in list_serial_ports():
        ids = f" [{p.vid:04X}:{p.pid or 0:04X}]" if p.vid is not None else ""
        row = Found("serial", p.device, p.description + ids, f"serial:{p.device}")
        if p.looks_like_belt or probe_all:
            probe(row, functools.partial(open_serial_port, p.device,
                                         timeout_s=min(timeout_s, PROBE_TIMEOUT_S),
                                         keepalive=False))
        else:
            row.note = "not probed (not an Arduino; --probe-all asks it anyway)"
        rows.append(row)
    return Discovery(rows)
