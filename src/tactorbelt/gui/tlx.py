"""The NASA-TLX screen: six workload sliders after a test block (raw TLX).

The six scales of the NASA Task Load Index (Hart & Staveland 1988), with the names,
questions, anchors and definitions of NASA's form (NASA Ames Research Center, *NASA
Task Load Index (TLX) v1.0, paper and pencil package*, 1986): mental, physical and
temporal demand, performance, effort and frustration. Each is rated 0..100 in steps of
5 (the form's 21 marks); the anchors are "Very low" / "Very high", except performance:
"Perfect" (0) / "Failure" (100). Raw TLX: no pairwise weighting.

The sliders start unmarked (no default position suggests an answer). The participant
marks all six, then confirms:

- stick: up/down selects a scale, left/right moves its mark (the first move puts it in
  the middle; held, it repeats), a joystick button confirms;
- keyboard: arrow keys the same, Space or Enter confirms;
- mouse: a click (or a drag) on a scale marks it there, a click on *Done* confirms.

Confirming with a scale unmarked selects that scale and says so instead.

:class:`TlxForm` is the state (pure); :class:`TlxScreen` draws it and turns pygame
events and the stick into form actions. The window's ``ask_workload`` runs it.

I/O: pygame (drawing, events), only in :class:`TlxScreen`; tactorbelt.tasks (names).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Final

from ..tasks import TLX_SCALES, TlxScale

__all__ = ["STEP", "TLX_SCALES", "TlxForm", "TlxScale", "TlxScreen"]

#: A mark moves in steps of 5 (0, 5, ..., 100).
STEP: Final = 5
#: Stick deflection (cursor units) that counts as a push.
STICK_PUSH: Final = 0.6
#: A held push repeats after this long, then every :data:`REPEAT_NS`.
REPEAT_DELAY_NS: Final = 400_000_000
REPEAT_NS: Final = 120_000_000


@dataclass
class TlxForm:
    """The state of the TLX screen: a mark per scale (None: not yet marked), the
    selected scale, and whether it was confirmed."""

    values: list[int | None] = field(default_factory=lambda: [None] * len(TLX_SCALES))
    selected: int = 0
    done: bool = False
    hint: str | None = None

    def select(self, delta: int) -> None:
        """Select the scale ``delta`` rows down (clamped)."""
        self.selected = min(max(self.selected + delta, 0), len(TLX_SCALES) - 1)
        self.hint = None

    def move(self, steps: int) -> None:
        """Move the selected scale's mark by ``steps`` of 5; an unmarked scale is marked
        in the middle (50) first."""
        v = self.values[self.selected]
        self.values[self.selected] = 50 if v is None else min(max(v + steps * STEP, 0), 100)
        self.hint = None

    def set(self, index: int, fraction: float) -> None:
        """Mark scale ``index`` at ``fraction`` (0..1) of its length, to the nearest 5."""
        f = min(max(float(fraction), 0.0), 1.0)
        self.values[index] = int(round(f * 100 / STEP) * STEP)
        self.selected = index
        self.hint = None

    def confirm(self) -> bool:
        """Done when every scale is marked; else select the first unmarked one."""
        missing = [i for i, v in enumerate(self.values) if v is None]
        if missing:
            self.selected = missing[0]
            self.hint = (f"Please rate every scale ({len(missing)} not yet marked: "
                         f"{TLX_SCALES[missing[0]].title} is selected).")
            return False
        self.done = True
        self.hint = None
        return True

    def result(self) -> dict[str, float]:
        """item -> 0..100 (every scale must be marked)."""
        out = {}
        for s, v in zip(TLX_SCALES, self.values, strict=True):
            if v is None:
                raise ValueError(f"the NASA-TLX scale {s.item} is not marked")
            out[s.item] = float(v)
        return out


class TlxScreen:
    """Draws a :class:`TlxForm` and maps pygame input to it.

    Args:
        form: the form.
        title: the screen's title (e.g. "How was that block?").
        subtitle: a line under it (e.g. which block).
        stick: whether the stick's deflection selects and moves (joystick input).
    """

    def __init__(self, form: TlxForm, title: str, subtitle: str = "", *,
                 stick: bool = False) -> None:
        import pygame

        self._pg = pygame
        self.form = form
        self.title = title
        self.subtitle = subtitle
        self.stick = stick
        #: pixel rects of the last frame: ``track<i>``, ``row<i>``, ``done``
        self.rects: dict[str, Any] = {}
        self._held: tuple[int, int] | None = None  # (dx, dy) of the push held
        self._next_repeat_ns = 0
        self._dragging: int | None = None

    # -- input -----------------------------------------------------------------------------
    def handle_event(self, ev: Any, stick_id: int | None = None) -> bool:
        """Apply ``ev`` to the form; True when it was the TLX screen's event. Joystick
        events of a stick other than ``stick_id`` (when given) are not."""
        pg = self._pg
        f = self.form
        t = ev.type
        if t == pg.KEYDOWN:
            arrow = {pg.K_UP: (f.select, -1), pg.K_DOWN: (f.select, 1),
                     pg.K_LEFT: (f.move, -1), pg.K_RIGHT: (f.move, 1)}.get(ev.key)
            if arrow is not None:
                arrow[0](arrow[1])
            elif ev.key in (pg.K_SPACE, pg.K_RETURN, pg.K_KP_ENTER):
                f.confirm()
            else:
                return False
            return True
        if t in (pg.JOYBUTTONDOWN, pg.JOYHATMOTION) and stick_id is not None \
                and getattr(ev, "instance_id", stick_id) != stick_id:
            return False
        if t == pg.JOYBUTTONDOWN:
            f.confirm()
            return True
        if t == pg.JOYHATMOTION:
            hx, hy = ev.value
            if hy:
                f.select(-hy)  # hat up is +1
            elif hx:
                f.move(hx)
            return True
        if t == pg.MOUSEBUTTONDOWN and ev.button == 1:
            done = self.rects.get("done")
            if done is not None and done.collidepoint(ev.pos):
                f.confirm()
                return True
            i = self._hit(ev.pos)
            if i is not None:
                self._dragging = i
                self._mark(i, ev.pos[0])
            return True
        if t == pg.MOUSEMOTION and self._dragging is not None:
            self._mark(self._dragging, ev.pos[0])
            return True
        if t == pg.MOUSEBUTTONUP and ev.button == 1:
            self._dragging = None
            return True
        return False

    def _hit(self, pos: tuple[int, int]) -> int | None:
        """The scale whose row (its track, widened) is under ``pos``."""
        for i in range(len(TLX_SCALES)):
            r = self.rects.get(f"hit{i}")
            if r is not None and r.collidepoint(pos):
                return i
        return None

    def _mark(self, i: int, x: float) -> None:
        r = self.rects[f"track{i}"]
        self.form.set(i, (x - r.left) / max(r.width, 1))

    def stick_at(self, x: float, y: float, now_ns: int) -> None:
        """The stick's deflection (cursor units, y up) at ``now_ns``: a push selects or
        moves once, and repeats while held."""
        if not self.stick:
            return
        dx = (x >= STICK_PUSH) - (x <= -STICK_PUSH)
        dy = (y >= STICK_PUSH) - (y <= -STICK_PUSH)
        if abs(y) > abs(x):
            dx = 0
        else:
            dy = 0
        push = (dx, dy) if (dx or dy) else None
        if push is None:
            self._held = None
            return
        if push != self._held:
            self._held = push
            self._next_repeat_ns = now_ns + REPEAT_DELAY_NS
        elif now_ns >= self._next_repeat_ns:
            self._next_repeat_ns = now_ns + REPEAT_NS
        else:
            return
        if dy:
            self.form.select(-dy)  # pushed forward (y up) selects the scale above
        else:
            self.form.move(dx)

    # -- drawing ---------------------------------------------------------------------------
    def draw(self, surface: Any, renderer: Any, colors: dict[str, tuple[int, int, int]]
             ) -> None:
        """Draw the screen on ``surface`` with ``renderer``'s fonts and scale."""
        pg = self._pg
        w, h = surface.get_size()
        u = renderer.unit
        surface.fill(colors["background"])
        self.rects = {}
        text = renderer.text
        y = int(18 * u)
        t = text(self.title, int(42 * u), colors["text"])
        surface.blit(t, t.get_rect(midtop=(w // 2, y)))
        y += t.get_height() + int(4 * u)
        if self.subtitle:
            t = text(self.subtitle, int(22 * u), colors["text_dim"])
            surface.blit(t, t.get_rect(midtop=(w // 2, y)))
            y += t.get_height()
        y += int(10 * u)
        bottom_room = int(150 * u)
        row_h = max(int((h - y - bottom_room) / len(TLX_SCALES)), int(40 * u))
        track_w = int(min(w * 0.56, 900 * u))
        x0 = (w - track_w) // 2
        f = self.form
        for i, s in enumerate(TLX_SCALES):
            top = y + i * row_h
            sel = i == f.selected
            row = pg.Rect(x0 - int(24 * u), top, track_w + int(48 * u), row_h - int(4 * u))
            self.rects[f"row{i}"] = row
            if sel:
                pg.draw.rect(surface, colors["panel"], row, border_radius=int(8 * u))
                pg.draw.rect(surface, colors["highlight"], row, max(int(2 * u), 1),
                             border_radius=int(8 * u))
            name = text(s.title, int(26 * u), colors["text"] if sel else colors["text_dim"])
            surface.blit(name, (x0, top + int(4 * u)))
            q = text(s.question, int(20 * u), colors["text_dim"])
            surface.blit(q, (x0 + name.get_width() + int(14 * u),
                             top + int(4 * u) + (name.get_height() - q.get_height())))
            ty = top + int(row_h * 0.55)
            track = pg.Rect(x0, ty - int(3 * u), track_w, max(int(6 * u), 2))
            self.rects[f"track{i}"] = track
            self.rects[f"hit{i}"] = track.inflate(0, int(row_h * 0.5))
            pg.draw.rect(surface, colors["bar_frame"], track)
            for k in range(0, 101, STEP):  # the form's 21 marks; the middle one longer
                tx = x0 + round(track_w * k / 100)
                tall = int((14 if k == 50 else 8) * u)
                pg.draw.line(surface, colors["ellipse_line"], (tx, ty - tall), (tx, ty),
                             max(int(u), 1))
            lo = text(s.low, int(19 * u), colors["text_dim"])
            hi = text(s.high, int(19 * u), colors["text_dim"])
            surface.blit(lo, lo.get_rect(topleft=(x0, ty + int(8 * u))))
            surface.blit(hi, hi.get_rect(topright=(x0 + track_w, ty + int(8 * u))))
            v = f.values[i]
            if v is not None:
                mx = x0 + round(track_w * v / 100)
                pg.draw.circle(surface, colors["cursor_line"], (mx, ty), int(11 * u) + 2)
                pg.draw.circle(surface, colors["highlight"], (mx, ty), int(11 * u))
        # the selected scale's definition, the hint, Done
        yb = y + len(TLX_SCALES) * row_h + int(4 * u)
        lines = renderer.wrap([TLX_SCALES[f.selected].definition], int(20 * u),
                               int(track_w + 48 * u))
        for line in lines[:3]:
            t = text(line, int(20 * u), colors["text_dim"])
            surface.blit(t, t.get_rect(midtop=(w // 2, yb)))
            yb += t.get_height()
        done = pg.Rect(0, 0, int(140 * u), int(44 * u))
        done.bottomright = (x0 + track_w + int(24 * u), h - int(12 * u))
        self.rects["done"] = done
        ready = all(v is not None for v in f.values)
        pg.draw.rect(surface, colors["home_ok"] if ready else colors["bar_frame"], done,
                     border_radius=int(8 * u))
        t = text("Done", int(26 * u), colors["text"])
        surface.blit(t, t.get_rect(center=done.center))
        help_ = ("Up/down: choose a scale.  Left/right: move its mark.  "
                 "Button or Space: done.  Or click on the scales.")
        t = text(help_, int(20 * u), colors["text_dim"])
        surface.blit(t, t.get_rect(midbottom=(w // 2, done.top - int(6 * u))))
        if f.hint:
            lines = renderer.wrap([f.hint], int(22 * u), done.left - x0 - int(40 * u))
            yh = done.centery - len(lines[:2]) * int(11 * u)
            for line in lines[:2]:
                t = text(line, int(22 * u), colors["banner"])
                surface.blit(t, (x0 - int(24 * u), yh))
                yh += int(22 * u)
