"""``make bench``: run every benchmark and write results.json and RESULTS.md.

``python benchmarks/run.py bench_player cli_help`` runs only those and keeps the other
figures of the last full run.

Each ``benchmarks/bench_*.py`` is a script that prints one JSON object (key -> number) as
its last line. This runner runs each one in its own process (so one failing benchmark
does not hide the others), merges the figures into ``benchmarks/results.json`` and
writes ``benchmarks/RESULTS.md``: figure, value, baseline, ratio, goal, met or not.

Every figure with a goal is compared with a baseline measured in the same run, because
these machines are shared and noisy: an absolute time alone says little.
"""

from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent


@dataclass(frozen=True)
class Goal:
    key: str
    baseline: str | None  # key of the baseline figure, if any
    op: str | None  # "<=", ">=" or None (a figure without a goal)
    limit: float | None
    unit: str
    limits: str  # what limits this figure


GOALS = [
    Goal("render_24_targets_ms", None, "<=", 10.0, "ms",
         "NumPy temporaries: exp and wrap over (24, 1000, 6) arrays"),
    Goal("render_frames_per_s", "loop_frames_per_s", None, None, "frames/s",
         "memory bandwidth of the vectorised law over (240, 1000, 6) arrays"),
    Goal("render_speedup_vs_loop", None, ">=", 50.0, "x",
         "baseline: a plain Python loop over samples computing the same values"),
    Goal("player_p99_ms", "sleep_loop_p99_ms", "<=", 0.2, "ms",
         "OS wake-up latency and other processes on 2 cores; the player sleeps, then spins"),
    Goal("player_p99_vs_sleep_loop", None, "<=", 0.2, "x",
         "same run: a naive time.sleep(1/rate) loop, which also drifts"),
    Goal("wire_encode_decode_per_s", None, None, None, "frames/s",
         "pure-Python COBS and CRC-16 per byte"),
    Goal("emulator_ping_p50_ms", None, None, None, "ms",
         "pseudo-terminal round trip and the reader thread's wake-up"),
    Goal("emulator_ping_p99_ms", None, None, None, "ms",
         "scheduling of the reader thread and the emulator on a shared machine"),
    Goal("lsl_marker_latency_p99_ms", None, "<=", 5.0, "ms",
         "LSL markers over loopback TCP to an inlet thread; its wake-up on 2 shared cores"),
    Goal("lsl_marker_latency_p50_ms", None, None, None, "ms", "as lsl_marker_latency_p99_ms"),
    Goal("lsl_on_sample_us", "lsl_push_sample_us", "<=", 50.0, "us",
         "per 100 Hz cursor sample: three brackets of LSL's clock around the runner's, "
         "and liblsl's push (baseline: the push alone)"),
    Goal("lsl_map_error_us", None, "<=", 50.0, "us",
         "the runner's clock mapped to LSL's against a direct reading: the time between "
         "the reads"),
    Goal("session_s", None, "<=", 2.0, "s",
         "288 SQLite commits with synchronous=FULL, the ERM model, 100 Hz runner loop"),
    Goal("sessions_1000_s", None, None, None, "s",
         "one store per worker, 2 workers; same costs as session_s"),
    Goal("sessions_linearity", None, "<=", 1.25, "x",
         "last 10 % of sessions over the first 10 %: 1.0 is linear growth"),
    Goal("model_session_s", None, "<=", 5.0, "s", "as session_s"),
    Goal("perceptual_calibration_s", None, "<=", 2.0, "s",
         "QUEST+ (questplus, xarray) updates and chooses in ~5 ms per trial, ~230 trials"),
    Goal("perceptual_trial_ms", None, None, None, "ms", "as perceptual_calibration_s"),
    Goal("factorial_session_s", None, "<=", 3.0, "s",
         "720 trials: as session_s (SQLite commits, the ERM model, the 100 Hz loop)"),
    Goal("factorial_trial_ms", "paper_model_trial_ms", None, None, "ms",
         "baseline: a paper-session trial of the same model participant, same run"),
    Goal("factorial_power_s", "paper_power_s", "<=", 60.0, "s",
         "20,000 simulated participants x 8 blocks on the fast path; the Wilcoxon p "
         "(exact sign flips)"),
    Goal("analyze_1000_s", None, "<=", 30.0, "s",
         "the accuracy and RT mixed models (Laplace GLMM, REML LMM) on 240,000 trials of "
         "participants and targets that differ; SQL aggregation; samples read only for "
         "plotted trials"),
    Goal("push_trials_per_s", None, None, None, "trials/s",
         "sync to PostgreSQL over a Unix socket: one transaction per trial (row + 150 "
         "samples) plus a state query per session; fsync off on the throwaway server"),
    Goal("pg_over_sqlite", None, "<=", 2.0, "x",
         "analyze() of 100 synthetic participants from PostgreSQL over the same from "
         "SQLite (1,000 take too long to load here)"),
    Goal("cli_help_s", "python_startup_s", "<=", 0.3, "s",
         "Python start-up plus click; --help imports no NumPy"),
    Goal("cli_help_vs_python", None, None, None, "x", "baseline: python -c pass"),
    Goal("audio_callback_cpu_pct", None, "<=", 5.0, "% of a core",
         "stimulus.amplitudes at 48 kHz x 8 channels, NumPy on 1024-sample chunks"),
    Goal("audio_underruns_60s", "jack_server_xruns_60s", "<=", 0.0, "",
         "the JACK dummy server's own late cycles on 2 shared cores (baseline: its xruns "
         "seen by an idle client in the same run), period 256 frames (5.3 ms)"),
    Goal("audio_render_block_us", None, None, None, "us", "as audio_callback_cpu_pct"),
    Goal("window_sample_p99_ms", None, "<=", 1.0, "ms",
         "OS wake-up latency of the 100 Hz loop while the window draws at 60 Hz"),
    Goal("window_load_p99_delta_ms", None, "<=", 1.0, "ms",
         "a 2-back in the window (tones: SDL's audio thread takes the GIL per 10 ms block; "
         "letters: a frame at each onset and end) over the same session without a task"),
    Goal("window_nback_audio_sample_p99_ms", "window_noload_sample_p99_ms", None, None, "ms",
         "as window_load_p99_delta_ms"),
    Goal("onset_device_p99_ms", "onset_host_p99_ms", "<=", 0.5, "ms",
         "the clock fit's offset error: asymmetry of the fastest round trips"),
    Goal("onset_host_vs_device", None, ">=", 4.0, "x",
         "baseline: the host-only stamp (Player.start), late by link latency and frame work"),
]


