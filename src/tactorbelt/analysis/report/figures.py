"""Figures of the analysis report, as PNG bytes (matplotlib, Agg, 150 dpi).

- ``fig1b.png``: the paper's Fig. 1(B): amplitude of each tactor against direction
  (top), then accuracy and median RT per direction for static and dynamic.
- ``polar.png``: accuracy and mean signed error per direction on polar axes, front at
  the top, clockwise (as the belt is seen from above).
- ``confusion.png``: target-by-response heatmaps, one per condition.
- ``trajectories.png``: cursor paths of a few test trials per condition in the
  response ellipse.
- ``paired.png``: per-participant between-tactor accuracy and median RT, static vs
  dynamic (only with several participants).
- factorial studies (more than one target count, or a load): ``resolution.png``
  (accuracy, information transfer and median RT against the target count, one line
  per condition and load, with 95 % intervals across participants) and
  ``fig1b-N.png``, the paper's Fig. 1(B) for the blocks of N targets;
- studies with a load: ``load.png``, ``secondary.png``, ``tlx.png``
  (:mod:`.tasks_figures`).

Static is always blue and dynamic vermillion (Okabe-Ito, colour-blind safe), with
distinct markers and line styles as well.

Pure apart from matplotlib: figures are built on :class:`matplotlib.figure.Figure`
with the Agg canvas (never pyplot, no display, no files); returns bytes. Imports
NumPy, pandas, matplotlib and tactorbelt.laws.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any, Final

import numpy as np
import pandas as pd

from ...factors import added_factors
from ...geometry import TargetSet
from ...laws import amplitudes
from ..summary import Summary
from ..tables.cells import is_factorial
from ..tables.design import StudyDesign
from ..tables.tables import CONDITIONS, NO_RESPONSE, direction_summary
from ..tables.transfer import ESTIMATOR
from .plot_style import (
    COLORS,
    DPI,
    LINESTYLES,
    MARKERS,
    ON_SHADE,
    TEXT_GREY,
    _figure,
    _mean_ci,
    _no_data,
    _png,
    _style,
    _tactor_color,
)
from .tasks import has_load
from .tasks_figures import load_figure, secondary_figure, tlx_figure

__all__ = [
    "COLORS",
    "DPI",
    "confusion_figure",
    "fig1b",
    "fig1b_per_resolution",
    "make_figures",
    "paired_figure",
    "polar_figure",
    "resolution_figure",
    "trajectory_figure",
]



def _direction_label(deg: float) -> str:
    names = {0.0: "front", 90.0: "right", 180.0: "back", 270.0: "left"}
    name = names.get(round(deg, 6))
    return f"{deg:g}°\n{name}" if name else f"{deg:g}°"


def _on_grid(d: pd.DataFrame, grid: np.ndarray) -> pd.DataFrame:
    """Rows of ``d`` on every target of ``grid`` (NaN where a target has no data).

    Lines then break at targets without data instead of joining across them.
    """
    keys = np.unique(np.round(np.concatenate([grid, d["target_deg"].to_numpy(dtype=float)]), 6))
    out = d.assign(target_deg=np.round(d["target_deg"].to_numpy(dtype=float), 6))
    out = out.drop_duplicates("target_deg").set_index("target_deg").reindex(keys)
    return out.rename_axis("target_deg").reset_index()


def fig1b(design: StudyDesign, directions: pd.DataFrame, *, title: str | None = None) -> bytes:
    """The paper's Fig. 1(B): amplitudes, accuracy and median RT per direction."""
    fig = _figure(9.0, 8.4)
    axes = fig.subplots(3, 1, sharex=True, height_ratios=[1.1, 1.0, 1.0])
    ax_amp, ax_acc, ax_rt = axes
    layout, targets = design.layout, design.targets
    x = np.linspace(0.0, 360.0, 1441)
    amp = amplitudes(layout, x, design.law, design.falloff_deg)
    tg = targets.angles
    on = targets.on_tactor(layout)
    amp_t = amplitudes(layout, tg, design.law, design.falloff_deg)
    for ax in axes:
        for t in tg[on]:
            ax.axvspan(t - 3.0, t + 3.0, color=ON_SHADE, zorder=0, linewidth=0)
    # Hide each curve where it and both neighbours are zero (the off stretch), so the
    # tactors' zero lines do not pile up on the axis.
    pos = amp > 0
    show = pos | np.roll(pos, 1, axis=0) | np.roll(pos, -1, axis=0)
    amp_drawn = np.where(show, amp, np.nan)
    for k in range(layout.n):
        color = _tactor_color(k, layout.n)
        ax_amp.plot(x, amp_drawn[:, k], color=color, linewidth=1.6,
                    label=f"tactor {k} ({layout.angles_deg[k]:g}°)")
        hit = amp_t[:, k] > 0
        ax_amp.plot(tg[hit & on], amp_t[hit & on, k], "o", color=color, markersize=5)
        ax_amp.plot(tg[hit & ~on], amp_t[hit & ~on, k], "o", markerfacecolor="white",
                    markeredgecolor=color, markersize=5)
    ax_amp.set_ylabel("amplitude")
    ax_amp.set_ylim(-0.02, 1.12)
    law = f"{design.law} law" + (f", T = {design.falloff_deg:g}°" if design.law == "paper" else "")
    ax_amp.set_title(f"Amplitude of each tactor against direction ({law}); "
                     "filled: on-tactor target, open: between-tactor target",
                     fontsize=9.5, loc="left")
    ax_amp.legend(fontsize=7.5, ncols=min(layout.n, 6), loc="upper center",
                  bbox_to_anchor=(0.5, -0.04), frameon=False, handlelength=1.5)
    _style(ax_amp)

    for cond in CONDITIONS:
        d = directions.loc[directions["condition"] == cond]
        if d.empty:
            continue
        d = _on_grid(d, tg)
        kw: dict[str, Any] = {
              "color": COLORS[cond], "marker": MARKERS[cond], "linestyle": LINESTYLES[cond],
              "markersize": 4.5, "linewidth": 1.4, "label": cond}
        se = d["accuracy_se"].to_numpy(dtype=float) if "accuracy_se" in d else None
        if se is not None and np.isfinite(se).any():
            acc = d["accuracy"].to_numpy(dtype=float)
            se = np.nan_to_num(se)
            yerr = np.vstack([np.minimum(se, np.nan_to_num(acc)),
                              np.minimum(se, 1.0 - np.nan_to_num(acc))])  # stay in [0, 1]
            ax_acc.errorbar(d["target_deg"], acc, yerr=yerr, capsize=2, elinewidth=0.8, **kw)
        else:
            ax_acc.plot(d["target_deg"], d["accuracy"], **kw)
        ax_rt.plot(d["target_deg"], d["median_rt_s"], **kw)
    if directions.empty:
        _no_data(ax_acc, "no counted test trials")
        _no_data(ax_rt, "no counted test trials")
    elif not directions["median_rt_s"].notna().any():
        _no_data(ax_rt, "no answered trial: every counted trial timed out")
    if not directions["median_rt_s"].notna().any() if len(directions) else True:
        ax_rt.set_ylim(0, 1)
    ax_acc.set_ylabel("accuracy")
    ax_acc.set_ylim(-0.03, 1.05)
    several = "accuracy_se" in directions and np.isfinite(
        directions["accuracy_se"].to_numpy(dtype=float)).any()
    ax_acc.set_title("Recognition accuracy per direction" +
                     (" (bars: SE across participants)" if several else ""),
                     fontsize=9.5, loc="left")
    ax_rt.set_ylabel("median RT (s)")
    ax_rt.set_title("Time from stimulus onset to target acquisition (median)",
                    fontsize=9.5, loc="left")
    ax_rt.set_xlabel("target direction (degrees clockwise from the navel); "
                     "grey bands: on-tactor targets")
    for ax in (ax_acc, ax_rt):
        _style(ax)
        if not directions.empty:
            ax.legend(fontsize=8, loc="lower right", bbox_to_anchor=(1.0, 1.0), ncols=2,
                      frameon=False, borderaxespad=0.1)
    step = 45.0 if targets.m > 12 else 360.0 / max(targets.m, 1)
    ticks = np.arange(0.0, 360.0 + 1e-9, step)
    ax_rt.set_xticks(ticks, [_direction_label(float(t)) for t in ticks], fontsize=8)
    ax_rt.set_xlim(-8, 368 if targets.m > 1 else 360)
    ax_rt.set_xticks(tg, minor=True)
    if title:
        fig.suptitle(title, fontsize=11)
    return _png(fig)


