"""``tactorbelt firmware``: the belt's firmware from the installed package.

- ``export DIR``: write the sketch as an Arduino sketch folder (``DIR/tactorbelt``), for
  the Arduino IDE or arduino-cli.
- ``build``: compile it for the Nano 33 BLE with arduino-cli.
- ``upload --port PORT``: compile and upload it to the board on PORT.

Without arduino-cli, ``build`` and ``upload`` print how to install it (exit 2). The
library is :mod:`tactorbelt.firmware`; this module parses, calls it and prints.
"""

from __future__ import annotations

from pathlib import Path

import click

__all__ = ["firmware"]

_imu = click.option("--imu", type=click.Choice(["bmi270", "lsm9ds1"]), default="bmi270",
                    show_default=True,
                    help="The board's IMU: bmi270 (Nano 33 BLE Rev2) or lsm9ds1 (Rev1).")
_build_dir = click.option(
    "--build-dir", type=click.Path(file_okay=False, path_type=Path), default=None,
    help="Where the sketch and the binaries go (default: a new temporary folder).")


@click.group("firmware")
def firmware() -> None:
    """The belt's firmware (Arduino Nano 33 BLE): export, build, upload.

    The installed package carries the sketch; its version is what 'tactorbelt devices'
    compares with a connected board's.
    """


@firmware.command("export")
@click.argument("dest", metavar="DIR", type=click.Path(file_okay=False, path_type=Path))
@click.option("--force", is_flag=True, help="Replace an existing DIR/tactorbelt.")
def export(dest: Path, force: bool) -> None:
    """Write the sketch as an Arduino sketch folder, DIR/tactorbelt."""
    from ..firmware import bundled_version, export_sketch

    out = export_sketch(dest, overwrite=force)
    click.echo(f"wrote firmware {bundled_version()} to {out}")
    click.echo(f"open {out / 'tactorbelt.ino'} in the Arduino IDE (board: Arduino Nano 33 BLE), "
               "or: tactorbelt firmware upload --port PORT")


@firmware.command("build")
@_imu
@_build_dir
def build(imu: str, build_dir: Path | None) -> None:
    """Compile the sketch for the Nano 33 BLE with arduino-cli."""
    from ..firmware import build as build_firmware

    result = build_firmware(build_dir=build_dir, imu=imu)
    click.echo(f"built {result.sketch} -> {result.output_dir}")


@firmware.command("upload")
@click.option("--port", required=True,
              help="The board's serial port (/dev/ttyACM0, COM3); 'tactorbelt devices' "
                   "lists them.")
@_imu
@_build_dir
def upload(port: str, imu: str, build_dir: Path | None) -> None:
    """Compile the sketch and upload it to the board on PORT with arduino-cli."""
    from ..firmware import bundled_version
    from ..firmware import upload as upload_firmware

    upload_firmware(port, build_dir=build_dir, imu=imu)
    click.echo(f"uploaded firmware {bundled_version()} to {port}; "
               f"check it with: tactorbelt devices")
