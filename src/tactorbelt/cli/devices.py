"""``tactorbelt devices``: list serial ports and BLE devices that answer as belts.

Serial ports that look like an Arduino Nano 33 BLE (USB vendor 0x2341) are asked
GET_INFO; other ports are listed without being written to unless ``--probe-all``.
BLE devices advertising the tactorbelt service (or name) are connected to and asked
GET_INFO. A machine without BLE gets a one-line note, not an error.

Imports pyserial and bleak only when the command runs (through the device backends).
"""

from __future__ import annotations

import functools
import json
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any

import click

if TYPE_CHECKING:
    from ..devices.base import Belt

__all__ = ["devices"]

#: Longest wait for one device's answer while probing.
PROBE_TIMEOUT_S = 0.5


@dataclass
class Found:
    """One port or BLE device and what it answered."""

    link: str
    port: str
    description: str
    url: str
    firmware_version: str | None = None
    tactors: int | None = None
    note: str = ""

    @property
    def is_belt(self) -> bool:
        return self.firmware_version is not None


def _probe(open_: Callable[[], Belt]) -> tuple[str | None, int | None, str]:
    """Open a belt, read version and tactor count, close it. Never raises."""
    from .._errors import TactorbeltError

    try:
        belt = open_()
    except TactorbeltError as exc:
        return None, None, str(exc)
    with belt:
        return belt.firmware_version, belt.n_tactors, ""


def _serial(timeout_s: float, probe_all: bool) -> list[Found]:
    from ..devices.serial import list_serial_ports, open_serial_port

    rows = []
    for p in list_serial_ports():
        ids = f" [{p.vid:04X}:{p.pid or 0:04X}]" if p.vid is not None else ""
        row = Found("serial", p.device, p.description + ids, f"serial:{p.device}")
        if p.looks_like_belt or probe_all:
            row.firmware_version, row.tactors, row.note = _probe(functools.partial(
                open_serial_port, p.device, timeout_s=min(timeout_s, PROBE_TIMEOUT_S),
                keepalive=False))
        else:
            row.note = "not probed (not an Arduino; --probe-all asks it anyway)"
        rows.append(row)
    return rows


def _ble(timeout_s: float) -> tuple[list[Found], str | None]:
    from ..devices.ble import BleUnavailableError, discover_belts, open_ble

    try:
        found = discover_belts(timeout_s)
    except BleUnavailableError as exc:
        return [], str(exc)
    rows = []
    for d in found:
        rssi = f", {d.rssi} dBm" if d.rssi is not None else ""
        row = Found("ble", d.address, f"{d.name or '(no name)'}{rssi}", f"ble:{d.address}")
        row.firmware_version, row.tactors, row.note = _probe(functools.partial(
            open_ble, d.address, scan_timeout_s=timeout_s, keepalive=False))
        rows.append(row)
    return rows, None


def _line(row: Found) -> str:
    if row.is_belt:
        what = f"belt: firmware {row.firmware_version}, {row.tactors} tactors -> --belt {row.url}"
    else:
        what = row.note or "no answer"
    return f"  {row.port}  {row.description}  {what}"


def _joysticks() -> tuple[list[dict[str, Any]], str | None]:
    """The joysticks SDL sees, or a note saying why none can be listed."""
    try:
        from ..inputs.joystick import list_joysticks

        return list_joysticks(), None
    except Exception as exc:  # no SDL, no display server: a note, not an error
        return [], f"joysticks cannot be listed here ({exc})"


@click.command()
@click.option("--timeout", "timeout_s", type=click.FloatRange(min=0.1, max=60.0), default=5.0,
              show_default=True,
              help="Seconds to scan for BLE devices (each device gets at most 0.5 s to answer).")
@click.option("--no-ble", is_flag=True, help="Do not scan for BLE devices.")
@click.option("--probe-all", is_flag=True,
              help="Also ask serial ports that do not look like an Arduino.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of text.")
def devices(timeout_s: float, no_ble: bool, probe_all: bool, as_json: bool) -> None:
    """List serial ports and BLE devices, and which of them answer as belts.

    A belt is a device running tactorbelt firmware (protocol v1): it answers
    GET_INFO with its firmware version and tactor count. Use the URL shown with
    --belt (e.g. --belt serial:/dev/ttyACM0), or --belt serial:auto.
    """
    rows = _serial(timeout_s, probe_all)
    ble_rows: list[Found] = []
    ble_note: str | None = "not scanned (--no-ble)" if no_ble else None
    if not no_ble:
        ble_rows, ble_note = _ble(timeout_s)
    belts = [r for r in rows + ble_rows if r.is_belt]
    sticks, stick_note = _joysticks()
    if as_json:
        click.echo(json.dumps({
            "serial": [asdict(r) for r in rows],
            "ble": [asdict(r) for r in ble_rows],
            "ble_note": ble_note,
            "belts": [r.url for r in belts],
            "joysticks": sticks,
            "joystick_note": stick_note,
        }, indent=2))
        return
    click.echo("Serial ports:")
    if rows:
        for r in rows:
            click.echo(_line(r))
    else:
        click.echo("  none")
    click.echo("BLE:")
    if ble_note:
        click.echo(f"  note: {ble_note}")
    elif ble_rows:
        for r in ble_rows:
            click.echo(_line(r))
    else:
        click.echo(f"  no device advertising a tactorbelt within {timeout_s:g} s")
    click.echo("Joysticks (for tactorbelt run --joystick INDEX|NAME):")
    if stick_note:
        click.echo(f"  note: {stick_note}")
    for js in sticks:
        click.echo(f"  {js['index']}  {js['name']}  ({js['axes']} axes, {js['buttons']} buttons)")
    if not sticks and not stick_note:
        click.echo("  none")
    if belts:
        click.echo(f"{len(belts)} belt(s) found.")
    else:
        click.echo("No belts found. Plug the belt in by USB (or switch it on for BLE), "
                   "or try the emulator: --belt emulator")
