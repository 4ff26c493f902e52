"""Figures of the stimulus engine: the amplitude law across directions, and a rendered stimulus.

``amplitude_figure`` draws the top of the paper's Fig. 1(B): the amplitude of each tactor
against target direction, with on-tactor and between-tactor targets marked.
``stimulus_figure`` draws a rendered stimulus (per-tactor amplitude against time).

Imports matplotlib (Agg) when called; pure otherwise (no devices, no store).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from .geometry import Layout, TargetSet
from .laws import DEFAULT_FALLOFF_DEG, amplitudes

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from .stimuli import Stimulus

__all__ = ["amplitude_figure", "save_figure", "stimulus_figure", "tactor_colors"]


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def tactor_colors(n: int) -> list[tuple[float, float, float, float]]:
    """One colour per tactor from a colour-blind-safe qualitative map."""
    import matplotlib

    cmap = matplotlib.colormaps["tab10" if n <= 10 else "tab20"]
    return [cmap(k % cmap.N) for k in range(n)]


def amplitude_figure(
    layout: Layout | None = None,
    targets: TargetSet | None = None,
    law: str = "paper",
    falloff_deg: float = DEFAULT_FALLOFF_DEG,
) -> Figure:
    """The top of the paper's Fig. 1(B) for any layout, target set and law: each tactor's
    amplitude against direction (curves and target marks)."""
    layout = layout or Layout.even(6)
    targets = targets or TargetSet.even(24)
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(9, 3.6), dpi=150)
    fine = np.linspace(0.0, 360.0, 1441)
    amp_fine = amplitudes(layout, fine, law, falloff_deg)
    amp_t = amplitudes(layout, targets.angles, law, falloff_deg)
    on = targets.on_tactor(layout)
    colors = tactor_colors(layout.n)
    for k in range(layout.n):
        ax.plot(fine, amp_fine[:, k], color=colors[k], lw=1.6,
                label=f"tactor {k} ({layout.angles_deg[k]:g}°)")
        ax.plot(targets.angles[on], amp_t[on, k], "o", color=colors[k], ms=5)
        ax.plot(targets.angles[~on], amp_t[~on, k], "o", mfc="white", color=colors[k], ms=5)
    for x, is_on in zip(targets.angles, on, strict=True):
        ax.axvline(x, color="#e08a1e" if is_on else "#9a9a9a", lw=0.6, alpha=0.35, zorder=0)
    ax.set_xlim(0, 360)
    ax.set_ylim(0, 1.05)
    ax.set_xticks(np.arange(0, 361, 45))
    ax.set_xlabel("target direction (deg; 0 = navel, clockwise from above)")
    ax.set_ylabel("amplitude")
    ax.grid(alpha=0.25)
    from matplotlib.lines import Line2D

    handles, labels = ax.get_legend_handles_labels()
    handles += [
        Line2D([], [], marker="o", ls="", color="k", label="on-tactor target"),
        Line2D([], [], marker="o", ls="", mfc="white", color="k", label="between-tactor target"),
    ]
    ax.legend(handles=handles, fontsize=7, ncol=2, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    title = f"{law} law" + (f", T = {falloff_deg:g}°" if law == "paper" else "")
    ax.set_title(f"Amplitude of each tactor against direction: {layout.n} tactors, "
                 f"{targets.m} targets, {title}", fontsize=9)
    fig.tight_layout()
    return fig


def stimulus_figure(stimulus: Stimulus, t: np.ndarray, amps: np.ndarray) -> Figure:
    """Per-tactor amplitude against time for a rendered stimulus."""
    plt = _pyplot()
    n = amps.shape[1]
    fig, ax = plt.subplots(figsize=(8, 3.4), dpi=150)
    colors = tactor_colors(n)
    for k in range(n):
        if np.any(amps[:, k] > 0):
            ax.plot(t, amps[:, k], color=colors[k], lw=1.6,
                    label=f"tactor {k} ({stimulus.layout.angles_deg[k]:g}°)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("amplitude")
    ax.set_ylim(0, 1.05)
    ax.grid(alpha=0.25)
    kind = "dynamic" if stimulus.is_dynamic else "static"
    extra = ""
    if stimulus.is_dynamic:
        extra = (f"; dwell {stimulus.dwell_near_s * 1000:.0f} ms on tactor {stimulus.near_idx}, "
                 f"{stimulus.dwell_far_s * 1000:.0f} ms on tactor {stimulus.far_idx}")
    ax.set_title(f"{kind} stimulus at {stimulus.target_deg:g}°, {stimulus.law} law{extra}",
                 fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    return fig


def save_figure(fig: Figure, path: str | Path) -> Path:
    """Save a figure as PNG at 150 dpi and close it."""
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(p, dpi=150)
    _pyplot().close(fig)
    return p
