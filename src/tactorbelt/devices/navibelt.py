"""feelSpace's naviBelt, driven through feelSpace's own Python library, pybelt (1.2.4;
``pip install 'tactorbelt[navibelt]'``): ``navibelt:auto``, ``navibelt:serial:PORT``,
``navibelt:ble:NAME`` and ``navibelt:emulator`` (docs/belts.md, "naviBelt").

The naviBelt has 16 motors, motor k at ``k * 22.5`` degrees (0 at the navel, clockwise);
the belt's layout is those 16 or the subset named by ``?motors=0,2,4,...``. It does not
take per-motor levels: it keeps six vibration *channels*, each one intensity (0-100 %)
on a set of motors (a 16-bit mask), and keeps channel 0 for its own inaccurate-orientation
signal. A frame is therefore sent as one channel per distinct intensity, on channels 1-5
(only the channels that change are sent); a frame needing more than five distinct
intensities at once is refused (ConfigError, naming them). Amplitudes reach the belt
through the motor calibration, as drive levels in whole percent.

Declared on the Belt interface: ``stream_rate_hz`` (the command rate: 50 Hz over USB,
20 Hz over BLE; pybelt sets no limit: derived from its transport, docs/belts.md "The
command rate"; ``?rate_hz=`` to change), ``vibration_channels`` (5),
``reserved_channels`` ((0,)), no device rendering, no device onsets.

Events: pybelt answers the belt's keep-alive requests itself (counted in :attr:`events`);
battery notifications set :attr:`battery_percent` (a warning below 10 %); a button press
or a mode change that leaves app mode (the wearer pressed pause, or the belt powers off)
stops the belt's vibration, and the next frame raises DeviceError saying so. A lost
connection is a DeviceError stating the motors' state: the belt leaves app mode and stops
vibrating when it loses its host.

Imports pybelt (and through it pyserial and bleak) only when a naviBelt is opened.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Final

import numpy as np
from numpy.typing import NDArray

from .._errors import ConfigError, DeviceError
from ..geometry import Layout
from .base import Belt, close_at_exit, closed_before_exit
from .calibration import Calibration
from .registry import Discovery, Found, check_options

if TYPE_CHECKING:
    from ._navibelt_emulation import NaviBeltEmulation

__all__ = ["APP_MODE", "MOTORS", "MOTOR_STEP_DEG", "NaviBelt", "discover", "open_navibelt"]

log = logging.getLogger(__name__)

MOTORS: Final = 16
MOTOR_STEP_DEG: Final = 360.0 / MOTORS
#: pybelt's BeltMode values
APP_MODE: Final = 3
_MODES: Final = {0: "standby", 1: "wait", 2: "compass", 3: "app", 4: "pause",
                 5: "calibration", 6: "crossing"}
_BUTTONS: Final = {1: "power", 2: "pause", 3: "compass", 4: "home"}
#: the channels tactorbelt drives (0 is the belt's own)
_CHANNELS: Final = (1, 2, 3, 4, 5)
_RATE_HZ: Final = {"serial": 50.0, "ble": 20.0, "emulator": 50.0}
_INSTALL: Final = "pip install 'tactorbelt[navibelt]'"


def _pybelt() -> Any:
    try:
        from pybelt import belt_controller
    except ImportError:
        raise DeviceError(f"naviBelts are driven through feelSpace's pybelt, which is not "
                          f"installed: {_INSTALL}") from None
    logger = logging.getLogger("pybelt")  # pybelt logs tracebacks; tactorbelt says what failed
    if not logger.handlers:
        logger.addHandler(logging.NullHandler())
        logger.propagate = False
    return belt_controller


def parse_motors(text: str | Sequence[int] | None, url: str) -> tuple[int, ...]:
    """``"0,2,4"`` (or a sequence) into motor indices; None: all 16."""
    if text is None:
        return tuple(range(MOTORS))
    items = text.split(",") if isinstance(text, str) else list(text)
    try:
        motors = tuple(int(str(m).strip()) for m in items if str(m).strip())
    except ValueError:
        raise ConfigError(f"motors of belt {url!r} must be motor numbers 0-15, comma-separated, "
                          f"got {text!r}") from None
    if len(motors) < 2 or len(set(motors)) != len(motors) or not all(
            0 <= m < MOTORS for m in motors):
        raise ConfigError(f"motors of belt {url!r} must be at least 2 different motor numbers "
                          f"0-15, got {text!r}")
    return motors


def motors_of_layout(layout: Layout, url: str) -> tuple[int, ...]:
    """The motors at a layout's angles (each must be a multiple of 22.5 degrees)."""
    motors = []
    for a in layout.angles_deg:
        k = round(a / MOTOR_STEP_DEG) % MOTORS
        if abs((a - k * MOTOR_STEP_DEG + 180.0) % 360.0 - 180.0) > 1e-6:
            raise ConfigError(f"belt {url!r} has motors every {MOTOR_STEP_DEG:g} deg from the "
                              f"navel; a tactor at {a:g} deg is not one of them (a study names "
                              "motor angles: [layout] tactors = 4 or 8, or tactor_angles = "
                              "[22.5, 90, 157.5, 202.5, 270, 337.5])")
        motors.append(k)
    return tuple(motors)


