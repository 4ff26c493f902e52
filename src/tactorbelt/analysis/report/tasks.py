"""The report's section on cognitive load: localisation by load, the secondary task
(signal detection by phase, dual-task cost) and the NASA-TLX.

Shown only when the study has a load, task events or ratings; otherwise
:func:`load_view` returns None. It gives the template (``templates/report.html.j2``) its
values; the figures come from :mod:`.tasks_figures`.

Pure: plain values from a Summary and PNG bytes.
"""

from __future__ import annotations

from typing import Any

from ..summary import Summary
from .formatting import figure_view
from .formatting import number as _f
from .formatting import p_value as _p
from .tasks_figures import TASK_FIGURE_CAPTIONS, TASK_FIGURE_ORDER

__all__ = ["has_load", "load_view", "test_text"]


def has_load(summary: Summary) -> bool:
    """The study has a load other than ``none``, task events or workload ratings."""
    cells = summary.cells
    loads = set() if cells is None or cells.empty else {str(v) for v in cells["load"]}
    return bool(loads - {"none"}) or summary.secondary_tasks is not None or \
        summary.tlx is not None


def test_text(t: dict[str, Any] | None) -> str:
    """A test of the load section in words (the template's ``test_text`` filter)."""
    if not t:
        return "no test"
    if not t.get("computed"):
        what, why = str(t.get("test") or "test"), str(t.get("reason", ""))
        return f"{what}: not computed ({why})"
    return (f"{t['test']}: statistic {_f(t['statistic'])}, p = {_p(t['p_value'])}"
            + (f" ({t['method']})" if t.get("method") else ""))


def load_view(summary: Summary, figures: dict[str, bytes]) -> dict[str, Any] | None:
    """The cognitive-load results as the template shows them (None for a study without
    a load)."""
    if not has_load(summary):
        return None
    cells = summary.cells
    rows = []
    if cells is not None and not cells.empty:
        rows = [{**r, "n_targets": int(r["n_targets"]), "n_participants": int(r["n_participants"]),
                 "n": int(r["n"])}
                for r in sorted(cells.to_dict("records"),
                                key=lambda r: (str(r["load"]) != "none", str(r["load"]),
                                               str(r["condition"]), int(r["n_targets"])))]
    return {"cells": rows, "secondary": summary.secondary_tasks, "tlx": summary.tlx,
            "figures": [figure_view(n, figures[n], TASK_FIGURE_CAPTIONS[n])
                        for n in TASK_FIGURE_ORDER if n in figures]}
