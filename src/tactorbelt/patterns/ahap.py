"""Apple's AHAP (Core Haptics) files: read into a pattern, and write one from a pattern.

An AHAP file is JSON: ``{"Version": 1, "Metadata": {...}, "Pattern": [...]}``, each item
an ``Event`` (``Time`` s, ``EventType``, ``EventDuration`` s for continuous events,
``EventParameters`` of ``ParameterID``/``ParameterValue``), a ``ParameterCurve``
(``ParameterID``, ``Time``, ``ParameterCurveControlPoints`` of ``Time``/``ParameterValue``)
or a dynamic ``Parameter`` (``ParameterID``, ``Time``, ``ParameterValue``).

What a belt shows of it (docs/patterns.md): AHAP has no place on the body, so every event
goes to one angle (``angle_deg``, default 0: the navel), rendered with the belt's law;
``HapticTransient`` becomes a pulse of :data:`TRANSIENT_MS`; ``HapticContinuous`` a
vibration of its duration; ``HapticIntensity`` its intensity; ``HapticIntensityControl``
curves and dynamic parameters its envelope (a curve applies over the span of its control
points; where several cover an instant, the one that starts last). Dropped, and said so:
sharpness (kept in the pattern for export, but a belt's motors have one frequency),
sharpness controls, attack/decay/release times, and audio events.

Imports the standard library, NumPy and the pattern model.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Final

import numpy as np

from .model import Event, Pattern, _Reader, imported

__all__ = ["CURVE_POINTS", "TRANSIENT_MS", "pattern_from_ahap", "pattern_to_ahap",
           "write_ahap"]

#: How long a transient (a tap) vibrates on a belt, ms: an ERM needs about this to spin up.
TRANSIENT_MS: Final = 30.0
#: Core Haptics takes at most 16 control points per parameter curve.
CURVE_POINTS: Final = 16
_DROPPED_PARAMS: Final = {"AttackTime", "DecayTime", "ReleaseTime", "Sustained"}


def pattern_from_ahap(doc: Any, path: str | None = None, angle_deg: float = 0.0) -> Pattern:
    """The pattern of a parsed AHAP document."""
    r = _Reader(path)
    top = r.obj(doc, "")
    version = top.get("Version", 1)
    if isinstance(version, bool) or not isinstance(version, int | float) or version != 1:
        raise r.fail("Version", f"expected 1 (the only AHAP version), got {version!r}")
    items = r.array(r.need(top, "Pattern", ""), "Pattern")
    dropped: set[str] = set()
    raw_events: list[tuple[str, dict[str, Any]]] = []
    curves: list[tuple[float, list[tuple[float, float]]]] = []
    for i, item in enumerate(items):
        where = f"Pattern[{i}]"
        d = r.obj(item, where)
        if "Event" in d:
            raw_events.append((f"{where}.Event", r.obj(d["Event"], f"{where}.Event")))
        elif "ParameterCurve" in d:
            c = r.obj(d["ParameterCurve"], f"{where}.ParameterCurve")
            cw = f"{where}.ParameterCurve"
            pid = r.string(r.need(c, "ParameterID", cw), f"{cw}.ParameterID")
            t0 = r.number(r.need(c, "Time", cw), f"{cw}.Time", 0.0)
            pts: list[tuple[float, float]] = []
            for j, p in enumerate(r.array(r.need(c, "ParameterCurveControlPoints", cw),
                                          f"{cw}.ParameterCurveControlPoints")):
                pw = f"{cw}.ParameterCurveControlPoints[{j}]"
                p = r.obj(p, pw)
                t = r.number(r.need(p, "Time", pw), f"{pw}.Time", 0.0)
                if pts and t0 + t < pts[-1][0]:
                    raise r.fail(f"{pw}.Time", "control point times must not decrease")
                pts.append((t0 + t, r.number(r.need(p, "ParameterValue", pw),
                                             f"{pw}.ParameterValue")))
            if pid == "HapticIntensityControl":
                for j, (_, v) in enumerate(pts):
                    if not 0.0 <= v <= 1.0:
                        raise r.fail(f"{cw}.ParameterCurveControlPoints[{j}].ParameterValue",
                                     f"must be in [0, 1], got {v:g}")
                if pts:
                    curves.append((t0, pts))
            else:
                dropped.add(f"parameter curves of {pid}")
        elif "Parameter" in d:
            p = r.obj(d["Parameter"], f"{where}.Parameter")
            pw = f"{where}.Parameter"
            pid = r.string(r.need(p, "ParameterID", pw), f"{pw}.ParameterID")
            t = r.number(r.need(p, "Time", pw), f"{pw}.Time", 0.0)
            v = r.number(r.need(p, "ParameterValue", pw), f"{pw}.ParameterValue")
            if pid == "HapticIntensityControl":
                if not 0.0 <= v <= 1.0:
                    raise r.fail(f"{pw}.ParameterValue", f"must be in [0, 1], got {v:g}")
                curves.append((t, [(t, v), (math.inf, v)]))
            else:
                dropped.add(f"dynamic parameters {pid}")
        else:
            raise r.fail(where, "expected an 'Event', 'ParameterCurve' or 'Parameter'")
    control = _Control(curves)
    events = []
    for where, e in raw_events:
        kind = r.string(r.need(e, "EventType", where), f"{where}.EventType")
        t = r.number(r.need(e, "Time", where), f"{where}.Time", 0.0)
        params: dict[str, float] = {}
        for j, p in enumerate(r.array(e.get("EventParameters", []), f"{where}.EventParameters")):
            pw = f"{where}.EventParameters[{j}]"
            p = r.obj(p, pw)
            pid = r.string(r.need(p, "ParameterID", pw), f"{pw}.ParameterID")
            value = p.get("ParameterValue")
            if pid in ("HapticIntensity", "HapticSharpness"):
                params[pid] = r.unit(r.need(p, "ParameterValue", pw), f"{pw}.ParameterValue")
            elif pid in _DROPPED_PARAMS:
                dropped.add(f"{pid} (the belt's motors keep their own ramps)")
            elif value is not None:
                dropped.add(f"event parameter {pid}")
        if kind.startswith("Audio"):
            dropped.add("audio events")
            continue
        if kind not in ("HapticTransient", "HapticContinuous"):
            raise r.fail(f"{where}.EventType", f"unknown event type {kind!r}; allowed: "
                         "HapticTransient, HapticContinuous, AudioCustom, AudioContinuous")
        intensity = params.get("HapticIntensity", 1.0)
        sharp = params.get("HapticSharpness")
        if sharp is not None:
            dropped.add("HapticSharpness (kept for export; a belt's motors have one frequency)")
        if kind == "HapticTransient":
            gain = float(control.at(np.array([t]))[0])
            events.append(Event(t * 1000.0, TRANSIENT_MS, intensity * gain, angle_deg=angle_deg,
                                transient=True, sharpness=sharp))
            continue
        dur = r.number(r.need(e, "EventDuration", where), f"{where}.EventDuration", 0.0,
                       lo_open=True)
        events.append(Event(t * 1000.0, dur * 1000.0, intensity, angle_deg=angle_deg,
                            envelope=control.envelope(t, t + dur), sharpness=sharp))
    return imported(events, path, "ahap", sorted(dropped), meta=top.get("Metadata"),
                    name_keys=("Description", "Project"), angle_deg=angle_deg)


class _Control:
    """The HapticIntensityControl in force at each instant (1 outside every curve)."""

    def __init__(self, curves: list[tuple[float, list[tuple[float, float]]]]) -> None:
        self.curves = sorted(curves, key=lambda c: c[0])  # the later start wins

    def at(self, t: np.ndarray) -> np.ndarray:
        out = np.ones_like(t, dtype=float)
        for _, pts in self.curves:
            xs = np.array([p[0] for p in pts])
            ys = np.array([p[1] for p in pts])
            inside = (t >= xs[0]) & (t <= xs[-1])
            if inside.any():  # a dynamic parameter's curve ends at infinity: a constant
                out[inside] = np.interp(t[inside], xs, ys)
        return out

    def envelope(self, start: float, end: float) -> tuple[tuple[float, float], ...]:
        """An event's envelope over [start, end] (s): points where the control changes."""
        if not self.curves:
            return ()
        times = {start, end}
        for _, pts in self.curves:
            for x, _ in pts:
                if start < x < end:
                    times.add(x)
            # where a curve's edge inside the event is a step, sample both sides of it
            for x in (pts[0][0], pts[-1][0]):
                if start < x < end:
                    sides = np.array([max(start, x - 1e-6), min(end, x + 1e-6)])
                    g = self.at(sides)
                    if abs(g[1] - g[0]) > 1e-3:  # a jump, not a slope
                        times.update(sides.tolist())
        ts = np.array(sorted(times))
        g = self.at(ts)
        if np.all(g == 1.0):
            return ()
        return tuple((float(round((a - start) * 1000.0, 6)), float(v)) for a, v in zip(ts, g,
                                                                                   strict=True))


