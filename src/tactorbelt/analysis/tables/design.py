"""The study design an analysis needs (layout, targets, amplitude law), from study TOML.

The store keeps each session's study file text (``sessions.study_toml``). This module
reads the parts the figures need, defensively: a text that cannot be parsed, or a
section that is missing or out of range, falls back to the paper's defaults (6 evenly
spaced tactors, 24 targets, the paper law with T = 15) and says so in
:attr:`StudyDesign.fallbacks`.

Pure: imports tomllib, tactorbelt.geometry and tactorbelt.laws only.
"""

from __future__ import annotations

import math
import tomllib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from ..._errors import ConfigError
from ...geometry import Layout, TargetSet
from ...laws import DEFAULT_FALLOFF_DEG, LAWS

__all__ = ["StudyDesign", "parse_design"]


@dataclass(frozen=True)
class StudyDesign:
    """Layout, targets and amplitude law of a study.

    Attributes:
        layout: the tactor layout.
        targets: the candidate targets.
        law: the amplitude law name.
        falloff_deg: T of the paper law.
        fallbacks: what was not found in the study text and was taken from the
            paper's defaults (empty when everything was read).
    """

    layout: Layout
    targets: TargetSet
    law: str = "paper"
    falloff_deg: float = DEFAULT_FALLOFF_DEG
    fallbacks: tuple[str, ...] = field(default=())


def _section(data: dict[str, Any], name: str) -> dict[str, Any]:
    sec = data.get(name)
    return sec if isinstance(sec, dict) else {}


def _first(sec: dict[str, Any], *keys: str) -> Any:
    for k in keys:
        if k in sec:
            return sec[k]
    return None


def _angles_or_count(data: dict[str, Any], fallbacks: list[str], name: str,
                     angle_keys: tuple[str, ...], count_keys: tuple[str, ...],
                     from_angles: Callable[[list[Any]], Any], even: Callable[[int], Any],
                     errors: type[Exception] | tuple[type[Exception], ...], default: Any) -> Any:
    """Section ``name`` (``layout``, ``targets``) from its angles (a list) or its count (an
    int); else ``default``, and in ``fallbacks`` why."""
    sec = _section(data, name)
    angles, count = _first(sec, *angle_keys), _first(sec, *count_keys)
    try:
        if isinstance(angles, list):
            return from_angles(angles)
        if isinstance(count, int) and not isinstance(count, bool):
            return even(count)
    except errors as exc:
        fallbacks.append(f"[{name}] unusable ({exc})")
    if data and not any(name in f for f in fallbacks):
        fallbacks.append(f"[{name}] not found")
    return default


def parse_design(study_toml: str | None) -> StudyDesign:
    """Read layout, targets and law from a study TOML text, falling back to the paper's.

    Reads ``[layout] tactors`` or ``angles_deg`` (also ``angles``, ``count``),
    ``[targets] count`` (or ``angles_deg``) and ``[stimulus] law``, ``falloff_deg``
    (or ``falloff``).
    """
    fallbacks: list[str] = []
    data: dict[str, Any] = {}
    if study_toml is None or not str(study_toml).strip():
        fallbacks.append("no study text stored")
    else:
        try:
            data = tomllib.loads(str(study_toml))
        except tomllib.TOMLDecodeError as exc:
            fallbacks.append(f"study text is not valid TOML ({exc})")

    layout: Layout = _angles_or_count(
        data, fallbacks, "layout", ("angles_deg", "angles", "tactor_angles"),
        ("tactors", "count", "n"), Layout.from_angles, Layout.even, ConfigError, Layout.even(6))
    targets: TargetSet = _angles_or_count(
        data, fallbacks, "targets", ("angles_deg", "angles"), ("count", "n", "targets"),
        lambda angles: TargetSet(tuple(float(a) for a in angles)), TargetSet.even,
        (ConfigError, TypeError, ValueError), TargetSet.even(24))

    ssec = _section(data, "stimulus")
    law = ssec.get("law", "paper")
    if law not in LAWS:
        if data:
            fallbacks.append(f"[stimulus] law {law!r} unknown")
        law = "paper"
    falloff = _first(ssec, "falloff_deg", "falloff")
    if falloff is None:
        falloff = DEFAULT_FALLOFF_DEG
    elif (isinstance(falloff, bool) or not isinstance(falloff, int | float)
          or not math.isfinite(falloff) or falloff <= 0):
        fallbacks.append(f"[stimulus] falloff {falloff!r} unusable")
        falloff = DEFAULT_FALLOFF_DEG
    return StudyDesign(layout=layout, targets=targets, law=str(law),
                       falloff_deg=float(falloff), fallbacks=tuple(fallbacks))
