"""The ``ble`` belt: tactorbelt firmware over Bluetooth LE, with bleak.

- ``ble:NAME`` connects to the device advertising that local name (the firmware
  advertises ``tactorbelt`` unless built otherwise); ``ble:AA:BB:CC:DD:EE:FF`` (or a
  macOS UUID) to that address; ``ble:auto`` to the first device advertising the
  tactorbelt service.
- The host writes each packet unframed, as one write-without-response to the RX
  characteristic; the device answers with notifications on the TX characteristic,
  one packet each (see docs/protocol.md). A packet is at most 64 bytes, so the link
  needs an ATT MTU of at least 67 (BlueZ, macOS and Windows negotiate more).
- After connecting, the transport reads the negotiated MTU (``client.mtu_size``; on
  BlueZ it first asks for it with ``_acquire_mtu``, as bleak advises, since BlueZ
  reports 23 until then). Below 67 the belt turns on framed replies (firmware 1.1,
  SET_CONFIG flag bit 1): notifications are then pieces of a COBS byte stream, split
  at 0x00 by the serial link's :class:`~tactorbelt.devices.wire.FrameDecoder`.
- bleak is asyncio-based; the belt's API is synchronous. One event loop runs in a
  daemon thread for the whole process and every bleak call is marshalled to it with
  ``asyncio.run_coroutine_threadsafe``. Notifications are decoded on that loop and
  handed to :class:`~tactorbelt.devices._firmware.FirmwareBelt` like serial packets.
- BLE streams at 40 Hz (``stream_rate_hz = 40.0``); use device-side rendering
  (``play``) for the 1 kHz dynamic stimuli.

Tests inject ``client_factory`` (an async function returning a bleak-like client), so
the whole path runs without an adapter.

Imports bleak lazily (inside functions); :func:`tactorbelt.devices.open_belt` imports
this module only when a ``ble:`` belt is opened.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import functools
import logging
import re
import threading
from collections.abc import Awaitable, Callable, Coroutine
from dataclasses import dataclass
from typing import Any, Final, Protocol, TypeVar

from .._errors import DeviceError, ProtocolError
from . import wire
from ._firmware import BLE_MIN_MTU, FIRMWARE_OPTIONS, FirmwareBelt, PacketSink, Transport, probe
from .registry import Discovery, Found, check_options

__all__ = [
    "BLE_STREAM_RATE_HZ",
    "DEVICE_NAME",
    "RX_CHAR_UUID",
    "SERVICE_UUID",
    "TX_CHAR_UUID",
    "BleBeltInfo",
    "BleClient",
    "BleTransport",
    "BleUnavailableError",
    "discover",
    "discover_belts",
    "open_ble",
]

log = logging.getLogger("tactorbelt.devices")

#: The tactorbelt GATT service.
SERVICE_UUID: Final = "7b1e0001-5c1a-4d8e-9f3b-6a2c74b0e1d5"
#: RX: the host writes request packets here (write without response).
RX_CHAR_UUID: Final = "7b1e0002-5c1a-4d8e-9f3b-6a2c74b0e1d5"
#: TX: the device notifies reply packets here.
TX_CHAR_UUID: Final = "7b1e0003-5c1a-4d8e-9f3b-6a2c74b0e1d5"
#: The local name the firmware advertises by default.
DEVICE_NAME: Final = "tactorbelt"

BLE_STREAM_RATE_HZ: Final = 40.0
#: The ATT MTU every link starts with (20 bytes per notification).
DEFAULT_ATT_MTU: Final = 23
DEFAULT_BLE_TIMEOUT_S: Final = 1.0
DEFAULT_SCAN_TIMEOUT_S: Final = 10.0
DEFAULT_CONNECT_TIMEOUT_S: Final = 20.0

OPTIONS: Final = FIRMWARE_OPTIONS | {"client_factory", "scan_timeout_s", "connect_timeout_s"}

#: A Bluetooth address, or the UUID macOS uses instead.
_ADDRESS = re.compile(
    r"^([0-9A-Fa-f]{2}[:-]){5}[0-9A-Fa-f]{2}$|^[0-9A-Fa-f]{8}(-[0-9A-Fa-f]{4}){3}-[0-9A-Fa-f]{12}$"
)

T = TypeVar("T")


class BleUnavailableError(DeviceError):
    """This machine cannot do BLE (no adapter, no BlueZ/D-Bus, permission denied)."""


class BleClient(Protocol):
    """The part of ``bleak.BleakClient`` the BLE belt uses (a fake implements it in tests)."""

    @property
    def mtu_size(self) -> int: ...

    async def connect(self) -> None: ...

    async def disconnect(self) -> None: ...

    async def start_notify(self, char: str, callback: Callable[[Any, bytearray], None],
                           ) -> None: ...

    async def write_gatt_char(self, char: str, data: bytes, response: bool) -> None: ...


#: ``await factory(target, on_disconnect, scan_timeout_s)`` gives an unconnected client.
ClientFactory = Callable[[str, Callable[[Any], None], float], Awaitable[BleClient]]


# --- the event loop thread ------------------------------------------------------------

_loop: asyncio.AbstractEventLoop | None = None
_loop_lock = threading.Lock()


def _event_loop() -> asyncio.AbstractEventLoop:
    """The process-wide BLE event loop, started on first use in a daemon thread."""
    global _loop
    with _loop_lock:
        if _loop is None or _loop.is_closed():
            loop = asyncio.new_event_loop()
            threading.Thread(target=loop.run_forever, name="tactorbelt-ble-loop",
                             daemon=True).start()
            _loop = loop
        return _loop


def run_on_loop(coro: Coroutine[Any, Any, T], timeout_s: float, what: str) -> T:
    """Run a coroutine on the BLE loop and wait for it (from any other thread).

    Raises:
        DeviceError: it took longer than ``timeout_s`` (the coroutine is cancelled).
    """
    future = asyncio.run_coroutine_threadsafe(coro, _event_loop())
    try:
        return future.result(timeout_s)
    except concurrent.futures.TimeoutError:
        future.cancel()
        raise DeviceError(f"{what} took longer than {timeout_s:g} s") from None


def _describe(exc: BaseException) -> str:
    text = str(exc) or type(exc).__name__
    if isinstance(exc, FileNotFoundError):
        return f"no BlueZ / D-Bus system bus ({text})"
    return text


async def _bleak_client(target: str, on_disconnect: Callable[[Any], None],
                        scan_timeout_s: float) -> BleClient:
    """Find the device by name, address or service (``auto``) and make a BleakClient."""
    from bleak import BleakClient, BleakScanner

    try:
        if target.lower() == "auto":
            device = await BleakScanner.find_device_by_filter(
                lambda d, ad: SERVICE_UUID in [u.lower() for u in ad.service_uuids],
                timeout=scan_timeout_s,
            )
        elif _ADDRESS.match(target):
            device = await BleakScanner.find_device_by_address(target, timeout=scan_timeout_s)
        else:
            device = await BleakScanner.find_device_by_name(target, timeout=scan_timeout_s)
    except Exception as exc:
        raise BleUnavailableError(f"BLE is not available on this machine: {_describe(exc)}"
                                  ) from None
    if device is None:
        what = "advertising the tactorbelt service" if target.lower() == "auto" else (
            f"named or at {target!r}")
        raise DeviceError(
            f"no BLE device {what} found within {scan_timeout_s:g} s; is the belt on "
            "and not connected to another host? ('tactorbelt devices' lists belts)"
        )
    client: Any = BleakClient(device, disconnected_callback=on_disconnect)
    return client


async def _negotiated_mtu(client: BleClient) -> int:
    """The ATT MTU of the connection. On BlueZ, bleak reports 23 until asked to acquire
    the negotiated MTU (BlueZ exchanges MTUs itself; other platforms report it)."""
    backend = getattr(client, "_backend", None)  # a bleak client, not a belt
    if type(backend).__name__ == "BleakClientBlueZDBus":
        with contextlib.suppress(Exception):
            await backend._acquire_mtu()  # type: ignore[union-attr]
    try:
        return max(DEFAULT_ATT_MTU, int(client.mtu_size))
    except (AttributeError, TypeError, ValueError):
        return DEFAULT_ATT_MTU


# --- the transport ----------------------------------------------------------------------


class BleTransport(Transport):
    """Unframed packets over a GATT write characteristic and a notify characteristic.

    Args:
        target: a name, an address, or ``auto``.
        client_factory: makes the client (default: scan with bleak, then BleakClient).
        scan_timeout_s: how long to look for the device.
        connect_timeout_s: how long connecting may take.
        write_timeout_s: a write that takes longer means the link is gone.

    Raises:
        BleUnavailableError: no BLE on this machine.
        DeviceError: the device is not found or the connection fails.
    """

    def __init__(
        self,
        target: str,
        client_factory: ClientFactory | None = None,
        scan_timeout_s: float = DEFAULT_SCAN_TIMEOUT_S,
        connect_timeout_s: float = DEFAULT_CONNECT_TIMEOUT_S,
        write_timeout_s: float = 1.0,
    ) -> None:
        self.port = f"BLE {target}"
        self._sink: PacketSink | None = None
        self._closing = False
        self._write_timeout_s = write_timeout_s
        self.mtu = DEFAULT_ATT_MTU
        factory = client_factory or _bleak_client
        self._client = run_on_loop(
            self._connect(factory, target, scan_timeout_s),
            scan_timeout_s + connect_timeout_s, f"connecting to {self.port}",
        )

    async def _connect(self, factory: ClientFactory, target: str, scan_timeout_s: float
                       ) -> BleClient:
        client = await factory(target, self._on_disconnect, scan_timeout_s)
        address = getattr(client, "address", None)
        if address and address.lower() != target.lower():
            self.port = f"BLE {target} ({address})"
        try:
            await client.connect()
            await client.start_notify(TX_CHAR_UUID, self._on_notify)
            self.mtu = await _negotiated_mtu(client)
        except DeviceError:
            raise
        except Exception as exc:
            with contextlib.suppress(Exception):
                await client.disconnect()
            raise DeviceError(f"cannot connect to {self.port}: {_describe(exc)}") from None
        return client

    @property
    def reply_limit(self) -> int:
        """The longest notification the link carries: ATT MTU - 3."""
        return self.mtu - 3

    def use_framed_replies(self) -> None:
        self._decoder = wire.FrameDecoder()

    def encode(self, packet: wire.Packet) -> bytes:
        return wire.encode_packet(packet)

    def write(self, data: bytes) -> None:
        if self._closing:
            raise DeviceError(f"{self.port} is closed")

        try:
            run_on_loop(self._client.write_gatt_char(RX_CHAR_UUID, data, response=False),
                        self._write_timeout_s, f"writing to {self.port}")
        except DeviceError:
            raise
        except Exception as exc:
            hint = ""
            if len(data) > self.reply_limit:
                hint = (f" (a {len(data)}-byte request; the link reported ATT MTU {self.mtu}, "
                        f"at most {self.reply_limit} bytes per write: the adapter must "
                        f"negotiate an MTU of at least {BLE_MIN_MTU})")
            raise DeviceError(f"write to {self.port} failed: {_describe(exc)}{hint}") from None

    def start(self, sink: PacketSink) -> None:
        self._sink = sink

    def _on_notify(self, _sender: Any, data: bytearray) -> None:
        decoder = self._decoder
        if decoder is not None:  # framed replies: one byte stream, split at 0x00
            packets = decoder.feed(bytes(data))
        else:
            try:
                packets = [wire.decode_packet(bytes(data))]
            except ProtocolError as exc:
                if "CRC" in str(exc):
                    self._crc_errors += 1
                else:
                    self._framing_errors += 1
                return
        if self._sink is not None:
            self.deliver(self._sink, packets)

    def _on_disconnect(self, _client: Any) -> None:
        if not self._closing and self._sink is not None:
            self._sink.link_lost("BLE disconnected")

    def close(self) -> None:
        if self._closing:
            return
        self._closing = True
        try:
            run_on_loop(self._client.disconnect(), 5.0, f"disconnecting {self.port}")
        except Exception as exc:
            log.debug("disconnecting %s: %s", self.port, exc)


# --- opening and discovery ----------------------------------------------------------------


def open_ble(target: str, **options: Any) -> FirmwareBelt:
    """Open ``ble:NAME``, ``ble:ADDRESS`` or ``ble:auto``.

    Args:
        target: the advertised name, the address, or ``auto``.
        **options: ``client_factory`` (tests), ``scan_timeout_s`` (10), ``connect_timeout_s``
            (20), and the :class:`FirmwareBelt` options ``timeout_s`` (1.0 for BLE),
            ``heartbeat_ms``, ``calibration``, ``layout``, ``keepalive``, ``clock``.

    Raises:
        BleUnavailableError: no BLE on this machine (a DeviceError).
        DeviceError: the device is not found, or does not answer.
        ProtocolError: it speaks another protocol version.
    """
    url = f"ble:{target}"
    check_options(options, OPTIONS, url)
    factory = options.pop("client_factory", None)
    scan_timeout_s = float(options.pop("scan_timeout_s", DEFAULT_SCAN_TIMEOUT_S))
    connect_timeout_s = float(options.pop("connect_timeout_s", DEFAULT_CONNECT_TIMEOUT_S))
    options.setdefault("timeout_s", DEFAULT_BLE_TIMEOUT_S)
    transport = BleTransport(target, factory, scan_timeout_s, connect_timeout_s)
    return FirmwareBelt(transport, url, stream_rate_hz=BLE_STREAM_RATE_HZ, **options)


@dataclass(frozen=True)
class BleBeltInfo:
    """A BLE device that advertises the tactorbelt service or name.

    Attributes:
        address: the Bluetooth address (a UUID on macOS).
        name: the advertised name.
        rssi: signal strength in dBm, when known.
    """

    address: str
    name: str
    rssi: int | None


async def _scan(timeout_s: float) -> list[BleBeltInfo]:
    from bleak import BleakScanner

    found = await BleakScanner.discover(timeout_s, return_adv=True)
    belts = []
    for device, adv in found.values():
        uuids = [u.lower() for u in adv.service_uuids]
        name = adv.local_name or device.name or ""
        if SERVICE_UUID in uuids or name.lower().startswith(DEVICE_NAME):
            belts.append(BleBeltInfo(device.address, name, adv.rssi))
    return sorted(belts, key=lambda b: -(b.rssi if b.rssi is not None else -999))


def discover_belts(timeout_s: float = 5.0) -> list[BleBeltInfo]:
    """Scan for ``timeout_s`` and list the devices that advertise as tactorbelts.

    Raises:
        BleUnavailableError: no adapter, no BlueZ / D-Bus, or no permission.
    """
    try:
        return run_on_loop(_scan(timeout_s), timeout_s + 10.0, "scanning for BLE belts")
    except DeviceError:
        raise
    except Exception as exc:
        raise BleUnavailableError(
            f"BLE is not available on this machine: {_describe(exc)}") from None


def discover(timeout_s: float = 5.0, probe_all: bool = False) -> Discovery:
    """Scan for belts and ask each GET_INFO (for ``tactorbelt devices``).

    A machine without BLE gets a note, not an error. ``probe_all`` is unused.
    """
    del probe_all
    empty = f"no device advertising a tactorbelt within {timeout_s:g} s"
    try:
        found = discover_belts(timeout_s)
    except BleUnavailableError as exc:
        return Discovery([], str(exc), empty)
    rows = []
    for d in found:
        rssi = f", {d.rssi} dBm" if d.rssi is not None else ""
        row = Found("ble", d.address, f"{d.name or '(no name)'}{rssi}", f"ble:{d.address}")
        probe(row, functools.partial(open_ble, d.address, scan_timeout_s=timeout_s,
                                     keepalive=False))
        rows.append(row)
    return Discovery(rows, None, empty)