class _Delegate:
    """pybelt's BeltControllerDelegate, forwarding to the belt (pybelt's listener thread;
    nothing before the belt exists: the handshake)."""

    belt: NaviBelt

    def on_connection_state_changed(self, state: int, error: Exception | None = None) -> None:
        if state == 0 and hasattr(self, "belt"):  # DISCONNECTED
            self.belt._event("disconnected", str(error) if error else "")
            if not self.belt._closing:
                self.belt._lost = f"the connection was lost ({error or 'closed'})"

    def on_belt_mode_changed(self, belt_mode: int) -> None:
        if not hasattr(self, "belt"):
            return
        self.belt._event("mode", _MODES.get(belt_mode, str(belt_mode)))
        if belt_mode != APP_MODE and self.belt._in_app_mode:
            self.belt._left = f"the belt left app mode for {_MODES.get(belt_mode, belt_mode)} mode"

    def on_belt_button_pressed(self, button_id: int, previous_mode: int, new_mode: int) -> None:
        if not hasattr(self, "belt"):
            return
        name = _BUTTONS.get(button_id, str(button_id))
        self.belt._event("button", f"{name} ({_MODES.get(previous_mode)} -> "
                                   f"{_MODES.get(new_mode)})")
        if new_mode != APP_MODE and self.belt._in_app_mode:
            self.belt._left = (f"the wearer pressed the {name} button (the belt went to "
                               f"{_MODES.get(new_mode, new_mode)} mode)")

    def on_belt_battery_notified(self, charge_level: float, extra: list[Any]) -> None:
        if hasattr(self, "belt"):
            self.belt._battery(float(charge_level))

    def __getattr__(self, name: str) -> Any:  # the other notifications: nothing to do
        if name.startswith("on_"):
            return lambda *a, **k: None
        raise AttributeError(name)


#: the naviBelt's keep-alive characteristic
_KEEP_ALIVE_UUID: Final = "0000fe02-0000-1000-8000-00805f9b34fb"


class _KeepAlives:
    """pybelt's notifications handler: counts the keep-alive requests pybelt answers."""

    def __init__(self, belt: NaviBelt) -> None:
        self.belt = belt

    def on_gatt_char_notified(self, gatt_char: Any, data: bytes) -> None:
        if getattr(gatt_char, "uuid", None) == _KEEP_ALIVE_UUID:
            self.belt.keepalives += 1


