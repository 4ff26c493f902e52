"""``summary.json`` values: every non-finite float as null (pure; standard library only)."""

from __future__ import annotations

import math
from typing import Any

__all__ = ["finite_json"]


def finite_json(v: Any) -> Any:
    """``v`` with every non-finite float replaced by None (summary.json has no NaN)."""
    if isinstance(v, dict):
        return {k: finite_json(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [finite_json(x) for x in v]
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v
