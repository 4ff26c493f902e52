"""``tactorbelt devices``: list serial ports and BLE devices that answer as belts.

Each registered backend with a discovery function (:mod:`tactorbelt.devices.registry`)
gets a section, in the registry's order. Serial ports that look like an Arduino Nano 33
BLE (USB vendor 0x2341) are asked GET_INFO; other ports are listed without being written
to unless ``--probe-all``. BLE devices advertising the tactorbelt service (or name) are
connected to and asked GET_INFO. A machine without BLE gets a one-line note, not an
error.

Imports pyserial and bleak only when the command runs (through the device backends).
"""

from __future__ import annotations

import json
from dataclasses import asdict
from typing import TYPE_CHECKING, Any

import click

from ..devices.registry import BACKENDS, url_options_help
from ._options import number

if TYPE_CHECKING:
    from ..devices.registry import Discovery, Found

__all__ = ["devices"]

#: The backends ``tactorbelt devices`` scans, in the registry's order.
_DISCOVERABLE = tuple(b.scheme for b in BACKENDS.values() if b.discover is not None)


def _line(row: Found) -> str:
    if row.is_belt:
        what = f"belt: firmware {row.firmware_version}, {row.tactors} tactors -> --belt {row.url}"
        if row.drive:
            what += f"\n    drive: {row.drive}"
        if row.note:  # e.g. older firmware than this tactorbelt carries, and the update
            what += f"\n    note: {row.note}"
    else:
        what = row.note or "no answer"
    return f"  {row.port}  {row.description}  {what}"


@click.command(epilog="\b\nBelt URLs (--belt URL):\n" + "\n".join(
    f"  {', '.join(b.examples)}: {b.summary}" for b in BACKENDS.values())
    + "\n\n\b\nURL options (--belt serial:auto?timeout_s=2&heartbeat_ms=500):\n"
    + url_options_help())
@click.option("--timeout", "timeout_s", type=number(float, 0.1, 60.0), default=5.0,
              show_default=True,
              help="Seconds to scan for BLE devices (each device gets at most 0.5 s to answer).")
@click.option("--no-ble", is_flag=True, help="Do not scan for BLE devices (same as --skip ble).")
@click.option("--skip", "skip", multiple=True, type=click.Choice(_DISCOVERABLE),
              help="Do not scan this kind of link (repeatable).")
@click.option("--probe-all", is_flag=True,
              help="Also ask serial ports that do not look like an Arduino.")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of text.")
def devices(timeout_s: float, no_ble: bool, skip: tuple[str, ...], probe_all: bool,
            as_json: bool) -> None:
    """List serial ports and BLE devices, and which of them answer as belts.

    A belt is a device running tactorbelt firmware (protocol v1): asked, it answers
    with its firmware version and tactor count. Use the URL shown with
    --belt (e.g. --belt serial:/dev/ttyACM0), or --belt serial:auto.
    """
    skipped = set(skip) | ({"ble"} if no_ble else set())
    found: dict[str, Discovery] = {}
    for scheme in _DISCOVERABLE:
        if scheme in skipped:
            from ..devices.registry import Discovery

            flag = "--no-ble" if scheme == "ble" and no_ble else f"--skip {scheme}"
            found[scheme] = Discovery([], f"not scanned ({flag})")
        else:
            discover = BACKENDS[scheme].load_discover()
            assert discover is not None
            found[scheme] = discover(timeout_s=timeout_s, probe_all=probe_all)
    belts: list[Found] = [r for d in found.values() for r in d.rows if r.is_belt]
    try:  # the joysticks SDL sees, or a note saying why none can be listed
        from ..inputs.joystick import list_joysticks

        sticks: list[dict[str, Any]] = list_joysticks()
        stick_note: str | None = None
    except Exception as exc:  # no SDL, no display server: a note, not an error
        sticks, stick_note = [], f"joysticks cannot be listed here ({exc})"
    if as_json:
        out: dict[str, Any] = {}
        for scheme, d in found.items():
            out[scheme] = [asdict(r) for r in d.rows]
            if d.note is not None or scheme != "serial":
                out[f"{scheme}_note"] = d.note
        out.update({"belts": [r.url for r in belts], "joysticks": sticks,
                    "joystick_note": stick_note})
        click.echo(json.dumps(out, indent=2))
        return
    for scheme, d in found.items():
        click.echo(f"{BACKENDS[scheme].title or scheme}:")
        if d.note:
            click.echo(f"  note: {d.note}")
        for r in d.rows:
            click.echo(_line(r))
        if not d.rows and not d.note:
            click.echo(f"  {d.empty}")
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
