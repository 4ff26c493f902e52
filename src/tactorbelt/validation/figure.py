"""The figures of ``tactorbelt validate onsets`` (every tactor's sensed envelopes) and of
``validate stimulus`` (:func:`stimulus_figure`: felt against intended, per target).

One row per tactor: on the left every pulse's envelope (normalised: 0 the baseline, 1
the steady amplitude) against the time from its command, the 10 % onset (the latency)
marked with a line and its spread over pulses, and the 10-90 % rise shaded; on the right
the same pulses from their stop command, with the 90-10 % fall shaded.

Imports matplotlib (Agg) when called.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .envelope import HIGH, LOW

if TYPE_CHECKING:
    from .run import OnsetValidation
    from .stimulus import StimulusValidation

__all__ = ["onset_figure", "stimulus_figure"]


def _fmt(mean: float | None, sd: float | None) -> str:
    if mean is None:
        return "n/a"
    return f"{mean:.1f}" + ("" if sd is None else f" ± {sd:.1f}") + " ms"


def onset_figure(result: OnsetValidation, path: str | Path) -> Path:
    """Draw ``result`` (see the module docstring) to a PNG at ``path``."""
    from ..figures import _pyplot, save_figure, tactor_colors

    plt = _pyplot()
    from matplotlib.lines import Line2D

    rows = result.tactors
    n = max(1, len(rows))
    fig, axes = plt.subplots(n, 2, figsize=(10, 1.9 * n + 1.0), sharey=True, squeeze=False,
                             gridspec_kw={"width_ratios": [3, 2]})
    colors = tactor_colors(len(result.angles_deg))
    levels = list(result.settings.levels)
    styles = ["-", "--", ":", "-."]
    span_on = result.settings.on_s * 1e3
    plain = {t.tactor: t for t in result.plain.tactors} if result.plain is not None else {}
    for ax_on, ax_off, summary in zip(axes[:, 0], axes[:, 1], rows, strict=False):
        d = summary.to_dict()
        color = colors[summary.tactor]
        before = plain.get(summary.tactor)
        for p in before.pulses if before is not None else ():  # --tune: the plain drive
            ax_on.plot(p.trace_ms, p.trace, color="grey", lw=0.6, alpha=0.35)
            if math.isfinite(p.off_ms):
                ax_off.plot(p.trace_ms - p.off_ms, p.trace, color="grey", lw=0.6, alpha=0.35)
        for p in summary.pulses:
            ls = styles[levels.index(p.level) % len(styles)] if p.level in levels else "-"
            ax_on.plot(p.trace_ms, p.trace, color=color, lw=0.7, alpha=0.45, ls=ls)
            if math.isfinite(p.off_ms):
                ax_off.plot(p.trace_ms - p.off_ms, p.trace, color=color, lw=0.7, alpha=0.45,
                            ls=ls)
        lat, lat_sd, rise = d["latency_ms"], d["latency_sd_ms"], d["rise_ms"]
        if lat is not None:
            ax_on.axvline(lat, color="black", lw=1.0)
            if lat_sd:
                ax_on.axvspan(lat - lat_sd, lat + lat_sd, color="black", alpha=0.12, lw=0)
            if rise is not None:
                ax_on.axvspan(lat, lat + rise, color=color, alpha=0.12, lw=0)
        stop, fall = d["stop_latency_ms"], d["fall_ms"]
        if stop is not None and fall is not None:
            ax_off.axvspan(stop, stop + fall, color=color, alpha=0.12, lw=0)
        for ax in (ax_on, ax_off):
            for y in (LOW, HIGH):
                ax.axhline(y, color="grey", lw=0.6, ls=":")
            ax.axvline(0.0, color="grey", lw=0.8)
            ax.grid(alpha=0.25)
        ax_on.set_xlim(-0.1 * span_on, span_on)
        ax_off.set_xlim(-0.1 * span_on, result.settings.off_s * 1e3)
        angle = result.angles_deg[summary.tactor]
        ax_on.set_title(f"tactor {summary.tactor} ({angle:g} deg): latency "
                        f"{_fmt(lat, lat_sd)}, rise 10-90 % {_fmt(rise, d['rise_sd_ms'])}",
                        fontsize=9, loc="left")
        ax_off.set_title(f"fall 90-10 % {_fmt(fall, d['fall_sd_ms'])}", fontsize=9,
                         loc="left")
        ax_on.set_ylabel("of steady")
    axes[-1, 0].set_xlabel("ms from the command (10 % onset: black line; 10-90 % rise: "
                           "shaded)")
    axes[-1, 1].set_xlabel("ms from the stop command (90-10 % fall: shaded)")
    for ax in axes[:, 0]:
        ax.set_ylim(-0.1, 1.2)
        ax.set_yticks(np.array([0.0, LOW, 0.5, HIGH, 1.0]))
    if len(levels) > 1:
        handles = [Line2D([], [], color="black", lw=0.9, ls=styles[i % len(styles)],
                          label=f"level {x:g}") for i, x in enumerate(levels)]
        axes[0, 1].legend(handles=handles, loc="upper right", fontsize=7, frameon=False)
    lv = ", ".join(f"{x:g}" for x in levels)
    drive = f"drive {result.drive}" + (" (grey: plain, before tuning)" if plain else "")
    fig.suptitle(f"Onset validation of {result.belt} sensed by {result.sensor}, {drive}\n"
                 f"({len(result.tactors[0].pulses) if result.tactors else 0} pulses a "
                 f"tactor at levels {lv}; {result.date})", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path)


def stimulus_figure(result: StimulusValidation, path: str | Path) -> Path:
    """One panel per target: each driven tactor's felt envelope (solid) over its intended
    one (dashed), normalised to the tactor's steady amplitude at full level, against the
    time from the onset; the title gives the target's RMS error."""
    from ..figures import _pyplot, save_figure, tactor_colors

    plt = _pyplot()
    rows = result.targets
    n = max(1, len(rows))
    cols = 1 if n == 1 else (2 if n <= 4 else 4)
    nrows = math.ceil(n / cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.2 * cols + (4 if n == 1 else 0),
                                                   2.3 * nrows + 1.0),
                             sharex=True, sharey=True, squeeze=False)
    first = next(iter(result.traces.values()), {})
    colors = tactor_colors(max(1, len(first)))
    for ax, row in zip(axes.ravel(), rows, strict=False):
        traces = result.traces[row["target"]]
        for t in row["tactors"]:
            if not t["driven"]:
                continue
            tr = traces[t["tactor"]]
            c = colors[t["tactor"]]
            ax.plot(tr.t_ms, tr.intended, color=c, lw=1.0, ls="--")
            ax.plot(tr.t_ms, tr.felt, color=c, lw=1.2, label=f"tactor {t['tactor']}")
        ax.axvline(result.duration_s * 1e3, color="grey", lw=0.8)
        ax.grid(alpha=0.25)
        where = "on a tactor" if row["on_tactor"] else "between tactors"
        ax.set_title(f"target {row['target']} ({row['target_deg']:g} deg, {where}): "
                     f"RMS {row['rms_error']:.3f}", fontsize=8, loc="left")
        ax.legend(fontsize=6, loc="upper right", frameon=False)
    for ax in axes.ravel()[len(rows):]:
        ax.set_visible(False)
    for ax in axes[-1]:
        ax.set_xlabel("ms from the onset (grey: the stop)")
    for ax in axes[:, 0]:
        ax.set_ylabel("of full-level steady")
    between = ("" if result.between_tactor_rms_error is None else
               f", between tactors {result.between_tactor_rms_error:.3f}")
    fig.suptitle(f"Felt (solid) and intended (dashed) {result.condition} stimulus on "
                 f"{result.belt}, drive {result.drive}, sensed by {result.sensor}: RMS "
                 f"error {result.rms_error:.3f}{between}", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, path)
