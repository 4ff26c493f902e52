"""Numbers and stored values as the report shows them (pure; standard library only).

The report's template uses these as filters (:mod:`.html`): ``num``, ``pval`` and
``pct`` in the main tables, ``g3`` and ``p3`` (``number``, ``p_value``) in the factorial
and load sections, ``cell`` for a stored value.
"""

from __future__ import annotations

import base64
import json
import math
from collections.abc import Sequence
from typing import Any

from ..tables._json import finite_float as _num

__all__ = ["cell_text", "figure_view", "finite", "fixed", "joined", "number", "p_value",
           "p_value4", "percent"]


def finite(v: Any) -> bool:
    """``v`` is a finite number."""
    return v is not None and _num(v) is not None


def number(v: Any, digits: int = 3) -> str:
    """``digits`` significant digits; ``n/a`` for a missing or non-finite value."""
    x = _num(v)
    return "n/a" if x is None else f"{x:.{digits}g}"


def percent(v: Any, missing: str = "n/a") -> str:
    """A proportion as a percentage with one decimal; ``missing`` when there is none."""
    x = _num(v)
    return missing if x is None else f"{100 * x:.1f} %"


def p_value(v: Any) -> str:
    """A p-value: ``< 0.001`` below that, else 3 significant digits; ``n/a`` when missing."""
    x = _num(v)
    if x is None:
        return "n/a"
    return "< 0.001" if x < 0.001 else f"{x:.3g}"


def fixed(v: Any, digits: int = 3, missing: str = "n/a") -> str:
    """A number for a table with ``digits`` decimals (``g`` for tiny or huge ones);
    ``missing`` (a word, never NaN) when there is none."""
    x = _num(v)
    if x is None:
        return missing
    f = x + 0.0  # no "-0.000"
    if round(f, digits) == 0:
        f = 0.0
    if f != 0 and (abs(f) < 10 ** -(digits) or abs(f) >= 1e6):
        return f"{f:.{digits}g}"
    return f"{f:.{digits}f}"


def p_value4(v: Any) -> str:
    """A p-value with 4 decimals, ``< 0.0001`` below that; ``n/a`` when missing."""
    x = _num(v)
    if x is None:
        return "n/a"
    return "< 0.0001" if x < 1e-4 else f"{x:.4f}"


def joined(values: Sequence[Any], limit: int = 30) -> str:
    """Values as 'a, b, ...' (at most ``limit``); ``not recorded`` when there are none."""
    if not values:
        return "not recorded"
    return ", ".join(str(v) for v in values[:limit]) + (" ..." if len(values) > limit else "")


def cell_text(v: Any) -> str:
    """A stored value as a reader writes it: no NaN, and a JSON list as 'a, b'."""
    if v is None or (isinstance(v, float) and math.isnan(v)) or str(v) == "<NA>":
        return ""
    text = str(v)
    if text.startswith("["):
        try:
            items = json.loads(text)
        except ValueError:
            return text
        if isinstance(items, list):
            return ", ".join(str(i) for i in items)
    return text


def figure_view(name: str, png: bytes, caption: str) -> dict[str, str]:
    """A figure as the template embeds it: its name, caption and base64 PNG."""
    return {"name": name, "caption": caption, "data": base64.b64encode(png).decode("ascii")}
