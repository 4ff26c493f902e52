"""Benchmark of device-true onsets: the emulator's ONSET times mapped to host time.

1,000 stimulus starts through a :class:`~tactorbelt.player.Player` on the firmware
emulator (``serial:PTY`` of an emulator this script runs with ``--levels-log``), half
rendered on the device (PLAY_TARGET), half streamed (the first SET_AMPLITUDES after a
stop), each stopped again. Per start, two onsets on the host clock
(``time.perf_counter_ns``):

- the host-only stamp: what ``Player.start`` returns (the clock just before the
  request is written; the runner's ``onset_ns``);
- the device onset: ``belt.last_onset()``, the emulator's ONSET time mapped by the
  belt's clock fit (the runner's ``device_onset_ns``).

The truth is the emulator's levels log (the device time of each output change), put on
the host clock by an offset bracket measured afterwards on a fresh connection: for
every PING round trip ``send - d <= zero <= receive - d``, so the intersection of 300
of them holds the emulator's clock zero (it is CLOCK_MONOTONIC, as perf_counter_ns).
``onset_truth_bracket_ms`` is that bracket's half width plus half a microsecond.

Prints one JSON object:

- ``onset_device_p99_ms``, ``onset_device_p50_ms``: |device onset - truth|;
- ``onset_host_p99_ms``, ``onset_host_p50_ms``: |host-only stamp - truth|;
- ``onset_host_p99_play_ms``, ``onset_host_p99_stream_ms``: the host-only stamp's p99
  for device-rendered and for streamed starts (a streamed start first computes a chunk
  of frames, after the stamp);
- ``onset_host_vs_device``: host p99 / device p99 (how much better the device onset is);
- ``onset_truth_bracket_ms``; ``onset_uncertainty_p50_ms``: the reported uncertainty;
  ``onset_within_uncertainty``: the fraction of device onsets within their reported
  uncertainty (plus the truth bracket).

Run alone: ``.venv/bin/python benchmarks/bench_onset.py`` (about 10 s). Skipped (with
``onset_error``) when the emulator cannot be built.
"""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # support.emulator_clock

N_ONSETS = 1000
PINGS = 300


def _offset_bracket(pty: str, pings: int = PINGS) -> tuple[int, int]:
    from support.emulator_clock import clock_offset_bracket

    return clock_offset_bracket(pty, pings)


def _log_starts(log: Path) -> list[int]:
    """Device times (us) at which the outputs left idle (state 0 to 1 or 2)."""
    rows = [[int(v) for v in ln.split(",")[:2]] for ln in log.read_text().splitlines()[1:]]
    return [b[0] for a, b in itertools.pairwise(rows) if a[1] == 0 and b[1] in (1, 2)]


def bench_onsets(n: int = N_ONSETS) -> dict[str, float]:
    from tactorbelt.devices import open_belt
    from tactorbelt.devices.emulator import build_emulator, firmware_dir
    from tactorbelt.player import Player
    from tactorbelt.stimuli import make_stimulus

    exe = build_emulator(firmware_dir())
    with tempfile.TemporaryDirectory(prefix="tactorbelt-bench-onset-") as tmp:
        log = Path(tmp) / "levels.csv"
        proc = subprocess.Popen([str(exe), "--levels-log", str(log)], stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        try:
            assert proc.stdout is not None
            pty = proc.stdout.readline().decode().strip()
            host: list[int] = []
            device: list[int] = []
            uncertainty: list[int] = []
            with open_belt(f"serial:{pty}") as belt:
                if not belt.reports_onsets:
                    raise RuntimeError("the emulator reports no onsets (firmware < 1.1?)")
                player = Player(belt)
                stimuli = [make_stimulus(belt.layout, 45.0 + 60.0 * k, mode="dynamic")
                           for k in range(6)]
                for i in range(n):
                    player.device_render = i % 2 == 0
                    onset = player.start(stimuli[i % 6])
                    got = belt.last_onset(timeout_s=1.0)
                    time.sleep(0.003)  # on for a few ms, so the log shows every start
                    player.stop()
                    if got is None:
                        raise RuntimeError(f"no device onset for start {i}")
                    host.append(onset)
                    device.append(got[0])
                    uncertainty.append(got[1])
                    time.sleep(0.002)
            lo, hi = _offset_bracket(pty)
            starts = _log_starts(log)
        finally:
            if proc.stdin is not None:
                proc.stdin.close()
            proc.wait(5)
    if len(starts) != n:
        raise RuntimeError(f"{len(starts)} output starts in the levels log for {n} onsets")
    truth = (lo + hi) // 2 + 500 + np.asarray(starts, dtype=np.int64) * 1000
    slack = (hi - lo) / 2 + 500
    dev_err = np.abs(np.asarray(device, dtype=np.int64) - truth) / 1e6
    host_err = np.abs(np.asarray(host, dtype=np.int64) - truth) / 1e6
    unc = np.asarray(uncertainty, dtype=float)
    dev_p99 = float(np.percentile(dev_err, 99))
    host_p99 = float(np.percentile(host_err, 99))
    return {
        "onset_device_p50_ms": float(np.percentile(dev_err, 50)),
        "onset_device_p99_ms": dev_p99,
        "onset_device_max_ms": float(dev_err.max()),
        "onset_host_p50_ms": float(np.percentile(host_err, 50)),
        "onset_host_p99_ms": host_p99,
        "onset_host_vs_device": host_p99 / dev_p99 if dev_p99 > 0 else float("inf"),
        "onset_host_p99_play_ms": float(np.percentile(host_err[0::2], 99)),
        "onset_host_p99_stream_ms": float(np.percentile(host_err[1::2], 99)),
        "onset_truth_bracket_ms": slack / 1e6,
        "onset_uncertainty_p50_ms": float(np.percentile(unc, 50)) / 1e6,
        "onset_within_uncertainty": float(np.mean(dev_err * 1e6 <= unc + slack)),
        "onsets": float(n),
    }


def main() -> None:
    try:
        result: dict[str, object] = dict(bench_onsets())
    except Exception as exc:  # no g++, no firmware tree: report, do not fail the run
        result = {"onset_error": f"{type(exc).__name__}: {exc}"}
        print(f"onset benchmark skipped: {exc}", file=sys.stderr)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
