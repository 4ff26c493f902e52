"""A toy belt backend for the registry tests (tests/test_toy_extensions.py): a belt that
keeps every frame it is sent in memory. Everything a backend is lives here, as a new
backend's module (``devices/NAME.py``) would; :data:`BACKEND` is its registry line.

- :class:`ToyBelt` implements the two methods a :class:`~tactorbelt.devices.base.Belt`
  must (``_write_levels``, ``_write_stop``) and keeps each frame with its time on the
  belt's clock (:attr:`ToyBelt.frames`). It models its vibration as the drive level
  itself (ideal motors), so the model participant can feel it.
- :func:`open_toy` is the opener (``toy:``); :func:`discover` is what ``tactorbelt
  devices`` lists.
- :func:`register` adds :data:`BACKEND` to the registry for this process. Loaded as a
  pytest plugin (``pytest -p support.toy_belt``, with ``tests/`` on ``PYTHONPATH``), the
  module registers it before the test files are collected, so the belt contract suite
  (tests/test_belt_contract.py) covers it as it covers every registered backend.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from tactorbelt import ConfigError, Layout
from tactorbelt.clock import Clock, WallClock
from tactorbelt.devices.base import Belt
from tactorbelt.devices.calibration import Calibration
from tactorbelt.devices.erm import sample_grid
from tactorbelt.devices.registry import BACKENDS, Backend, Discovery, Found, check_options

__all__ = ["BACKEND", "OPENED", "ToyBelt", "discover", "open_toy", "register"]

#: The toy's registry line: no target, no URL options, a contract URL that opens it with
#: no hardware, and a simulated clock for a model participant.
BACKEND = Backend(
    "toy", "support.toy_belt:open_toy", "a toy belt that keeps its frames in memory",
    ("toy:",), discover="support.toy_belt:discover", title="Toy belts",
    contract_url="toy:", simulated_time=True)

#: Every toy belt opened in this process, oldest first (a test reads what it was sent).
OPENED: list[ToyBelt] = []


class ToyBelt(Belt):
    """A belt whose device is a list: ``frames`` holds ``(t_ns, levels)`` for every frame
    written (calibrated levels; zeros for a stop), on the belt's clock."""

    def __init__(self, layout: Layout, clock: Clock | None = None,
                 calibration: Calibration | None = None) -> None:
        super().__init__("toy:", "toy belt", layout, calibration=calibration)
        self.clock: Clock = clock if clock is not None else WallClock()
        self.frames: list[tuple[int, NDArray[np.float64]]] = [
            (self.clock.now_ns(), np.zeros(layout.n))]

    def _write_levels(self, levels: NDArray[np.float64]) -> None:
        self.frames.append((self.clock.now_ns(), np.array(levels, dtype=float)))

    def _write_stop(self) -> None:
        self.frames.append((self.clock.now_ns(), np.zeros(self.n_tactors)))

    @property
    def models_vibration(self) -> bool:
        return True

    def vibration(self, t0_ns: int, t1_ns: int, rate_hz: float = 1000.0
                  ) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """The drive level in force at each sample time of [t0, t1) (ideal motors)."""
        times = sample_grid(t0_ns, t1_ns, rate_hz)
        at = np.array([t for t, _ in self.frames], dtype=np.int64)
        levels = np.array([lv for _, lv in self.frames])
        i = np.searchsorted(at, times, side="right") - 1
        return times, np.where((i >= 0)[:, None], levels[np.maximum(i, 0)], 0.0)


def open_toy(target: str = "", **options: Any) -> ToyBelt:
    """Open the toy belt (``toy:``). Options: ``layout`` (default 6 even tactors),
    ``clock``, ``calibration``."""
    if target:
        raise ConfigError(f"the toy belt takes no target, got 'toy:{target}'")
    check_options(options, ("layout", "clock", "calibration"), f"toy:{target}")
    belt = ToyBelt(options.get("layout") or Layout.even(6), options.get("clock"),
                   options.get("calibration"))
    OPENED.append(belt)
    return belt


def discover(timeout_s: float = 5.0, probe_all: bool = False) -> Discovery:
    """The one toy belt there always is (for ``tactorbelt devices``)."""
    del timeout_s, probe_all
    return Discovery([Found("memory", "toy", "toy belt (frames kept in memory)", "toy:",
                            tactors=6, note="6 tactors -> --belt toy:")])


def register() -> None:
    """Add the toy's registry line for the rest of this process (a test that must leave
    the registry as it found it sets ``BACKENDS["toy"]`` with monkeypatch instead)."""
    BACKENDS[BACKEND.scheme] = BACKEND


def pytest_configure(config: Any) -> None:
    """As a pytest plugin (``-p support.toy_belt``): register before collection."""
    register()