def pattern_to_ahap(pattern: Pattern) -> tuple[dict[str, Any], list[str]]:
    """An AHAP document for ``pattern``, and what it could not carry (places: AHAP is one
    actuator; overlapping envelopes, which share one intensity control)."""
    notes: list[str] = []
    if any(e.place != "angle" for e in pattern.events) or len(
            {e.angle_deg for e in pattern.events}) > 1:
        notes.append("places (AHAP drives one actuator: every event is written, none placed)")
    items: list[dict[str, Any]] = []
    shaped_end = -math.inf
    # Core Haptics scales every event by the intensity control in force, transients too: a
    # transient under an envelope is written louder by as much, where it can be
    curves = [(e.at_ms / 1000.0, [((e.at_ms + t) / 1000.0, g) for t, g in _held(e)])
              for e in pattern.events if e.envelope and not e.transient]
    control = _Control(curves)
    weaker = 0
    for e in pattern.events:
        intensity = e.intensity
        if e.transient and curves:
            gain = float(control.at(np.array([e.at_ms / 1000.0]))[0])
            if intensity > gain:
                weaker += 1
            intensity = min(1.0, intensity / gain) if gain > 0 else 1.0
        params = [{"ParameterID": "HapticIntensity", "ParameterValue": _r(intensity)}]
        if e.sharpness is not None:
            params.append({"ParameterID": "HapticSharpness", "ParameterValue": _r(e.sharpness)})
        if e.transient:
            items.append({"Event": {"Time": _r(e.at_ms / 1000.0), "EventType": "HapticTransient",
                                    "EventParameters": params}})
            continue
        items.append({"Event": {"Time": _r(e.at_ms / 1000.0), "EventType": "HapticContinuous",
                                "EventDuration": _r(e.duration_ms / 1000.0),
                                "EventParameters": params}})
        if e.envelope:
            if e.at_ms / 1000.0 < shaped_end:
                notes.append("overlapping envelopes (one intensity control: the later wins)")
            shaped_end = e.end_ms / 1000.0
            pts = _held(e)
            for k in range(0, max(len(pts) - 1, 1), CURVE_POINTS - 1):
                chunk = pts[k:k + CURVE_POINTS]
                t0 = chunk[0][0]
                items.append({"ParameterCurve": {
                    "ParameterID": "HapticIntensityControl",
                    "Time": _r((e.at_ms + t0) / 1000.0),
                    "ParameterCurveControlPoints": [
                        {"Time": _r((t - t0) / 1000.0), "ParameterValue": _r(g)}
                        for t, g in chunk]}})
    if weaker:
        notes.append(f"the full intensity of {weaker} transient(s) under an envelope (AHAP's "
                     "intensity control scales them too)")
    doc = {"Version": 1.0,
           "Metadata": {"Project": "tactorbelt", "Description": pattern.name or "pattern"},
           "Pattern": items}
    return doc, sorted(set(notes))


def _held(e: Event) -> list[tuple[float, float]]:
    """An event's envelope over its whole span: the first and last gains held to its start
    and end (a curve controls only its own span)."""
    pts = list(e.envelope)
    if pts[0][0] > 0.0:
        pts.insert(0, (0.0, pts[0][1]))
    if pts[-1][0] < e.duration_ms:
        pts.append((e.duration_ms, pts[-1][1]))
    return pts


def write_ahap(pattern: Pattern, path: str | Path) -> list[str]:
    """Write ``pattern`` as AHAP; returns what was dropped (see :func:`pattern_to_ahap`)."""
    doc, notes = pattern_to_ahap(pattern)
    Path(path).write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    return notes


def _r(x: float) -> float:
    return round(float(x), 9)
