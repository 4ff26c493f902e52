"""The firmware in a pip user's hands: ``tactorbelt firmware export|build|upload``, the
version a board reports against the one the package carries, and the DTR line.

arduino-cli cannot be installed on the test machines (it is on no package registry they
reach), so the build and upload tests put a stand-in ``arduino-cli`` on the PATH that
records its arguments: it checks the command lines we give arduino-cli, not arduino-cli.
The real compile of the exported sketch runs with the board's real core headers
(``../shared/arduino-nano33ble/compile.sh``) where that folder and arm-none-eabi-g++ are
there.
"""

from __future__ import annotations

import filecmp
import os
import shutil
import stat
import subprocess
import sys
import venv
from collections.abc import Iterator
from pathlib import Path

import pytest
from click.testing import CliRunner

from support.belts import FakeFirmware, PtyDevice, comports, port_info
from support.cli import tactorbelt
from tactorbelt import DeviceError, ProtocolError
from tactorbelt import firmware as fw
from tactorbelt.cli import cli
from tactorbelt.devices import open_belt

ROOT = Path(__file__).resolve().parents[1]
SKETCH = ROOT / "firmware" / "tactorbelt"
SHARED_CORE = ROOT.parent / "shared" / "arduino-nano33ble"


def _sources(root: Path) -> list[str]:
    return sorted(str(p.relative_to(root)) for p in root.rglob("*")
                  if p.is_file() and p.suffix in {".ino", ".cpp", ".h"})


# -- export ---------------------------------------------------------------------------

def test_export_writes_an_arduino_sketch_folder_equal_to_the_source(tmp_path: Path) -> None:
    result = tactorbelt("firmware", "export", str(tmp_path / "out"))
    assert result.returncode == 0, result.stdout + result.stderr
    out = tmp_path / "out" / "tactorbelt"
    assert (out / "tactorbelt.ino").is_file()  # Arduino: the folder is named as the .ino
    assert _sources(out) == _sources(SKETCH)
    for rel in _sources(SKETCH):
        assert filecmp.cmp(out / rel, SKETCH / rel, shallow=False), rel
    assert f"firmware {fw.bundled_version()}" in result.stdout


def test_export_never_overwrites_without_force_and_replaces_with_it(tmp_path: Path) -> None:
    out = fw.export_sketch(tmp_path)
    stale = out / "stale.h"
    stale.write_text("// left from an older version\n")
    again = tactorbelt("firmware", "export", str(tmp_path))
    assert again.returncode == 2
    assert "exists; pass --force" in again.stderr
    assert stale.exists()
    forced = tactorbelt("firmware", "export", "--force", str(tmp_path))
    assert forced.returncode == 0, forced.stderr
    assert not stale.exists()
    assert _sources(out) == _sources(SKETCH)


def test_export_into_a_file_is_a_user_error(tmp_path: Path) -> None:
    f = tmp_path / "file"
    f.write_text("x")
    result = tactorbelt("firmware", "export", str(f))
    assert result.returncode == 2
    assert "error:" in result.stderr


def test_the_bundled_version_is_the_one_the_firmware_core_reports() -> None:
    text = (SKETCH / "src" / "core" / "protocol.h").read_text()
    major, minor, patch = fw.bundled_version().split(".")
    assert f"kFirmwareMajor = {major};" in text
    assert f"kFirmwareMinor = {minor};" in text
    assert f"kFirmwarePatch = {patch};" in text


# -- build and upload through arduino-cli -----------------------------------------------

