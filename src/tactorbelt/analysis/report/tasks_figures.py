"""Figures of a study with cognitive load, as PNG bytes (matplotlib, Agg).

- ``load.png``: localisation accuracy, information transfer and median RT against the
  load level (none first), one line per condition (and target count, by line style),
  means over participants with 95 % t intervals;
- ``secondary.png``: the secondary task's d' (log-linear correction) and hit and
  false-alarm rates by phase (practice, baseline: the task alone; dual: with the
  localisation trials), one grey line per participant, the mean in black;
- ``tlx.png``: raw NASA-TLX per load level, one grey line per participant, the mean
  with its 95 % t interval.

Pure apart from matplotlib (see :mod:`.figures`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Final

import numpy as np
import pandas as pd

from ...tasks import PHASES
from ..tables.tables import CONDITIONS
from ..tables.tasks import load_order
from .plot_style import COLORS, LINESTYLES, MARKERS, _figure, _mean_ci, _no_data, _png, _style

__all__ = ["TASK_FIGURE_CAPTIONS", "TASK_FIGURE_ORDER", "load_figure", "secondary_figure",
           "tlx_figure"]

TASK_FIGURE_ORDER: Final = ("load.png", "secondary.png", "tlx.png")
TASK_FIGURE_CAPTIONS: Final = {
    "load.png": "Localisation under load: accuracy, information transfer (bits, "
                "Chao-Shen bias-corrected, per participant) and median RT against the "
                "load level; one line per condition (and target count). Points are means "
                "over participants, bars their 95 % t intervals.",
    "secondary.png": "The secondary task by phase: d' (log-linear correction, Hautus 1995), "
                     "hit rate and false-alarm rate alone (practice, baseline) and with "
                     "the localisation trials (dual). Grey: one line per participant; "
                     "black: the mean.",
    "tlx.png": "Raw NASA-TLX (mean of the six items, 0-100) per load level. Grey: one "
               "line per participant; black: the mean with its 95 % t interval.",
}
_COUNT_STYLES: Final = ("-", "--", ":", "-.")


def load_figure(participant_cells: pd.DataFrame) -> bytes:
    """Accuracy, information transfer and median RT against the load level."""
    pc = participant_cells
    fig = _figure(11.5, 4.2)
    axes = fig.subplots(1, 3)
    loads = load_order([str(v) for v in pc["load"].tolist()]) if len(pc) else ["none"]
    counts = sorted({int(n) for n in pc["n_targets"].tolist()}) if len(pc) else []
    x = np.arange(len(loads))
    n_part = int(pc["participant"].nunique()) if len(pc) else 0
    specs = (("accuracy", "accuracy"), ("it_bits", "information transfer (bits)"),
             ("median_rt_s", "median RT (s)"))
    for ax, (col, label) in zip(axes, specs, strict=True):
        _style(ax)
        for cond in CONDITIONS:
            for ci, n in enumerate(counts):
                sel = pc.loc[(pc["condition"] == cond) & (pc["n_targets"] == n)]
                if sel.empty:
                    continue
                xs, ms, hs = [], [], []
                for i, lv in enumerate(loads):
                    v = sel.loc[sel["load"] == lv, col].to_numpy(dtype=float)
                    if v.size == 0:
                        continue
                    m, h = _mean_ci(v)
                    xs.append(float(x[i]))
                    ms.append(m)
                    hs.append(h)
                name = cond if len(counts) == 1 else f"{cond}, {n} targets"
                style = (LINESTYLES[cond] if len(counts) == 1
                         else _COUNT_STYLES[ci % len(_COUNT_STYLES)])
                ax.errorbar(xs, ms, yerr=hs, color=COLORS[cond], marker=MARKERS[cond],
                            linestyle=style, capsize=3, linewidth=1.5, markersize=5,
                            label=name)
        if col == "accuracy":
            ax.set_ylim(-0.03, 1.03)
        ax.set_xticks(x, loads, fontsize=8)
        ax.set_xlim(-0.4, len(loads) - 0.6)
        ax.set_xlabel("load")
        ax.set_ylabel(label)
        if pc.empty:
            _no_data(ax, "no counted test trials")
    axes[0].legend(fontsize=7.5, frameon=False, loc="lower left")
    bars = ("bars: 95 % t interval of the mean across participants" if n_part > 1
            else "one participant: no interval")
    fig.suptitle(f"Localisation against cognitive load ({n_part} participant(s); {bars})",
                 fontsize=10.5)
    return _png(fig)


def _people_and_mean(ax: Any, rows: Sequence[Mapping[str, Any]], at: str, col: str,
                     levels: list[str], **mean_style: Any) -> None:
    """One grey line per participant through their ``col`` at each of ``levels`` (of the
    rows' ``at``), then the mean over participants with its 95 % t interval in black."""
    x = np.arange(len(levels))
    for pid in sorted({str(r["participant"]) for r in rows}):
        vals = {str(r[at]): r[col] for r in rows if str(r["participant"]) == pid}
        ax.plot(x, [np.nan if vals.get(lv) is None else float(vals[lv]) for lv in levels],
                color="#BBBBBB", marker="o", markersize=3, linewidth=0.8)
    means = [_mean_ci(np.array([float(r[col]) for r in rows
                                if r[at] == lv and r[col] is not None], dtype=float))
             for lv in levels]
    ax.errorbar(x, [m for m, _ in means], yerr=[h for _, h in means], color="black",
                marker="s", capsize=3, linewidth=1.6, **mean_style)


def secondary_figure(rows: Sequence[Mapping[str, Any]]) -> bytes:
    """d', hit rate and false-alarm rate of each task by phase (rows of
    :func:`~tactorbelt.analysis.tables.tasks.secondary_task_rows`)."""
    tasks = sorted({str(r["task"]) for r in rows})
    fig = _figure(11.5, 3.6 * max(len(tasks), 1))
    axes = np.atleast_2d(fig.subplots(max(len(tasks), 1), 3))
    specs = (("d_prime", "d' (log-linear)"), ("hit_rate", "hit rate"),
             ("fa_rate", "false-alarm rate"))
    for ti, task in enumerate(tasks or ["(no task)"]):
        sub = [r for r in rows if str(r["task"]) == task]
        phases = [p for p in PHASES if any(r["phase"] == p for r in sub)]
        phases += sorted({str(r["phase"]) for r in sub} - set(phases))
        x = np.arange(len(phases))
        for ax, (col, label) in zip(axes[ti], specs, strict=True):
            _style(ax)
            if not sub:
                _no_data(ax, "no task events")
                continue
            _people_and_mean(ax, sub, "phase", col, phases, markersize=5)
            ax.set_xticks(x, phases, fontsize=8)
            ax.set_xlim(-0.4, len(phases) - 0.6)
            ax.set_ylabel(label)
            ax.set_title(task, fontsize=9)
            if col != "d_prime":
                ax.set_ylim(-0.03, 1.03)
    fig.suptitle("Secondary task: alone (practice, baseline) and with localisation (dual)",
                 fontsize=10.5)
    return _png(fig)


def tlx_figure(tlx: Mapping[str, Any]) -> bytes:
    """Raw TLX per load level (``summary.json["tlx"]``)."""
    fig = _figure(5.5, 4.2)
    ax = fig.subplots(1, 1)
    _style(ax)
    loads = list(tlx.get("loads", []))
    x = np.arange(len(loads))
    if loads:  # no loads: no ratings either
        _people_and_mean(ax, tlx.get("per_participant", []), "load", "raw_tlx", loads)
    else:
        _no_data(ax, "no NASA-TLX ratings")
    ax.set_xticks(x, loads, fontsize=8)
    ax.set_xlim(-0.4, max(len(loads), 1) - 0.6)
    ax.set_ylim(0, 100)
    ax.set_xlabel("load")
    ax.set_ylabel("raw NASA-TLX (0-100)")
    test = tlx.get("test") or {}
    sub = ""
    if test.get("computed"):
        sub = f"\n{test['test']}: p = {float(test['p_value']):.3g}"
    fig.suptitle("Workload per load level" + sub, fontsize=10)
    return _png(fig)
