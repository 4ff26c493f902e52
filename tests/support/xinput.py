"""A user at an X display (Xvfb): find a window, look at it, move the mouse, click.

    from support.xinput import XUser

    with Xvfb() as display, XUser(display) as user:
        x, y, w, h = user.wait_for_window(timeout_s=30)   # the first window shown
        user.move(x + w // 2, y + h // 2)
        user.press(1); user.release(1)                    # left button
        user.brightest(x, y + h - 100, w, 100)            # 0..255, what is drawn there

Input goes through the XTEST extension (Xvfb has it), as from a real mouse: the window
gets the events its toolkit (pyglet, under PsychoPy) reads. Needs python-xlib, which
PsychoPy installs on Linux.
"""

from __future__ import annotations

import time
from types import TracebackType
from typing import Any

__all__ = ["XUser"]


class XUser:
    """Mouse input and screen reading on an X display (module doc)."""

    def __init__(self, display: str) -> None:
        from Xlib import display as xdisplay

        self._d: Any = xdisplay.Display(display)
        self._root: Any = self._d.screen().root

    def close(self) -> None:
        self._d.close()

    def __enter__(self) -> XUser:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def windows(self) -> list[tuple[int, int, int, int]]:
        """The shown top-level windows: (x, y, width, height) on the screen."""
        from Xlib import X

        out = []
        for w in self._root.query_tree().children:
            try:
                if w.get_attributes().map_state != X.IsViewable:
                    continue
                g = w.get_geometry()
                pos = w.translate_coords(self._root, 0, 0)
            except Exception:
                continue
            if g.width > 1 and g.height > 1:
                out.append((-pos.x, -pos.y, int(g.width), int(g.height)))
        return out

    def wait_for_window(self, timeout_s: float = 30.0,
                        alive: Any = None) -> tuple[int, int, int, int]:
        """The first window shown within ``timeout_s`` (TimeoutError otherwise; also
        when ``alive()`` turns False, e.g. the process that should open it ended)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            shown = self.windows()
            if shown:
                return shown[0]
            if alive is not None and not alive():
                raise TimeoutError("the program ended before it showed a window")
            time.sleep(0.05)
        raise TimeoutError(f"no window shown within {timeout_s:g} s")

    def move(self, x: int, y: int) -> None:
        """Move the pointer to (x, y) on the screen."""
        from Xlib import X
        from Xlib.ext import xtest

        xtest.fake_input(self._d, X.MotionNotify, x=int(x), y=int(y))
        self._d.sync()

    def press(self, button: int = 1) -> None:
        """Press a mouse button (1 = left) and keep it down."""
        from Xlib import X
        from Xlib.ext import xtest

        xtest.fake_input(self._d, X.ButtonPress, button)
        self._d.sync()

    def release(self, button: int = 1) -> None:
        """Release a mouse button."""
        from Xlib import X
        from Xlib.ext import xtest

        xtest.fake_input(self._d, X.ButtonRelease, button)
        self._d.sync()

    def brightest(self, x: int, y: int, width: int, height: int) -> int:
        """The brightest colour channel (0..255) in a rectangle of the screen: a white
        text on a grey background shows as 255 there, the background alone as ~128."""
        from Xlib import X

        img = self._root.get_image(int(x), int(y), int(width), int(height), X.ZPixmap,
                                   0xFFFFFFFF)
        data = img.data if isinstance(img.data, bytes) else bytes(img.data)
        # 24-bit depth: 4 bytes a pixel (B, G, R, padding)
        return max((max(data[i:i + 3]) for i in range(0, len(data) - 3, 4)), default=0)
