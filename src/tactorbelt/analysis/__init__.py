"""Analysis of session stores: tables, statistics, figures and the HTML report.

- :func:`analyze` (``report``): stores in, report.html / summary.json /
  per_target.csv / PNGs out; returns a :class:`Summary`.
- :func:`summarize` (``stats``): the pure computation behind it.
- :func:`load_stores` (``load``): stores into pandas tables.
- :func:`print_summary_table` (``report``): the headline numbers with rich.

Heavy libraries (pandas, SciPy, statsmodels, matplotlib) load only when one of these
names is first used. Never imports devices, inputs or the window.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .load import load_stores
    from .report import analyze, print_summary_table
    from .stats import Summary, TestResult, summarize

__all__ = ["Summary", "TestResult", "analyze", "load_stores", "print_summary_table",
           "summarize"]

_LAZY = {
    "analyze": ".report",
    "print_summary_table": ".report",
    "summarize": ".stats",
    "Summary": ".stats",
    "TestResult": ".stats",
    "load_stores": ".load",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name], __name__), name)
    raise AttributeError(f"module 'tactorbelt.analysis' has no attribute {name!r}")
