"""The sensor registry: each sensor's URL scheme, opener, options and help.

Imports no NumPy (``tactorbelt validate onsets --help`` lists the sensors); the sensors
themselves are :mod:`.sensors`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .._errors import ConfigError
from ..devices.registry import UrlOption

__all__ = ["SENSORS", "SensorBackend", "SensorOption", "resolve_sensor", "sense_url_help"]


class SensorOption(UrlOption):
    """A ``?key=value`` option of a sensor URL (errors say "sensor URL")."""

    def parse(self, text: str, url: str) -> Any:
        try:
            return super().parse(text, url)
        except ConfigError as exc:
            raise ConfigError(str(exc).replace("of belt URL", "of sensor URL")) from None


@dataclass(frozen=True)
class SensorBackend:
    """One registered sensor: its URL scheme, its opener (``"module:function"``, called
    as ``opener(target, belt, **options)``), a summary and examples for the help, whether
    the URL needs a target (``audio:DEVICE``), its options, its docs page."""

    scheme: str
    opener: str
    summary: str
    examples: tuple[str, ...]
    target: str = ""
    options: tuple[SensorOption, ...] = ()
    docs: str = "docs/validation.md"

    @property
    def usage(self) -> str:
        return f"{self.scheme}:{self.target}" if self.target else self.scheme


SENSORS: dict[str, SensorBackend] = {s.scheme: s for s in (
    SensorBackend("model", "tactorbelt.validation.sensors:open_model",
                  "the belt's own vibration model (the sim belt; the default there)",
                  ("model",),
                  options=(SensorOption("rate_hz", float, "samples per second", 100.0,
                                        1e6),)),
    SensorBackend("audio", "tactorbelt.validation.sensors:open_audio_sensor",
                  "an input channel of a sound card: a loopback cable, or a piezo or "
                  "accelerometer on the tactor",
                  ("audio:default?channel=0", "audio:3?map=0,1,2,3,4,5"), target="DEVICE",
                  options=(SensorOption("channel", int, "the input channel that senses "
                                        "every tactor", 0, 255),
                           SensorOption("map", str, "tactor k's input channel: 0,1,2,3,4,5"),
                           SensorOption("samplerate", int, "sample rate (Hz)", 1000, 768_000),
                           SensorOption("latency", str, "low, high or seconds (PortAudio)"),
                           SensorOption("blocksize", int, "frames per callback (0: "
                                        "PortAudio's)", 0, 16384),
                           SensorOption("window_ms", float, "the envelope's moving mean "
                                        "(ms; about one carrier period)", 0.05, 1000.0))),
    SensorBackend("board", "tactorbelt.validation.sensors:open_board",
                  "the IMU on the belt's own board (firmware 1.2)", ("board",),
                  options=(SensorOption("rate_hz", float, "the sampling rate asked for",
                                        1.0, 10_000.0),
                           SensorOption("window_ms", float, "the envelope's moving mean (ms)",
                                        0.05, 1000.0))),
)}


def resolve_sensor(url: str) -> tuple[SensorBackend, str, dict[str, Any]]:
    """Split ``scheme:target?key=value&...`` into its sensor, target and options.

    Raises:
        ConfigError: not a string, an unknown scheme, a missing target, an unknown or
            malformed option (every message names the URL).
    """
    if not isinstance(url, str) or not url.strip():
        raise ConfigError(f"sensor URL must be a non-empty string, got {url!r}")
    head, _, query = url.strip().partition("?")
    scheme, _, target = head.partition(":")
    backend = SENSORS.get(scheme.lower())
    if backend is None:
        allowed = ", ".join(s.usage for s in SENSORS.values())
        raise ConfigError(f"unknown sensor URL {url!r}; allowed: {allowed}")
    if backend.target and not target:
        raise ConfigError(f"sensor URL {url!r} needs a device, e.g. {backend.examples[0]}")
    if not backend.target and target:
        raise ConfigError(f"sensor URL {url!r} takes no target; use {backend.usage!r}")
    known = {o.name: o for o in backend.options}
    options: dict[str, Any] = {}
    for item in filter(None, query.split("&")):
        key, eq, value = item.partition("=")
        if not eq:
            raise ConfigError(f"sensor URL {url!r}: expected key=value after '?', got "
                              f"{item!r}")
        opt = known.get(key.strip())
        if opt is None:
            raise ConfigError(f"unknown option {key.strip()!r} in sensor URL {url!r}; "
                              f"allowed: {', '.join(known) or 'none'}")
        options[opt.name] = opt.parse(value.strip(), url)
    return backend, target, options




def sense_url_help() -> str:
    """The ``--sense URL`` help: every registered sensor with an example."""
    return "; ".join(f"{', '.join(s.examples)}: {s.summary}" for s in SENSORS.values())