def run_script(path: Path, timeout: float) -> dict[str, float]:
    env = dict(os.environ, SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy", MPLBACKEND="Agg")
    proc = subprocess.run([sys.executable, str(path)], capture_output=True, text=True,
                          timeout=timeout, env=env)
    if proc.returncode != 0:
        raise RuntimeError(proc.stderr.strip().splitlines()[-1] if proc.stderr else "failed")
    last = [ln for ln in proc.stdout.splitlines() if ln.strip().startswith("{")][-1]
    data = json.loads(last)
    return {k: float(v) for k, v in data.items() if isinstance(v, int | float)}


def cli_help() -> dict[str, float]:
    exe = Path(sys.executable).with_name("tactorbelt")
    cmd = [str(exe), "--help"] if exe.exists() else [sys.executable, "-m", "tactorbelt", "--help"]

    def best(argv: list[str]) -> float:
        times = []
        for _ in range(7):
            t0 = time.perf_counter()
            subprocess.run(argv, capture_output=True, check=True)
            times.append(time.perf_counter() - t0)
        return min(times)

    base = best([sys.executable, "-c", "pass"])
    ours = best(cmd)
    return {"cli_help_s": ours, "python_startup_s": base, "cli_help_vs_python": ours / base}


def main() -> int:
    only = set(sys.argv[1:])
    results: dict[str, float] = {}
    previous = HERE / "results.json"
    if only and previous.exists():  # a partial run updates the figures it measures
        results.update(json.loads(previous.read_text()))
    failures: dict[str, str] = {}
    scripts = sorted(HERE.glob("bench_*.py"))
    for path in scripts:
        name = path.stem
        if only and name not in only:
            continue
        print(f"running {name} ...", flush=True)
        try:
            results.update(run_script(path, timeout=1800))
        except Exception as exc:  # report and go on: one failure must not hide the rest
            failures[name] = str(exc)
            print(f"  {name} failed: {exc}", flush=True)
    if not only or "cli_help" in only:
        results.update(cli_help())
    (HERE / "results.json").write_text(json.dumps(results, indent=2, sort_keys=True) + "\n")
    lines = [
        "# Benchmark results",
        "",
        f"Machine: {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"{platform.system()} {platform.machine()}. Written by `make bench`.",
        "",
        "| figure | value | baseline | ratio | goal | met | what limits it |",
        "|---|---|---|---|---|---|---|",
    ]
    for g in GOALS:
        goal = f"{g.op} {g.limit:g} {g.unit}" if g.op and g.limit is not None else "none"
        if g.key not in results:
            lines.append(f"| {g.key} | not measured | | | {goal} | | {g.limits} |")
            continue
        v = results[g.key]
        base = results.get(g.baseline) if g.baseline else None
        ratio = f"{v / base:.3g}" if base else ""
        if g.op is None or g.limit is None:
            met = ""
        else:
            met = "yes" if (v <= g.limit if g.op == "<=" else v >= g.limit) else "NO"
        lines.append(
            f"| {g.key} | {v:.4g} | {'' if base is None else f'{base:.4g}'} | {ratio} | "
            f"{goal} | {met} | {g.limits} |"
        )
    lines += ["", "## All figures", "", "| key | value |", "|---|---|"]
    lines += [f"| {k} | {v:.6g} |" for k, v in sorted(results.items())]
    if failures:
        lines += ["", "## Failed benchmarks", ""]
        lines += [f"- {k}: {v}" for k, v in failures.items()]
    (HERE / "RESULTS.md").write_text("\n".join(lines) + "\n")
    print((HERE / "RESULTS.md").read_text())
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
