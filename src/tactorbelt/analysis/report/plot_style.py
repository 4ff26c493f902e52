"""What every figure of the analysis report shares: the colours, markers and line styles
(static blue, dynamic vermillion: Okabe-Ito, colour-blind safe), a Figure on the Agg
canvas, PNG bytes at 150 dpi, the axes' style, the "no data" note, a mean with its 95 %
t interval. :mod:`.figures` and :mod:`.tasks_figures` draw with them.

Pure apart from matplotlib (never pyplot): NumPy, SciPy, matplotlib.
"""

from __future__ import annotations

import io
from typing import TYPE_CHECKING, Any, Final

import numpy as np
from scipy.stats import t as t_dist

if TYPE_CHECKING:
    from matplotlib.figure import Figure

__all__ = ["COLORS", "DPI", "LINESTYLES", "MARKERS", "ON_SHADE", "TACTOR_COLORS", "TEXT_GREY"]

DPI: Final = 150
#: Okabe-Ito: static blue, dynamic vermillion, everywhere.
COLORS: Final = {"static": "#0072B2", "dynamic": "#D55E00"}
MARKERS: Final = {"static": "o", "dynamic": "s"}
LINESTYLES: Final = {"static": "-", "dynamic": "--"}
#: Paul Tol's "muted" palette for tactors (colour-blind safe).
TACTOR_COLORS: Final = ("#332288", "#88CCEE", "#44AA99", "#117733", "#999933", "#DDCC77",
                        "#CC6677", "#882255", "#AA4499")
ON_SHADE: Final = "#EEEEEE"
TEXT_GREY: Final = "#555555"


def _figure(width: float, height: float) -> Figure:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def _png(fig: Figure) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=DPI, facecolor="white")
    return buf.getvalue()


def _style(ax: Any) -> None:
    ax.spines["top"].set_visible(False)
    ax.spines["right"].set_visible(False)
    ax.grid(True, axis="y", color="#DDDDDD", linewidth=0.6)
    ax.set_axisbelow(True)


def _tactor_color(k: int, n: int) -> str:
    if n <= len(TACTOR_COLORS):
        return TACTOR_COLORS[k]
    from matplotlib import colormaps
    from matplotlib.colors import to_hex

    return str(to_hex(colormaps["viridis"](k / max(n - 1, 1))))


def _no_data(ax: Any, text: str) -> None:
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center",
            color=TEXT_GREY, fontsize=10, wrap=True)


def _mean_ci(values: np.ndarray) -> tuple[float, float]:
    """Mean and the half-width of its 95 % t interval (0 for fewer than 2 values)."""
    v = values[np.isfinite(values)]
    if v.size == 0:
        return float("nan"), 0.0
    if v.size < 2:
        return float(v.mean()), 0.0
    se = float(v.std(ddof=1) / np.sqrt(v.size))
    return float(v.mean()), float(t_dist.ppf(0.975, v.size - 1)) * se
