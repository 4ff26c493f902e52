"""The perceptual calibration in a window: a person answers with the stick, the mouse or keys.

:class:`WindowRespondent` is a :class:`~tactorbelt.perceptual.Respondent` that asks each
calibration question on a screen of its own (one window for the whole calibration):

- "which was stronger": two boxes, *first* (left) and *second* (right);
- "nearer a or b than the mark": the belt seen from above with tactors a and b
  highlighted and the marked point drawn on the ellipse, and two boxes, *nearer a*
  (left) and *nearer b* (right).

Answers: a mouse click on a box; keys ``1``/``2`` or ``a``/``b`` or the left/right
arrows; the stick pushed left or right selects a box and a joystick button confirms
(a push alone never answers, so a slip of the stick is not an answer). Esc twice
within 2 s quits (:class:`~tactorbelt.calibrate.CalibrationQuit`: nothing is written).
The window closes on every exit path; the calibration itself turns the motors off.

:class:`ChoiceState` is the answer logic (pure); the drawing and the event loop use
pygame, imported when the window opens.
"""

from __future__ import annotations

import functools
import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Final

from .._errors import DeviceError
from ..calibration.motor import CalibrationQuit
from ..calibration.perceptual import Interval, Respondent
from ..geometry import Layout

__all__ = ["ChoiceState", "WindowRespondent"]

#: Stick deflection that selects a box.
STICK_PUSH: Final = 0.6
#: Esc twice within this long quits.
ESC_WINDOW_S: Final = 2.0
BG: Final = (18, 18, 22)
FG: Final = (230, 230, 235)
DIM: Final = (120, 120, 130)
ACCENT: Final = (90, 200, 255)
TACTOR: Final = (70, 70, 78)
MARK: Final = (255, 170, 60)


@dataclass
class ChoiceState:
    """A two-way choice: ``selected`` (0 left, 1 right, None) and ``answer`` once given."""

    selected: int | None = None
    answer: int | None = None

    def key(self, name: str, keys: dict[str, int]) -> None:
        """A key: one of ``keys`` (or the left/right arrow) answers at once."""
        if name in keys:
            self.answer = keys[name]
        elif name in ("left", "right"):
            self.answer = 0 if name == "left" else 1

    def stick(self, x: float) -> None:
        """The stick's x: pushed past :data:`STICK_PUSH` selects that side."""
        if x <= -STICK_PUSH:
            self.selected = 0
        elif x >= STICK_PUSH:
            self.selected = 1

    def button(self) -> None:
        """A joystick button confirms the selected side (nothing selected: nothing)."""
        if self.selected is not None:
            self.answer = self.selected

    def click(self, index: int | None) -> None:
        if index is not None:
            self.answer = index


