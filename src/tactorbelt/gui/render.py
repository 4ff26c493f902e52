"""Drawing of the experiment window: one :class:`View` in, one frame out.

The :class:`Renderer` knows nothing about sessions, trials or devices: the window
fills a :class:`View` (what to show) and the renderer draws it on a pygame surface.
Static parts (background, ellipse, targets) are drawn once per window size into a
cached layer and blitted each frame, and text surfaces are cached, so a frame costs
about a millisecond and never delays the 100 Hz sampling noticeably.

What the participant sees: the ellipse (the torso from above, front at the top), the
candidate targets on it (on-tactor in orange, between-tactor in grey, as in the
paper's Fig. 1(A)), the home zone at the centre and the cursor. Tactor positions are
hidden; the experimenter overlay (:attr:`View.overlay`) shows them, with the live
amplitude of each tactor as a ring and as bars, and the session's state in text.

I/O (pygame); imports tactorbelt.inputs.screen (the geometry). Import it only when a
window is opened.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pygame

from ..inputs.screen import EllipseGeometry, bar_rects, fit_ellipse

__all__ = ["COLORS", "Renderer", "View"]

#: The palette (RGB). Targets follow the paper's Fig. 1(A): orange and grey.
COLORS: dict[str, tuple[int, int, int]] = {
    "background": (28, 30, 36),
    "ellipse_fill": (42, 45, 54),
    "ellipse_line": (190, 194, 204),
    "on_tactor": (245, 130, 32),
    "between": (150, 150, 150),
    "highlight": (80, 200, 255),
    "correct": (70, 200, 90),
    "wrong": (230, 70, 60),
    "home": (120, 124, 136),
    "home_ok": (70, 200, 90),
    "home_wait": (240, 190, 60),
    "cursor": (255, 255, 255),
    "cursor_line": (10, 10, 10),
    "text": (232, 234, 240),
    "text_dim": (150, 154, 166),
    "tactor": (255, 70, 160),
    "bar": (255, 70, 160),
    "bar_frame": (110, 114, 126),
    "panel": (12, 12, 16),
    "banner": (230, 70, 60),
}


@dataclass
class View:
    """Everything one frame shows. The window fills it; the renderer only reads it.

    Attributes:
        screen: ``instructions``, ``block``, ``trial``, ``break``, ``pause`` or ``end``.
        targets_deg: candidate targets; ``on_tactor``: same length, which are on a tactor.
        tactors_deg: tactor angles (drawn only in the overlay).
        home_radius: radius of the home zone in cursor units.
        cursor: the cursor in cursor units, or None to hide it.
        home_state: ``idle``, ``wait`` (return to the centre) or ``ok`` (at home).
        highlight_deg: a target to highlight (training: the stimulus's target).
        chosen_deg: the answer's target (training feedback), with ``chosen_correct``.
        status_left, status_right: small text lines at the top of the window.
        prompt: one line under the ellipse (e.g. "Return to the centre").
        modal_title, modal_lines: a centred box over the dimmed scene (instructions,
            breaks, pause, end), or None.
        banner: a red line at the bottom (e.g. "Press Esc again to abort").
        overlay: draw the experimenter overlay.
        overlay_lines: text of the overlay panel.
        levels: live amplitude of each tactor in [0, 1] (overlay), or None.
        glyph: a visual secondary-task item (a letter, ``3+4``), drawn as two identical
            copies left and right of the ellipse at the height of its centre (so it
            cues no direction), or None.
    """

    screen: str = "trial"
    targets_deg: tuple[float, ...] = ()
    on_tactor: tuple[bool, ...] = ()
    tactors_deg: tuple[float, ...] = ()
    home_radius: float = 0.15
    cursor: tuple[float, float] | None = None
    home_state: str = "idle"
    highlight_deg: float | None = None
    chosen_deg: float | None = None
    chosen_correct: bool | None = None
    status_left: str = ""
    status_right: str = ""
    prompt: str = ""
    modal_title: str | None = None
    modal_lines: list[str] = field(default_factory=list)
    banner: str | None = None
    overlay: bool = False
    overlay_lines: list[str] = field(default_factory=list)
    levels: Any = None
    glyph: str | None = None


def _translucent(size: tuple[int, int], rgba: tuple[int, int, int, int]) -> Any:
    surf = pygame.Surface(size, pygame.SRCALPHA)
    surf.fill(rgba)
    return surf


class Renderer:
    """Draws :class:`View` objects on a surface of a given size.

    Args:
        size: the surface size in pixels.
        aspect: width over height of the ellipse (1.25 by default).
    """

    def __init__(self, size: tuple[int, int], aspect: float = 1.25) -> None:
        self.aspect = aspect
        self.overlay_layout = False
        #: a font of a size in pixels (at least 8); the surface of a text in a size and
        #: colour: ``text(s, px, color)``, each made once (the last 512 texts kept)
        self._font = functools.cache(lambda px: pygame.font.Font(None, max(int(px), 8)))
        self.text = functools.lru_cache(maxsize=512)(
            lambda s, px, color: self._font(px).render(s, True, color))
        self._static: Any = None
        self._static_key: tuple[Any, ...] | None = None
        #: a translucent rectangle of a size and RGBA colour (the last 16 kept)
        self._shade = functools.lru_cache(maxsize=16)(_translucent)
        self.resize(size)

    # -- geometry ----------------------------------------------------------------------
    def resize(self, size: tuple[int, int], overlay: bool | None = None) -> None:
        """Lay out for a new surface size; with ``overlay`` (default: as before) the
        ellipse moves right of a column kept for the experimenter overlay, so the panel
        hides no target, label or prompt."""
        self.size = (max(int(size[0]), 64), max(int(size[1]), 64))
        if overlay is not None:
            self.overlay_layout = bool(overlay)
        w, h = self.size
        self.unit = max(min(w, h) / 800.0, 0.35)
        self.top_band = int(44 * self.unit)
        self.panel_width = max(int(0.3 * w), min(int(340 * self.unit), w // 2)) \
            if self.overlay_layout else 0
        g = fit_ellipse(w - self.panel_width, h, self.aspect, margin=0.12,
                        top_band=self.top_band)
        self.geometry: EllipseGeometry = EllipseGeometry(g.cx + self.panel_width, g.cy,
                                                         g.rx, g.ry)
        #: where the last frame drew the overlay panel and the prompt (pygame Rects).
        self.rects: dict[str, Any] = {}
        self.target_radius = max(int(15 * self.unit), 4)
        self.cursor_radius = max(int(9 * self.unit), 3)
        self._static = None

    # -- static layer ------------------------------------------------------------------
    def _static_layer(self, view: View) -> Any:
        key = (self.size, view.targets_deg, view.on_tactor, view.home_radius)
        if self._static is not None and self._static_key == key:
            return self._static
        g = self.geometry
        surf = pygame.Surface(self.size)
        surf.fill(COLORS["background"])
        rect = pygame.Rect(round(g.cx - g.rx), round(g.cy - g.ry), round(2 * g.rx),
                           round(2 * g.ry))
        pygame.draw.ellipse(surf, COLORS["ellipse_fill"], rect)
        pygame.draw.ellipse(surf, COLORS["ellipse_line"], rect, max(int(3 * self.unit), 1))
        # "front" label above the top of the ellipse
        lab = self.text("front", int(20 * self.unit), COLORS["text_dim"])
        surf.blit(lab, lab.get_rect(midbottom=(round(g.cx), round(g.cy - g.ry - 1.6 *
                                                                   self.target_radius))))
        if view.targets_deg:
            pos = g.targets(view.targets_deg)
            for (px, py), on in zip(pos.tolist(), view.on_tactor, strict=False):
                color = COLORS["on_tactor"] if on else COLORS["between"]
                pygame.draw.circle(surf, color, (round(px), round(py)), self.target_radius)
        if pygame.display.get_surface() is not None:
            surf = surf.convert()  # the display's pixel format: the fastest blit
        self._static = surf
        self._static_key = key
        return surf

    # -- the frame ---------------------------------------------------------------------
    def draw(self, surface: Any, view: View) -> None:
        """Draw ``view`` on ``surface`` (which must have this renderer's size)."""
        if surface.get_size() != self.size or view.overlay != self.overlay_layout:
            self.resize(surface.get_size(), overlay=view.overlay)
        self.rects = {}
        surface.blit(self._static_layer(view), (0, 0))
        g = self.geometry
        u = self.unit
        # home zone
        hx, hy, hw, hh = g.scaled(view.home_radius)
        home_rect = pygame.Rect(round(hx), round(hy), round(hw), round(hh))
        if view.home_state == "ok":
            pygame.draw.ellipse(surface, COLORS["home_ok"], home_rect)
        elif view.home_state == "wait":
            pygame.draw.ellipse(surface, COLORS["home_wait"], home_rect, max(int(4 * u), 2))
        else:
            pygame.draw.ellipse(surface, COLORS["home"], home_rect, max(int(2 * u), 1))
        # training highlight and feedback
        r = self.target_radius
        if view.highlight_deg is not None:
            (px, py), = g.targets([view.highlight_deg]).tolist()
            pygame.draw.circle(surface, COLORS["highlight"], (round(px), round(py)), r)
            pygame.draw.circle(surface, COLORS["highlight"], (round(px), round(py)),
                               round(r * 1.6), max(int(3 * u), 2))
        if view.chosen_deg is not None:
            (px, py), = g.targets([view.chosen_deg]).tolist()
            color = COLORS["correct"] if view.chosen_correct else COLORS["wrong"]
            pygame.draw.circle(surface, color, (round(px), round(py)), r)
        if view.overlay:
            self._draw_tactors(surface, view)
        # cursor
        if view.cursor is not None:
            cx, cy = g.to_pixels(view.cursor[0], view.cursor[1])
            c = (round(cx), round(cy))
            pygame.draw.circle(surface, COLORS["cursor_line"], c, self.cursor_radius + 2)
            pygame.draw.circle(surface, COLORS["cursor"], c, self.cursor_radius)
        # status and prompt
        small = int(22 * u)
        if view.status_left:
            surface.blit(self.text(view.status_left, small, COLORS["text_dim"]),
                         (int(12 * u), int(12 * u)))
        if view.status_right:
            t = self.text(view.status_right, small, COLORS["text_dim"])
            surface.blit(t, t.get_rect(topright=(self.size[0] - int(12 * u), int(12 * u))))
        if view.prompt:
            t = self.text(view.prompt, int(30 * u), COLORS["text"])
            y = min(g.cy + g.ry + 2.2 * r, self.size[1] - int(20 * u))
            rect = t.get_rect(center=(round(g.cx), round(y)))
            surface.blit(t, rect)
            self.rects["prompt"] = rect
        if view.glyph:
            self._draw_glyph(surface, view.glyph)
        if view.overlay:
            self._draw_overlay_panel(surface, view)
        if view.modal_title is not None:
            self._draw_modal(surface, view.modal_title, view.modal_lines)
        if view.banner:
            t = self.text(view.banner, int(28 * u), COLORS["banner"])
            surface.blit(t, t.get_rect(midbottom=(self.size[0] // 2,
                                                  self.size[1] - int(10 * u))))

    def glyph_rects(self, glyph: str) -> list[Any]:
        """Where :meth:`draw` puts the two copies of a task glyph (pygame Rects): left and
        right of the ellipse, clear of the targets and tactor labels, centred on the
        ellipse's height, inside the window."""
        g = self.geometry
        t = self.text(glyph, int(72 * self.unit), COLORS["text"])
        gap = 3.2 * self.target_radius + t.get_width() / 2
        w = self.size[0]
        left_x = max(g.cx - g.rx - gap, self.panel_width + t.get_width() / 2 + 4)
        right_x = min(g.cx + g.rx + gap, w - t.get_width() / 2 - 4)
        return [t.get_rect(center=(round(x), round(g.cy))) for x in (left_x, right_x)]

    def _draw_glyph(self, surface: Any, glyph: str) -> None:
        t = self.text(glyph, int(72 * self.unit), COLORS["text"])
        self.rects["glyph"] = self.glyph_rects(glyph)
        for rect in self.rects["glyph"]:
            surface.blit(t, rect)

    def _draw_tactors(self, surface: Any, view: View) -> None:
        g = self.geometry
        u = self.unit
        if not view.tactors_deg:
            return
        pos = g.targets(view.tactors_deg).tolist()
        levels = None if view.levels is None else np.clip(np.asarray(view.levels, float), 0, 1)
        for k, (px, py) in enumerate(pos):
            c = (round(px), round(py))
            side = int(12 * u)
            pygame.draw.rect(surface, COLORS["tactor"],
                             pygame.Rect(c[0] - side // 2, c[1] - side // 2, side, side),
                             max(int(2 * u), 1))
            if levels is not None and k < len(levels) and levels[k] > 0.005:
                pygame.draw.circle(surface, COLORS["tactor"], c,
                                   round(self.target_radius * (1.2 + 1.6 * levels[k])),
                                   max(int(3 * u), 1))
            # index label outside the ellipse
            dx, dy = px - g.cx, py - g.cy
            d = max(np.hypot(dx, dy), 1.0)
            lx = px + dx / d * 2.6 * self.target_radius
            ly = py + dy / d * 2.6 * self.target_radius
            t = self.text(f"T{k}", int(20 * u), COLORS["tactor"])
            surface.blit(t, t.get_rect(center=(round(lx), round(ly))))

    def _draw_overlay_panel(self, surface: Any, view: View) -> None:
        u = self.unit
        px = int(19 * u)
        width = self.panel_width - int(20 * u)
        lines = self.wrap(view.overlay_lines, px, width - int(20 * u))
        n_levels = 0 if view.levels is None else len(np.asarray(view.levels).reshape(-1))
        bar_w, gap, max_h = int(16 * u), int(7 * u), int(60 * u)
        bar_w = max(min(bar_w, (width - int(20 * u)) // max(n_levels, 1) - gap), 2)
        height = int(12 * u) + len(lines) * int(px * 0.95)
        if n_levels:
            height += max_h + int(44 * u)
        x0 = int(10 * u)
        y0 = max(self.top_band, self.size[1] - height - int(10 * u))
        self.rects["overlay"] = pygame.Rect(x0, y0, width, height)
        surface.blit(self._shade((width, height), (*COLORS["panel"], 215)), (x0, y0))
        y = y0 + int(8 * u)
        for line in lines:
            surface.blit(self.text(line, px, COLORS["text"]), (x0 + int(10 * u), y))
            y += int(px * 0.95)
        if n_levels:
            base = y + int(10 * u) + max_h
            rects = bar_rects(view.levels, (x0 + int(10 * u), base), bar_w, max_h, gap)
            for k, (bx, by, bw, bh) in enumerate(rects):
                pygame.draw.rect(surface, COLORS["bar_frame"],
                                 pygame.Rect(round(bx), base - max_h, round(bw), max_h), 1)
                if bh >= 0.5:
                    pygame.draw.rect(surface, COLORS["bar"],
                                     pygame.Rect(round(bx), round(by), round(bw), round(bh)))
                t = self.text(f"T{k}", int(18 * u), COLORS["text_dim"])
                surface.blit(t, t.get_rect(midtop=(round(bx + bw / 2), base + int(4 * u))))

    def wrap(self, lines: list[str], px: int, width: int) -> list[str]:
        """Lines broken at spaces to fit ``width`` pixels (text of ``px`` pixels)."""
        out: list[str] = []
        for line in lines:
            words = line.split(" ")
            cur = ""
            for word in words:
                cand = f"{cur} {word}" if cur else word
                if cur and self.text(cand, px, COLORS["text"]).get_width() > width:
                    out.append(cur)
                    cur = word.lstrip()
                else:
                    cur = cand
            out.append(cur)
        return out

    def _draw_modal(self, surface: Any, title: str, lines: list[str]) -> None:
        u = self.unit
        w, h = self.size
        surface.blit(self._shade((w, h), (0, 0, 0, 170)), (0, 0))
        title_s = self.text(title, int(48 * u), COLORS["text"])
        body = [self.text(line, int(28 * u), COLORS["text"]) if line else None
                for line in lines]
        line_h = int(34 * u)
        box_w = max([title_s.get_width()] + [b.get_width() for b in body if b is not None])
        box_w = min(box_w + int(60 * u), w - int(20 * u))
        box_h = title_s.get_height() + int(30 * u) + line_h * len(body) + int(30 * u)
        box = pygame.Rect(0, 0, box_w, box_h)
        box.center = (w // 2, h // 2)
        pygame.draw.rect(surface, COLORS["panel"], box, border_radius=int(12 * u))
        pygame.draw.rect(surface, COLORS["ellipse_line"], box, 2, border_radius=int(12 * u))
        y = box.top + int(20 * u)
        surface.blit(title_s, title_s.get_rect(midtop=(w // 2, y)))
        y += title_s.get_height() + int(20 * u)
        for b in body:
            if b is not None:
                surface.blit(b, b.get_rect(midtop=(w // 2, y)))
            y += line_h
