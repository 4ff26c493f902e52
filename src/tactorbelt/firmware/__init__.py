"""The belt's firmware as the installed package carries it: export, build, upload.

The wheel carries the Arduino sketch (``firmware/tactorbelt`` of the source tree,
copied into ``tactorbelt/firmware/sketch/tactorbelt`` by ``setup.py`` at build time). In a
source checkout (an editable install) the sketch is read from the checkout itself.

- :func:`sketch_dir` finds the sketch; :func:`export_sketch` writes it as an Arduino
  sketch folder (``DIR/tactorbelt/tactorbelt.ino`` and its sources).
- :func:`build` and :func:`upload` run arduino-cli (when it is installed; otherwise they
  raise :class:`ArduinoCliMissing`, whose message is the install steps).
- :func:`bundled_version` is the firmware version the sketch declares
  (``src/core/protocol.h``), which ``tactorbelt devices`` compares with a board's.

Standard library only; imports nothing from the rest of tactorbelt but ``_errors``.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import tempfile
from collections.abc import Sequence
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Final

from .._errors import ConfigError, DeviceError, TactorbeltError

__all__ = [
    "ARDUINO_LIBRARIES",
    "FQBN",
    "IMUS",
    "INSTALL_STEPS",
    "ArduinoCliMissing",
    "BuildResult",
    "build",
    "bundled_version",
    "export_sketch",
    "sketch_dir",
    "update_command",
    "upload",
    "version_note",
]

#: arduino-cli's name of the board (Arduino Mbed OS Nano Boards, Nano 33 BLE).
FQBN: Final = "arduino:mbed_nano:nano33ble"
#: The board package the sketch builds with.
CORE: Final = "arduino:mbed_nano"
#: The board revision's IMU -> (its compile-time define, its library): the sketch builds
#: for one (imu_config.h; the libraries cannot be linked together).
IMUS: Final = {
    "bmi270": ("TACTORBELT_IMU_BMI270", "Arduino_BMI270_BMM150"),  # Nano 33 BLE Rev2
    "lsm9ds1": ("TACTORBELT_IMU_LSM9DS1", "Arduino_LSM9DS1"),      # Nano 33 BLE Rev1
}
#: Libraries the sketch includes, as arduino-cli names them (``lib install``).
ARDUINO_LIBRARIES: Final = ("ArduinoBLE", *(lib for _, lib in IMUS.values()))
#: The sketch's folder name (Arduino requires folder name == .ino name).
SKETCH_NAME: Final = "tactorbelt"

_INSTALL_SH: Final = "https://raw.githubusercontent.com/arduino/arduino-cli/master/install.sh"
INSTALL_STEPS: Final = f"""arduino-cli is not installed (it builds and uploads the sketch).
Install it:
  Linux/macOS: curl -fsSL {_INSTALL_SH} | sh
               (or: brew install arduino-cli)
  Windows:     winget install ArduinoSA.CLI
  (https://arduino.github.io/arduino-cli/latest/installation/)
then, once:
  arduino-cli core update-index
  arduino-cli core install {CORE}
  arduino-cli lib install {" ".join(ARDUINO_LIBRARIES)}
and run this command again. Without arduino-cli: 'tactorbelt firmware export DIR' writes
the sketch for the Arduino IDE (open DIR/{SKETCH_NAME}/{SKETCH_NAME}.ino, board
"Arduino Nano 33 BLE")."""


class ArduinoCliMissing(TactorbeltError):
    """arduino-cli is not on the PATH; the message says how to install it."""


def sketch_dir() -> Path:
    """The sketch folder this installation carries.

    Raises:
        TactorbeltError: neither the installed copy nor a source checkout's is there (a
            broken install).
    """
    packaged = Path(str(resources.files(__name__))) / "sketch" / SKETCH_NAME
    if (packaged / f"{SKETCH_NAME}.ino").is_file():
        return packaged
    # a source checkout: src/tactorbelt/firmware/__init__.py -> firmware/tactorbelt
    checkout = Path(__file__).resolve().parents[3] / "firmware" / SKETCH_NAME
    if (checkout / f"{SKETCH_NAME}.ino").is_file():
        return checkout
    raise TactorbeltError(
        f"this tactorbelt installation carries no firmware sketch (looked in {packaged} "
        f"and {checkout}); reinstall it: pip install --force-reinstall tactorbelt"
    )


def _sketch_files(root: Path) -> list[Path]:
    """The files of a sketch folder that belong in an export (sources, no build output)."""
    keep = {".ino", ".cpp", ".c", ".h", ".hpp"}  # as setup.py copies into the wheel
    return sorted(p for p in root.rglob("*") if p.is_file() and p.suffix in keep
                  and "__pycache__" not in p.parts)


def export_sketch(dest: str | os.PathLike[str], *, overwrite: bool = False) -> Path:
    """Write the sketch as ``DEST/tactorbelt/`` (an Arduino sketch folder).

    Args:
        dest: the folder to write into (created when missing).
        overwrite: replace an existing ``DEST/tactorbelt`` (else an error).

    Returns:
        The sketch folder written (``DEST/tactorbelt``).

    Raises:
        ConfigError: ``DEST`` is a file, or ``DEST/tactorbelt`` exists and not ``overwrite``.
    """
    dest = Path(dest)
    if dest.exists() and not dest.is_dir():
        raise ConfigError(f"{dest} is a file; give a folder to write the sketch into")
    out = dest / SKETCH_NAME
    if out.exists() and not overwrite:
        raise ConfigError(f"{out} exists; pass --force to replace it")
    src = sketch_dir()
    dest.mkdir(parents=True, exist_ok=True)
    # write beside, then swap in: an interrupted export never leaves half a sketch
    tmp = Path(tempfile.mkdtemp(prefix=".tactorbelt-export-", dir=dest))
    try:
        for f in _sketch_files(src):
            target = tmp / f.relative_to(src)
            target.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(f, target)
        if out.exists():
            shutil.rmtree(out)
        tmp.rename(out)
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return out


_VERSION_RE = re.compile(r"constexpr\s+uint8_t\s+kFirmware(Major|Minor|Patch)\s*=\s*(\d+)\s*;")


def bundled_version() -> str:
    """The firmware version of the sketch this installation carries (``1.1.0``)."""
    text = (sketch_dir() / "src" / "core" / "protocol.h").read_text(encoding="utf-8")
    parts = dict(_VERSION_RE.findall(text))
    if set(parts) != {"Major", "Minor", "Patch"}:
        raise TactorbeltError("the bundled firmware's protocol.h declares no version")
    return f"{parts['Major']}.{parts['Minor']}.{parts['Patch']}"


def update_command(port: str | None) -> str:
    """The command that puts this installation's firmware on the board at ``port`` (a
    USB serial port; None for a board reached another way, e.g. over BLE)."""
    if port is None:
        return "connect the board by USB and run: tactorbelt firmware upload --port PORT"
    return f"tactorbelt firmware upload --port {port}"


def version_note(board_version: str | None, usb_port: str | None) -> str:
    """What to say of a board's firmware version against the one this tactorbelt
    carries: "" when they are equal (or cannot be compared), else which is newer and the
    command that makes them match."""
    try:
        ours = bundled_version()
    except TactorbeltError:
        return ""
    if board_version is None:
        return ""
    try:
        board, mine = (tuple(int(x) for x in v.split(".")) for v in (board_version, ours))
    except ValueError:  # a version that is not dotted numbers cannot be compared
        return ""
    if board == mine:
        return ""
    if board < mine:
        return (f"firmware {board_version} is older than this tactorbelt's {ours}; update "
                f"it: {update_command(usb_port)}")
    return (f"firmware {board_version} is newer than this tactorbelt's {ours}: "
            "pip install -U tactorbelt")


@dataclass(frozen=True)
class BuildResult:
    """What a build or upload did: the sketch built, the output folder, the commands run."""

    sketch: Path
    output_dir: Path
    commands: tuple[tuple[str, ...], ...]


def _arduino_cli(cli: str | None) -> str:
    found = shutil.which(cli or os.environ.get("ARDUINO_CLI", "arduino-cli"))
    if found is None:
        raise ArduinoCliMissing(INSTALL_STEPS)
    return found


_BUILD_HINT: Final = (f"Missing the board package or a library? arduino-cli core install {CORE}; "
                      f"arduino-cli lib install {' '.join(ARDUINO_LIBRARIES)}")


def _run(cmd: Sequence[str], what: str, hint: str) -> None:
    """Run arduino-cli with its output on the terminal; a failure names the step."""
    try:
        proc = subprocess.run(list(cmd), check=False)
    except OSError as exc:
        raise TactorbeltError(f"{what}: cannot run {cmd[0]}: {exc}") from None
    if proc.returncode != 0:
        raise TactorbeltError(
            f"{what} failed (arduino-cli exited {proc.returncode}; its output is above). {hint}"
        )


def _prepare(build_dir: str | os.PathLike[str] | None) -> tuple[Path, Path]:
    work = Path(build_dir) if build_dir is not None else Path(tempfile.mkdtemp(
        prefix="tactorbelt-firmware-"))
    sketch = export_sketch(work / "sketch", overwrite=True)
    return sketch, work / "build"


def build(*, build_dir: str | os.PathLike[str] | None = None,
          cli: str | None = None, imu: str = "bmi270") -> BuildResult:
    """Compile the bundled sketch for the Nano 33 BLE with arduino-cli.

    Args:
        build_dir: where the exported sketch and the binaries go (a new temporary
            folder by default).
        cli: the arduino-cli executable (default ``$ARDUINO_CLI`` or ``arduino-cli``).
        imu: the board revision's IMU: ``bmi270`` (Rev2, the default) or ``lsm9ds1`` (Rev1).

    Raises:
        ConfigError: an unknown ``imu``.
        ArduinoCliMissing: arduino-cli is not installed (the message is the steps).
        TactorbeltError: the compile failed.
    """
    if imu not in IMUS:
        raise ConfigError(f"imu must be one of {', '.join(IMUS)} (bmi270: Nano 33 BLE Rev2, "
                          f"lsm9ds1: Rev1), got {imu!r}")
    exe = _arduino_cli(cli)
    sketch, out = _prepare(build_dir)
    cmd = (exe, "compile", "--fqbn", FQBN, "--warnings", "all", "--build-property",
           f"compiler.cpp.extra_flags=-D{IMUS[imu][0]}", "--output-dir", str(out), str(sketch))
    _run(cmd, "building the firmware", _BUILD_HINT)
    return BuildResult(sketch, out, (cmd,))


def upload(port: str, *, build_dir: str | os.PathLike[str] | None = None,
           cli: str | None = None, imu: str = "bmi270") -> BuildResult:
    """Compile the bundled sketch and upload it to the board on ``port``.

    Args:
        port: the board's serial port (``/dev/ttyACM0``, ``COM3``).
        build_dir, cli, imu: as for :func:`build`.

    Raises:
        ConfigError: an empty port.
        ArduinoCliMissing: arduino-cli is not installed.
        DeviceError: the upload failed (the board is not on that port, or busy).
    """
    if not port or not port.strip():
        raise ConfigError("--port is empty; 'tactorbelt devices' lists the serial ports")
    result = build(build_dir=build_dir, cli=cli, imu=imu)
    exe = result.commands[0][0]
    cmd = (exe, "upload", "--fqbn", FQBN, "--port", port, "--input-dir",
           str(result.output_dir), str(result.sketch))
    try:
        _run(cmd, f"uploading to {port}", f"Is the board on {port}? Close any serial "
             "monitor; a double press of the board's reset button starts its bootloader.")
    except TactorbeltError as exc:
        raise DeviceError(str(exc)) from None
    return BuildResult(result.sketch, result.output_dir, (*result.commands, cmd))
