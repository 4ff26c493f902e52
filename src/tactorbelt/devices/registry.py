"""The belt backend registry: one entry per URL scheme, modelled on pyserial's URL handlers.

Each backend registers, in :data:`BACKENDS` (one line each, at the end of this module):

- its ``scheme`` (``serial``) and whether the URL needs a target (``serial:PORT``);
- the ``opener``, a ``"module:function"`` string imported only when such a belt is
  opened (so the registry never imports pyserial or bleak); the function takes
  ``(target, **options)`` and returns a :class:`~tactorbelt.devices.base.Belt`;
- its URL options (``serial:/dev/ttyACM0?timeout_s=2``): the ``?key=value`` query is
  parsed and validated here, in one place, and passed to the opener as keywords;
- a one-line summary and example URLs (the ``--belt`` help and ``tactorbelt devices``
  are generated from them);
- optionally a ``discover`` function (``"module:function"``), which ``tactorbelt
  devices`` calls as ``discover(timeout_s=..., probe_all=...)`` to list what answers.

Imports only the standard library and tactorbelt._registry (the URL parsing shared with
the sensors).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, Final

from .._registry import UrlOption, check_option
from .._registry import parse_url as _parse_url
from .._registry import resolve as _load

__all__ = [
    "BACKENDS",
    "Backend",
    "Discovery",
    "Found",
    "UrlOption",
    "belt_url_help",
    "check_options",
    "parse_url",
    "resolve",
    "runs_on_simulated_time",
]


@dataclass(frozen=True)
class Backend:
    """One registered belt backend (see the module docstring)."""

    scheme: str
    opener: str
    summary: str
    examples: tuple[str, ...]
    #: ``"PORT"`` when the URL needs a target (``serial:PORT``), "" when it takes none
    #: or an optional one.
    target: str = ""
    options: tuple[UrlOption, ...] = ()
    discover: str | None = None
    #: heading of the backend's section in ``tactorbelt devices``.
    title: str = ""
    #: the URL forms an unknown-scheme error lists (default: :attr:`usage`).
    allowed: tuple[str, ...] = ()
    #: a URL that opens this backend on a machine with no hardware (a dummy device or
    #: server the backend brings), so the belt contract suite covers it with no code of
    #: its own; None when the suite needs a harness with a fake device
    #: (tests/support/belts.py).
    contract_url: str | None = None
    #: what its tactors are, for a session's record (BIDS ``StimulusSystem.ActuatorType``)
    actuator: str = ""
    #: the carrier its tactors vibrate at by default (Hz), when it drives a carrier (the
    #: ``carrier_hz`` URL option sets another); None: the motor's own frequency
    carrier_hz: float | None = None
    #: the belt can run on a simulated clock (``clock=SimClock()``): a model participant
    #: on it needs no real time (``run``, ``calibrate perceptual``, the demo)
    simulated_time: bool = False

    @property
    def usage(self) -> str:
        """``serial:PORT`` or ``sim``."""
        return f"{self.scheme}:{self.target}" if self.target else self.scheme

    @property
    def forms(self) -> tuple[str, ...]:
        return self.allowed or (self.usage,)

    def load_discover(self) -> Callable[..., Discovery] | None:
        """Import the backend module and return its discovery function (None: none)."""
        return None if self.discover is None else _load(self.discover)


@dataclass
class Found:
    """One port or device a discovery function saw, and what it answered."""

    link: str
    port: str
    description: str
    url: str
    firmware_version: str | None = None
    tactors: int | None = None
    note: str = ""
    #: what the belt's drive can do (firmware belts: ``Belt.drive_summary``), or None
    drive: str | None = None

    @property
    def is_belt(self) -> bool:
        return self.firmware_version is not None


@dataclass
class Discovery:
    """What one backend's discovery found: rows, a note when it could not look, and
    what to say when it looked and found nothing."""

    rows: list[Found] = field(default_factory=list)
    note: str | None = None
    empty: str = "none"


def check_options(options: dict[str, Any], allowed: Iterable[str], url: str) -> None:
    """Raise ConfigError naming a keyword option a backend does not know."""
    allowed = sorted(allowed)
    for name in sorted(options):
        check_option(f"option for belt {url!r}:", name, allowed)


def resolve(url: str) -> tuple[Backend, str, dict[str, Any]]:
    """Split ``scheme:target?key=value&...`` into its backend, target and URL options.

    Raises:
        ConfigError: not a string, an unknown scheme, a missing target, an unknown or
            malformed URL option (every message names the URL).
    """
    return _parse_url(url, BACKENDS, "belt URL",
                      allowed=[form for b in BACKENDS.values() for form in b.forms],
                      example=lambda b: f"{b.scheme}:auto")


def runs_on_simulated_time(url: str) -> bool:
    """True when the belt ``url`` opens can run on a simulated clock (its backend says
    so: :attr:`Backend.simulated_time`)."""
    backend, _, _ = resolve(url)
    return backend.simulated_time


def parse_url(url: str) -> tuple[str, str]:
    """Split ``scheme:target`` (the URL options are checked, then dropped)."""
    backend, target, _ = resolve(url)
    return backend.scheme, target


def belt_url_help() -> str:
    """The ``--belt URL`` help text: every registered scheme with an example."""
    return "; ".join(f"{', '.join(b.examples)}: {b.summary}" for b in BACKENDS.values()) + (
        ". Options: URL?key=value (tactorbelt devices --help).")


def url_options_help() -> str:
    """One line per backend with URL options (for ``tactorbelt devices --help``)."""
    return "\n".join(f"  {b.scheme}: {o.name} ({o.kind.__name__}): {o.help}"
                     for b in BACKENDS.values() for o in b.options)


_TIMEOUT: Final = UrlOption("timeout_s", float, "seconds a request waits for its reply",
                            0.01, 60.0)
_HEARTBEAT: Final = UrlOption("heartbeat_ms", int, "the device's failsafe timeout (ms)",
                              50, 2000)

_DRIVE: Final = UrlOption("drive", str, "plain, or shaped: overdrive kicks and brake pulses "
                          "(ERM belts that can; docs/belts.md)")

_SUPPLY: Final = UrlOption("supply_v", float, "the motor supply (V; bounds the overdrive)",
                           0.5, 24.0)
_KICK: Final = UrlOption("kick_ms", float, "a kick may apply the whole supply, above the "
                         "motor's maximum voltage, for at most this long (ms; default 0: "
                         "never)", 0.0, 1000.0)

#: scheme -> backend. Adding a backend: its module, one line here, its docs page.
BACKENDS: dict[str, Backend] = {b.scheme: b for b in (
    Backend("sim", "tactorbelt.devices.sim:open_sim",
            "simulated ERM belt (sim:8 tactors; sim:virtual runs on a simulated clock)",
            ("sim", "sim:virtual", "sim:8"),
            options=(UrlOption("horizon_s", float, "seconds of history kept", 0.001, 1e6),
                     _DRIVE,
                     UrlOption("overdrive", float, "the shaper's largest drive, times the "
                               "rated (default: 3.6 V / 3.0 V)", 1.0, 4.0),
                     _SUPPLY, _KICK,
                     UrlOption("brake", bool, "both H-bridge inputs wired (default 1)")),
            simulated_time=True,
            actuator="ERM vibration motor, simulated (tactorbelt's ERM model: no motor "
                     "vibrated)"),
    Backend("emulator", "tactorbelt.devices.emulator:open_emulator",
            "the firmware core built for this computer, on a pseudo-terminal",
            ("emulator",),
            options=(UrlOption("tactors", int, "emulated channels", 2, 16), _HEARTBEAT,
                     _TIMEOUT, UrlOption("build", bool, "run make first"),
                     UrlOption("watchdog_ms", int, "the board's watchdog (ms; off)", 1, 10000),
                     UrlOption("debug_frames", bool, "accept DEBUG_HANG (tests)"),
                     UrlOption("imu", str, "the board's simulated IMU: bmi270, lsm9ds1, "
                               "none (firmware 1.1) or broken"),
                     UrlOption("brake", bool, "both H-bridge inputs wired (default 1; 0: IN2 "
                               "to ground, a shaped fall coasts)"), _DRIVE, _SUPPLY, _KICK),
            actuator="ERM vibration motor driven by the tactorbelt firmware, emulated on "
                     "the host (no motor vibrated)"),
    Backend("serial", "tactorbelt.devices.serial:open_serial",
            "firmware over USB serial", ("serial:/dev/ttyACM0", "serial:auto"), target="PORT",
            options=(_TIMEOUT, _HEARTBEAT,
                     UrlOption("baudrate", int, "for real UARTs", 300, 4_000_000),
                     UrlOption("dtr", bool, "assert DTR (default 1; the board is mute "
                               "without it)"), _DRIVE, _SUPPLY, _KICK),
            discover="tactorbelt.devices.serial:discover", title="Serial ports",
            allowed=("serial:PORT", "serial:auto"),
            actuator="ERM vibration motor driven by the tactorbelt firmware (PWM), over USB "
                     "serial"),
    Backend("ble", "tactorbelt.devices.ble:open_ble",
            "firmware over Bluetooth LE (40 Hz streaming)", ("ble:NAME", "ble:auto"),
            target="NAME_OR_ADDRESS",
            options=(_TIMEOUT, _HEARTBEAT,
                     UrlOption("scan_timeout_s", float, "seconds to scan", 0.1, 120.0),
                     UrlOption("connect_timeout_s", float, "seconds to connect", 0.1, 120.0),
                     _DRIVE, _SUPPLY, _KICK),
            discover="tactorbelt.devices.ble:discover", title="BLE",
            actuator="ERM vibration motor driven by the tactorbelt firmware (PWM), over "
                     "Bluetooth LE"),
    Backend("audio", "tactorbelt.devices.audio:open_audio",
            "voice-coil/LRA tactors on a multichannel sound card (PortAudio; a sine carrier)",
            ("audio:default?channels=6", "audio:3?carrier_hz=250&map=0,1,2,3,4,5"),
            target="DEVICE",
            options=(UrlOption("channels", int, "output channels opened", 1, 256),
                     UrlOption("carrier_hz", float, "carrier frequency (Hz)", 1.0, 100_000.0),
                     UrlOption("map", str, "output channel of each tactor: 0,1,2,3,4,5"),
                     UrlOption("samplerate", int, "sample rate (Hz)", 1000, 768_000),
                     UrlOption("latency", str, "low, high or seconds (PortAudio)"),
                     UrlOption("blocksize", int, "frames per callback (0: PortAudio's)", 0,
                               16384),
                     UrlOption("ramp_ms", float, "ramp of every amplitude change", 0.1,
                               100.0), _DRIVE),
            discover="tactorbelt.devices.audio:discover", title="Audio outputs",
            allowed=("audio:DEVICE", "audio:default"),
            actuator="voice-coil or LRA actuator driven by a sound card output channel (a "
                     "sine carrier modulated by the drive level)",
            carrier_hz=250.0),  # the skin's most sensitive band (Pacinian receptors)
    Backend("navibelt", "tactorbelt.devices.navibelt:open_navibelt",
            "feelSpace naviBelt through pybelt (16 motors; pip install 'tactorbelt[navibelt]')",
            ("navibelt:auto", "navibelt:serial:/dev/ttyACM0", "navibelt:ble:NAME",
             "navibelt:emulator"), target="TARGET",
            options=(UrlOption("motors", str, "the motors used, e.g. 0,2,4,6 (default all 16)"),
                     UrlOption("rate_hz", float, "command rate (Hz)", 1.0, 200.0), _DRIVE),
            discover="tactorbelt.devices.navibelt:discover", title="naviBelts",
            allowed=("navibelt:auto", "navibelt:serial:PORT", "navibelt:ble:NAME",
                     "navibelt:emulator")),
)}