@pytest.fixture
def fake_cli(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Iterator[Path]:
    """A stand-in arduino-cli on the PATH that logs its arguments; it fails when the
    environment asks it to (ARDUINO_FAKE_FAIL)."""
    bindir = tmp_path / "bin"
    bindir.mkdir()
    log = tmp_path / "calls.log"
    exe = bindir / "arduino-cli"
    exe.write_text(
        "#!/bin/sh\n"
        f'printf "%s\\n" "$*" >> "{log}"\n'
        'if [ -n "$ARDUINO_FAKE_FAIL" ] && [ "$1" = "$ARDUINO_FAKE_FAIL" ]; then\n'
        '  echo "Error: no board on that port" >&2; exit 1; fi\n'
        "exit 0\n"
    )
    exe.chmod(exe.stat().st_mode | stat.S_IEXEC)
    monkeypatch.setenv("PATH", f"{bindir}{os.pathsep}{os.environ['PATH']}")
    monkeypatch.delenv("ARDUINO_CLI", raising=False)
    yield log


def test_build_compiles_the_exported_sketch_for_the_nano_33_ble(
    fake_cli: Path, tmp_path: Path
) -> None:
    result = tactorbelt("firmware", "build", "--build-dir", str(tmp_path / "b"))
    assert result.returncode == 0, result.stdout + result.stderr
    (call,) = fake_cli.read_text().splitlines()
    sketch = tmp_path / "b" / "sketch" / "tactorbelt"
    assert call.split() == ["compile", "--fqbn", "arduino:mbed_nano:nano33ble", "--warnings",
                            "all", "--build-property",
                            "compiler.cpp.extra_flags=-DTACTORBELT_IMU_BMI270",
                            "--output-dir", str(tmp_path / "b" / "build"), str(sketch)]
    assert _sources(sketch) == _sources(SKETCH)


def test_upload_builds_then_uploads_to_the_port(fake_cli: Path, tmp_path: Path) -> None:
    result = tactorbelt("firmware", "upload", "--port", "/dev/ttyACM7", "--imu", "lsm9ds1",
                        "--build-dir", str(tmp_path / "b"))
    assert result.returncode == 0, result.stdout + result.stderr
    compile_call, upload_call = fake_cli.read_text().splitlines()
    assert compile_call.startswith("compile --fqbn arduino:mbed_nano:nano33ble")
    assert "compiler.cpp.extra_flags=-DTACTORBELT_IMU_LSM9DS1" in compile_call  # a Rev1 board
    assert upload_call.split()[:5] == ["upload", "--fqbn", "arduino:mbed_nano:nano33ble",
                                       "--port", "/dev/ttyACM7"]
    assert "uploaded firmware" in result.stdout


def test_a_failed_upload_is_a_device_error_naming_the_port(
    fake_cli: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("ARDUINO_FAKE_FAIL", "upload")
    result = tactorbelt("firmware", "upload", "--port", "/dev/ttyACM7")
    assert result.returncode == 3
    assert "uploading to /dev/ttyACM7 failed" in result.stderr


def test_a_failed_build_says_what_to_install(
    fake_cli: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("ARDUINO_FAKE_FAIL", "compile")
    result = tactorbelt("firmware", "build")
    assert result.returncode == 2
    assert "arduino-cli core install arduino:mbed_nano" in result.stderr


@pytest.mark.parametrize("command", [["build"], ["upload", "--port", "/dev/ttyACM0"]])
def test_without_arduino_cli_the_install_steps_are_printed(
    command: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("PATH", str(tmp_path))  # no arduino-cli anywhere
    monkeypatch.delenv("ARDUINO_CLI", raising=False)
    result = tactorbelt("firmware", *command)
    assert result.returncode == 2
    assert "arduino-cli is not installed" in result.stderr
    assert "arduino-cli core install arduino:mbed_nano" in result.stderr
    assert ("arduino-cli lib install ArduinoBLE Arduino_BMI270_BMM150 Arduino_LSM9DS1"
            in result.stderr)
    assert "tactorbelt firmware export DIR" in result.stderr


# -- versions ------------------------------------------------------------------------

def test_an_older_protocol_names_the_command_that_updates_the_board() -> None:
    dev = PtyDevice(FakeFirmware(protocol_version=0))
    try:
        with pytest.raises(ProtocolError) as info:
            open_belt(f"serial:{dev.path}")
        assert f"tactorbelt firmware upload --port {dev.path}" in str(info.value)
    finally:
        dev.close()


def test_a_newer_protocol_says_to_update_tactorbelt() -> None:
    dev = PtyDevice(FakeFirmware(protocol_version=2))
    try:
        with pytest.raises(ProtocolError, match="pip install -U tactorbelt"):
            open_belt(f"serial:{dev.path}")
    finally:
        dev.close()


def test_devices_says_a_board_runs_older_firmware_and_how_to_update_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from serial.tools import list_ports

    dev = PtyDevice(FakeFirmware(fw_version=(1, 0, 0)))
    try:
        monkeypatch.setattr(list_ports, "comports", comports(
            port_info(dev.path, "Nano 33 BLE", 0x2341)))
        result = CliRunner().invoke(cli, ["devices", "--no-ble"])
    finally:
        dev.close()
    assert result.exit_code == 0, result.output
    assert (f"firmware 1.0.0 is older than this tactorbelt's {fw.bundled_version()}"
            in result.output)
    assert f"tactorbelt firmware upload --port {dev.path}" in result.output


def test_devices_says_nothing_of_a_board_that_matches(monkeypatch: pytest.MonkeyPatch) -> None:
    from serial.tools import list_ports

    ours = tuple(int(x) for x in fw.bundled_version().split("."))
    dev = PtyDevice(FakeFirmware(fw_version=ours))  # type: ignore[arg-type]
    try:
        monkeypatch.setattr(list_ports, "comports", comports(
            port_info(dev.path, "Nano 33 BLE", 0x2341)))
        result = CliRunner().invoke(cli, ["devices", "--no-ble"])
    finally:
        dev.close()
    assert result.exit_code == 0, result.output
    serial_section = result.output.split("BLE:")[0]
    assert dev.path in serial_section
    assert "note:" not in serial_section
    assert "tactorbelt firmware upload" not in result.output


# -- DTR -----------------------------------------------------------------------------

def test_the_port_is_opened_with_dtr_asserted_and_no_dtr_flow_control() -> None:
    from tactorbelt.devices.serial import SerialTransport

    dev = PtyDevice(FakeFirmware())
    try:
        t = SerialTransport(dev.path)
        try:
            assert t._ser.dtr is True
            assert t._ser.dsrdtr is False
            assert t.dtr_line is None  # a pseudo-terminal has no modem lines
            assert t.silence_hint() == ""
        finally:
            t.close()
    finally:
        dev.close()


def test_a_port_opened_without_dtr_is_reported_not_silently_mute() -> None:
    """The board's USB serial (USBCDC::send_nb) sends nothing while DTR is low: the
    device stays silent, and the error says why."""
    dev = PtyDevice(FakeFirmware(silent=True))
    try:
        with pytest.raises(DeviceError, match="DTR is low") as info:
            open_belt(f"serial:{dev.path}?dtr=0&timeout_s=0.05")
        assert "no tactorbelt firmware answered" in str(info.value)
        # with DTR asserted, a silent device is not blamed on DTR
        with pytest.raises(DeviceError) as plain:
            open_belt(f"serial:{dev.path}?timeout_s=0.05")
        assert "DTR" not in str(plain.value)
    finally:
        dev.close()


def test_a_dtr_line_the_os_reports_low_is_named() -> None:
    from tactorbelt.devices.serial import SerialTransport

    dev = PtyDevice(FakeFirmware())
    try:
        t = SerialTransport(dev.path)
        try:
            t.dtr_line = False  # what TIOCMGET reports when a driver ignored TIOCMBIS
            assert "DTR is low" in t.silence_hint()
            assert "although tactorbelt asserted it" in t.silence_hint()
        finally:
            t.close()
    finally:
        dev.close()


# -- the wheel -----------------------------------------------------------------------

@pytest.mark.slow
def test_the_wheel_carries_the_sketch_and_it_compiles_on_the_real_core(tmp_path: Path) -> None:
    """Build the wheel, install it (not editable) into a fresh venv, export the sketch
    from there, and compile the export with the board's real core headers."""
    wheels = tmp_path / "wheels"
    build = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(wheels), str(ROOT)],
        capture_output=True, text=True, timeout=600)
    assert build.returncode == 0, build.stderr[-2000:]
    (wheel,) = wheels.glob("tactorbelt-*.whl")
    env_dir = tmp_path / "venv"
    venv.create(env_dir, with_pip=True)
    py = env_dir / ("Scripts" if os.name == "nt" else "bin") / "python"
    # click is all `tactorbelt firmware` needs; --no-deps keeps the install small
    install = subprocess.run(
        [str(py), "-m", "pip", "install", "-q", "--no-deps", str(wheel), "click"],
        capture_output=True, text=True, timeout=600)
    if install.returncode != 0 and "click" in install.stderr:
        pytest.skip(f"click could not be installed into a fresh venv: {install.stderr[-300:]}")
    assert install.returncode == 0, install.stderr[-2000:]
    out = tmp_path / "export"
    run = subprocess.run(
        [str(py), "-c", "import sys; from tactorbelt.cli import main; sys.exit(main())",
         "firmware", "export", str(out)],
        capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "site-packages" in subprocess.run(
        [str(py), "-c", "import tactorbelt.firmware as f; print(f.sketch_dir())"],
        capture_output=True, text=True, timeout=60, cwd=tmp_path).stdout
    assert _sources(out / "tactorbelt") == _sources(SKETCH)
    compile_sh = SHARED_CORE / "compile.sh"
    if not compile_sh.is_file():
        pytest.skip(f"the board's core headers are not beside the checkout ({SHARED_CORE})")
    if shutil.which("arm-none-eabi-g++") is None:
        pytest.skip("arm-none-eabi-g++ not installed (apt-get install gcc-arm-none-eabi "
                    "libnewlib-arm-none-eabi libstdc++-arm-none-eabi-newlib)")
    compiled = subprocess.run(["bash", str(compile_sh), str(out / "tactorbelt"),
                               str(tmp_path / "objects")],
                              capture_output=True, text=True, timeout=600)
    assert compiled.returncode == 0, (compiled.stdout + compiled.stderr)[-4000:]


def test_1200_baud_is_refused_before_the_port_is_touched() -> None:
    """Opening a Nano 33 BLE at 1200 baud and closing it resets it into its bootloader."""
    from tactorbelt import ConfigError

    dev = PtyDevice(FakeFirmware())
    try:
        with pytest.raises(ConfigError, match="bootloader"):
            open_belt(f"serial:{dev.path}?baudrate=1200")
        assert dev.firmware.requests == []
    finally:
        dev.close()