def polar_figure(directions: pd.DataFrame, targets: np.ndarray | None = None) -> bytes:
    """Accuracy and mean signed error per direction, front up, clockwise."""
    fig = _figure(9.0, 5.2)
    ax_acc: Any = fig.add_subplot(1, 2, 1, projection="polar")
    ax_err: Any = fig.add_subplot(1, 2, 2, projection="polar")
    emax = 10.0
    grid = np.asarray([] if targets is None else targets, dtype=float)
    for cond in CONDITIONS:
        d = directions.loc[directions["condition"] == cond]
        if d.empty:
            continue
        d = _on_grid(d, grid)
        th = np.deg2rad(np.append(d["target_deg"].to_numpy(), d["target_deg"].iloc[0]))
        acc = np.append(d["accuracy"].to_numpy(), d["accuracy"].iloc[0])
        kw: dict[str, Any] = {
              "color": COLORS[cond], "marker": MARKERS[cond], "linestyle": LINESTYLES[cond],
              "markersize": 3.5, "linewidth": 1.3, "label": cond}
        ax_acc.plot(th, acc, **kw)
        e = d[["target_deg", "mean_signed_error_deg"]]
        if e["mean_signed_error_deg"].notna().any():
            the = np.deg2rad(np.append(e["target_deg"].to_numpy(), e["target_deg"].iloc[0]))
            err = np.append(e["mean_signed_error_deg"].to_numpy(),
                            e["mean_signed_error_deg"].iloc[0])
            emax = max(emax, float(np.nanmax(np.abs(err))))
            ax_err.plot(the, err, **kw)
    lim = float(np.ceil(emax / 5.0) * 5.0)
    for ax in (ax_acc, ax_err):
        ax.set_theta_zero_location("N")
        ax.set_theta_direction(-1)
        ax.set_thetagrids(np.arange(0, 360, 45),
                          ["front", "45°", "right", "135°", "back", "225°", "left", "315°"],
                          fontsize=8)
        ax.tick_params(axis="y", labelsize=7, colors=TEXT_GREY)
    ax_acc.set_ylim(0, 1)
    ax_acc.set_rticks([0.25, 0.5, 0.75, 1.0])
    ax_acc.set_title("Accuracy per direction\n(radius: proportion correct)", fontsize=10, pad=14)
    ax_err.set_ylim(-lim, lim)
    ax_err.set_rticks([-lim, -lim / 2, 0, lim / 2, lim],
                      [f"{-lim:g}°", f"{-lim / 2:g}°", "0°", f"+{lim / 2:g}°", f"+{lim:g}°"])
    zero = np.linspace(0, 2 * np.pi, 200)
    ax_err.plot(zero, np.zeros_like(zero), color="black", linewidth=0.9, zorder=1)
    ax_err.set_title("Mean signed error per direction\n(black circle: 0; outward: clockwise)",
                     fontsize=10, pad=14)
    if len(directions) and not directions["mean_signed_error_deg"].notna().any():
        ax_err.text(0.5, 0.3, "no answered trial", transform=ax_err.transAxes, ha="center",
                    color=TEXT_GREY, fontsize=10)
    if directions.empty:
        _no_data(ax_acc, "no counted test trials")
    else:
        handles, labels = ax_acc.get_legend_handles_labels()
        fig.legend(handles, labels, loc="outside lower center", ncols=2, fontsize=9,
                   frameon=False)
    return _png(fig)


