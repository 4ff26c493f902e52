"""The ``emulator`` belt: the real firmware core, built for this computer, on a pseudo-terminal.

``open_belt("emulator")`` builds ``firmware/build/emulator`` if needed (``make -C
firmware emulator``; needs make and g++), starts it, reads the pseudo-terminal path
it prints as its first line, and talks to it through the serial backend: the same
frames, decoder, renderer and failsafe as on the board, with the host's clock. Its board
has an IMU (``imu``, a BMI270 by default) simulated from the ERM motor model, which
``belt.sense()`` records as on a real board (docs/protocol.md, "The emulator").

Closing the belt stops the motors, closes the port, then ends the emulator (closing
its stdin, then SIGTERM, then SIGKILL if it lingers).

The firmware directory is found next to the package source (a source checkout:
``Path(__file__).parents[3] / "firmware"``), or from ``$TACTORBELT_FIRMWARE_DIR``.

Imports pyserial through :mod:`tactorbelt.devices.serial`.
"""

from __future__ import annotations

import contextlib
import logging
import os
import selectors
import shutil
import subprocess
import tempfile
import threading
import time
from pathlib import Path
from typing import IO, Any, Final

from .._errors import ConfigError, DeviceError
from ..geometry import Layout
from ._firmware import FIRMWARE_OPTIONS, FirmwareBelt, checked_int
from .registry import check_options
from .serial import SERIAL_STREAM_RATE_HZ, SerialTransport

__all__ = ["EmulatorBelt", "build_emulator", "emulator_path", "firmware_dir", "open_emulator"]

log = logging.getLogger("tactorbelt.devices")

#: How long the emulator may take to print its pseudo-terminal path.
START_TIMEOUT_S: Final = 10.0
#: How long ``make`` may take.
BUILD_TIMEOUT_S: Final = 300.0

OPTIONS: Final = FIRMWARE_OPTIONS | {"tactors", "levels_log", "build", "firmware_dir",
                                     "extra_args", "watchdog_ms", "debug_frames", "imu", "brake"}
#: What the emulator's ``--imu`` takes.
IMU_KINDS: Final = ("bmi270", "lsm9ds1", "none", "broken")

_build_lock = threading.Lock()


def firmware_dir(override: str | os.PathLike[str] | None = None) -> Path:
    """The firmware source directory.

    Raises:
        DeviceError: it is not there (an installed package without the source tree).
    """
    fw = Path(override if override is not None else
              os.environ.get("TACTORBELT_FIRMWARE_DIR")
              or Path(__file__).resolve().parents[3] / "firmware")
    if (fw / "Makefile").is_file():
        return fw
    raise DeviceError(
        f"the emulator needs the firmware sources, not found at {fw}; run from a "
        "source checkout of tactorbelt or set TACTORBELT_FIRMWARE_DIR to its firmware/ directory"
    )


def emulator_path(fw_dir: Path) -> Path:
    """Where ``make emulator`` puts the binary."""
    return fw_dir / "build" / "emulator"


def build_emulator(fw_dir: Path | None = None) -> Path:
    """Run ``make -C firmware emulator`` (a no-op when up to date); return the binary.

    Raises:
        DeviceError: make or g++ is missing, or the build fails (with make's output).
    """
    fw = fw_dir or firmware_dir()
    missing = [tool for tool in ("make", "g++") if shutil.which(tool) is None]
    if missing:
        exe = emulator_path(fw)
        if exe.is_file():
            log.info("%s not found; using the existing %s", " and ".join(missing), exe)
            return exe
        raise DeviceError(
            f"building the emulator needs {' and '.join(missing)} (on Debian/Ubuntu: "
            "sudo apt-get install make g++)"
        )
    with _build_lock:
        try:
            proc = subprocess.run(
                ["make", "-C", str(fw), "emulator"], capture_output=True, text=True,
                timeout=BUILD_TIMEOUT_S, check=False,
            )
        except subprocess.TimeoutExpired:
            raise DeviceError(f"building the emulator took longer than {BUILD_TIMEOUT_S:g} s"
                              ) from None
    if proc.returncode != 0:
        tail = "\n".join((proc.stdout + proc.stderr).strip().splitlines()[-15:])
        raise DeviceError(f"building the emulator failed (make -C {fw} emulator):\n{tail}")
    exe = emulator_path(fw)
    if not exe.is_file():
        raise DeviceError(f"make -C {fw} emulator succeeded but {exe} is missing")
    return exe


