"""The experiment window (pygame-ce): what the participant sees, and the experimenter's keys.

- :func:`session_window` / :func:`run_with_window` (``gui.window``): open the window for
  one session and run it in the main thread; the window's state machine is
  ``gui.controller``, what each kind of screen shows ``gui.screens``;
- :func:`target_positions`, :class:`EllipseGeometry` (``inputs.screen``, pure): where
  targets and the cursor are drawn.

Importing this package imports neither pygame nor NumPy; the names below are loaded
on first use (``tactorbelt --help`` stays fast).
"""

from __future__ import annotations

from .._registry import lazy_attributes

__all__ = [
    "EllipseGeometry",
    "ExperimentWindow",
    "SessionWindow",
    "run_with_window",
    "session_window",
    "target_positions",
]

_LAZY = {
    "EllipseGeometry": "tactorbelt.inputs.screen",
    "target_positions": "tactorbelt.inputs.screen",
    "ExperimentWindow": "tactorbelt.gui.window",
    "SessionWindow": "tactorbelt.gui.window",
    "run_with_window": "tactorbelt.gui.window",
    "session_window": "tactorbelt.gui.window",
}


__getattr__ = lazy_attributes(__name__, _LAZY)


def __dir__() -> list[str]:
    return sorted(__all__)
