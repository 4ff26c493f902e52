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

from typing import TYPE_CHECKING, Any

from .._errors import ConfigError
from .._registry import lazy_attributes
from .._registry import resolve as _load
from .registry import BACKENDS, parse_url, resolve, runs_on_simulated_time

if TYPE_CHECKING:
    from ..stimuli import Stimulus
    from .base import Belt
    from .calibration import Calibration

__all__ = ["BACKENDS", "Belt", "open_belt", "open_belt_for", "parse_url",
           "runs_on_simulated_time"]


def open_belt(url: str = "sim", **options: Any) -> Belt:
    """Open a belt by URL. Use it as a context manager: motors are off on exit.

    Args:
        url: ``sim``, ``emulator``, ``serial:PORT``, ``serial:auto``, ``ble:NAME``, with
            optional ``?key=value`` options (see :mod:`tactorbelt.devices.registry`).
        **options: passed to the backend (``clock``, ``layout``, ``calibration``, ...);
            ``drive`` (``plain`` or ``shaped``, also a URL option of every backend) is set
            on the open belt (:meth:`~tactorbelt.devices.base.Belt.set_drive`).

    Raises:
        ConfigError: an unknown scheme or URL option, or an option given twice.
        DeviceError: the belt cannot be reached.
    """
    backend, target, url_options = resolve(url)
    both = sorted(set(url_options) & set(options))
    if both:
        raise ConfigError(f"option {both[0]!r} is given both in belt URL {url!r} and as a "
                          "keyword; give it once")
    drive = url_options.pop("drive", options.pop("drive", None))  # given once (above)
    belt: Belt = _load(backend.opener)(target, **url_options, **options)
    if drive is not None:
        try:
            belt.set_drive(drive)
        except BaseException:
            belt.close()
            raise
    return belt


# Belt imports NumPy: loaded on first use, so the registry (the --belt help) is cheap
__getattr__ = lazy_attributes(__name__, {"Belt": ".base"})


def open_belt_for(url: str, stimulus: Stimulus | None = None, *, explicit_layout: bool = False,
                  calibration: Calibration | None = None,
                  calibration_file: str | None = None) -> tuple[Belt, Stimulus | None]:
    """Open the belt at ``url`` for ``stimulus``.

    With ``explicit_layout`` the belt is opened with the stimulus's layout (the sim belt
    takes it; a hardware belt must have as many tactors). Otherwise the belt keeps its
    own layout and the stimulus is remade on it.

    Returns:
        The open belt (use it as a context manager) and the stimulus to play on it.

    Raises:
        ConfigError: an unknown URL, or a calibration or layout that does not fit.
    """
    from ..stimuli import make_stimulus

    parse_url(url)  # an unknown scheme fails before anything is opened
    where = f"calibration file {calibration_file!r}" if calibration_file else "the calibration"
    options: dict[str, Any] = {}
    if calibration is not None:
        options["calibration"] = calibration
    if explicit_layout and stimulus is not None:
        if calibration is not None and calibration.n != stimulus.layout.n:
            raise ConfigError(f"{where} has {calibration.n} tactors but the layout asked for "
                              f"has {stimulus.layout.n}")
        options["layout"] = stimulus.layout
    try:
        belt = open_belt(url, **options)
    except ConfigError as exc:
        if calibration is not None and "calibration has" in str(exc):
            raise ConfigError(f"{where} does not fit belt {url!r}: {exc}") from None
        raise
    try:
        if stimulus is None:
            return belt, None
        if explicit_layout and belt.n_tactors != stimulus.layout.n:
            raise ConfigError(f"belt {url!r} has {belt.n_tactors} tactors but the stimulus "
                              f"was asked for {stimulus.layout.n} (--tactors/--tactor-angles)")
        if not explicit_layout and belt.layout != stimulus.layout:
            stimulus = make_stimulus(belt.layout, stimulus.target_deg, stimulus.mode,
                                     stimulus.law, stimulus.falloff_deg, stimulus.period_s,
                                     stimulus.transit_s)
        return belt, stimulus
    except BaseException:
        belt.close()
        raise