class NaviBelt(Belt):
    """A naviBelt through pybelt's ``BeltController`` (see the module docstring).

    Attributes:
        motors: the naviBelt motor of each tactor.
        link: ``serial``, ``ble`` or ``emulator``; ``port``: the port or BLE address.
        battery_percent: the last charge the belt reported (None: none yet).
        keepalives: keep-alive requests answered.
        events: ``(monotonic s, kind, detail)`` of mode changes, buttons, battery,
            disconnection, newest last.
        emulation: the emulated belt (``navibelt:emulator``), else None.
    """

    vibration_channels = len(_CHANNELS)
    reserved_channels = (0,)

    def __init__(self, url: str, controller: Any, link: str, port: str,
                 motors: tuple[int, ...], calibration: Calibration | None = None,
                 rate_hz: float | None = None,
                 emulation: NaviBeltEmulation | None = None) -> None:
        layout = Layout(tuple(m * MOTOR_STEP_DEG for m in motors))
        fw = controller.get_firmware_version()
        super().__init__(url, f"naviBelt ({link} {port})", layout,
                         firmware_version=None if fw is None else str(fw),
                         calibration=calibration)
        self.stream_rate_hz = float(rate_hz or _RATE_HZ[link])
        self.motors = motors
        self.link, self.port = link, port
        self.emulation = emulation
        self.battery_percent: float | None = None
        self.keepalives = 0
        self.events: list[tuple[float, str, str]] = []
        self._controller = controller
        self._channels: dict[int, tuple[int, int]] = {}  # channel -> (intensity %, mask)
        self._lost: str | None = None
        self._left: str | None = None
        self._in_app_mode = False
        self._warned_battery = False
        self._events_lock = threading.Lock()
        close_at_exit(self)

    # -- events (pybelt's listener thread) ---------------------------------------------------
    def _event(self, kind: str, detail: str) -> None:
        with self._events_lock:
            self.events.append((time.monotonic(), kind, detail))
            del self.events[:-200]

    def _battery(self, percent: float) -> None:
        self.battery_percent = percent
        self._event("battery", f"{percent:.0f} %")
        if percent < 10.0 and not self._warned_battery:
            self._warned_battery = True
            log.warning("naviBelt on %s: battery at %.0f %%", self.port, percent)

    def _start(self) -> None:
        """Enter app mode (the only mode in which the belt takes the host's vibration)."""
        try:
            ok = self._controller.set_belt_mode(APP_MODE, wait_ack=True)
        except TimeoutError:
            ok = False
        if not ok:
            raise DeviceError(f"naviBelt on {self.port} did not enter app mode")
        self._in_app_mode = True
        self._controller.stop_vibration()

    # -- the Belt interface -------------------------------------------------------------------
    def _check_link(self, doing: str) -> None:
        why = self._lost or self._left
        if why is not None:
            state = ("the belt stops its own motors when it leaves app mode"
                     if self._left and not self._lost else
                     "the belt stops its motors when it loses its host (it leaves app "
                     "mode for wait mode)")
            last = ("" if not self._channels else "; last sent: " + ", ".join(
                f"{i} % on motors {[k for k in range(MOTORS) if m >> k & 1]}"
                for i, m in self._channels.values()))
            raise DeviceError(f"naviBelt on {self.port}: {why} while {doing}; {state}{last}")

    def channels_needed(self, levels: NDArray[np.float64]) -> NDArray[np.int64]:
        """One channel per distinct intensity (whole percent) above 0, per frame."""
        steps = np.sort(np.rint(np.atleast_2d(levels) * 100.0).astype(np.int64), axis=1)
        new = np.diff(steps, axis=1, prepend=0) != 0
        return np.asarray((new & (steps > 0)).sum(axis=1), dtype=np.int64)

    def _write_levels(self, levels: NDArray[np.float64]) -> None:
        self._check_link("playing")
        steps = np.rint(np.asarray(levels) * 100.0).astype(int)
        groups: dict[int, int] = {}  # what channels_needed counts
        for k, s in enumerate(steps):
            if s > 0:
                groups[int(s)] = groups.get(int(s), 0) | 1 << self.motors[k]
        if len(groups) > len(_CHANNELS):
            raise ConfigError(
                f"naviBelt on {self.port} shows at most {len(_CHANNELS)} different intensities "
                f"at once (channels 1-5; channel 0 is the belt's own), this frame needs "
                f"{len(groups)}: {sorted(groups)} %")
        wanted = {(i, m) for i, m in groups.items()}
        keep = {ch: v for ch, v in self._channels.items() if v in wanted}
        todo = sorted(wanted - set(keep.values()))
        # overwrite channels that change before taking free ones, so nothing is stopped first
        reuse = [ch for ch in self._channels if ch not in keep]
        free = reuse + [ch for ch in _CHANNELS if ch not in self._channels]
        new = dict(keep)
        for (intensity, mask), ch in zip(todo, free, strict=False):
            self._send(ch, intensity, mask)
            new[ch] = (intensity, mask)
        for ch in self._channels:
            if ch not in new:
                self._sent(self._controller.stop_vibration(ch), "stopping")
        self._channels = new

    def _send(self, channel: int, intensity: int, mask: int) -> None:
        self._sent(self._controller.send_vibration_command(
            channel_index=channel, pattern=1, intensity=min(100, intensity), orientation_type=0,
            orientation=mask, pattern_iterations=None, pattern_period=500, pattern_start_time=0,
            exclusive_channel=False, clear_other_channels=False), "playing")

    def _sent(self, ok: bool, doing: str) -> None:
        """pybelt could not send a command (it returned False): the link is lost."""
        if not ok:
            self._lost = self._lost or "pybelt could not send (not connected)"
            self._check_link(doing)

    def _write_stop(self) -> None:
        if self._lost is not None:
            self._channels = {}
            if self._closing:
                return  # the belt stopped its motors itself when the link dropped
            self._check_link("stopping")
        ok = self._controller.stop_vibration()
        self._channels = {}
        if not self._closing:
            self._sent(ok, "stopping")
        if ok and self._closing:  # the stop has reached the belt before the link closes
            try:
                self.ping()
            except DeviceError as exc:
                log.warning("%s", exc)

    @property
    def models_vibration(self) -> bool:
        """True on the emulation: its motors' intensities over time are known."""
        return self.emulation is not None

    def vibration(self, t0_ns: int, t1_ns: int, rate_hz: float = 1000.0
                  ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """The emulated motors' intensities over [t0, t1) (ideal motors: each follows its
        commands at once, as the emulation received them). Only ``navibelt:emulator``."""
        if self.emulation is None:
            return super().vibration(t0_ns, t1_ns, rate_hz)
        from .erm import sample_grid

        times = sample_grid(t0_ns, t1_ns, rate_hz)
        timeline = list(self.emulation.timeline)
        at = np.array([t for t, _ in timeline], dtype=np.int64)
        levels = np.array([lv for _, lv in timeline])[:, list(self.motors)]
        i = np.searchsorted(at, times, side="right") - 1
        return times, np.where((i >= 0)[:, None], levels[np.maximum(i, 0)], 0.0)

    def ping(self) -> None:
        """A round trip (read the firmware version): every command sent before it has
        reached the belt when it returns. Raises DeviceError when the belt does not answer."""
        self._check_link("checking the link")
        profile = self._controller._gatt_profile  # pybelt 1.2.4 keeps it private
        if self._controller.read_gatt(profile.firmware_info_char) != 0:
            raise DeviceError(f"naviBelt on {self.port} did not answer")

    def _close(self) -> None:
        closed_before_exit(self)
        try:
            self._controller.disconnect_belt(wait=True)
        finally:
            if self.emulation is not None:
                self.emulation.close()


def _as_daemon(what: str, fn: Any) -> Any:
    """``fn()`` run in a daemon thread, waited for. The threads pybelt starts inside it (its
    serial listener, its BLE event loop) inherit ``daemon``: pybelt makes them ordinary
    threads, so a naviBelt left open held the interpreter at exit for ever (the exit
    joins ordinary threads before the ``atexit`` hook that closes open belts can run)."""
    out: dict[str, Any] = {}

    def run() -> None:
        try:
            out["value"] = fn()
        except BaseException as exc:  # handed to the caller
            out["error"] = exc

    t = threading.Thread(target=run, name=f"navibelt-{what}", daemon=True)
    t.start()
    t.join()
    if "error" in out:
        raise out["error"]
    return out.get("value")


def _connect(controller_module: Any, belt: Any, what: str, delegate: Any = None) -> Any:
    if isinstance(belt, str):  # a port that cannot be opened says so (pybelt only logs it)
        import serial

        try:
            serial.Serial(belt, 115200, timeout=0).close()
        except (serial.SerialException, OSError, ValueError) as exc:
            raise DeviceError(f"cannot open serial port {belt} for a naviBelt: {exc}") from None
    controller = controller_module.BeltController(delegate)
    _as_daemon("connect", lambda: controller.connect(belt))
    if controller.get_connection_state() != controller_module.BeltConnectionState.CONNECTED:
        controller.disconnect_belt(wait=False)
        raise DeviceError(f"no naviBelt answered on {what} (pybelt's handshake failed)")
    return controller


def ble_unavailable(exc: BaseException) -> str:
    """Why a BLE scan could not run, in a person's words (bleak's errors on Linux: no
    D-Bus system bus, BlueZ not running, no adapter, an adapter powered off)."""
    reason = getattr(exc, "reason", None)  # bleak's BleakBluetoothNotAvailableError
    name = getattr(reason, "name", None)
    if name == "NO_BLUETOOTH":
        return "no Bluetooth adapter (BlueZ lists none)"
    if name == "POWERED_OFF":
        return "the Bluetooth adapter is powered off (bluetoothctl power on)"
    if name == "DENIED_BY_SYSTEM":
        return "the system denied access to Bluetooth (D-Bus policy or permissions)"
    if name is not None:
        return f"Bluetooth is not available ({exc.args[0] if exc.args else name})"
    text = str(exc)
    if "org.bluez" in text and ("ServiceUnknown" in text or "not provided" in text):
        return "BlueZ is not running (no org.bluez on the D-Bus system bus; start bluetoothd)"
    if isinstance(exc, FileNotFoundError | ConnectionRefusedError):
        return ("no D-Bus system bus to reach BlueZ (/run/dbus/system_bus_socket or "
                "DBUS_SYSTEM_BUS_ADDRESS)")
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _ble_device(name: str, url: str) -> Any:
    from pybelt import belt_scanner

    try:
        with belt_scanner.create() as scanner:
            found = scanner.scan()
    except Exception as exc:  # no adapter, no BlueZ, no D-Bus
        raise DeviceError(f"cannot scan for naviBelts over BLE for {url!r}: "
                          f"{ble_unavailable(exc)}; a naviBelt on USB: "
                          "navibelt:serial:PORT") from None
    for d in found:
        if name in ("auto", "") or name.lower() in ((d.name or "").lower(),
                                                    str(d.address).lower()):
            return d
    raise DeviceError(f"no naviBelt named {name!r} advertising over BLE (belt {url!r}); "
                      f"found: {', '.join(d.name or d.address for d in found) or 'none'}")


def _serial_candidates(probe_all: bool) -> list[Any]:
    from serial.tools import list_ports

    ports = list(list_ports.comports())
    if probe_all:
        return ports
    return [p for p in ports if any(w in f"{p.description} {p.manufacturer} {p.product}".lower()
                                    for w in ("navibelt", "feelspace"))]


def open_navibelt(target: str, **options: Any) -> NaviBelt:
    """Open ``navibelt:TARGET``: ``auto``, ``serial:PORT``, ``ble:NAME`` or ``emulator``.

    Options (URL or keyword): ``motors`` (``"0,4,8,12"``), ``rate_hz``; keywords:
    ``layout`` (angles on the naviBelt's motors), ``calibration``.

    Raises:
        ConfigError: a bad target or option. DeviceError: pybelt missing, no belt answered.
    """
    url = f"navibelt:{target}"
    check_options(options, ("motors", "rate_hz", "layout", "calibration", "clock"), url)
    clock = options.get("clock")
    if clock is not None and getattr(clock, "simulated", False):
        raise ConfigError(f"belt {url!r} runs on wall time only, not on a simulated clock")
    motors = parse_motors(options.get("motors"), url)
    if options.get("layout") is not None:
        motors = motors_of_layout(options["layout"], url)
    link, _, where = target.partition(":")
    if link not in ("auto", "serial", "ble", "emulator") or (
            link in ("serial", "ble") and not where) or (link in ("auto", "emulator") and where):
        raise ConfigError(f"unknown naviBelt {url!r}; allowed: navibelt:auto, "
                          "navibelt:serial:PORT, navibelt:ble:NAME, navibelt:emulator")
    module = _pybelt()
    emulation = None
    if link == "emulator":
        from ._navibelt_emulation import NaviBeltEmulation

        emulation = NaviBeltEmulation()
        where = emulation.path
    delegate = _Delegate()
    try:
        if link in ("serial", "emulator"):
            controller = _connect(module, where, where, delegate)
        elif link == "ble":
            device = _ble_device(where, url)
            controller = _connect(module, device, f"BLE {where}", delegate)
            where = str(device.address)
        else:
            controller, link, where = _auto(module, url, delegate)
        belt = NaviBelt(url, controller, link, where, motors, options.get("calibration"),
                        options.get("rate_hz"), emulation)
    except BaseException:
        if emulation is not None:
            emulation.close()
        raise
    try:
        delegate.belt = belt
        controller.add_notifications_handler(_KeepAlives(belt))
        belt._start()
    except BaseException:
        belt.close()
        raise
    return belt


def _auto(module: Any, url: str, delegate: Any) -> tuple[Any, str, str]:
    for port in _serial_candidates(probe_all=False):
        try:
            return _connect(module, port.device, port.device, delegate), "serial", port.device
        except DeviceError:
            continue
    device = _ble_device("auto", url)
    return (_connect(module, device, f"BLE {device.address}", delegate), "ble",
            str(device.address))


def discover(timeout_s: float = 5.0, probe_all: bool = False) -> Discovery:
    """naviBelts on USB serial (ports that name feelSpace or the naviBelt; every port with
    ``probe_all``, each asked through pybelt's handshake) and over BLE (pybelt's scanner)."""
    del timeout_s
    empty = "no naviBelt on a serial port or over BLE"
    try:
        module = _pybelt()
    except DeviceError as exc:
        return Discovery([], str(exc), empty)
    rows: list[Found] = []
    notes = []
    try:
        ports = _serial_candidates(probe_all)
    except Exception as exc:  # no serial support here: a note, not an error
        ports, notes = [], [f"cannot list serial ports: {exc}"]
    for port in ports:
        row = Found("serial", port.device, port.description or "", f"navibelt:serial:{port.device}")
        try:
            controller = _connect(module, port.device, port.device)
        except DeviceError as exc:
            row.note = str(exc)
        else:
            row.firmware_version = str(controller.get_firmware_version())
            row.tactors = MOTORS
            controller.disconnect_belt(wait=True)
        rows.append(row)
    try:
        from pybelt import belt_scanner

        with belt_scanner.create() as scanner:
            for d in scanner.scan():
                rows.append(Found("ble", str(d.address), d.name or "(no name)",
                                  f"navibelt:ble:{d.address}", note="a naviBelt advertising",
                                  tactors=MOTORS))
    except Exception as exc:  # no adapter, no BlueZ: a note, not an error
        notes.append(f"no BLE scan for naviBelts: {ble_unavailable(exc)}")
    return Discovery(rows, "; ".join(notes) or None, empty)
