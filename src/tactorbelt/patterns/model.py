"""The pattern format ``tactorbelt.pattern/1``: events in time, each on a tactor, at an
angle, or moving along a between-tactor path (docs/patterns.md).

A :class:`Pattern` is plain data: it is read from and written to JSON here, checked as it
is read (every refusal names the file, the field and the reason: :class:`PatternFileError`),
and rendered onto a belt's layout by :mod:`tactorbelt.patterns.render`.

Imports the standard library and tactorbelt's kernel, geometry and law names only.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

from .._errors import ConfigError
from .._lawnames import LAWS

__all__ = [
    "FORMAT",
    "Event",
    "Pattern",
    "PatternFileError",
    "imported",
    "pattern_from_dict",
    "pattern_to_dict",
    "save_pattern",
]

#: The value of a pattern file's ``"format"`` key.
FORMAT: Final = "tactorbelt.pattern/1"
#: Times are kept to the microsecond (ms with 3 decimals) when written.
_DECIMALS: Final = 6


class PatternFileError(ConfigError):
    """A pattern (or a file to import) that cannot be used: names the file, the field
    (a JSON path such as ``events[3].intensity``) and the reason. Exit status 2."""

    def __init__(self, message: str, *, path: str | None = None,
                 field: str | None = None) -> None:
        self.path = path
        self.field = field
        self.reason = message
        where = f"{path}: " if path else ""
        if field:
            where += f"{field}: "
        super().__init__(where + message)


@dataclass(frozen=True)
class Event:
    """One vibration of a pattern.

    Exactly one place: ``tactor`` (an index into the pattern's ``layout_deg``),
    ``angle_deg`` (rendered with the belt's amplitude law), or ``path`` (``(from_deg,
    to_deg)``: the felt location moves linearly from one to the other over the event, the
    sign of ``to - from`` giving the direction; rendered with the law, so the motion is
    felt between the motors).

    Attributes:
        at_ms: start, milliseconds from the pattern's start.
        duration_ms: how long it lasts (a transient's pulse length).
        intensity: peak intensity in [0, 1].
        envelope: ``((t_ms, gain), ...)`` from the event's start, gains in [0, 1],
            linear between points, held before the first and after the last; empty:
            a flat 1.
        transient: an impulse (AHAP's HapticTransient, a .haptic emphasis).
        sharpness: AHAP's HapticSharpness, kept for export (a belt cannot show it).
    """

    at_ms: float
    duration_ms: float
    intensity: float = 1.0
    tactor: int | None = None
    angle_deg: float | None = None
    path: tuple[float, float] | None = None
    envelope: tuple[tuple[float, float], ...] = ()
    transient: bool = False
    sharpness: float | None = None

    @property
    def end_ms(self) -> float:
        return self.at_ms + self.duration_ms

    @property
    def place(self) -> str:
        """``tactor``, ``angle`` or ``path``."""
        return "tactor" if self.tactor is not None else "angle" if self.path is None else "path"


@dataclass(frozen=True)
class Pattern:
    """A haptic pattern (see the module docstring and docs/patterns.md).

    Attributes:
        events: the events, by start time.
        name: a name for people.
        layout_deg: the places of ``tactor`` events (angles, degrees); empty when no event
            names a tactor.
        law: the amplitude law for angles and paths (None: the player's, ``paper``).
        duration_ms: the pattern's length (at least the last event's end).
        source: where it came from (``{"format": "ahap", "file": ..., "dropped": [...]}``).
    """

    events: tuple[Event, ...]
    name: str = ""
    layout_deg: tuple[float, ...] = ()
    law: str | None = None
    duration_ms: float = 0.0
    source: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        end = max((e.end_ms for e in self.events), default=0.0)
        if self.duration_ms < end:
            object.__setattr__(self, "duration_ms", end)
        object.__setattr__(self, "events", tuple(sorted(self.events, key=lambda e: e.at_ms)))

    @property
    def duration_s(self) -> float:
        return self.duration_ms / 1000.0

    @property
    def dropped(self) -> list[str]:
        """What the import could not carry over (said on the terminal)."""
        return list(self.source.get("dropped", ()))


def imported(events: list[Event], path: str | None, fmt: str, dropped: list[str], *,
             meta: Any = None, name_keys: tuple[str, ...] = (), layout_deg: tuple[float, ...] = (),
             duration_ms: float = 0.0, angle_deg: float | None = None) -> Pattern:
    """The pattern an import made: named by the first of ``name_keys`` its ``meta`` dict
    holds (else the file's stem), its ``source`` saying the format, the file, the angle it
    was placed at (AHAP, ``.haptic``) and what was ``dropped`` (in that order)."""
    meta = meta if isinstance(meta, dict) else {}
    name = next((str(meta[k]) for k in name_keys if meta.get(k)), Path(path).stem if path else "")
    source: dict[str, Any] = {"format": fmt, "file": Path(path).name if path else ""}
    if angle_deg is not None:
        source["angle_deg"] = angle_deg
    source["dropped"] = list(dropped)
    return Pattern(tuple(events), name, layout_deg, None, duration_ms, source)


# -- reading ---------------------------------------------------------------------------------
class _Reader:
    """Checks one JSON document, naming the file and field of every refusal."""

    def __init__(self, path: str | None) -> None:
        self.path = path

    def fail(self, where: str, message: str) -> PatternFileError:
        return PatternFileError(message, path=self.path, field=where or None)

    def obj(self, value: Any, where: str) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.fail(where, f"must be a JSON object, got {_kind(value)}")
        return value

    def array(self, value: Any, where: str) -> list[Any]:
        if not isinstance(value, list):
            raise self.fail(where, f"must be a JSON array, got {_kind(value)}")
        return value

    def need(self, d: Mapping[str, Any], key: str, where: str) -> Any:
        if key not in d:
            raise self.fail(where, f"missing key {key!r}")
        return d[key]

    def number(self, value: Any, where: str, lo: float | None = None,
               hi: float | None = None, lo_open: bool = False) -> float:
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.fail(where, f"must be a number, got {_kind(value)}")
        x = float(value)
        if not math.isfinite(x):
            raise self.fail(where, f"must be finite, got {value!r}")
        if lo is not None and (x < lo or (lo_open and x == lo)):
            rng = f"> {lo:g}" if lo_open else f">= {lo:g}"
            raise self.fail(where, f"must be {rng}" + (f" and <= {hi:g}" if hi is not None
                                                       else "") + f", got {value!r}")
        if hi is not None and x > hi:
            raise self.fail(where, f"must be in [{lo:g}, {hi:g}], got {value!r}")
        return x

    def unit(self, value: Any, where: str) -> float:
        return self.number(value, where, 0.0, 1.0)

    def string(self, value: Any, where: str) -> str:
        if not isinstance(value, str):
            raise self.fail(where, f"must be a string, got {_kind(value)}")
        return value


def _kind(value: Any) -> str:
    if value is None:
        return "null"
    return {bool: "a boolean", int: "a number", float: "a number", str: "a string",
            list: "an array", dict: "an object"}.get(type(value), type(value).__name__)


_EVENT_KEYS: Final = frozenset({"at_ms", "duration_ms", "intensity", "tactor", "angle_deg",
                                "path", "envelope", "transient", "sharpness"})
_TOP_KEYS: Final = frozenset({"format", "name", "layout_deg", "law", "duration_ms", "events",
                              "source"})


def pattern_from_dict(doc: Any, path: str | None = None) -> Pattern:
    """Check a parsed ``tactorbelt.pattern/1`` document and build the Pattern.

    Raises:
        PatternFileError: a wrong version, a missing or unknown key, a value out of range
            (the message names ``path``, the field and the reason).
    """
    r = _Reader(path)
    top = r.obj(doc, "")
    fmt = r.need(top, "format", "")
    if fmt != FORMAT:
        raise r.fail("format", f"expected {FORMAT!r}, got {fmt!r} (this tactorbelt reads "
                               "version 1 of the pattern format)")
    unknown = sorted(set(top) - _TOP_KEYS)
    if unknown:
        raise r.fail(unknown[0], f"unknown key; allowed: {', '.join(sorted(_TOP_KEYS))}")
    name = r.string(top.get("name", ""), "name")
    layout = tuple(r.number(a, f"layout_deg[{i}]", 0.0, 360.0) % 360.0
                   for i, a in enumerate(r.array(top.get("layout_deg", []), "layout_deg")))
    if len(set(layout)) != len(layout):
        raise r.fail("layout_deg", "two tactors at the same angle")
    law = top.get("law")
    if law is not None and law not in LAWS:
        raise r.fail("law", f"unknown law {law!r}; allowed: {', '.join(LAWS)}")
    duration = r.number(top.get("duration_ms", 0.0), "duration_ms", 0.0)
    source = r.obj(top.get("source", {}), "source")
    events = []
    for i, raw in enumerate(r.array(r.need(top, "events", ""), "events")):
        events.append(_event(r, raw, f"events[{i}]", len(layout)))
    return Pattern(tuple(events), name, layout, law, duration, source)


def _event(r: _Reader, raw: Any, where: str, n_tactors: int) -> Event:
    d = r.obj(raw, where)
    unknown = sorted(set(d) - _EVENT_KEYS)
    if unknown:
        raise r.fail(f"{where}.{unknown[0]}",
                     f"unknown key; allowed: {', '.join(sorted(_EVENT_KEYS))}")
    at = r.number(r.need(d, "at_ms", where), f"{where}.at_ms", 0.0)
    dur = r.number(r.need(d, "duration_ms", where), f"{where}.duration_ms", 0.0, lo_open=True)
    intensity = r.unit(d.get("intensity", 1.0), f"{where}.intensity")
    places = [k for k in ("tactor", "angle_deg", "path") if k in d]
    if len(places) != 1:
        raise r.fail(where, "needs exactly one place: 'tactor', 'angle_deg' or 'path', got "
                            + (", ".join(places) or "none"))
    tactor = angle = path = None
    if "tactor" in d:
        t = d["tactor"]
        if isinstance(t, bool) or not isinstance(t, int):
            raise r.fail(f"{where}.tactor", f"must be an integer, got {_kind(t)}")
        if not 0 <= t < n_tactors:
            raise r.fail(f"{where}.tactor", f"tactor {t} is not in the pattern's layout_deg "
                                            f"({n_tactors} tactors)")
        tactor = t
    elif "angle_deg" in d:
        angle = r.number(d["angle_deg"], f"{where}.angle_deg") % 360.0
    else:
        p = r.obj(d["path"], f"{where}.path")
        path = (r.number(r.need(p, "from_deg", f"{where}.path"), f"{where}.path.from_deg"),
                r.number(r.need(p, "to_deg", f"{where}.path"), f"{where}.path.to_deg"))
    env: list[tuple[float, float]] = []
    for j, pt in enumerate(r.array(d.get("envelope", []), f"{where}.envelope")):
        pw = f"{where}.envelope[{j}]"
        pair = r.array(pt, pw)
        if len(pair) != 2:
            raise r.fail(pw, "must be [t_ms, gain]")
        t_ms = r.number(pair[0], pw + "[0]", 0.0, dur)
        if env and t_ms < env[-1][0]:
            raise r.fail(pw + "[0]", f"times must not decrease ({t_ms:g} after {env[-1][0]:g})")
        env.append((t_ms, r.unit(pair[1], pw + "[1]")))
    transient = d.get("transient", False)
    if not isinstance(transient, bool):
        raise r.fail(f"{where}.transient", f"must be true or false, got {_kind(transient)}")
    sharp = d.get("sharpness")
    sharpness = None if sharp is None else r.unit(sharp, f"{where}.sharpness")
    return Event(at, dur, intensity, tactor, angle, path, tuple(env), transient, sharpness)


def read_json(path: str | Path) -> Any:
    """Parse a JSON file, refusing with the file and the line of a syntax error."""
    try:
        text = Path(path).read_text(encoding="utf-8-sig")
    except OSError as exc:
        raise PatternFileError(f"cannot read: {exc.strerror or exc}", path=str(path)) from None
    except UnicodeDecodeError:
        raise PatternFileError("not a text (UTF-8) file", path=str(path)) from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise PatternFileError(f"not valid JSON: {exc.msg} at line {exc.lineno}, column "
                               f"{exc.colno}", path=str(path)) from None


# -- writing ---------------------------------------------------------------------------------
def _r(x: float) -> float:
    y = round(float(x), _DECIMALS)
    return int(y) if y == int(y) else y


def pattern_to_dict(pattern: Pattern) -> dict[str, Any]:
    """The JSON document of a pattern (what :func:`pattern_from_dict` reads back)."""
    events = []
    for e in pattern.events:
        d: dict[str, Any] = {"at_ms": _r(e.at_ms), "duration_ms": _r(e.duration_ms),
                             "intensity": _r(e.intensity)}
        if e.tactor is not None:
            d["tactor"] = e.tactor
        elif e.path is not None:
            d["path"] = {"from_deg": _r(e.path[0]), "to_deg": _r(e.path[1])}
        else:
            assert e.angle_deg is not None
            d["angle_deg"] = _r(e.angle_deg)
        if e.envelope:
            d["envelope"] = [[_r(t), _r(g)] for t, g in e.envelope]
        if e.transient:
            d["transient"] = True
        if e.sharpness is not None:
            d["sharpness"] = _r(e.sharpness)
        events.append(d)
    doc: dict[str, Any] = {"format": FORMAT, "name": pattern.name}
    if pattern.layout_deg:
        doc["layout_deg"] = [_r(a) for a in pattern.layout_deg]
    if pattern.law is not None:
        doc["law"] = pattern.law
    doc["duration_ms"] = _r(pattern.duration_ms)
    if pattern.source:
        doc["source"] = dict(pattern.source)
    doc["events"] = events
    return doc


def save_pattern(pattern: Pattern, path: str | Path) -> Path:
    """Write a pattern as ``tactorbelt.pattern/1`` JSON (indented, UTF-8)."""
    out = Path(path)
    text = json.dumps(pattern_to_dict(pattern), indent=1)
    text = _PAIR.sub(r"[\1, \2]", text)  # an envelope point on one line
    out.write_text(text + "\n", encoding="utf-8")
    return out


_PAIR: Final = re.compile(r"\[\s*(-?[0-9][0-9.eE+-]*),\s*(-?[0-9][0-9.eE+-]*)\s*\]")

