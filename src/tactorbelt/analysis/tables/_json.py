"""``summary.json`` values: every non-finite float as null (pure; standard library only)."""

from __future__ import annotations

import math
from typing import Any

__all__ = ["finite_float", "finite_json"]


def finite_float(v: Any) -> float | None:
    """``v`` as a finite float, or None (missing, not a number, or not finite)."""
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def finite_json(v: Any) -> Any:
    """``v`` with every non-finite float replaced by None (summary.json has no NaN)."""
    if isinstance(v, dict):
        return {k: finite_json(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [finite_json(x) for x in v]
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v
