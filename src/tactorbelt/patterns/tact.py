"""bHaptics ``.tact`` files (from the bHaptics Designer): tracks of dot and path feedback
over a device's layout.

A ``.tact`` file is JSON: ``{"project": {"name", "layout": {"layouts": {"VestFront": [{"index",
"x", "y"}, ...], ...}}, "tracks": [{"enable", "effects": [{"startTime" ms, "offsetTime" ms,
"modes": {"VestFront": {"mode": "DOT_MODE" | "PATH_MODE", "dotMode": {"feedback":
[{"startTime", "endTime", "pointList": [{"index", "intensity"}]}]}, "pathMode": {"feedback":
[{"pointList": [{"x", "y", "intensity", "time"}]}]}}}}]}]}, "durationMillis": ms}``.

A belt around the torso shows the vest's columns, so a ``.tact`` pattern keeps its
layout's places (docs/patterns.md): the front panel spans the front half (x from 0 to 1
is 60 deg to -60 deg, the wearer's right to left, as the panel is seen from the front), the
back panel the back half (x from 0 to 1 is 240 deg to 120 deg, left to right, seen from
behind). A dot is a ``tactor`` event on the column of its index (rows collapse: a belt
has one row); a path is a run of ``path`` events between its points. Inferred, not
documented by bHaptics: which edge of each panel is x = 0. Dropped, and said so: the
height on the vest (y), playback types (fade in/out) and moving patterns, disabled
tracks. Content for a device that is not around the torso (head, arms, hands, feet) is a
layout the belt cannot show: refused, with the place.

Imports the standard library and the pattern model.
"""

from __future__ import annotations

import itertools
from typing import Any, Final

from .model import Event, Pattern, _Reader, imported

__all__ = ["TORSO_PANELS", "VEST_COLUMNS", "pattern_from_tact"]

#: The vest panels a belt can show, with the angle of x = 0 and of x = 1.
TORSO_PANELS: Final = {"VestFront": (60.0, -60.0), "VestBack": (240.0, 120.0)}
#: Columns per panel on the bHaptics vest (x = 0, 1/3, 2/3, 1).
VEST_COLUMNS: Final = 4


def _angle(panel: str, x: float) -> float:
    a, b = TORSO_PANELS[panel]
    return (a + (b - a) * x) % 360.0


def pattern_from_tact(doc: Any, path: str | None = None) -> Pattern:
    """The pattern of a parsed ``.tact`` document."""
    r = _Reader(path)
    top = r.obj(doc, "")
    project = r.obj(r.need(top, "project", ""), "project")
    xs = _columns(r, project)
    panels = list(TORSO_PANELS)
    layout = tuple(_angle(p, c / (VEST_COLUMNS - 1)) for p in panels for c in range(VEST_COLUMNS))
    dropped: set[str] = set()
    dots: dict[tuple[float, float, int], float] = {}
    paths: list[Event] = []
    for i, track in enumerate(r.array(r.need(project, "tracks", "project"), "project.tracks")):
        tw = f"project.tracks[{i}]"
        track = r.obj(track, tw)
        if track.get("enable", True) is False:
            dropped.add("disabled tracks")
            continue
        for j, effect in enumerate(r.array(track.get("effects", []), f"{tw}.effects")):
            ew = f"{tw}.effects[{j}]"
            effect = r.obj(effect, ew)
            start = r.number(effect.get("startTime", 0), f"{ew}.startTime", 0.0)
            length = r.number(effect.get("offsetTime", 0), f"{ew}.offsetTime", 0.0)
            for place, mode in r.obj(r.need(effect, "modes", ew), f"{ew}.modes").items():
                mw = f"{ew}.modes.{place}"
                mode = r.obj(mode, mw)
                if place not in TORSO_PANELS:
                    if _has_content(mode):
                        raise r.fail(mw, f"a {place} layout cannot be shown on a belt (a belt "
                                         "shows the vest's panels around the torso: "
                                         f"{', '.join(TORSO_PANELS)})")
                    continue
                col0 = panels.index(place) * VEST_COLUMNS
                which = mode.get("mode", "DOT_MODE")
                if which == "DOT_MODE":
                    _dots(r, mode, mw, start, place, col0, xs, dots, dropped)
                elif which == "PATH_MODE":
                    paths.extend(_paths(r, mode, mw, start, length, place, dropped))
                else:
                    raise r.fail(f"{mw}.mode", f"expected DOT_MODE or PATH_MODE, got {which!r}")
    events = [Event(at, dur, i, tactor=k) for (at, dur, k), i in dots.items()] + paths
    duration = r.number(top.get("durationMillis", 0), "durationMillis", 0.0)
    if events or dropped:
        dropped.add("the height on the vest (y): a belt has one row")
    return imported(events, path, "tact", sorted(dropped), meta=project, name_keys=("name",),
                    layout_deg=layout, duration_ms=duration)


