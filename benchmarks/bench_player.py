"""Benchmark: the player's deadline error at 1 kHz on the sim belt, wall clock.

Plays a dynamic stimulus on the ``sim`` belt for ``--seconds`` (default 10) with the
player streaming at ``--rate`` (default 1000 Hz) on the wall clock, then runs a naive
loop (``time.sleep(1/rate)`` between frames) on the same belt for the same time, and
prints one JSON object:

- ``player_p99_ms``: 99th percentile of the player's deadline error;
- ``sleep_loop_p99_ms``: the same for the naive loop, whose frame i is due at
  ``start + i/rate`` (its error grows as the sleeps' overshoots add up);
- ``player_p99_vs_sleep_loop``: their ratio (goal: at most 0.2);
- ``sleep_loop_interval_p99_ms``: the naive loop's p99 of (interval - period), a
  fairer view of its jitter that ignores the drift;
- ``player_missed``, ``player_frames``, ``player_p50_ms``, ``player_max_ms``;
- ``pattern_player_p99_ms``, ``pattern_player_missed``: the same player streaming a
  haptic pattern (a between-tactor path, one turn a second: docs/patterns.md) for as long
  on a fresh sim belt, so pattern playback's timing stands beside the stimulus's;
- ``sim_vibration_session_s``: total time of ``SimBelt.vibration`` over 2 s of stimulus
  for each of 264 trials (a paper session) on a SimClock, as the model participant
  calls it; ``sim_vibration_call_ms`` per call.

Run alone: ``.venv/bin/python benchmarks/bench_player.py [--seconds 10] [--spin-us N]``.
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np


def naive_loop(belt, stimulus, seconds: float, rate: float) -> tuple[float, float]:
    """A time.sleep(1/rate) loop: p99 deadline error and p99 interval error (ms)."""
    n = round(seconds * rate)
    period_ns = 1e9 / rate
    t = np.arange(n) / rate
    frames = stimulus.amplitudes(t)
    stamps = np.zeros(n, dtype=np.int64)
    start = time.perf_counter_ns()
    for i in range(n):
        stamps[i] = time.perf_counter_ns()
        belt.set_amplitudes(frames[i])
        time.sleep(1.0 / rate)
    belt.stop()
    deadlines = start + np.round(np.arange(n) * period_ns).astype(np.int64)
    err = (stamps - deadlines) / 1e6
    interval = (np.diff(stamps) - period_ns) / 1e6
    return float(np.percentile(err, 99)), float(np.percentile(interval, 99))


def sim_vibration_session(trials: int = 264) -> float:
    """Seconds spent in SimBelt.vibration for a paper session on a SimClock."""
    from tactorbelt.clock import SimClock
    from tactorbelt.devices.sim import open_sim
    from tactorbelt.geometry import Layout
    from tactorbelt.stimuli import make_stimulus

    clock = SimClock()
    layout = Layout.even(6)
    stimuli = [make_stimulus(layout, k * 15.0, mode) for k in range(24)
               for mode in ("static", "dynamic")]
    spent = 0.0
    with open_sim("", clock=clock) as belt:
        for k in range(trials):
            clock.advance(1_500_000_000)  # inter-trial interval and going home
            onset = clock.now_ns()
            belt.play(stimuli[k % len(stimuli)], 3.0)
            clock.advance(2_000_000_000)  # the response comes after 2 s
            belt.stop()
            t0 = time.perf_counter()
            belt.vibration(onset, onset + 2_000_000_000)
            spent += time.perf_counter() - t0
    return spent


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--rate", type=float, default=1000.0)
    ap.add_argument("--spin-us", type=float, default=None,
                    help="spin this long before each deadline (default: the WallClock's)")
    args = ap.parse_args()

    from tactorbelt.clock import WallClock
    from tactorbelt.devices.sim import open_sim
    from tactorbelt.geometry import Layout
    from tactorbelt.player import Player
    from tactorbelt.stimuli import make_stimulus

    clock = WallClock() if args.spin_us is None else WallClock(round(args.spin_us * 1000))
    stimulus = make_stimulus(Layout.even(6), 15.0, "dynamic")
    with open_sim("", clock=clock) as belt:
        player = Player(belt, rate_hz=args.rate, device_render=False)
        stats = player.play(stimulus, args.seconds)
    from tactorbelt.patterns.model import Event, Pattern
    from tactorbelt.patterns.render import PatternPlayback

    turn = Pattern((Event(0.0, args.seconds * 1000.0, path=(0.0, 360.0 * args.seconds)),))
    with open_sim("", clock=clock) as belt:
        player = Player(belt, rate_hz=args.rate, device_render=False)
        pattern_stats = player.play(PatternPlayback(turn, belt.layout), args.seconds)
    with open_sim("", clock=clock) as belt:
        naive_p99, naive_interval_p99 = naive_loop(belt, stimulus, args.seconds, args.rate)
    sim_s = sim_vibration_session()
    out = {
        "player_p99_ms": round(stats.deadline_error_p99_ms, 4),
        "sleep_loop_p99_ms": round(naive_p99, 4),
        "player_p99_vs_sleep_loop": float(f"{stats.deadline_error_p99_ms / naive_p99:.4g}")
        if naive_p99 > 0 else None,
        "sleep_loop_interval_p99_ms": round(naive_interval_p99, 4),
        "player_p50_ms": round(stats.deadline_error_p50_ms, 4),
        "player_max_ms": round(stats.deadline_error_max_ms, 4),
        "player_frames": stats.frames,
        "player_missed": stats.missed,
        "pattern_player_p99_ms": round(pattern_stats.deadline_error_p99_ms, 4),
        "pattern_player_missed": pattern_stats.missed,
        "sim_vibration_session_s": round(sim_s, 4),
        "sim_vibration_call_ms": round(sim_s / 264 * 1e3, 4),
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
