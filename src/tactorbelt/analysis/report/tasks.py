"""The report's section on cognitive load: localisation by load, the secondary task
(signal detection by phase, dual-task cost) and the NASA-TLX.

Shown only when the study has a load, task events or ratings; otherwise
:func:`load_section` returns ''. Figures come from :mod:`.tasks_figures`.

Pure: builds a string from a Summary and PNG bytes.
"""

from __future__ import annotations

import base64
import html
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

from .formatting import number as _f
from .formatting import p_value as _p
from .formatting import percent as _pct
from .tasks_figures import TASK_FIGURE_CAPTIONS, TASK_FIGURE_ORDER

if TYPE_CHECKING:
    from ..summary import Summary

__all__ = ["has_load", "load_section"]


def has_load(summary: Summary) -> bool:
    """The study has a load other than ``none``, task events or workload ratings."""
    cells = summary.cells
    loads = set() if cells is None or cells.empty else {str(v) for v in cells["load"]}
    return bool(loads - {"none"}) or summary.secondary_tasks is not None or \
        summary.tlx is not None


def _table(head: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    return ('<table class="num"><thead><tr>' + "".join(f"<th>{h}</th>" for h in head)
            + "</tr></thead><tbody>"
            + "".join("<tr>" + "".join(f"<td>{c}</td>" for c in row) + "</tr>" for row in rows)
            + "</tbody></table>")


def _test_text(t: dict[str, Any] | None) -> str:
    if not t:
        return "no test"
    if not t.get("computed"):
        what, why = str(t.get("test") or "test"), str(t.get("reason", ""))
        return f"{html.escape(what)}: not computed ({html.escape(why)})"
    return (f"{html.escape(str(t['test']))}: statistic {_f(t['statistic'])}, "
            f"p = {_p(t['p_value'])}" + (f" ({html.escape(str(t['method']))})"
                                        if t.get("method") else ""))


def load_section(summary: Summary, figures: dict[str, bytes]) -> str:
    """HTML of the cognitive-load results ('' for a study without a load)."""
    if not has_load(summary):
        return ""
    e = html.escape
    parts = ["<h2>Cognitive load</h2>"]
    cells = summary.cells
    if cells is not None and not cells.empty:
        rows = []
        order = sorted(cells.to_dict("records"),
                       key=lambda r: (str(r["load"]) != "none", str(r["load"]),
                                      str(r["condition"]), int(r["n_targets"])))
        for r in order:
            rows.append([e(str(r["load"])), e(str(r["condition"])), str(int(r["n_targets"])),
                         str(int(r["n_participants"])), str(int(r["n"])), _pct(r["accuracy"]),
                         _f(r["it_bits"]), _f(r["median_rt_s"]),
                         _pct(r["accuracy_between_tactor"])])
        parts.append("<h3>Localisation by load</h3>" + _table(
            ["load", "condition", "targets", "participants", "n trials", "accuracy",
             "information transfer (bits)", "median RT (s)", "between-tactor accuracy"], rows))
    st = summary.secondary_tasks
    if st is not None:
        rows = [[e(str(r["task"])), e(str(r["phase"])), str(r["n_participants"]),
                 str(r["items"]), _pct(r["mean_hit_rate"]), _pct(r["mean_fa_rate"]),
                 _pct(r["mean_accuracy"]), _f(r["mean_d_prime"]), _f(r["mean_median_rt_s"])]
                for r in st["by_phase"]]
        parts.append(
            "<h3>Secondary task</h3><p>Practice and baseline: the task alone, before the "
            "first block with its load; dual: the task during the localisation trials. "
            "d' uses the log-linear correction (Hautus 1995): H = (hits + 0.5)/(go + 1), "
            "F = (false alarms + 0.5)/(no-go + 1). Means over participants; RT is the "
            "median RT of the hits (summary.json <code>secondary_tasks</code>).</p>"
            + _table(["task", "phase", "participants", "items", "hit rate",
                      "false-alarm rate", "accuracy", "d'", "median RT (s)"], rows))
        costs = st["dual_task_cost"]
        if costs:
            rows = [[e(str(c["task"])), str(c["n_participants"]),
                     _f(c["mean_accuracy_cost"]), _f(c["mean_d_prime_cost"]),
                     _test_text(c["d_prime_test"])] for c in costs]
            parts.append("<h4>Dual-task cost (baseline minus dual, paired within "
                         "participant)</h4>" + _table(
                             ["task", "participants", "accuracy cost", "d' cost",
                              "test of the d' cost"], rows))
        else:
            parts.append("<p>No dual-task cost: it needs a single-task baseline "
                         "(<code>baseline = N</code> in the task's table) and dual-task "
                         "blocks of the same participants.</p>")
    tlx = summary.tlx
    if tlx is not None:
        rows = [[e(str(r["load"])), str(r["n_participants"]), _f(r["mean_raw_tlx"]),
                 _f(r["sd_raw_tlx"])] for r in tlx["by_load"]]
        parts.append("<h3>Workload (raw NASA-TLX)</h3><p>Raw TLX: the mean of the six "
                     "items (0-100), per participant and load, then over participants "
                     f"({tlx['n_blocks']} rated block(s)). Test across load levels, within "
                     f"participant: {_test_text(tlx['test'])}.</p>"
                     + _table(["load", "participants", "mean raw TLX", "SD"], rows))
    for name in TASK_FIGURE_ORDER:
        if name in figures:
            data = base64.b64encode(figures[name]).decode("ascii")
            parts.append(f'<figure><img src="data:image/png;base64,{data}" alt="{e(name)}">'
                         f"<figcaption>{e(TASK_FIGURE_CAPTIONS[name])} ({e(name)})"
                         "</figcaption></figure>")
    return "".join(parts)