def _read_first_line(stream: IO[bytes], timeout_s: float) -> str:
    """The first stdout line of the emulator, or "" if it exits or times out first."""
    fd = stream.fileno()
    buf = b""
    deadline = time.monotonic() + timeout_s
    with selectors.DefaultSelector() as sel:
        sel.register(fd, selectors.EVENT_READ)
        while b"\n" not in buf:
            left = deadline - time.monotonic()
            if left <= 0 or not sel.select(left):
                return ""
            chunk = os.read(fd, 4096)
            if not chunk:
                return ""
            buf += chunk
    line, _, rest = buf.partition(b"\n")
    if rest:
        log.debug("emulator: %s", rest.decode(errors="replace").rstrip())
    return line.decode(errors="replace").strip()


def _drain(stream: IO[bytes]) -> None:
    """Keep reading the emulator's stdout so that it never blocks on a full pipe."""
    with contextlib.suppress(OSError, ValueError):
        for line in stream:
            log.debug("emulator: %s", line.decode(errors="replace").rstrip())


class EmulatorBelt(FirmwareBelt):
    """A FirmwareBelt whose device is an emulator process it owns (and ends on close).

    Attributes:
        process: the emulator (``subprocess.Popen``).
        pty_path: the pseudo-terminal it serves.
    """

    def __init__(self, transport: SerialTransport, process: subprocess.Popen[bytes],
                 pty_path: str, **options: Any) -> None:
        self.process = process
        self.pty_path = pty_path
        super().__init__(transport, "emulator", stream_rate_hz=SERIAL_STREAM_RATE_HZ, **options)

    def _close(self) -> None:
        try:
            super()._close()
        finally:
            stop_process(self.process)


def stop_process(proc: subprocess.Popen[bytes], timeout_s: float = 2.0) -> None:
    """End the emulator: close its stdin (it exits), then SIGTERM, then SIGKILL."""
    if proc.stdin is not None:
        with contextlib.suppress(OSError):
            proc.stdin.close()
    for signal_it in (None, proc.terminate, proc.kill):
        if signal_it is not None:
            with contextlib.suppress(OSError):
                signal_it()
        try:
            proc.wait(0.5 if signal_it is None else timeout_s)
            break
        except subprocess.TimeoutExpired:
            continue
    if proc.stdout is not None:
        with contextlib.suppress(OSError):
            proc.stdout.close()


