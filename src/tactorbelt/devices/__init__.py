"""Belts: open one by URL.

``open_belt(url)`` looks the URL's scheme up in the backend registry
(:mod:`tactorbelt.devices.registry`) and imports that backend lazily, so using the
simulated belt never imports pyserial or bleak:

- ``sim`` (default): the simulated ERM belt (:mod:`tactorbelt.devices.sim`);
- ``emulator``: the real firmware core built for the host, on a pseudo-terminal;
- ``serial:/dev/ttyACM0`` or ``serial:auto``: the firmware over USB serial;
- ``ble:NAME_OR_ADDRESS``: the firmware over Bluetooth LE.

A URL may carry options as a query: ``serial:auto?timeout_s=2&heartbeat_ms=500``.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from .._errors import ConfigError
from .registry import BACKENDS, parse_url, resolve

if TYPE_CHECKING:
    from .base import Belt

__all__ = ["BACKENDS", "Belt", "open_belt", "parse_url"]


def open_belt(url: str = "sim", **options: Any) -> Belt:
    """Open a belt by URL. Use it as a context manager: motors are off on exit.

    Args:
        url: ``sim``, ``emulator``, ``serial:PORT``, ``serial:auto``, ``ble:NAME``, with
            optional ``?key=value`` options (see :mod:`tactorbelt.devices.registry`).
        **options: passed to the backend (``clock``, ``layout``, ``calibration``, ...).

    Raises:
        ConfigError: an unknown scheme or URL option, or an option given twice.
        DeviceError: the belt cannot be reached.
    """
    backend, target, url_options = resolve(url)
    both = sorted(set(url_options) & set(options))
    if both:
        raise ConfigError(f"option {both[0]!r} is given both in belt URL {url!r} and as a "
                          "keyword; give it once")
    belt: Belt = backend.load_opener()(target, **url_options, **options)
    return belt


def __getattr__(name: str) -> Any:
    # Belt imports NumPy: loaded on first use, so the registry (the --belt help) is cheap
    if name == "Belt":
        return importlib.import_module(f"{__name__}.base").Belt
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
