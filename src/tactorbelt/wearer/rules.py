"""What the wearer profile and its file model (:mod:`.file`) share: the file's format
name and version, and the rule of a warp's knots (:func:`warp_problem`).

Imports only the standard library.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, Final

__all__ = ["EPS", "FORMAT", "VERSION", "warp_problem"]

FORMAT: Final = "tactorbelt-wearer-profile"
VERSION: Final = 1
#: Knots of a warp closer than this (as a fraction of the gap) count as equal.
EPS: Final = 1e-9


def warp_problem(intended: Sequence[Any], rendered: Sequence[Any]) -> tuple[str, str] | None:
    """(field, message) of what is wrong with a warp's knots, or None."""
    for name, values in (("intended", intended), ("rendered", rendered)):
        if not all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                   for v in values):
            return name, f"must be finite numbers, got {list(values)!r}"
    if len(intended) != len(rendered):
        return "rendered", (f"has {len(rendered)} values for {len(intended)} intended "
                            "positions; give one rendered position per intended one")
    for name, values in (("intended", intended), ("rendered", rendered)):
        pts = [0.0, *map(float, values), 1.0]
        for k in range(1, len(pts)):
            if pts[k] <= pts[k - 1] + EPS:
                return name, (f"must increase strictly from 0 to 1 (a monotone warp), got "
                              f"{list(values)!r}")
    return None