def open_emulator(target: str = "", **options: Any) -> EmulatorBelt:
    """Build (if needed) and start the firmware emulator, and open it as a belt.

    Args:
        target: unused (``emulator`` takes no target).
        **options:
            tactors (int, 6): channels of the emulated belt (2..16), evenly spaced.
            layout (Layout | None): emulate a belt with these tactor angles instead.
            heartbeat_ms (int | None): the emulator's heartbeat timeout at start.
            levels_log (path | None): the emulator writes every change of its outputs
                there as CSV ``t_us,state,level_0,...`` (device time since start).
            build (bool, True): run ``make -C firmware emulator`` first.
            firmware_dir: the firmware directory (default: next to the package).
            watchdog_ms (int | None): run the board's watchdog model (1..10000 ms; the
                board uses 300): a loop that stops for that long resets the core, and the
                belt reports the watchdog reset. Off by default.
            debug_frames (bool, False): accept DEBUG_HANG (0x7E), which stops the
                emulator's loop until the watchdog resets it (tests of the watchdog).
            imu (str, "bmi270"): the board's simulated IMU: "bmi270" (1600 Hz, a Rev2
                board), "lsm9ds1" (952 Hz, Rev1), "none" (no IMU streaming: firmware
                1.1's behaviour), "broken" (an IMU that did not start).
            brake (bool, True): the emulated board has both inputs of each motor's
                H-bridge wired (INFO bits SHAPE and BRAKE: a shaped fall brakes); False
                emulates the older wiring, IN2 to ground (SHAPE only: a shaped fall
                coasts). The emulator's ``--wiring bridge|in1``.
            supply_v (float), kick_ms (float): the emulated motors' supply (V) and how long
                a kick may apply it above their maximum voltage; shaped, SET_DRIVE sends
                the rated level and the kick bound (docs/belts.md, "The kick bound"). The
                emulated motor's speed is in units of the full duty: give the belt a
                calibration whose ceiling is the rated level (rated voltage over supply).
            extra_args (list[str]): more emulator arguments.
            timeout_s, calibration, keepalive, clock: as for every firmware belt.

    Raises:
        ConfigError: an unknown option or a bad tactor count.
        DeviceError: no firmware sources, no compiler, a failed build, or an emulator
            that does not start or answer.
    """
    check_options(options, OPTIONS, "emulator")
    if target:
        raise ConfigError(f"the emulator belt takes no target, got 'emulator:{target}'")
    for name, lo, hi in (("tactors", 2, 16), ("heartbeat_ms", 50, 2000), ("watchdog_ms", 1, 10000)):
        if options.get(name) is not None:
            checked_int(name, options[name], lo, hi)
    tactors = options.pop("tactors", None)
    layout = options.pop("layout", None)
    if layout is not None:
        if not isinstance(layout, Layout) or not 2 <= layout.n <= 16:
            raise ConfigError(f"layout must be a Layout of 2..16 tactors, got {layout!r}")
        if tactors is not None and tactors != layout.n:
            raise ConfigError(f"tactors={tactors} but the layout has {layout.n} tactors")
    imu = options.pop("imu", None)
    if imu is not None and imu not in IMU_KINDS:
        raise ConfigError(f"imu must be one of {', '.join(IMU_KINDS)}, got {imu!r}")
    fw = firmware_dir(options.pop("firmware_dir", None))
    if options.pop("build", True):
        exe = build_emulator(fw)
    else:
        exe = emulator_path(fw)
        if not exe.is_file():
            raise DeviceError(f"no emulator at {exe}; build it with: make -C {fw} emulator")
    if layout is not None:
        args = [str(exe), "--tactor-angles", ",".join(f"{a:.2f}" for a in layout.angles_deg)]
    else:
        args = [str(exe), "--tactors", str(6 if tactors is None else tactors)]
    given = {"--heartbeat-ms": options.pop("heartbeat_ms", None),
             "--levels-log": options.pop("levels_log", None),
             "--watchdog-ms": options.pop("watchdog_ms", None), "--imu": imu}
    args += [a for flag, v in given.items() if v is not None for a in (flag, str(v))]
    if options.pop("debug_frames", False):
        args += ["--debug-frames"]
    if not options.pop("brake", True):
        args += ["--wiring", "in1"]
    args += [str(a) for a in options.pop("extra_args", ())]

    with tempfile.TemporaryFile() as stderr:
        try:
            # its own session: the terminal's Ctrl-C (SIGINT to the foreground process
            # group) reaches only the host, which stops the motors, then ends the
            # emulator; if the host dies, the emulator's stdin reaches end of file and
            # it exits by itself
            proc = subprocess.Popen(args, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                    stderr=stderr, start_new_session=True)
        except OSError as exc:
            raise DeviceError(f"cannot start the emulator {exe}: {exc}") from None
        assert proc.stdout is not None
        path = _read_first_line(proc.stdout, START_TIMEOUT_S)
        if not path:
            stop_process(proc)
            stderr.seek(0)
            err = stderr.read().decode(errors="replace").strip()
            raise DeviceError(
                f"the emulator did not print its pseudo-terminal within {START_TIMEOUT_S:g} s "
                f"(exit code {proc.returncode}){': ' + err if err else ''}"
            )
    threading.Thread(target=_drain, args=(proc.stdout,), name="tactorbelt-emulator-stdout",
                     daemon=True).start()
    try:
        transport = SerialTransport(path)
    except BaseException:
        stop_process(proc)
        raise
    try:  # a FirmwareBelt that fails to open closes its transport
        return EmulatorBelt(transport, proc, path, **options)
    except BaseException:
        stop_process(proc)
        raise
