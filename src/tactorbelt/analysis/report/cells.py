"""The report's section on a factorial study: results per cell and their figures.

Shown only when the study has more than one target count or a load
(:func:`~tactorbelt.analysis.tables.cells.is_factorial`); a paper-protocol report does not
change. :func:`cells_view` gives the template (``templates/report.html.j2``) its values;
the figures are drawn by :func:`tactorbelt.analysis.report.figures.make_figures`
(``resolution.png``, ``fig1b-N.png``).

Pure: plain values from a Summary and PNG bytes.
"""

from __future__ import annotations

import math
import re
from typing import Any, Final

from ...factors import added_factors
from ..summary import Summary
from ..tables.cells import IT_N_BOOT, is_factorial
from ..tables.transfer import ESTIMATOR
from .formatting import figure_view

__all__ = ["CELL_FIGURE_CAPTIONS", "cells_view"]

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


def cells_view(summary: Summary, figures: dict[str, bytes]) -> dict[str, Any] | None:
    """The per-cell results and figures as the template shows them (None for a study that
    is not factorial)."""
    cells = summary.cells
    if not is_factorial(cells):
        return None
    assert cells is not None
    added = [f.column for f in added_factors() if f.column in cells]
    rows = [{**r, "n_targets": int(r["n_targets"]), "n_participants": int(r["n_participants"]),
             "n": int(r["n"]), "n_on_tactor": int(r["n_on_tactor"]),
             "n_between_tactor": int(r["n_between_tactor"]),
             "added": [str(r[k]) for k in added],
             "it_ci": math.isfinite(float(r["it_bits_ci_low"]))}
            for r in cells.to_dict("records")]
    # resolution.png, then fig1b-N.png by N
    per = sorted((int(m.group(1)), m.group(1), n) for n in figures if (m := _FIG1B.match(n)))
    shown = [figure_view(n, figures[n], CELL_FIGURE_CAPTIONS[n])
             for n in ("resolution.png",) if n in figures]
    shown += [figure_view(name, figures[name], CELL_FIGURE_CAPTIONS["fig1b"].format(n=n))
              for _, n, name in per]
    return {
        "factors": ["condition", "targets", "load", *added],
        "headers": ["condition", "targets", "load", *added, "participants", "n trials",
                    "accuracy", "information transfer, bits [95 % CI]", "median RT (s)",
                    "mean |error| (°)", "on-tactor accuracy", "between-tactor accuracy"],
        "rows": rows, "estimator": ESTIMATOR, "n_boot": IT_N_BOOT, "figures": shown,
    }
