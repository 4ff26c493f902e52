"""Benchmark of the Lab Streaming Layer streams (tactorbelt.lsl) on this machine.

Prints one JSON object:

- ``lsl_marker_latency_p50_ms``, ``lsl_marker_latency_p99_ms``: from a marker's
  timestamp (LSL's clock when it is sent) to its arrival at an inlet in another thread,
  over loopback TCP, for 400 markers sent at 200 Hz: how late a live consumer (an online
  analysis, a BCI) sees an event;
- ``lsl_on_sample_us``: what :meth:`LslListener.on_sample` costs the runner per cursor
  sample (the clock bracket and the push), and ``lsl_push_sample_us``, the bare
  ``push_sample`` of the same sample (baseline);
- ``lsl_map_error_us``: the largest difference between the observer's mapping of the
  runner's clock to LSL's and a direct reading of LSL's clock, over 1000 readings.

LSL stays on this machine (an ``lsl_api.cfg`` with ``ResolveScope = machine`` and a
session id of its own, through ``LSLAPICFG``). Run alone:
``.venv/bin/python benchmarks/bench_lsl.py``. Without pylsl or liblsl it prints
``{"lsl_error": ...}``.
"""

from __future__ import annotations

import json
import os
import statistics
import tempfile
import threading
import time
import uuid
from pathlib import Path
from typing import Any


def _loopback() -> None:
    d = Path(tempfile.mkdtemp(prefix="tactorbelt-lsl-"))
    cfg = d / "lsl_api.cfg"
    cfg.write_text("[ports]\nIPv6 = disable\n\n[multicast]\nResolveScope = machine\n\n"
                   f"[lab]\nSessionID = tactorbelt-bench-{uuid.uuid4().hex}\n\n"
                   "[log]\nlevel = -3\n")
    os.environ["LSLAPICFG"] = str(cfg)


def marker_latency(pylsl: Any, n: int = 400, rate_hz: float = 200.0) -> list[float]:
    info = pylsl.StreamInfo("bench-markers", "Markers", 1, pylsl.IRREGULAR_RATE, "string",
                            f"bench-{uuid.uuid4().hex}")
    outlet = pylsl.StreamOutlet(info)
    found = pylsl.resolve_byprop("source_id", info.source_id(), 1, 10.0)
    inlet = pylsl.StreamInlet(found[0])
    inlet.open_stream(10.0)
    outlet.wait_for_consumers(10.0)
    lat: list[float] = []

    def pull() -> None:
        while len(lat) < n:
            sample, ts = inlet.pull_sample(5.0)
            if sample is None:
                return
            lat.append(pylsl.local_clock() - ts)

    t = threading.Thread(target=pull)
    t.start()
    for i in range(n):
        outlet.push_sample([json.dumps({"event": "trial_start", "trial_index": i})],
                           pylsl.local_clock())
        time.sleep(1.0 / rate_hz)
    t.join(10.0)
    return lat


def on_sample_cost(pylsl: Any, n: int = 20000) -> tuple[float, float, float]:
    from tactorbelt.clock import WallClock
    from tactorbelt.inputs.base import CursorSample
    from tactorbelt.lsl import LslListener

    clock = WallClock()
    obs = LslListener(clock, belt=None, pylsl=pylsl)  # type: ignore[arg-type]
    info = pylsl.StreamInfo("bench-cursor", "Position", 2, 100.0, "float32",
                            f"bench-{uuid.uuid4().hex}")
    obs.cursor = pylsl.StreamOutlet(info)
    samples = [CursorSample(clock.now_ns(), 0.1, 0.2) for _ in range(n)]
    t0 = time.perf_counter()
    for s in samples:
        obs.on_sample(s)
    ours = (time.perf_counter() - t0) / n * 1e6
    t0 = time.perf_counter()
    for s in samples:
        obs.cursor.push_sample([s.x, s.y], s.t_ns / 1e9)
    bare = (time.perf_counter() - t0) / n * 1e6
    worst = 0.0
    for _ in range(1000):
        t = clock.now_ns()
        direct = pylsl.local_clock()
        worst = max(worst, abs(obs.to_lsl(t) - direct))
    obs.close()
    return ours, bare, worst * 1e6


def main() -> None:
    _loopback()
    try:
        from tactorbelt.lsl import load_pylsl

        pylsl = load_pylsl()
    except Exception as exc:
        print(json.dumps({"lsl_error": str(exc)}))
        return
    lat = sorted(marker_latency(pylsl))
    ours, bare, err = on_sample_cost(pylsl)
    print(json.dumps({
        "lsl_marker_latency_p50_ms": statistics.median(lat) * 1e3,
        "lsl_marker_latency_p99_ms": lat[min(len(lat) - 1, int(0.99 * len(lat)))] * 1e3,
        "lsl_markers_received": len(lat),
        "lsl_on_sample_us": ours,
        "lsl_push_sample_us": bare,
        "lsl_map_error_us": err,
    }))


if __name__ == "__main__":
    main()
