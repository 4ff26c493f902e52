"""Screen geometry of the experiment window (the ellipse, the targets, the cursor): it lives
in :mod:`tactorbelt.inputs.screen`, beside the inputs that map pixels to cursor units
(the mouse), and is re-exported here for the window.

Pure: imports only the standard library and NumPy (no pygame).
"""

from __future__ import annotations

from ..inputs.screen import (
    EllipseGeometry,
    bar_rects,
    fit_ellipse,
    ray_radius,
    target_positions,
)

__all__ = [
    "EllipseGeometry",
    "bar_rects",
    "fit_ellipse",
    "ray_radius",
    "target_positions",
]
