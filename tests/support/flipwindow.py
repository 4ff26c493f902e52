"""A stand-in for the part of ``psychopy.visual.Window`` that tactorbelt.psychopy uses.

    from support.flipwindow import FRAME_NS, FlipWindow

    win = FlipWindow(clock)          # a SimClock (exact) or a WallClock
    win.callOnFlip(f, *args)         # f runs right after the next flip
    win.flip()                       # waits for the next frame boundary (60 Hz)

As PsychoPy implements them (``psychopy/visual/window.py``): ``flip()`` swaps the buffers
(here: waits for the next frame boundary of the clock), takes its timestamp, then calls
the functions ``callOnFlip`` scheduled before it, in order, and leaves those scheduled
during these calls for the next flip; ``close()`` closes the window. PsychoPy's window
needs OpenGL and a display, which the test machines lack.
"""

from __future__ import annotations

from typing import Any

__all__ = ["FRAME_NS", "FlipWindow"]

FRAME_NS = 16_666_667  # 60 Hz


class FlipWindow:
    """``psychopy.visual.Window``'s ``callOnFlip``, ``flip`` and ``close`` (module doc)."""

    def __init__(self, clock: Any) -> None:
        self.clock = clock
        self._toCall: list[tuple[Any, tuple[Any, ...], dict[str, Any]]] = []
        self.flips: list[int] = []
        self.closed = False

    def callOnFlip(self, function: Any, *args: Any, **kwargs: Any) -> None:
        self._toCall.append((function, args, kwargs))

    def flip(self) -> float:
        now = self.clock.now_ns()
        self.clock.sleep_until_ns((now // FRAME_NS + 1) * FRAME_NS)  # the vertical blank
        t = self.clock.now_ns()
        self.flips.append(t)
        n = len(self._toCall)
        for function, args, kwargs in self._toCall[:n]:
            function(*args, **kwargs)
        del self._toCall[:n]
        return t / 1e9

    def close(self) -> None:
        self.closed = True
