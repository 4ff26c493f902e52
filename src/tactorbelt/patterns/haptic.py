"""Meta Haptics Studio's ``.haptic`` files (Lofelt's haptic data model, version 1).

A ``.haptic`` file is JSON: ``{"version": {"major": 1, ...}, "metadata": {...},
"signals": {"continuous": {"envelopes": {"amplitude": [{"time": s, "amplitude": 0..1,
"emphasis": {"amplitude", "frequency"}}, ...], "frequency": [{"time", "frequency"}]}}}}``.

What a belt shows of it (docs/patterns.md): like AHAP it has no place on the body, so it
goes to one angle (``angle_deg``, default 0), rendered with the belt's law. The amplitude
envelope becomes one continuous event from the first breakpoint to the last, its
breakpoints the event's envelope; each emphasis becomes a transient of its amplitude (its
frequency kept as sharpness). Dropped, and said so: the frequency envelope (a belt's
motors have one frequency) and the metadata.

Imports the standard library and the pattern model.
"""

from __future__ import annotations

from typing import Any

from .ahap import TRANSIENT_MS
from .model import Event, Pattern, _Reader, imported

__all__ = ["pattern_from_haptic"]


def pattern_from_haptic(doc: Any, path: str | None = None, angle_deg: float = 0.0) -> Pattern:
    """The pattern of a parsed ``.haptic`` document."""
    r = _Reader(path)
    top = r.obj(doc, "")
    version = r.obj(r.need(top, "version", ""), "version")
    major = r.need(version, "major", "version")
    if major != 1 or isinstance(major, bool):
        raise r.fail("version.major", f"expected 1 (haptic data model v1), got {major!r}")
    signals = r.obj(r.need(top, "signals", ""), "signals")
    cont = r.obj(r.need(signals, "continuous", "signals"), "signals.continuous")
    envs = r.obj(r.need(cont, "envelopes", "signals.continuous"),
                 "signals.continuous.envelopes")
    base = "signals.continuous.envelopes.amplitude"
    amp = r.array(r.need(envs, "amplitude", "signals.continuous.envelopes"), base)
    if not amp:
        raise r.fail(base, "the amplitude envelope is empty (it needs a breakpoint at least)")
    dropped = []
    if envs.get("frequency"):
        dropped.append("the frequency envelope (a belt's motors have one frequency)")
    points: list[tuple[float, float]] = []
    emphases: list[Event] = []
    for i, bp in enumerate(amp):
        w = f"{base}[{i}]"
        d = r.obj(bp, w)
        t = r.number(r.need(d, "time", w), f"{w}.time", 0.0)
        if points and t < points[-1][0]:
            raise r.fail(f"{w}.time", f"breakpoint times must not decrease ({t:g} s after "
                                      f"{points[-1][0]:g} s)")
        a = r.unit(r.need(d, "amplitude", w), f"{w}.amplitude")
        points.append((t, a))
        if "emphasis" in d:
            em = r.obj(d["emphasis"], f"{w}.emphasis")
            ea = r.unit(r.need(em, "amplitude", f"{w}.emphasis"), f"{w}.emphasis.amplitude")
            ef = r.unit(r.need(em, "frequency", f"{w}.emphasis"), f"{w}.emphasis.frequency")
            emphases.append(Event(t * 1000.0, TRANSIENT_MS, ea, angle_deg=angle_deg,
                                  transient=True, sharpness=ef))
    events = list(emphases)
    t0, t1 = points[0][0], points[-1][0]
    if t1 > t0:
        env = tuple((round((t - t0) * 1000.0, 6), a) for t, a in points)
        events.append(Event(t0 * 1000.0, (t1 - t0) * 1000.0, 1.0, angle_deg=angle_deg,
                            envelope=env))
    else:
        dropped.append("an amplitude envelope of a single instant")
    return imported(events, path, "haptic", dropped, meta=top.get("metadata"),
                    name_keys=("description", "project"), angle_deg=angle_deg)