def confusion_figure(confusion: dict[str, pd.DataFrame], on_tactor: set[float]) -> bytes:
    """Target-by-response heatmaps (row proportions), one panel per condition."""
    fig = _figure(11.0, 5.6)
    axes = fig.subplots(1, len(CONDITIONS), sharey=True)
    im = None
    for ax, cond in zip(axes, CONDITIONS, strict=True):
        m = confusion.get(cond)
        if m is None or m.to_numpy().sum() == 0:
            _no_data(ax, f"no {cond} test trials")
            ax.set_xticks([])
            ax.set_yticks([])
            ax.set_title(cond, color=COLORS[cond], fontsize=11, fontweight="bold")
            continue
        counts = m.to_numpy(dtype=float)
        rows = counts.sum(axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            prop = np.where(rows > 0, counts / rows, np.nan)
        im = ax.imshow(prop, cmap="cividis", vmin=0, vmax=1, aspect="auto",
                       interpolation="nearest")
        targets = [float(t) for t in m.index]
        cols = list(m.columns)
        every = max(1, len(targets) // 12)
        ax.set_xticks(range(len(cols)),
                      [("none" if c == NO_RESPONSE else
                        (f"{float(c):g}" if i % every == 0 else "")) for i, c in enumerate(cols)],
                      fontsize=7, rotation=90)
        ax.set_yticks(range(len(targets)),
                      [f"{t:g}" if i % every == 0 else "" for i, t in enumerate(targets)],
                      fontsize=7)
        for lab, t in zip(ax.get_yticklabels(), targets, strict=False):
            if round(t, 6) in on_tactor:
                lab.set_fontweight("bold")
        ax.axvline(len(cols) - 1.5, color="white", linewidth=1.5)
        ax.set_xlabel("response (selected target, deg)")
        ax.set_title(f"{cond} (n = {int(counts.sum())})", color=COLORS[cond], fontsize=11,
                     fontweight="bold")
    axes[0].set_ylabel("target (deg; bold = on-tactor)")
    if im is not None:
        cb = fig.colorbar(im, ax=list(axes), shrink=0.85)
        cb.set_label("proportion of the target's trials")
    fig.suptitle("Confusion matrices: target by response (rows sum to 1; last column: "
                 "timed out)", fontsize=10.5)
    return _png(fig)


def trajectory_figure(samples: pd.DataFrame, trials: pd.DataFrame,
                      design: StudyDesign) -> bytes:
    """Cursor paths of a few trials per condition in the response ellipse.

    Args:
        samples: ``store, trial_id, t_s, x, y`` of the chosen trials.
        trials: the chosen trials (``store, trial_id, condition, target_deg,
            response_target_deg, participant``).
        design: for the target positions.
    """
    fig = _figure(9.0, 4.9)
    axes = fig.subplots(1, len(CONDITIONS))
    tg = design.targets.angles
    on = design.targets.on_tactor(design.layout)
    ring = np.linspace(0, 2 * np.pi, 361)
    rad = np.deg2rad(tg)
    for ax, cond in zip(axes, CONDITIONS, strict=True):
        ax.plot(np.sin(ring), np.cos(ring), color="#888888", linewidth=1.0)
        ax.plot(np.sin(rad[on]) * 1.08, np.cos(rad[on]) * 1.08, "o", color="#444444",
                markersize=5, linestyle="none", label="on-tactor target")
        ax.plot(np.sin(rad[~on]) * 1.08, np.cos(rad[~on]) * 1.08, "o",
                markerfacecolor="white", markeredgecolor="#444444", markersize=5,
                linestyle="none", label="between-tactor target")
        ax.plot([0], [0], "+", color="black", markersize=8)
        sel = trials.loc[trials["condition"] == cond]
        drawn = 0
        for _, tri in sel.iterrows():  # a handful of trials, not per-sample
            s = samples.loc[(samples["store"] == tri["store"])
                            & (samples["trial_id"] == tri["trial_id"])]
            if s.empty:
                continue
            drawn += 1
            ax.plot(s["x"], s["y"], color=COLORS[cond], linewidth=1.2, alpha=0.85,
                    linestyle=LINESTYLES[cond])
            ax.plot(s["x"].iloc[-1], s["y"].iloc[-1], MARKERS[cond], color=COLORS[cond],
                    markersize=4)
            t = np.deg2rad(float(tri["target_deg"]))
            ax.plot(np.sin(t) * 1.08, np.cos(t) * 1.08, "*", color=COLORS[cond],
                    markersize=11, markeredgecolor="black", markeredgewidth=0.4)
        if drawn == 0:
            ax.text(0.5, 0.62, f"no {cond} trial\nwith cursor samples", transform=ax.transAxes,
                    ha="center", va="center", color=TEXT_GREY, fontsize=10)
        ax.set_aspect("equal")
        ax.set_xlim(-1.3, 1.3)
        ax.set_ylim(-1.3, 1.3)
        ax.set_xticks([-1, 0, 1])
        ax.set_yticks([-1, 0, 1])
        ax.tick_params(labelsize=7)
        ax.set_xlabel("x (ellipse radii; + = right)", fontsize=8)
        ax.set_ylabel("y (ellipse radii; + = front)", fontsize=8)
        who = sorted(sel["participant"].astype(str).unique().tolist())
        ax.set_title(f"{cond}: {drawn} trial(s)" + (f", {', '.join(who[:2])}" if drawn else "")
                     + "\n★ = target shown", fontsize=9.5, color=COLORS[cond])
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles[:2], labels[:2], loc="outside lower center", ncols=2, fontsize=8,
               frameon=False)
    fig.suptitle("Cursor trajectories of sample test trials (normalised ellipse, front up)",
                 fontsize=10.5)
    return _png(fig)


def paired_figure(per_participant: pd.DataFrame) -> bytes:
    """Per-participant between-tactor accuracy and median RT, static vs dynamic."""
    from matplotlib.collections import LineCollection

    fig = _figure(8.0, 4.4)
    axes = fig.subplots(1, 2)
    b = per_participant.loc[per_participant["kind"] == "between_tactor"]
    for ax, col, label in ((axes[0], "accuracy", "between-tactor accuracy"),
                           (axes[1], "median_rt_s", "between-tactor median RT (s)")):
        w = b.pivot(index="participant", columns="condition", values=col)
        w = w.reindex(columns=list(CONDITIONS)).dropna()
        _style(ax)
        if w.empty:
            _no_data(ax, "no participant has both conditions")
            ax.set_ylabel(label)
            continue
        n = len(w)
        rng = np.random.default_rng(0)
        jit = rng.uniform(-0.06, 0.06, (n, 2))
        xs = np.array([0.0, 1.0]) + jit
        ys = w.to_numpy(dtype=float)
        segs = np.stack([np.column_stack([xs[:, 0], ys[:, 0]]),
                         np.column_stack([xs[:, 1], ys[:, 1]])], axis=1)
        alpha = float(np.clip(4.0 / np.sqrt(n), 0.04, 0.6))
        ax.add_collection(LineCollection(list(segs), colors="#777777", linewidths=0.8,
                                         alpha=alpha))
        for i, cond in enumerate(CONDITIONS):
            ax.scatter(xs[:, i], ys[:, i], s=14 if n < 100 else 4, color=COLORS[cond],
                       marker=MARKERS[cond], alpha=min(1.0, alpha + 0.2), zorder=3,
                       linewidths=0)
            m, half = _mean_ci(ys[:, i])
            ax.errorbar([i + (0.22 if i else -0.22)], [m], yerr=[half], fmt=MARKERS[cond],
                        color=COLORS[cond], markersize=8, capsize=4, linewidth=2, zorder=4,
                        markeredgecolor="black")
        ax.plot([-0.22, 1.22], ys.mean(axis=0), color="black", linewidth=1.5, zorder=3)
        ax.set_xticks([0, 1], list(CONDITIONS))
        for tick, cond in zip(ax.get_xticklabels(), CONDITIONS, strict=True):
            tick.set_color(COLORS[cond])
            tick.set_fontweight("bold")
        ax.set_xlim(-0.5, 1.5)
        ax.set_ylabel(label)
        if col == "accuracy":
            ax.set_ylim(-0.03, 1.03)
        ax.set_title(f"{n} participant(s); large markers: mean ± 95 % CI (t)", fontsize=9)
    fig.suptitle("Per-participant between-tactor performance (lines join one participant)",
                 fontsize=10.5)
    return _png(fig)


LOAD_STYLES: Final = ("-", ":", "-.", (0, (5, 1)), (0, (3, 1, 1, 1, 1, 1)))


def _with_variant(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with ``_variant``: what besides the condition and the target count
    tells its cells apart (``load nback2``, ``load none, posture standing``: the columns
    that vary)."""
    keys = ["load", *(f.column for f in added_factors() if f.column in frame)]
    keys = [k for k in keys if frame[k].nunique(dropna=False) > 1] or ["load"]
    out = frame.copy()
    out["_variant"] = [", ".join(f"{k} {v}" for k, v in zip(keys, row, strict=True))
                       for row in frame[keys].itertuples(index=False)] if len(frame) else []
    return out


def resolution_figure(participant_cells: pd.DataFrame, cells: pd.DataFrame) -> bytes:
    """Accuracy, information transfer and median RT against the number of targets.

    One line per condition (and per load, by line style); each point is the mean over
    participants of their per-cell value. Accuracy and RT bars: the 95 % t interval of
    that mean (no bar with one participant). Information transfer: each participant's
    estimate from their confusion matrix of the cell
    (:func:`tactorbelt.analysis.tables.transfer.estimate_transfer`), averaged; its bars are
    the cell's bootstrap interval (``it_bits_ci_low``/``it_bits_ci_high`` of ``cells``,
    :func:`tactorbelt.analysis.tables.transfer.cell_interval`), drawn with one participant
    too. The dotted grey line is the most a cell can carry, log2(targets).
    """
    fig = _figure(11.5, 4.2)
    axes = fig.subplots(1, 3)
    # a line per condition and variant: the load and the levels of any declared factor
    cells, pc = _with_variant(cells), _with_variant(participant_cells)
    loads = list(dict.fromkeys(cells["_variant"].tolist())) if len(cells) else ["none"]
    counts = sorted({int(n) for n in cells["n_targets"].tolist()})
    n_part = int(pc["participant"].nunique()) if len(pc) else 0
    specs = (("accuracy", "accuracy"),
             ("it_bits", f"information transfer (bits, {ESTIMATOR})"),
             ("median_rt_s", "median RT (s)"))
    # lines side by side (0.5 target apart) so that their bars do not hide each other
    lines = [(c, ld) for c in CONDITIONS for ld in loads]
    dodge = {key: 0.5 * (i - (len(lines) - 1) / 2) for i, key in enumerate(lines)}
    for ax, (col, label) in zip(axes, specs, strict=True):
        _style(ax)
        for cond in CONDITIONS:
            for li, load in enumerate(loads):
                sel = pc.loc[(pc["condition"] == cond) & (pc["_variant"] == load)]
                if sel.empty:
                    continue
                xs: list[float] = []
                ms, lo, hi = [], [], []
                for n in counts:
                    v = sel.loc[sel["n_targets"] == n, col].to_numpy(dtype=float)
                    if v.size == 0:
                        continue
                    m, h = _mean_ci(v)
                    down, up = h, h
                    c = cells.loc[(cells["condition"] == cond) & (cells["_variant"] == load)
                                  & (cells["n_targets"] == n)]
                    if col == "it_bits" and len(c):
                        m = float(c["it_bits"].iloc[0])
                        ci = c[["it_bits_ci_low", "it_bits_ci_high"]].iloc[0].to_numpy(float)
                        down, up = ((max(0.0, m - ci[0]), max(0.0, ci[1] - m))
                                    if np.isfinite(ci).all() else (0.0, 0.0))
                    xs.append(n + dodge[(cond, load)])
                    ms.append(m)
                    lo.append(down)
                    hi.append(up)
                name = cond if len(loads) == 1 else f"{cond}, {load}"
                ax.errorbar(xs, ms, yerr=[lo, hi], color=COLORS[cond], marker=MARKERS[cond],
                            linestyle=LOAD_STYLES[li % len(LOAD_STYLES)] if len(loads) > 1
                            else LINESTYLES[cond], capsize=3, linewidth=1.5, markersize=5,
                            label=name)
        if col == "it_bits" and counts:
            ax.plot(counts, np.log2(counts), color="#999999", linestyle=":", linewidth=1,
                    label="log2(targets)")
            ax.set_ylim(bottom=0)
        if col == "accuracy":
            ax.set_ylim(-0.03, 1.03)
        if col == "median_rt_s" and not np.isfinite(pc[col].to_numpy(dtype=float)).any():
            _no_data(ax, "no answered trial")
        ax.set_xticks(counts, [f"{n}\n{360 / n:g}°" for n in counts], fontsize=8)
        ax.set_xlabel("targets (spacing)")
        ax.set_ylabel(label)
        if pc.empty:
            _no_data(ax, "no counted test trials")
    axes[0].legend(fontsize=7.5, frameon=False, loc="lower left")
    axes[1].legend(fontsize=7.5, frameon=False, loc="upper left")
    bars = ("accuracy and RT bars: 95 % t interval across participants; " if n_part > 1
            else "one participant: no accuracy or RT bars; ")
    what = ("participants and their trials resampled" if n_part > 1
            else "trials resampled within each target")
    fig.suptitle(f"Performance against target resolution ({n_part} participant(s))\n{bars}"
                 f"information-transfer bars: 95 % bootstrap interval ({what})", fontsize=10)
    return _png(fig)


def fig1b_per_resolution(design: StudyDesign, trials: pd.DataFrame) -> dict[str, bytes]:
    """The paper's Fig. 1(B) for each target count: ``fig1b-N.png`` -> PNG bytes.

    ``trials`` are the prepared trials (with ``n_targets``); a figure pools the loads
    of its target count.
    """
    out: dict[str, bytes] = {}
    counted = trials.loc[trials["counted"]]
    for n in sorted({int(v) for v in counted["n_targets"].tolist()}):
        sub = trials.loc[trials["n_targets"] == n]
        d = replace(design, targets=TargetSet.even(n))
        out[f"fig1b-{n}.png"] = fig1b(d, direction_summary(sub),
                                      title=f"{n} targets ({360 / n:g}° apart)")
    return out


def make_figures(summary: Summary, samples: pd.DataFrame | None = None,
                 sample_trials: pd.DataFrame | None = None) -> dict[str, bytes]:
    """Every figure of the report: file name -> PNG bytes.

    Args:
        summary: what :func:`~tactorbelt.analysis.summary.summarize` returned.
        samples, sample_trials: cursor samples and the trials they belong to (the
            trajectory figure is left out when None).
    """
    on = {round(float(t), 6) for t, o in zip(summary.design.targets.angles_deg,
                                               summary.design.targets.on_tactor(
                                                   summary.design.layout), strict=True) if o}
    on |= {round(float(t), 6) for t in
           summary.trials.loc[summary.trials["on_tactor"], "target_deg"].unique()}
    figs = {
        "fig1b.png": fig1b(summary.design, summary.directions),
        "polar.png": polar_figure(summary.directions, summary.design.targets.angles),
        "confusion.png": confusion_figure(summary.confusion, on),
    }
    if samples is not None and sample_trials is not None:
        figs["trajectories.png"] = trajectory_figure(samples, sample_trials, summary.design)
    if summary.counts.get("participants_with_test_trials", 0) >= 2:
        figs["paired.png"] = paired_figure(summary.per_participant)
    if is_factorial(summary.cells) and summary.participant_cells is not None:
        assert summary.cells is not None
        figs["resolution.png"] = resolution_figure(summary.participant_cells, summary.cells)
        figs.update(fig1b_per_resolution(summary.design, summary.trials))
    if has_load(summary):  # load.png, secondary.png and tlx.png (.tasks_figures)
        pc = summary.participant_cells
        if pc is not None and len(pc) and pc["load"].nunique() > 1:
            figs["load.png"] = load_figure(pc)
        if summary.secondary_tasks is not None:
            figs["secondary.png"] = secondary_figure(summary.secondary_tasks["rows"])
        if summary.tlx is not None:
            figs["tlx.png"] = tlx_figure(summary.tlx)
    return figs
