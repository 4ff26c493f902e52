"""Rendering speed: vectorised rendering against a plain Python loop over samples.

Prints one JSON object: render_24_targets_ms (one second at 1 kHz for all 24 targets,
dynamic), render_frames_per_s (frames of 6 amplitudes per second, many targets at once),
loop_frames_per_s (a plain Python loop computing the same values) and
render_speedup_vs_loop. Goals: render_24_targets_ms < 10, speedup >= 50.
"""

from __future__ import annotations

import json
import math
import time

import numpy as np

from tactorbelt.geometry import Layout, TargetSet
from tactorbelt.stimuli import make_stimulus, render_batch


def _best(fn, repeat: int = 7) -> float:
    best = math.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def _loop_render(stim, rate: float, duration: float) -> list[list[float]]:
    """The same values, one sample and one tactor at a time in plain Python."""
    angles = stim.layout.angles_deg
    n = len(angles)
    gaps_cw = [float(g) for g in stim.layout.gaps_deg()]
    _, ccw = stim.layout.neighbour_indices()
    gaps_ccw = [gaps_cw[int(ccw[k])] for k in range(n)]
    out = []
    for i in range(round(duration * rate)):
        x = float(stim.location(i / rate))
        row = []
        for k in range(n):
            signed = 180.0 - (180.0 - (x - angles[k])) % 360.0
            s = gaps_cw[k] if signed >= 0 else gaps_ccw[k]
            row.append(max(1.0 - math.exp(-(s - abs(signed)) / stim.falloff_deg), 0.0))
        out.append(row)
    return out


def main() -> dict[str, float]:
    layout = Layout.even(6)
    targets = TargetSet.even(24)
    stims = [make_stimulus(layout, x, "dynamic") for x in targets]
    t24 = _best(lambda: render_batch(stims, 1000.0, 1.0))
    many = [make_stimulus(layout, x, "dynamic") for x in np.linspace(0, 359, 240)]
    t_many = _best(lambda: render_batch(many, 1000.0, 1.0), repeat=5)
    frames_per_s = 240 * 1000 / t_many
    t_loop = _best(lambda: _loop_render(stims[1], 1000.0, 1.0), repeat=3)
    loop_frames_per_s = 1000 / t_loop
    # the loop computes the same values
    ref = render_batch([stims[1]], 1000.0, 1.0)[1][0]
    assert np.allclose(np.array(_loop_render(stims[1], 1000.0, 1.0)), ref, atol=1e-9)
    return {
        "render_24_targets_ms": t24 * 1000,
        "render_frames_per_s": frames_per_s,
        "loop_frames_per_s": loop_frames_per_s,
        "render_speedup_vs_loop": frames_per_s / loop_frames_per_s,
    }


if __name__ == "__main__":
    print(json.dumps(main()))
