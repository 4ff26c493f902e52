"""Numbers as the report's section tables show them (pure; standard library only)."""

from __future__ import annotations

import math
from typing import Any

__all__ = ["number", "p_value", "percent"]


def _float(v: Any) -> float | None:
    try:
        x = float(v)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def number(v: Any, digits: int = 3) -> str:
    """``digits`` significant digits; ``n/a`` for a missing or non-finite value."""
    x = _float(v)
    return "n/a" if x is None else f"{x:.{digits}g}"


def percent(v: Any) -> str:
    """A proportion as a percentage with one decimal; ``n/a`` when missing."""
    x = _float(v)
    return "n/a" if x is None else f"{100 * x:.1f} %"


def p_value(v: Any) -> str:
    """A p-value: ``< 0.001`` below that, else 3 significant digits; ``n/a`` when missing."""
    x = _float(v)
    if x is None:
        return "n/a"
    return "< 0.001" if x < 0.001 else f"{x:.3g}"
