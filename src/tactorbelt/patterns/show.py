"""``pattern show``: a PNG of each tactor's envelope, one row per tactor, on a shared time axis.

Imports matplotlib (Agg) when called, NumPy and the pattern modules.
"""

from __future__ import annotations

from pathlib import Path

from ..figures import _pyplot, save_figure, tactor_colors
from ..geometry import Layout
from .model import Pattern
from .render import PatternPlayback, render_pattern

__all__ = ["show_pattern"]


def show_pattern(pattern: Pattern, layout: Layout, out: str | Path, law: str | None = None,
                 rate_hz: float = 1000.0, source: str | None = None) -> Path:
    """Draw ``pattern`` rendered on ``layout`` (the law for angles and paths) to ``out``."""
    plt = _pyplot()
    playback = PatternPlayback(pattern, layout, law, source=source)
    t, amps = render_pattern(playback, rate_hz)
    n = layout.n
    fig, axes = plt.subplots(n, 1, sharex=True, figsize=(8.0, 0.55 * n + 1.4), squeeze=False)
    colors = tactor_colors(n)
    for k in range(n):
        ax = axes[k][0]
        ax.fill_between(t * 1000.0, amps[:, k], color=colors[k], alpha=0.35, lw=0)
        ax.plot(t * 1000.0, amps[:, k], color=colors[k], lw=1.0)
        ax.set_ylim(0.0, 1.05)
        ax.set_yticks([])
        ax.set_ylabel(f"{k}: {layout.angles_deg[k]:g}°", rotation=0, ha="right", va="center",
                      fontsize=8)
        for side in ("top", "right"):
            ax.spines[side].set_visible(False)
    axes[-1][0].set_xlabel("time (ms)")
    title = pattern.name or (Path(source).name if source else "pattern")
    fig.suptitle(f"{title}: {len(pattern.events)} events on {n} tactors "
                 f"({playback.law} law)", fontsize=10)
    fig.tight_layout()
    return save_figure(fig, out)