class WindowRespondent(Respondent):
    """A person answering the calibration in a window (see the module doc).

    Args:
        layout: the belt's tactors (drawn for the location questions).
        joystick: use the first joystick (``--input joystick``); else mouse and keys.
        size: the window size in pixels.
        events: a source of pygame events (tests); default ``pygame.event.get``.
        on_frame: called with the window surface after each drawn frame (tests,
            screenshots).
    """

    name = "window"

    def __init__(self, layout: Layout, *, joystick: bool = False,
                 size: tuple[int, int] = (1000, 700),
                 events: Callable[[], Sequence[Any]] | None = None,
                 on_frame: Callable[[Any, str], None] | None = None) -> None:
        os.environ.setdefault("PYGAME_HIDE_SUPPORT_PROMPT", "1")
        import pygame

        self._pg = pygame
        self.layout = layout
        pygame.display.init()
        pygame.font.init()
        self._stick: Any = None
        if joystick:
            pygame.joystick.init()
            if pygame.joystick.get_count() == 0:
                pygame.quit()
                raise DeviceError("--input joystick: no joystick found; plug one in, or "
                                  "answer with --input mouse (mouse and keys)")
            self._stick = pygame.joystick.Joystick(0)
        self.surface = pygame.display.set_mode(size)
        pygame.display.set_caption("tactorbelt: perceptual calibration")
        self._events = events or pygame.event.get
        self._on_frame = on_frame
        self._font = functools.cache(lambda px: pygame.font.Font(None, px))  # by size
        self._message = "Feel each vibration, then answer. Esc twice quits."
        self._last_esc = -math.inf
        self.answers: list[int] = []
        self.closed = False

    # -- Respondent ------------------------------------------------------------------------
    def say(self, text: str) -> None:
        self._message = text

    def stronger(self, first: Interval, second: Interval) -> int:
        return self._ask("stronger", "Which vibration was stronger?",
                         ("first", "second"), {"1": 0, "2": 1}, None)

    def side(self, interval: Interval, pair: tuple[int, int], marked_deg: float,
             layout: Layout) -> int:
        a, b = pair
        return self._ask("side", "Was it nearer tactor a or tactor b than the mark?",
                         (f"nearer a ({layout.angles_deg[a]:g} deg)",
                          f"nearer b ({layout.angles_deg[b]:g} deg)"),
                         {"a": 0, "b": 1}, (a, b, marked_deg))

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self._pg.quit()

    def __enter__(self) -> WindowRespondent:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- the question loop -----------------------------------------------------------------
    def _ask(self, kind: str, question: str, labels: tuple[str, str], keys: dict[str, int],
             where: tuple[int, int, float] | None) -> int:
        pg = self._pg
        state = ChoiceState()
        boxes = self._boxes()
        while state.answer is None:
            for ev in self._events():
                if ev.type == pg.QUIT:
                    raise CalibrationQuit("perceptual calibration abandoned (window "
                                           "closed); nothing was written")
                if ev.type == pg.KEYDOWN:
                    name = pg.key.name(ev.key)
                    if name == "escape":
                        now = time.monotonic()
                        if now - self._last_esc <= ESC_WINDOW_S:
                            raise CalibrationQuit("perceptual calibration abandoned (Esc "
                                                   "Esc); nothing was written")
                        self._last_esc = now
                        self._message = "Press Esc again to quit (nothing is written)."
                    else:
                        state.key(name, keys)
                elif ev.type == pg.MOUSEBUTTONDOWN and ev.button == 1:
                    state.click(next((i for i, r in enumerate(boxes)
                                      if r.collidepoint(ev.pos)), None))
                elif ev.type == pg.JOYAXISMOTION and ev.axis == 0:
                    state.stick(float(ev.value))
                elif ev.type == pg.JOYBUTTONDOWN:
                    state.button()
            self._draw(kind, question, labels, boxes, state.selected, where)
            if state.answer is None:
                time.sleep(1 / 60)
        self.answers.append(state.answer)
        return state.answer

    # -- drawing ---------------------------------------------------------------------------
    def _text(self, s: str, px: int, color: tuple[int, int, int], center: tuple[int, int]
              ) -> None:
        img = self._font(px).render(s, True, color)
        self.surface.blit(img, img.get_rect(center=center))

    def _boxes(self) -> list[Any]:
        w, h = self.surface.get_size()
        bw, bh = int(w * 0.34), int(h * 0.12)
        y = int(h * 0.80)
        return [self._pg.Rect(int(w * 0.25) - bw // 2, y, bw, bh),
                self._pg.Rect(int(w * 0.75) - bw // 2, y, bw, bh)]

    def _draw(self, kind: str, question: str, labels: tuple[str, str], boxes: list[Any],
              selected: int | None, where: tuple[int, int, float] | None) -> None:
        pg = self._pg
        s = self.surface
        w, h = s.get_size()
        s.fill(BG)
        self._text(question, 44, FG, (w // 2, int(h * 0.08)))
        self._text(self._message, 26, DIM, (w // 2, int(h * 0.15)))
        if where is not None:
            self._draw_belt(where)
        else:
            self._text("1: first    2: second", 30, DIM, (w // 2, int(h * 0.45)))
        for i, (r, label) in enumerate(zip(boxes, labels, strict=True)):
            pg.draw.rect(s, ACCENT if selected == i else TACTOR, r, border_radius=10,
                         width=0 if selected == i else 3)
            self._text(label, 34, BG if selected == i else FG, r.center)
        hint = ("stick left/right, then a button" if self._stick is not None
                else "click a box, or keys " + ("1 / 2" if where is None else "a / b")
                + " or the arrows")
        self._text(hint, 24, DIM, (w // 2, int(h * 0.96)))
        pg.display.flip()
        if self._on_frame is not None:
            self._on_frame(s, kind)

    def _draw_belt(self, where: tuple[int, int, float]) -> None:
        pg = self._pg
        s = self.surface
        w, h = s.get_size()
        cx, cy = w // 2, int(h * 0.47)
        rx, ry = int(w * 0.22), int(h * 0.22)

        def at(deg: float) -> tuple[int, int]:  # 0 deg = front (up), clockwise
            r = math.radians(deg)
            return int(cx + rx * math.sin(r)), int(cy - ry * math.cos(r))

        pg.draw.ellipse(s, TACTOR, pg.Rect(cx - rx, cy - ry, 2 * rx, 2 * ry), width=3)
        self._text("front", 22, DIM, (cx, cy - ry - 22))
        a, b, mark = where
        for k, deg in enumerate(self.layout.angles_deg):
            hot = k in (a, b)
            pg.draw.circle(s, ACCENT if hot else TACTOR, at(deg), 16 if hot else 11)
            if hot:
                x, y = at(deg)
                dx, dy = x - cx, y - cy
                norm = math.hypot(dx, dy) or 1.0
                self._text("a" if k == a else "b", 32, FG,
                           (int(x + 34 * dx / norm), int(y + 34 * dy / norm)))
        mx, my = at(mark)
        pg.draw.line(s, MARK, (cx, cy), (mx, my), 3)
        pg.draw.circle(s, MARK, (mx, my), 9)
