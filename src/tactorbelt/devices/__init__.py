"""Belts: open one by URL.

``open_belt(url)`` picks a backend by URL scheme and imports it lazily, so using the
simulated belt never imports pyserial or bleak:

- ``sim`` (default): the simulated ERM belt (:mod:`tactorbelt.devices.sim`);
- ``emulator``: the real firmware core built for the host, on a pseudo-terminal;
- ``serial:/dev/ttyACM0`` or ``serial:auto``: the firmware over USB serial;
- ``ble:NAME_OR_ADDRESS``: the firmware over Bluetooth LE.
"""

from __future__ import annotations

import importlib
from typing import Any

from .._errors import ConfigError
from .base import Belt

__all__ = ["BACKENDS", "Belt", "open_belt", "parse_url"]

#: scheme -> "module:function"; the function takes (target, **options) and returns a Belt.
BACKENDS: dict[str, str] = {
    "sim": "tactorbelt.devices.sim:open_sim",
    "emulator": "tactorbelt.devices.emulator:open_emulator",
    "serial": "tactorbelt.devices.serial:open_serial",
    "ble": "tactorbelt.devices.ble:open_ble",
}


def parse_url(url: str) -> tuple[str, str]:
    """Split ``scheme:target`` (``sim`` and ``emulator`` need no target)."""
    if not isinstance(url, str) or not url.strip():
        raise ConfigError(f"belt URL must be a non-empty string, got {url!r}")
    scheme, _, target = url.strip().partition(":")
    scheme = scheme.lower()
    if scheme not in BACKENDS:
        raise ConfigError(
            f"unknown belt URL {url!r}; allowed: sim, emulator, serial:PORT, serial:auto, "
            "ble:NAME_OR_ADDRESS"
        )
    if scheme in ("serial", "ble") and not target:
        raise ConfigError(f"belt URL {url!r} needs a target, e.g. {scheme}:auto")
    return scheme, target


def open_belt(url: str = "sim", **options: Any) -> Belt:
    """Open a belt by URL. Use it as a context manager: motors are off on exit.

    Args:
        url: ``sim``, ``emulator``, ``serial:PORT``, ``serial:auto`` or ``ble:NAME``.
        **options: passed to the backend (``clock``, ``layout``, ``calibration``, ...).

    Raises:
        ConfigError: an unknown scheme.
        DeviceError: the belt cannot be reached.
    """
    scheme, target = parse_url(url)
    module_name, _, func_name = BACKENDS[scheme].partition(":")
    module = importlib.import_module(module_name)
    opener = getattr(module, func_name)
    belt: Belt = opener(target, **options)
    return belt
