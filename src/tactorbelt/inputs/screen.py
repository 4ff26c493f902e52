"""Screen geometry of the experiment window: the ellipse, the targets and the cursor.

The participant sees the torso from above as an ellipse, the front (navel, 0 deg) at
the top, angles growing clockwise. A target at angle θ is drawn where the ray from the
centre in direction ``(sin θ, cos θ)`` (x right, y up) meets the ellipse, at the
distance ``r(θ) = 1 / sqrt((sin θ / rx)^2 + (cos θ / ry)^2)`` from the centre.

Cursor units (docs/conventions.md, "Data store"): the ellipse has radius 1 along each
axis, y up = front. The window maps them to pixels *along rays*: a cursor at ``ρ (sin φ,
cos φ)`` is drawn at ``ρ r(φ)`` pixels from the centre in direction φ. On the two axes
this is the plain scaling ``(x rx, y ry)``; elsewhere it keeps angles, so the direction
the participant sees on screen is the direction the trial machine computes (``atan2(x,
y)``), and a cursor on a drawn target has exactly that target's angle. For a circle (rx
== ry) it is the plain scaling everywhere.

Pure: imports only the standard library and NumPy (no pygame).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "EllipseGeometry",
    "bar_rects",
    "fit_ellipse",
    "ray_radius",
    "target_positions",
]

FloatArray = NDArray[np.float64]


def ray_radius(angles_deg: ArrayLike, rx: float, ry: float) -> Any:
    """Distance from the centre to the ellipse along the ray at each angle (pixels).

    Args:
        angles_deg: angles clockwise from the front (top), degrees.
        rx: horizontal half-axis (pixels, > 0).
        ry: vertical half-axis (pixels, > 0).
    """
    t = np.radians(np.asarray(angles_deg, dtype=float))
    r = 1.0 / np.sqrt((np.sin(t) / rx) ** 2 + (np.cos(t) / ry) ** 2)
    return float(r) if r.ndim == 0 else r


def target_positions(
    angles_deg: ArrayLike, center: tuple[float, float], rx: float, ry: float
) -> FloatArray:
    """Pixel positions of targets on the ellipse (screen y grows downwards).

    Args:
        angles_deg: target angles, clockwise from the front (0 = top of the screen).
        center: the ellipse centre in pixels ``(cx, cy)``.
        rx: horizontal half-axis in pixels.
        ry: vertical half-axis in pixels.

    Returns:
        An ``(M, 2)`` float array of ``(px, py)``: where the ray from the centre in
        direction ``(sin θ, cos θ)`` meets the ellipse.
    """
    t = np.radians(np.atleast_1d(np.asarray(angles_deg, dtype=float)))
    r = ray_radius(np.degrees(t), rx, ry)
    px = center[0] + r * np.sin(t)
    py = center[1] - r * np.cos(t)
    return np.stack([px, py], axis=-1)


@dataclass(frozen=True)
class EllipseGeometry:
    """The response ellipse on screen, and the map between cursor units and pixels.

    Attributes:
        cx, cy: centre in pixels.
        rx, ry: horizontal and vertical half-axes in pixels.
    """

    cx: float
    cy: float
    rx: float
    ry: float

    @property
    def center(self) -> tuple[float, float]:
        return (self.cx, self.cy)

    def targets(self, angles_deg: ArrayLike) -> FloatArray:
        """Pixel positions of targets (see :func:`target_positions`)."""
        return target_positions(angles_deg, self.center, self.rx, self.ry)

    def to_pixels(self, x: ArrayLike, y: ArrayLike) -> tuple[Any, Any]:
        """Cursor units (radius 1 on the ellipse, y up) to pixels, along rays."""
        xa = np.asarray(x, dtype=float)
        ya = np.asarray(y, dtype=float)
        phi = np.degrees(np.arctan2(xa, ya))
        scale = ray_radius(phi, self.rx, self.ry)
        # ρ r(φ) (sin φ, cos φ) == (x, y) r(φ) since (x, y) = ρ (sin φ, cos φ)
        px = self.cx + xa * scale
        py = self.cy - ya * scale
        if np.ndim(px) == 0:
            return float(px), float(py)
        return px, py

    def from_pixels(self, px: float, py: float, clamp: bool = True) -> tuple[float, float]:
        """Pixels to cursor units (the inverse of :meth:`to_pixels`).

        Args:
            px, py: a pixel position.
            clamp: limit the result to radius 1 (the ellipse).
        """
        dx = px - self.cx
        dy = self.cy - py
        d = math.hypot(dx, dy)
        if d == 0.0:
            return 0.0, 0.0
        phi = math.degrees(math.atan2(dx, dy))
        r = float(ray_radius(phi, self.rx, self.ry))
        x, y = dx / r, dy / r
        rho = d / r
        if clamp and rho > 1.0:
            x, y = x / rho, y / rho
        return x, y

    def scaled(self, factor: float) -> tuple[float, float, float, float]:
        """The rectangle ``(left, top, width, height)`` of the ellipse scaled by ``factor``.

        In cursor units this is the circle of radius ``factor`` (e.g. the home zone).
        """
        w = 2 * self.rx * factor
        h = 2 * self.ry * factor
        return (self.cx - w / 2, self.cy - h / 2, w, h)


def fit_ellipse(
    width: int, height: int, aspect: float = 1.25, margin: float = 0.14, top_band: float = 0.0
) -> EllipseGeometry:
    """The largest ellipse of ``rx / ry == aspect`` that fits in a window with margins.

    Args:
        width, height: the window size in pixels.
        aspect: width over height of the ellipse (a torso seen from above is wider
            than deep; 1.0 draws a circle).
        margin: fraction of the smaller window side kept free around the ellipse
            (room for the target markers and the text).
        top_band: pixels reserved at the top of the window (status text).
    """
    m = margin * min(width, height)
    avail_w = max(width - 2 * m, 10.0)
    avail_h = max(height - top_band - 2 * m, 10.0)
    ry = min(avail_h / 2, avail_w / 2 / aspect)
    rx = ry * aspect
    return EllipseGeometry(cx=width / 2, cy=top_band + m + avail_h / 2, rx=rx, ry=ry)


def bar_rects(
    levels: ArrayLike, origin: tuple[float, float], bar_w: float, max_h: float, gap: float
) -> list[tuple[float, float, float, float]]:
    """Rectangles ``(left, top, width, height)`` of amplitude bars on a common baseline.

    Args:
        levels: one value per tactor, clipped to [0, 1].
        origin: the bottom-left corner of the first bar, pixels.
        bar_w: bar width; ``max_h``: height of a bar at 1; ``gap``: space between bars.
    """
    lv = np.clip(np.asarray(levels, dtype=float).reshape(-1), 0.0, 1.0)
    x0, base = origin
    out = []
    for k, v in enumerate(lv.tolist()):
        h = v * max_h
        out.append((x0 + k * (bar_w + gap), base - h, bar_w, h))
    return out