def _columns(r: _Reader, project: dict[str, Any]) -> dict[str, dict[int, float]]:
    """x of each dot index per panel, from the project's layout (default: the vest's
    4-column grid, index % 4)."""
    out: dict[str, dict[int, float]] = {}
    layout = project.get("layout")
    layouts = layout.get("layouts", {}) if isinstance(layout, dict) else {}
    for panel in TORSO_PANELS:
        dots = layouts.get(panel) if isinstance(layouts, dict) else None
        if isinstance(dots, list) and dots:
            m = {}
            for k, d in enumerate(dots):
                w = f"project.layout.layouts.{panel}[{k}]"
                d = r.obj(d, w)
                idx = r.number(r.need(d, "index", w), f"{w}.index", 0.0)
                m[int(idx)] = r.unit(r.need(d, "x", w), f"{w}.x")
            out[panel] = m
    return out


def _has_content(mode: dict[str, Any]) -> bool:
    for key in ("dotMode", "pathMode"):
        sub = mode.get(key)
        feedback = sub.get("feedback", []) if isinstance(sub, dict) else []
        for f in feedback if isinstance(feedback, list) else []:
            if isinstance(f, dict) and f.get("pointList"):
                return True
    return False


def _dots(r: _Reader, mode: dict[str, Any], mw: str, start: float, panel: str, col0: int,
          xs: dict[str, dict[int, float]], dots: dict[tuple[float, float, int], float],
          dropped: set[str]) -> None:
    dot = r.obj(mode.get("dotMode", {}), f"{mw}.dotMode")
    for k, fb in enumerate(r.array(dot.get("feedback", []), f"{mw}.dotMode.feedback")):
        fw = f"{mw}.dotMode.feedback[{k}]"
        fb = r.obj(fb, fw)
        t0 = r.number(r.need(fb, "startTime", fw), f"{fw}.startTime", 0.0)
        t1 = r.number(r.need(fb, "endTime", fw), f"{fw}.endTime", 0.0)
        if fb.get("playbackType", "NONE") not in ("NONE", None):
            dropped.add("playback types (fade in/out)")
        points = r.array(fb.get("pointList", []), f"{fw}.pointList")
        if points and t1 <= t0:
            raise r.fail(f"{fw}.endTime", f"must be after startTime ({t0:g} ms), got {t1:g}")
        for m, p in enumerate(points):
            pw = f"{fw}.pointList[{m}]"
            p = r.obj(p, pw)
            idx = r.number(r.need(p, "index", pw), f"{pw}.index", 0.0)
            if idx != int(idx):
                raise r.fail(f"{pw}.index", f"must be an integer, got {idx:g}")
            intensity = r.unit(r.need(p, "intensity", pw), f"{pw}.intensity")
            grid = xs.get(panel)
            if grid is not None and int(idx) not in grid:
                raise r.fail(f"{pw}.index", f"dot {int(idx)} is not in the project's "
                                            f"{panel} layout")
            x = grid[int(idx)] if grid is not None else (int(idx) % VEST_COLUMNS) / (
                VEST_COLUMNS - 1)
            col = min(VEST_COLUMNS - 1, round(x * (VEST_COLUMNS - 1)))
            key = (start + t0, t1 - t0, col0 + col)
            dots[key] = max(dots.get(key, 0.0), intensity)


def _paths(r: _Reader, mode: dict[str, Any], mw: str, start: float, length: float, panel: str,
           dropped: set[str]) -> list[Event]:
    out: list[Event] = []
    sub = r.obj(mode.get("pathMode", {}), f"{mw}.pathMode")
    for k, fb in enumerate(r.array(sub.get("feedback", []), f"{mw}.pathMode.feedback")):
        fw = f"{mw}.pathMode.feedback[{k}]"
        fb = r.obj(fb, fw)
        if fb.get("playbackType", "NONE") not in ("NONE", None):
            dropped.add("playback types (fade in/out)")
        if fb.get("movingPattern") not in (None, "CONST_SPEED", "CONST_TDM"):
            dropped.add("moving patterns")
        pts: list[tuple[float, float, float]] = []
        for m, p in enumerate(r.array(fb.get("pointList", []), f"{fw}.pointList")):
            pw = f"{fw}.pointList[{m}]"
            p = r.obj(p, pw)
            t = r.number(r.need(p, "time", pw), f"{pw}.time", 0.0)
            if pts and t < pts[-1][0]:
                raise r.fail(f"{pw}.time", "point times must not decrease")
            pts.append((t, r.unit(r.need(p, "x", pw), f"{pw}.x"),
                        r.unit(r.need(p, "intensity", pw), f"{pw}.intensity")))
        if len(pts) == 1:
            t, x, i = pts[0]
            if length > t:
                out.append(Event(start + t, length - t, i, angle_deg=_angle(panel, x)))
        for (ta, xa, ia), (tb, xb, ib) in itertools.pairwise(pts):
            if tb <= ta:
                continue
            a, b = _angle(panel, xa), _angle(panel, xb)
            b = a + ((b - a + 180.0) % 360.0 - 180.0)  # within a panel: the short way
            out.append(Event(start + ta, tb - ta, 1.0, path=(a, b),
                             envelope=((0.0, ia), (tb - ta, ib))))
    return out
