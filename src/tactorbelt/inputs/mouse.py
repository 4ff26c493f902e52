"""Mouse cursor source: the mouse position relative to the response ellipse.

A fallback when no joystick is at hand. The window tells the source where the ellipse
is (:attr:`MouseCursor.geometry`, pixels); after each event pump (main thread) the
window calls :meth:`MouseCursor.update`, which converts the pointer position to cursor
units (radius 1 on the ellipse, y up = front) and clamps it to the ellipse.
:meth:`read` may be called from any thread: it returns the latest state.

Buttons: bit 0 left, bit 1 middle, bit 2 right.

Imports the standard library, tactorbelt.inputs.base and tactorbelt.inputs.screen (pure);
pygame only inside methods.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .base import LiveCursor
from .screen import EllipseGeometry

if TYPE_CHECKING:
    from .kinds import InputContext

__all__ = ["MouseCursor"]


class MouseCursor(LiveCursor):
    """The mouse pointer as a cursor source (create and update it in the main thread).

    Args:
        geometry: where the ellipse is on screen; the window sets it when it lays out.
    """

    def __init__(self, geometry: EllipseGeometry | None = None) -> None:
        super().__init__()
        self.geometry = geometry

    def place(self, px: float, py: float, buttons: int = 0) -> None:
        """Set the state from a pixel position (clamped to the ellipse)."""
        if self.geometry is None:
            return
        x, y = self.geometry.from_pixels(px, py, clamp=True)
        self.set_state(x, y, buttons)

    def handle_event(self, event: Any) -> None:
        import pygame

        if event.type in (pygame.MOUSEMOTION, pygame.MOUSEBUTTONDOWN, pygame.MOUSEBUTTONUP):
            self.update()

    def update(self) -> None:
        import pygame

        if not pygame.display.get_init() or pygame.display.get_surface() is None:
            return
        px, py = pygame.mouse.get_pos()
        pressed = pygame.mouse.get_pressed(3)
        buttons = sum(1 << i for i, p in enumerate(pressed) if p)
        self.place(px, py, buttons)


def cursor(ctx: InputContext) -> MouseCursor:
    """The ``mouse`` input kind's cursor (:mod:`tactorbelt.inputs.kinds`), on the
    window's ellipse ``ctx.geometry``."""
    return MouseCursor(ctx.geometry)
