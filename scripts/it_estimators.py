#!/usr/bin/env python3
"""Bias and RMSE of information-transfer estimators on channels of known transfer.

Every grid point is a channel (a matrix of response probabilities given the target),
a target count M and a number of repetitions r (trials per target of one participant
in one cell). The true transfer is the channel's mutual information with every target
equally likely, computed exactly. ``--sims`` confusion matrices are drawn from the
channel (each row: r trials, multinomial), and every estimator of
:mod:`tactorbelt.analysis.tables.transfer` is applied to each, clamped to ``[0, H(S)]`` as the
analysis reports it (and unclamped, for the raw bias). Channels:

- ``perfect``: always right; ``chance``: a uniform answer whatever the target;
- ``uniform p``: right with probability p, otherwise any other target alike;
- ``neighbour p``: right with probability p, otherwise one of the two neighbours;
- ``angular s``: the answer is the target plus a normal error of s degrees, snapped
  to the nearest target (as a belt wearer's pointing error; the same error in degrees
  spans more targets at higher resolution).

Then a coverage check of the cell interval (:func:`tactorbelt.analysis.tables.transfer.
cell_interval`): ``--coverage-sims`` studies of n participants whose angular errors
differ (s drawn log-normally around 20 degrees), against the population mean of the
true transfer.

It prints the Markdown tables of docs/analysis.md ("Information transfer") and writes
``docs/img/it_estimators.png``:

    python scripts/it_estimators.py            # about 3 minutes on one free core

The seed is fixed (``--seed``), so the numbers are the same on every run.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.stats import norm

from tactorbelt.analysis.tables.transfer import (
    ESTIMATOR,
    estimate_transfer,
    expanded_levels,
    two_level_means,
)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from support.it_estimators import ESTIMATORS  # the estimators compared

COUNTS = (12, 24, 36, 48)
REPS = (2, 3, 5, 10)
NAMES = list(ESTIMATORS)
OUT = Path(__file__).resolve().parents[1] / "docs" / "img" / "it_estimators.png"


def channel(kind: str, value: float, m: int) -> np.ndarray:
    """P(response j | target i), an m x m row-stochastic matrix."""
    if kind == "perfect":
        return np.eye(m)
    if kind == "chance":
        return np.full((m, m), 1.0 / m)
    if kind == "uniform":
        p = np.full((m, m), (1.0 - value) / (m - 1))
        np.fill_diagonal(p, value)
        return p
    if kind == "neighbour":
        p = np.eye(m) * value
        i = np.arange(m)
        p[i, (i - 1) % m] += (1.0 - value) / 2
        p[i, (i + 1) % m] += (1.0 - value) / 2
        return p
    if kind == "angular":
        step = 360.0 / m
        k = np.arange(m)
        # offset of response bin j from the target (clockwise, [0, 360)); its arc is
        # [o - step/2, o + step/2] plus any whole turn (wrap -1 reaches it anticlockwise)
        off = ((k[None, :] - k[:, None]) % m) * step
        prob = np.zeros((m, m))
        for wrap in range(-3, 4):
            lo = off - step / 2 + 360.0 * wrap
            prob += norm.cdf(lo + step, scale=value) - norm.cdf(lo, scale=value)
        return prob / prob.sum(axis=1, keepdims=True)
    raise ValueError(kind)


CHANNELS: list[tuple[str, float]] = [
    ("perfect", 1.0), ("uniform", 0.9), ("uniform", 0.6), ("uniform", 0.3),
    ("neighbour", 0.8), ("neighbour", 0.5), ("angular", 10.0), ("angular", 20.0),
    ("angular", 40.0), ("chance", 0.0),
]


def label(kind: str, value: float) -> str:
    if kind in ("perfect", "chance"):
        return kind
    return f"{kind} {value:g}" + ("°" if kind == "angular" else "")


def true_transfer(p: np.ndarray) -> float:
    """Mutual information (bits) of channel p with equally likely targets."""
    joint = p / p.shape[0]
    pr = joint.sum(axis=0)
    nz = joint > 0
    ratio = joint[nz] / (np.full_like(joint, 1.0 / p.shape[0]) * pr[None, :])[nz]
    return float(np.sum(joint[nz] * np.log2(ratio)))


def draw(p: np.ndarray, reps: int, sims: int, rng: np.random.Generator) -> np.ndarray:
    return rng.multinomial(reps, p, size=(sims, p.shape[0])).astype(float)


def run_grid(sims: int, boot_sims: int, seed: int) -> list[dict[str, object]]:
    rng = np.random.default_rng(seed)
    rows: list[dict[str, object]] = []
    for m in COUNTS:
        for kind, value in CHANNELS:
            p = channel(kind, value, m)
            truth = true_transfer(p)
            for reps in REPS:
                mats = draw(p, reps, sims, rng)
                row: dict[str, object] = {"m": m, "channel": label(kind, value),
                                          "reps": reps, "truth": truth}
                for name, f in ESTIMATORS.items():
                    if name == "bootstrap":
                        sub = mats[:boot_sims]
                        est = np.asarray(f(sub, n_boot=100, rng=rng))
                        raw = np.asarray(f(sub, n_boot=100, rng=rng, clamp=False))
                    else:
                        est = np.asarray(f(mats))
                        raw = np.asarray(f(mats, clamp=False))
                    row[name] = est - truth
                    row[name + " raw"] = raw - truth
                rows.append(row)
    return rows


def _summary(rows: list[dict[str, object]], name: str, panel: int) -> tuple[float, ...]:
    """Over the grid points: mean bias, mean |bias|, RMSE, max |bias|, RMSE of a mean
    over ``panel`` participants (sqrt of the mean of bias^2 + var / panel)."""
    bias = np.array([np.mean(r[name]) for r in rows])  # type: ignore[arg-type]
    raw = np.array([np.mean(r[name + " raw"]) for r in rows])  # type: ignore[arg-type]
    mse = np.array([np.mean(np.square(r[name])) for r in rows])  # type: ignore[arg-type]
    var = np.array([np.var(r[name]) for r in rows])  # type: ignore[arg-type]
    return (float(bias.mean()), float(np.abs(bias).mean()), float(np.sqrt(mse.mean())),
            float(np.abs(bias).max()), float(np.abs(raw).mean()),
            float(np.sqrt(np.mean(bias ** 2 + var / panel))))


def print_tables(rows: list[dict[str, object]], panel: int) -> str:
    out = []
    out.append(f"| estimator | mean bias | mean abs bias | RMSE | max abs bias | mean abs bias "
               f"unclamped | RMSE of a {panel}-participant mean |")
    out.append("|---|---|---|---|---|---|---|")
    best = min(NAMES, key=lambda n: _summary(rows, n, panel)[2])
    for name in NAMES:
        s = _summary(rows, name, panel)
        cells = [f"{v:+.3f}" if i == 0 else f"{v:.3f}" for i, v in enumerate(s)]
        nm = f"**{name}**" if name == best else name
        out.append(f"| {nm} | " + " | ".join(cells) + " |")
    out.append("")
    out.append("Bias / RMSE (bits) by repetitions per target, over all channels and target "
               "counts:")
    out.append("")
    out.append("| repetitions | " + " | ".join(NAMES) + " |")
    out.append("|---" * (len(NAMES) + 1) + "|")
    for reps in REPS:
        sel = [r for r in rows if r["reps"] == reps]
        cells = []
        for name in NAMES:
            s = _summary(sel, name, panel)
            cells.append(f"{s[0]:+.2f} / {s[2]:.2f}")
        out.append(f"| {reps} | " + " | ".join(cells) + " |")
    out.append("")
    out.append("Bias / RMSE (bits) by channel, over all target counts and repetitions:")
    out.append("")
    out.append("| channel | true IT (12 / 48 targets) | " + " | ".join(NAMES) + " |")
    out.append("|---" * (len(NAMES) + 2) + "|")
    for kind, value in CHANNELS:
        lab = label(kind, value)
        sel = [r for r in rows if r["channel"] == lab]
        t12 = next(float(r["truth"]) for r in sel if r["m"] == 12)  # type: ignore[arg-type]
        t48 = next(float(r["truth"]) for r in sel if r["m"] == 48)  # type: ignore[arg-type]
        cells = []
        for name in NAMES:
            s = _summary(sel, name, panel)
            cells.append(f"{s[0]:+.2f} / {s[2]:.2f}")
        out.append(f"| {lab} | {t12:.2f} / {t48:.2f} | " + " | ".join(cells) + " |")
    text = "\n".join(out)
    print(text)
    return best


def coverage(sims: int, seed: int) -> list[dict[str, object]]:
    """Coverage of cell intervals: of the population mean transfer (several participants)
    and of the participants' own mean true transfer (every n, the only target for one)."""
    from scipy.stats import t as t_dist

    rng = np.random.default_rng(seed + 1)
    out: list[dict[str, object]] = []
    methods = ("expanded", "percentile", "participants", "t")
    for m in (12, 24):
        # the population: log-normal angular error around 20 degrees (SD of log 0.4)
        pop = np.exp(np.log(20.0) + 0.4 * rng.standard_normal(400))
        truth = float(np.mean([true_transfer(channel("angular", s, m)) for s in pop]))
        for reps in (3, 5):
            for n in (1, 4, 12):
                hits = dict.fromkeys(methods, 0)
                own = dict.fromkeys(methods, 0)
                width = dict.fromkeys(methods, 0.0)
                err = 0.0
                for _ in range(sims):
                    sig = np.exp(np.log(20.0) + 0.4 * rng.standard_normal(n))
                    chans = [channel("angular", s, m) for s in sig]
                    mine = float(np.mean([true_transfer(c) for c in chans]))
                    mats = [draw(c, reps, 1, rng)[0] for c in chans]
                    vals = np.array([float(estimate_transfer(x)) for x in mats])
                    err += vals.mean() - truth
                    boot = two_level_means(mats, rng=rng, n_boot=4000)
                    ivs = {"expanded": np.quantile(boot, expanded_levels(n)),
                           "percentile": np.quantile(boot, [0.025, 0.975])}
                    if n > 1:
                        b = rng.integers(n, size=(4000, n))
                        ivs["participants"] = np.quantile(vals[b].mean(axis=1), [0.025, 0.975])
                        h = float(t_dist.ppf(0.975, n - 1) * vals.std(ddof=1) / math.sqrt(n))
                        ivs["t"] = np.array([vals.mean() - h, vals.mean() + h])
                    for k, (lo, hi) in ivs.items():
                        hits[k] += int(lo <= truth <= hi)
                        own[k] += int(lo <= mine <= hi)
                        width[k] += hi - lo
                out.append({"m": m, "reps": reps, "n": n, "truth": truth,
                            "bias": err / sims,
                            **{f"cov {k}": hits[k] / sims for k in methods},
                            **{f"own {k}": own[k] / sims for k in methods},
                            **{f"width {k}": width[k] / sims for k in methods}})
    print()
    print("Coverage of the population mean (of these participants' own mean with one "
          "participant), mean width in bits:")
    print()
    print("| targets | repetitions | participants | true mean IT | bias of the cell value | "
          "two-level, expanded (used) | two-level, plain percentile | participants only, "
          "percentile | t interval |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in out:
        def c(k: str, r: dict[str, object] = r) -> str:
            if r["n"] == 1:
                if k in ("participants", "t"):
                    return "-"
                return f"{r['own ' + k]:.2f} ({r['width ' + k]:.2f})"
            return f"{r['cov ' + k]:.2f} ({r['width ' + k]:.2f})"
        print(f"| {r['m']} | {r['reps']} | {r['n']} | {r['truth']:.2f} | {r['bias']:+.2f} | "
              + " | ".join(c(k) for k in methods) + " |")
    return out


def figure(rows: list[dict[str, object]], path: Path) -> None:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 9))
    FigureCanvasAgg(fig)
    axes = fig.subplots(3, len(COUNTS), sharey="row")
    styles = {"plug-in": ("#000000", "o", "-"), "Miller-Madow": ("#E69F00", "s", "--"),
              "Panzeri-Treves": ("#56B4E9", "^", "-."), "jackknife": ("#009E73", "D", "-"),
              "Chao-Shen": ("#CC79A7", "v", ":"), "bootstrap": ("#D55E00", "P", "--")}
    shades = {2: "#f4a6d7", 3: "#d46bb0", 5: "#a0327f", 10: "#5c0a47"}
    for j, m in enumerate(COUNTS):
        for name in NAMES:
            col, mk, ls = styles[name]
            b, e = [], []
            for reps in REPS:
                sel = [r for r in rows if r["m"] == m and r["reps"] == reps]
                s = _summary(sel, name, 12)
                b.append(s[0])
                e.append(s[2])
            axes[0, j].plot(REPS, b, color=col, marker=mk, linestyle=ls, label=name)
            axes[1, j].plot(REPS, e, color=col, marker=mk, linestyle=ls, label=name)
        # the chosen estimator's bias against the true transfer, channel by channel
        for reps in REPS:
            sel = sorted((r for r in rows if r["m"] == m and r["reps"] == reps),
                         key=lambda r: float(r["truth"]))  # type: ignore[arg-type]
            axes[2, j].plot([float(r["truth"]) for r in sel],  # type: ignore[arg-type]
                            [float(np.mean(r[ESTIMATOR])) for r in sel],  # type: ignore
                            color=shades[reps], marker="v", linewidth=1.2,
                            label=f"{ESTIMATOR}, {reps} reps")
        sel = sorted((r for r in rows if r["m"] == m and r["reps"] == 3),
                     key=lambda r: float(r["truth"]))  # type: ignore[arg-type]
        axes[2, j].plot([float(r["truth"]) for r in sel],  # type: ignore[arg-type]
                        [float(np.mean(r["plug-in"])) for r in sel],  # type: ignore
                        color="#000000", marker="o", linestyle="--", linewidth=1,
                        label="plug-in, 3 reps")
        axes[0, j].set_title(f"{m} targets (log2 = {math.log2(m):.2f} bits)", fontsize=10)
        axes[1, j].set_xlabel("repetitions per target")
        axes[2, j].set_xlabel("true information transfer (bits)")
        for ax in axes[:2, j]:
            ax.set_xticks(REPS)
        for ax in axes[:, j]:
            ax.grid(alpha=0.3)
            if ax is not axes[1, j]:
                ax.axhline(0, color="#999999", linewidth=0.8)
    axes[0, 0].set_ylabel("mean bias (bits)")
    axes[1, 0].set_ylabel("RMSE (bits)")
    axes[2, 0].set_ylabel("bias (bits), per channel")
    axes[0, 0].legend(fontsize=8, frameon=False)
    axes[2, 0].legend(fontsize=7.5, frameon=False)
    fig.suptitle("Information-transfer estimators on one participant's confusion matrix "
                 "(clamped to [0, log2 M])\nrows 1-2: mean over "
                 f"{len(CHANNELS)} channels from perfect to chance; row 3: each channel "
                 f"(the chosen {ESTIMATOR} estimator, and the plug-in at 3 repetitions)",
                 fontsize=10.5)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sims", type=int, default=300, help="matrices per grid point")
    ap.add_argument("--boot-sims", type=int, default=60,
                    help="matrices per grid point for the (slow) bootstrap correction")
    ap.add_argument("--coverage-sims", type=int, default=150)
    ap.add_argument("--panel", type=int, default=12, help="participants per cell (table)")
    ap.add_argument("--seed", type=int, default=20261124)
    ap.add_argument("--out", type=Path, default=OUT)
    args = ap.parse_args()
    t0 = time.perf_counter()
    rows = run_grid(args.sims, args.boot_sims, args.seed)
    best = print_tables(rows, args.panel)
    print(f"\nsmallest RMSE over the grid: {best}")
    figure(rows, args.out)
    if args.coverage_sims:
        coverage(args.coverage_sims, args.seed)
    print(f"\n({time.perf_counter() - t0:.0f} s; figure: {args.out})")


if __name__ == "__main__":
    main()
