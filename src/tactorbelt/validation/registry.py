"""The sensor registry: each sensor's URL scheme, opener, options and help.

Imports no NumPy (``tactorbelt validate onsets --help`` lists the sensors); the sensors
themselves are :mod:`.sensors`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .._registry import UrlOption, parse_url

__all__ = ["SENSORS", "SensorBackend", "resolve_sensor", "sense_url_help"]


@dataclass(frozen=True)
class SensorBackend:
    """One registered sensor: its URL scheme, its opener (``"module:function"``, called
    as ``opener(target, belt, **options)``), a summary and examples for the help, whether
    the URL needs a target (``audio:DEVICE``), its options (the belt URL's kind: their
    errors say "sensor URL")."""

    scheme: str
    opener: str
    summary: str
    examples: tuple[str, ...]
    target: str = ""
    options: tuple[UrlOption, ...] = ()

    @property
    def usage(self) -> str:
        return f"{self.scheme}:{self.target}" if self.target else self.scheme


SENSORS: dict[str, SensorBackend] = {s.scheme: s for s in (
    SensorBackend("model", "tactorbelt.validation.sensors:open_model",
                  "the belt's own vibration model (the sim belt; the default there)",
                  ("model",),
                  options=(UrlOption("rate_hz", float, "samples per second", 100.0,
                                     1e6),)),
    SensorBackend("audio", "tactorbelt.validation.sensors:open_audio_sensor",
                  "an input channel of a sound card: a loopback cable, or a piezo or "
                  "accelerometer on the tactor",
                  ("audio:default?channel=0", "audio:3?map=0,1,2,3,4,5"), target="DEVICE",
                  options=(UrlOption("channel", int, "the input channel that senses "
                                     "every tactor", 0, 255),
                           UrlOption("map", str, "tactor k's input channel: 0,1,2,3,4,5"),
                           UrlOption("samplerate", int, "sample rate (Hz)", 1000, 768_000),
                           UrlOption("latency", str, "low, high or seconds (PortAudio)"),
                           UrlOption("blocksize", int, "frames per callback (0: "
                                     "PortAudio's)", 0, 16384),
                           UrlOption("window_ms", float, "the envelope's moving mean "
                                     "(ms; about one carrier period)", 0.05, 1000.0))),
    SensorBackend("board", "tactorbelt.validation.sensors:BoardSensor",
                  "the IMU on the belt's own board (firmware 1.2)", ("board",),
                  options=(UrlOption("rate_hz", float, "the sampling rate asked for",
                                     1.0, 10_000.0),
                           UrlOption("window_ms", float, "the envelope's moving mean (ms)",
                                     0.05, 1000.0))),
)}


def resolve_sensor(url: str) -> tuple[SensorBackend, str, dict[str, Any]]:
    """Split ``scheme:target?key=value&...`` into its sensor, target and options.

    Raises:
        ConfigError: not a string, an unknown scheme, a missing target, an unknown or
            malformed option (every message names the URL).
    """
    return parse_url(url, SENSORS, "sensor URL", allowed=[s.usage for s in SENSORS.values()],
                     target_word="device", no_target=True)


def sense_url_help() -> str:
    """The ``--sense URL`` help: every registered sensor with an example."""
    return "; ".join(f"{', '.join(s.examples)}: {s.summary}" for s in SENSORS.values())
