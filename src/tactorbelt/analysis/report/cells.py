"""The report's section on a factorial study: results per cell and their figures.

Shown only when the study has more than one target count or a load
(:func:`~tactorbelt.analysis.tables.cells.is_factorial`); a paper-protocol report does not
change. :func:`cells_section` returns the HTML; the figures are drawn by
:func:`tactorbelt.analysis.report.figures.make_figures` (``resolution.png``, ``fig1b-N.png``).

Pure: builds a string from a Summary and PNG bytes.
"""

from __future__ import annotations

import base64
import html
import math
import re
from typing import TYPE_CHECKING, Any, Final

from ...factors import added_factors
from ..tables.cells import IT_N_BOOT, is_factorial
from ..tables.transfer import ESTIMATOR
from .formatting import number as _fmt
from .formatting import percent as _pct

if TYPE_CHECKING:
    from ..summary import Summary

__all__ = ["CELL_FIGURE_CAPTIONS", "cell_figure_names", "cells_section"]

CELL_FIGURE_CAPTIONS: Final = {
    "resolution.png": "Accuracy, information transfer (bits, from each participant's "
                      f"confusion matrix of the cell, {ESTIMATOR} bias-corrected and clamped "
                      "to [0, log2 targets], then averaged) and median RT against the "
                      "number of targets; one line per condition (and load). Points are "
                      "means over participants; accuracy and RT bars their 95 % t "
                      "intervals, information-transfer bars the 95 % two-level bootstrap "
                      "interval (participants, and trials within each target, resampled; "
                      "expanded percentile).",
    "fig1b": "Fig. 1(B) of the paper for the blocks of {n} targets: amplitude of each "
             "tactor against direction, accuracy and median RT per direction, static vs "
             "dynamic (loads pooled).",
}
_FIG1B = re.compile(r"^fig1b-(\d+)\.png$")


def cell_figure_names(names: Any) -> list[str]:
    """The factorial figures among ``names``, in report order."""
    per = sorted((int(m.group(1)), n) for n in names if (m := _FIG1B.match(n)))
    return (["resolution.png"] if "resolution.png" in names else []) + [n for _, n in per]


def cells_section(summary: Summary, figures: dict[str, bytes]) -> str:
    """HTML of the per-cell results and figures ('' for a study that is not factorial)."""
    cells = summary.cells
    if not is_factorial(cells):
        return ""
    assert cells is not None
    e = html.escape
    added = [f.column for f in added_factors() if f.column in cells]
    head = ["condition", "targets", "load", *added, "participants", "n trials", "accuracy",
            "information transfer, bits [95 % CI]", "median RT (s)", "mean |error| (°)",
            "on-tactor accuracy", "between-tactor accuracy"]
    rows = []
    for r in cells.to_dict("records"):
        it = _fmt(r["it_bits"])
        if math.isfinite(float(r["it_bits_ci_low"])):
            it += f" [{_fmt(r['it_bits_ci_low'])}, {_fmt(r['it_bits_ci_high'])}]"
        rows.append([e(str(r["condition"])), str(int(r["n_targets"])), e(str(r["load"])),
                     *(e(str(r[k])) for k in added), str(int(r["n_participants"])),
                     str(int(r["n"])), _pct(r["accuracy"]),
                     it, _fmt(r["median_rt_s"]), _fmt(r["mean_abs_error_deg"]),
                     _pct(r["accuracy_on_tactor"]) + f" ({int(r['n_on_tactor'])})",
                     _pct(r["accuracy_between_tactor"])
                     + f" ({int(r['n_between_tactor'])})"])
    table = ('<table class="num"><thead><tr>' + "".join(f"<th>{h}</th>" for h in head)
             + "</tr></thead><tbody>"
             + "".join("<tr>" + "".join(f"<td>{c}</td>" for c in row) + "</tr>"
                       for row in rows) + "</tbody></table>")
    parts = [f"<h2>Results by cell ({' x '.join(['condition', 'targets', 'load', *added])})"
             "</h2>", table,
             "<p><small>Accuracy, RT and error pool the cell's trials. Information "
             "transfer is the mean over participants of each one's estimate from their "
             "confusion matrix of the cell: the mutual information between target and "
             f"response with the {e(ESTIMATOR)} bias correction (coverage-adjusted "
             "entropies, Chao &amp; Shen 2003; chosen as the estimator with the smallest "
             "error in a simulation with known truth), clamped to [0, log2 targets] "
             "(no channel carries more, no information is negative). The interval is a "
             f"95 % bootstrap interval of that mean ({IT_N_BOOT} resamples at two levels: "
             "participants resampled, and each one's trials resampled within each "
             "target; Hesterberg's expanded percentile interval, which widens the plain "
             "one for few participants). With few trials per target the estimate is "
             "still biased "
             "upwards, most for diffuse answers (summary.json <code>cells</code>; "
             "docs/analysis.md).</small></p>"]
    for name in cell_figure_names(figures):
        m = _FIG1B.match(name)
        cap = (CELL_FIGURE_CAPTIONS["fig1b"].format(n=m.group(1)) if m
               else CELL_FIGURE_CAPTIONS[name])
        data = base64.b64encode(figures[name]).decode("ascii")
        parts.append(f'<figure><img src="data:image/png;base64,{data}" alt="{e(name)}">'
                     f"<figcaption>{e(cap)} ({e(name)})</figcaption></figure>")
    return "".join(parts)
