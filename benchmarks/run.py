"""``make bench``: run every benchmark and write results.json and RESULTS.md.

``make bench`` (``run.py``) is the quick suite (under 5 minutes): a figure that is a rate
is measured on a smaller store or fewer participants (:data:`QUICK_ARGS`).
``make bench-full`` (``run.py --full``) runs every script with its own defaults (1,000
participants) and writes results-full.json and RESULTS-full.md.

``python benchmarks/run.py bench_player cli_help`` runs only those and keeps the other
figures of the last run; ``--report`` measures nothing and rewrites RESULTS.md (with
``--full``, RESULTS-full.md) from the stored figures, after a goal or its text changed.
Ctrl-C (exit 130) or SIGTERM (143) stops the benchmark running, its worker processes
too, and writes no results.

Each run is compared with the last committed results file of its suite (``git show
HEAD:benchmarks/results.json``): a figure more than 20 % worse than there is flagged in
the terminal and in RESULTS.md (an instruction count, which the machine does not move,
at 3 %: :data:`TOLERANCE`) (the direction of "worse" comes from the figure's goal,
else from its unit: times, sizes, CPU and errors are better lower, rates and speed-ups
higher). Beside each flagged figure stands how long a fixed reference workload
(:func:`speed_ref`) took during the same script now over then (:class:`SpeedSampler`
times it before, during and after each script; ``speed_ref_<script>_s``): these shared
machines move by 10-70 % from one minute to the next. The figures are not scaled by it:
the workload moves more than tactorbelt's code does (1.6-1.7 x against 1.04-1.17 x in
the same scripts of one run), so scaling would hide regressions.

Each ``benchmarks/bench_*.py`` is a script that prints one JSON object (key -> number) as
its last line. This runner runs each one in its own process (so one failing benchmark
does not hide the others), merges the figures into ``benchmarks/results.json`` and
writes ``benchmarks/RESULTS.md``: figure, value, baseline, ratio, goal, met or not.

Every figure with a goal is compared with a baseline measured in the same run, because
these machines are shared and noisy: an absolute time alone says little.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import platform
import signal
import statistics
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
    full_only: bool = False  # measured by ``make bench-full`` only


#: Arguments of the quick suite (``make bench``): rates on smaller stores and runs.
QUICK_ARGS: dict[str, list[str]] = {
    "bench_sessions": ["--participants", "30", "--long-repetitions", "8"],
    "bench_analysis": ["--participants", "100"],
    "bench_postgresql": ["--participants", "20", "--trials", "200"],
    "bench_audio": ["--seconds", "15"],
    "bench_player": ["--seconds", "3"],
    "bench_validate": ["--pulses", "4"],
    "bench_condition_tests": ["--participants", "30", "--pb-participants", "6", "--pb-sims",
                              "20", "--no-r"],
    "bench_window_load": ["--rounds", "1", "--targets", "6"],
    "bench_drive": ["--stimulus"],
    "bench_participant_drive": ["--participants", "6"],
}
#: A figure this much worse than in the last committed results is flagged.
REGRESSION = 0.20
#: Figures flagged at a smaller change: counts a shared machine does not move.
TOLERANCE: dict[str, float] = {"session_instructions": 0.03,
                                "shaped_session_instructions": 0.03}
#: The reference workload is timed this many times (the median is kept) before and after
#: each script (:class:`SpeedSampler` takes fewer while it runs): short runs, like the
#: benchmarks' own repeats, so that other processes taking turns on the cores (which a
#: median of short runs does not see) do not count, and a slower machine (which every
#: run sees) does.
SPEED_REPEATS = 101
#: Stored as ``speed_ref_workload``: change it with :func:`_workload` (reference times of
#: another workload are not compared).
SPEED_WORKLOAD = 2


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
    Goal("pattern_player_p99_ms", "player_p99_ms", "<=", 0.2, "ms",
         "the same player and deadlines as player_p99_ms, streaming a haptic pattern (a "
         "between-tactor path) instead of a stimulus"),
    Goal("display_frame_ms", "frame_budget_ms", "<=", 0.05, "ms",
         "DirectionDisplay.update, dynamic, angle moving: the trapezoid state machine on "
         "floats (~0.003 ms), the paper law on 6 tactors (NumPy on one row, ~0.012 ms), "
         "belt.set_amplitudes (~0.011 ms on the sim belt, its motor model's state kept "
         "every 256 frames included); ~300,000 instructions a frame"),
    Goal("display_static_frame_ms", "frame_budget_ms", "<=", 0.05, "ms",
         "as display_frame_ms without the trapezoid"),
    Goal("player_frame_ms", "frame_budget_ms", "<=", 0.05, "ms",
         "a row of the chunked stimulus cache, the deadline, belt.set_amplitudes (about "
         "0.011 ms on the sim belt: NumPy checks and calibration of 6 values, the motor "
         "model's log)"),
    Goal("wire_encode_decode_per_s", "wire_reference_per_s", None, None, "frames/s",
         "Python calls per packet (builder, Packet, split/join, struct); CRC-16 in C "
         "(binascii.crc_hqx), COBS with bytes methods"),
    Goal("wire_speedup_vs_reference", None, ">=", 10.0, "x",
         "baseline: the same round trip with the per-byte reference CRC-16 and COBS"),
    Goal("wire_stream_cpu_pct_1khz", None, "<=", 2.0, "% of a core",
         "one 6-tactor SET_AMPLITUDES built and framed per ms (codec only)"),
    Goal("belt_stream_cpu_pct_1khz", None, "<=", 2.0, "% of a core",
         "Belt.set_amplitudes to the emulator: the write system call (about half: one "
         "os.write a frame, pyserial only for what the port refuses), NumPy checks and "
         "calibration on 6 values, the levels and the codec in Python"),
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
    Goal("validate_sim_s", "validate_sim_schedule_s", "<=", 60.0, "s",
         "6 tactors x 20 pulses on the sim belt (wall clock): the pulses themselves take "
         "most of it (the baseline); the rest is opening the belt, sleep overshoot, the "
         "figure and the files", full_only=True),
    Goal("validate_sim_overhead_s", None, "<=", 5.0, "s",
         "validate onsets besides its pulses: the figure (about 1-2 s), opening the belt, "
         "the sleeps' overshoot, writing the files"),
    Goal("bridge_handshake_uncertainty_ms", None, "<=", 1.0, "ms",
         "tactorbelt serve's clock handshake from a Python page on loopback: half the "
         "least of 16 WebSocket round trips (median of 20 hellos)"),
    Goal("bridge_play_to_onset_p99_ms", None, "<=", 5.0, "ms",
         "a Python page's play request to the sim belt's onset on the page clock: the "
         "loopback WebSocket and the bridge's event loop on 2 shared cores"),
    Goal("session_s", "session_per_trial_s", "<=", 2.0, "s",
         "the store (~30 %; a third of the instructions: ~58,000 sample rows, 100 to an "
         "INSERT with the trial_id bound once and the rest in 64, 32, ..., 1 rows (8 "
         "statement texts, which PRAGMA foreign_keys makes SQLite parse again every "
         "session), each with its trial_id index entry, each trial a savepoint kept in "
         "memory, a WAL checkpoint every 1,000 pages; no foreign-key lookup per row in a "
         "batch), the model's "
         "decisions (~30 %: the ERM model's vibration ~0.08-0.11 ms a query, the "
         "window's terms memoised; sensing ~0.065 ms and perceiving ~0.03 ms a trial), "
         "the 100 Hz sampling read in runs of ticks (~15 %), the runner (~20 %): some "
         "300 small operations a trial, three quarters of the time in the interpreter "
         "and NumPy's cost per call; commits batched (64 trials, no fsync) here"),
    Goal("session_batch_speedup", None, None, None, "x",
         "baseline: the same sessions committing (and fsyncing) every trial; the disk"),
    Goal("sessions_1000_s", None, "<=", 120.0, "s",
         "one store per worker, 2 workers; same costs as session_s, each session "
         "slower with both cores busy (0.21 s of CPU, 0.19-0.22 s alone); 107-110 s "
         "over 3 runs of this code (sessions_1000_steady_s 103-105 s); 114-119 s over 3 "
         "runs of the code 6 % of instructions before it, and 132-145 s over 3 runs of "
         "the code 5 % before it during a slow spell of this machine (session_s 0.24-0.36 "
         "s alone, while the reference workload ran at its usual speed)",
         full_only=True),
    Goal("sessions_1000_est_s", None, "<=", 120.0, "s",
         "make bench: 30 participants, scaled to 1,000; as session_s (0.24 s a session "
         "on each of 2 cores busy at once, ~0.83 ms a trial; this machine's speed moves "
         "by 10-30 % within minutes: see machine_drift)"),
    Goal("sessions_per_s", None, None, None, "participants/s",
         "the fast path (batched commits), 2 workers; as session_s"),
    Goal("long_session_rss_growth_mb", None, "<=", 20.0, "MB",
         "resident memory of a long session (1,920 trials; full: 10,080) from trial "
         "1,100 (or 20 %) to its end: ~1 KB a trial, the TrialResult kept per trial "
         "(samples kept for the last 1,000 trials only)"),
    Goal("sessions_linearity", None, "<=", 1.25, "x",
         "last 10 % of sessions over the first 10 %: 1.0 is linear growth (the "
         "machine's drift during the run counts in it)"),
    Goal("sessions_tenths_spread", None, None, None, "x",
         "the slowest tenth of the run's sessions over the fastest (each worker's "
         "sessions in order): a slow spell anywhere in the run, which machine_drift "
         "(the ends only) misses; 1.0: a steady machine"),
    Goal("sessions_1000_steady_s", None, None, None, "s",
         "sessions_1000_s at the pace of the run's fastest tenth: the code's cost when "
         "the machine's other load lets it run (not the goal figure)"),
    Goal("session_cpu_s", None, None, None, "s",
         "CPU seconds (user + system) of the workers per session: as session_s"),
    Goal("session_instructions", None, None, None, "instructions",
         "user-space instructions of one paper session (session_s's work), counted by "
         "valgrind: unlike the wall-time figures it moves ~1 % from run to run, so it "
         "is flagged when 3 % worse than in the committed results; ~23 % of it is "
         "SQLite inserting rows (sqlite3_step), the rest the interpreter and NumPy"),
    Goal("shaped_session_instructions", "session_instructions", None, None, "instructions",
         "session_instructions with the study's drive shaped (the sim belt's shaper): a "
         "trial's read taken from its stimulus's memo, where the shaper was at rest at "
         "the onset (docs/belts.md, 'How it is solved')"),
    Goal("shaped_session_instructions_x", None, "<=", 1.05, "x",
         "shaped_session_instructions over session_instructions, the same run: the rest "
         "is the read's search and gathering over the memo and the walks that remain"),
    Goal("drive_kick_rise_ms", "drive_plain_rise_ms", "<=", 30.0, "ms",
         "drive shaping (docs/belts.md): the sim belt's 10-90 % rise at full level with a "
         "5 V kick (k = 1.67, at most 40 ms; baseline: plain, the same run)"),
    Goal("drive_shaped_rise_ms", "drive_plain_rise_ms", "<=", 30.0, "ms",
         "the same within the motor's maximum voltage (3.6 V, k = 1.2, the default): not "
         "met, physics: a 30 ms rise needs k >= 1.52 (docs/belts.md, 'The goals, "
         "measured')"),
    Goal("drive_shaped_half_rise_ms", "drive_plain_half_rise_ms", "<=", 30.0, "ms",
         "the 10-90 % rise at level 0.5, 3.6 V"),
    Goal("drive_shaped_fall_ms", "drive_plain_fall_ms", "<=", 30.0, "ms",
         "the 90-10 % fall at full level, 3.6 V (reverse drive, bounded by the board's "
         "budget)"),
    Goal("drive_overshoot_max_pct", None, "<=", 5.0, "%",
         "the largest overshoot of any shaped pulse (0 by construction on the model)"),
    Goal("drive_kick_dynamic_x", None, ">=", 3.0, "x",
         "the paper's dynamic stimulus, felt against intended over the 18 between-tactor "
         "targets: plain's RMS error over the 5 V kick's, the same run"),
    Goal("drive_shaped_dynamic_x", None, ">=", 3.0, "x",
         "the same within the motor's maximum voltage: not met (2.46x), its slow full-level "
         "rise (see drive_shaped_rise_ms)"),
    Goal("drive_shaped_static_onset_max_ms", None, "<=", 10.0, "ms",
         "the worst onset error of any driven tactor of the 24 static targets, 3.6 V, "
         "with the 3 ms pre-roll (plain: 15 ms)"),
    Goal("sessions_core_use", None, None, None, "x",
         "the workers' CPU seconds over wall time x workers: 1.0 is both cores busy "
         "throughout (less: waiting on the disk, or one worker done early)"),
    Goal("machine_drift", None, None, None, "x",
         "session_s's sessions again after the many-session run over before it: how far "
         "the machine's speed moved meanwhile (1.0: not at all)"),
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
         "plotted trials", full_only=True),
    Goal("analyze_100_s", None, None, None, "s",
         "make bench: 100 participants; as analyze_1000_s"),
    Goal("max_rss_mb", None, "<=", 1000.0, "MB",
         "peak resident memory of analyze (full: 1,000 participants, a 1.8 GB store): "
         "the trial table and the mixed models' design matrices"),
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
    Goal("browser_clock_uncertainty_ms", None, "<=", 1.0, "ms",
         "half the least round trip of 16 WebSocket pings, Chromium <-> bridge on loopback"),
    Goal("browser_play_to_onset_p99_ms", None, "<=", 5.0, "ms",
         "Chromium's WebSocket send, the bridge's event loop and belt thread, the sim "
         "belt's start; on 2 shared cores beside the browser and Selenium; and the shaped "
         "sim belt's 3 ms pre-roll (its onset is stated 3 ms after the command, "
         "docs/belts.md 'Pre-roll'; p50 0.74 ms before it)"),
    Goal("browser_trials_stored", None, ">=", 120.0, "",
         "a 120-trial browser session: every trial in the store once"),
    Goal("browser_analysis_equal", None, ">=", 1.0, "",
         "the browser session's analysis equals the runner's on the same answers"),
]


def run_script(path: Path, timeout: float, args: list[str] | None = None) -> dict[str, float]:
    """Run one benchmark script and return the figures of its last JSON line.

    The script runs in a process group of its own. On a timeout, Ctrl-C or SIGTERM (see
    :func:`main`) the whole group is stopped, the script's worker processes too, before
    the exception goes on: none is left running after the runner."""
    env = dict(os.environ, SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy", MPLBACKEND="Agg")
    proc = subprocess.Popen([sys.executable, str(path), *(args or [])], env=env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True)
    try:
        stdout, stderr = proc.communicate(timeout=timeout)
    except BaseException:
        _stop_group(proc)
        raise
    if proc.returncode != 0:
        raise RuntimeError(stderr.strip().splitlines()[-1] if stderr.strip() else "failed")
    last = [ln for ln in stdout.splitlines() if ln.strip().startswith("{")][-1]
    data = json.loads(last)
    return {k: float(v) for k, v in data.items() if isinstance(v, int | float)}


def _stop_group(proc: subprocess.Popen[str]) -> None:
    """SIGTERM to a script's process group; 5 s later SIGKILL to whatever of it is left
    (worker processes outlive a script that ends on SIGTERM)."""
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGTERM)
    with contextlib.suppress(subprocess.TimeoutExpired):
        proc.communicate(timeout=5.0)
    with contextlib.suppress(ProcessLookupError):
        os.killpg(proc.pid, signal.SIGKILL)
    proc.communicate()


_LOWER_IS_BETTER = ("_s", "_ms", "_us", "_mb", "_pct", "_pct_1khz", "errors", "gaps",
                    "missed", "underruns_60s", "xruns_60s", "linearity", "_over_sqlite",
                    "_vs_python", "_vs_sleep_loop", "_vs_device", "delta_ms", "_instructions")
_HIGHER_IS_BETTER = ("per_s", "speedup", "_fps", "_vs_loop", "_vs_reference")
#: Figures that are counts or settings, not performance.
_NOT_COMPARED = ("participants", "trials", "samples", "sample_rows", "store_mb",
                 "player_frames", "push_trials", "samples_per_session", "factorial_power_at_8",
                 "factorial_session_trials", "long_session_trials", "audio_latency_ms",
                 "trials_pg", "trials_sqlite", "window_fps", "session_instructions_sessions")


def better(key: str) -> str | None:
    """``lower``, ``higher`` or None (not a performance figure): from the figure's goal,
    else from its name."""
    # a script's run time (noisy) and the reference workload's time are not compared
    if key in _NOT_COMPARED or key.startswith(("time_", "speed_ref_")):
        return None
    for g in GOALS:
        if g.key == key and g.op is not None:
            return "lower" if g.op == "<=" else "higher"
    if key.endswith(_HIGHER_IS_BETTER):
        return "higher"
    if key.endswith(_LOWER_IS_BETTER):
        return "lower"
    return None


def committed(name: str) -> dict[str, float]:
    """The results file ``name`` as last committed (empty when none or no git)."""
    try:
        proc = subprocess.run(["git", "show", f"HEAD:benchmarks/{name}"], cwd=HERE,
                              capture_output=True, text=True, timeout=10, check=False)
    except (OSError, subprocess.SubprocessError):
        return {}
    if proc.returncode != 0:
        return {}
    try:
        data = json.loads(proc.stdout)
    except json.JSONDecodeError:
        return {}
    return {k: float(v) for k, v in data.items() if isinstance(v, int | float)}


def _workload() -> float:
    """What :func:`speed_ref` times: interpreted arithmetic and dict stores, then NumPy
    calls on small arrays (most of tactorbelt's time goes to such work), ~0.2 ms."""
    import math

    import numpy as np

    a = np.linspace(0.0, 1.0, 256)
    acc = 0.0
    table: dict[int, float] = {}
    for i in range(750):
        acc += math.sin(i) * 0.5
        table[i & 255] = acc
    for i in range(75):
        acc += float((a * i).sum())
    return acc


def speed_ref(repeats: int = SPEED_REPEATS) -> float:
    """Seconds the reference workload takes now (median of ``repeats``): this machine's
    current speed, to compare figures measured at different times."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        _workload()
        times.append(time.perf_counter() - t0)
    return statistics.median_high(times)


class SpeedSampler:
    """The machine's speed while a script runs: :func:`speed_ref` before, every ``every``
    seconds from a thread (about 1 % of a core; the script is another process) and after;
    :attr:`seconds` is the median of them all. The machine's speed moves within a script
    as well as between scripts."""

    def __init__(self, every: float = 0.25, repeats: int = 11) -> None:
        import threading

        self.every, self.repeats = every, repeats
        self.samples: list[float] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._sample, name="speed-ref", daemon=True)

    def _sample(self) -> None:
        while not self._stop.wait(self.every):
            self.samples.append(speed_ref(self.repeats))

    def __enter__(self) -> SpeedSampler:
        self.samples.append(speed_ref())
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()
        if exc[0] is None:
            self.samples.append(speed_ref())

    @property
    def seconds(self) -> float:
        return statistics.median_high(self.samples)


def speed_key(script: str) -> str:
    """The results key of the reference time around ``script``."""
    return f"speed_ref_{script}_s"


def speed_factors(now: dict[str, float], before: dict[str, float],
                  measured: dict[str, str]) -> dict[str, float]:
    """Per figure measured now (``measured``: figure -> script), how much longer the
    reference workload took during its script now than in ``before`` (none where either
    run lacks a reference time, or timed another workload)."""
    out: dict[str, float] = {}
    if now.get("speed_ref_workload") != before.get("speed_ref_workload"):
        return out
    for key, script in measured.items():
        ref_now, ref_then = now.get(speed_key(script)), before.get(speed_key(script))
        if ref_now and ref_then and ref_now > 0 and ref_then > 0:
            out[key] = ref_now / ref_then
    return out


def regressions(now: dict[str, float], before: dict[str, float],
                limit: float = REGRESSION) -> list[tuple[str, float, float, float]]:
    """Figures more than ``limit`` worse than before: (key, before, now, how much worse)."""
    out = []
    for key in sorted(now.keys() & before.keys()):
        way = better(key)
        old, new = before[key], now[key]
        if way is None or old <= 0 or new < 0:
            continue
        worse = (new - old) / old if way == "lower" else (old - new) / old
        if worse > TOLERANCE.get(key, limit):
            out.append((key, old, new, worse))
    return out


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


def _files(full: bool) -> tuple[str, str]:
    """The results file and the report of the quick or the full suite."""
    return ("results-full.json", "RESULTS-full.md") if full else ("results.json", "RESULTS.md")


def _parse(argv: list[str]) -> argparse.Namespace:
    names = [*sorted(p.stem for p in HERE.glob("bench_*.py")), "cli_help"]
    ap = argparse.ArgumentParser(
        prog="benchmarks/run.py",
        description="Run the benchmarks and write results.json and RESULTS.md (--full: "
                    "results-full.json and RESULTS-full.md), comparing every figure with "
                    "the last committed results of the same suite.")
    ap.add_argument("names", nargs="*", metavar="NAME",
                    help="run only these (the other figures of the last run are kept): "
                         + ", ".join(names))
    ap.add_argument("--full", action="store_true",
                    help="every script with its own defaults (1,000 participants; make "
                         "bench-full) instead of the quick suite")
    ap.add_argument("--report", action="store_true",
                    help="measure nothing: rewrite RESULTS.md (or RESULTS-full.md) from "
                         "the stored figures with the goals and texts as they are now")
    args = ap.parse_args(argv)
    unknown = sorted(set(args.names) - set(names))
    if unknown:
        ap.error(f"no benchmark {', '.join(unknown)}; choose from {', '.join(names)}")
    if args.report and args.names:
        ap.error("--report measures nothing; give no benchmark names with it")
    return args


def _terminated(signum: int, frame: object) -> None:
    raise SystemExit(128 + signum)  # through run_script's clean-up: its group is stopped


def main(argv: list[str] | None = None) -> int:
    args = _parse(sys.argv[1:] if argv is None else argv)
    full = args.full
    only = set(args.names)
    results_name = _files(full)[0]
    previous = HERE / results_name
    before = committed(results_name)
    if args.report:
        if not previous.exists():
            print(f"run.py: no {previous} to report; run the benchmarks first",
                  file=sys.stderr)
            return 2
        write_report(json.loads(previous.read_text()), full, only, {}, before, {},
                     rewritten=True)
        return 0
    results: dict[str, float] = {}
    if only and previous.exists():  # a partial run updates the figures it measures
        results.update(json.loads(previous.read_text()))
    failures: dict[str, str] = {}
    seconds: dict[str, float] = {}
    measured: dict[str, str] = {}  # figure -> the script that measured it now
    t_all = time.perf_counter()
    scripts = sorted(HERE.glob("bench_*.py"))
    for path in scripts:
        name = path.stem
        if only and name not in only:
            continue
        script_args = [] if full else QUICK_ARGS.get(name, [])
        print(f"running {name} {' '.join(script_args)}...", flush=True)
        t0 = time.perf_counter()
        figures = {}
        with SpeedSampler() as speed:
            try:
                figures = run_script(path, timeout=1800, args=script_args)
            except Exception as exc:  # report and go on: one failure must not hide the rest
                failures[name] = str(exc)
                print(f"  {name} failed: {exc}", flush=True)
        _keep(results, measured, name, figures, speed)
        seconds[name] = time.perf_counter() - t0
        results[f"time_{name}_s"] = round(seconds[name], 1)  # kept by partial runs
        print(f"  {seconds[name]:.1f} s", flush=True)
    if not only or "cli_help" in only:
        with SpeedSampler() as speed:
            figures = cli_help()
        _keep(results, measured, "cli_help", figures, speed)
    results["speed_ref_workload"] = SPEED_WORKLOAD
    if not only:
        results["bench_total_s" if not full else "bench_full_total_s"] = round(
            time.perf_counter() - t_all, 1)
    previous.write_text(json.dumps(results, indent=2, sort_keys=True) + "\n")
    write_report(results, full, only, failures, before,
                 speed_factors(results, before, measured))
    return 1 if failures else 0


def _keep(results: dict[str, float], measured: dict[str, str], name: str,
          figures: dict[str, float], speed: SpeedSampler) -> None:
    """Add what ``name`` measured to ``results``, noting each figure's script in
    ``measured``, and the reference workload's time meanwhile (kept by partial runs)."""
    results.update(figures)
    measured.update(dict.fromkeys(figures, name))
    results[speed_key(name)] = round(speed.seconds, 9)


def _limits_text() -> str:
    """How much worse a figure may get: ``20 % (session_instructions: 3 %)``."""
    others = ", ".join(f"{k}: {v:.0%}" for k, v in TOLERANCE.items())
    return f"{REGRESSION:.0%}" + (f" ({others})" if others else "")


def write_report(results: dict[str, float], full: bool, only: set[str],
                 failures: dict[str, str], before: dict[str, float],
                 speed: dict[str, float], rewritten: bool = False) -> None:
    """Write RESULTS.md (RESULTS-full.md) from ``results`` and print it, then the figures
    more than :data:`REGRESSION` (:data:`TOLERANCE`) worse than ``before`` (the
    committed results), each with the reference workload's time now over then
    (``speed``: :func:`speed_factors`)."""
    results_name, report_name = _files(full)
    worse = regressions(results, before)
    lines = [
        "# Benchmark results" + (" (make bench-full)" if full else ""),
        "",
        f"Machine: {os.cpu_count()} cores, Python {platform.python_version()}, "
        f"{platform.system()} {platform.machine()}. Written by "
        f"`make {'bench-full' if full else 'bench'}`"
        + (f" in {results['bench_total_s']:.0f} s (goal: under 300 s)."
           if "bench_total_s" in results and not full else "."),
        *([f"A partial run: {', '.join(sorted(only))} measured now; every other figure is "
           f"from an earlier run (their dates are in git)."] if only else []),
        *([f"Rewritten by `run.py --report` from {results_name}: the figures as measured "
           f"(their dates are in git), the goals and texts as they are now."]
          if rewritten else []),
        "",
        "| figure | value | baseline | ratio | goal | met | what limits it |",
        "|---|---|---|---|---|---|---|",
    ]
    for g in GOALS:
        goal = f"{g.op} {g.limit:g} {g.unit}" if g.op and g.limit is not None else "none"
        if g.key not in results:
            where = "make bench-full only" if g.full_only and not full else "not measured"
            lines.append(f"| {g.key} | {where} | | | {goal} | | {g.limits} |")
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
    lines += ["", f"## Compared with the last committed {results_name}", ""]
    if before and speed:
        lo, hi = min(speed.values()), max(speed.values())
        lines += [f"The reference workload took {lo:.2f}-{hi:.2f} x as long during the same "
                  "scripts as in the committed run (a figure is not scaled by it; one "
                  "flagged where the machine was much slower is suspect).", ""]
    elif before and not rewritten:
        lines += ["The committed results hold no reference times of this workload "
                  "(speed_ref_*).", ""]
    if not before:
        lines.append("No committed results to compare with.")
    elif not worse:
        lines.append(f"No figure is more than {_limits_text()} worse.")
    else:
        lines += [f"{len(worse)} figure(s) more than {_limits_text()} worse (shared, noisy "
                  "machine: run the benchmark again alone before believing one):", "",
                  "| figure | committed | now | worse by | reference workload now/then |",
                  "|---|---|---|---|---|"]
        lines += [f"| {k} | {old:.4g} | {new:.4g} | {w:.0%} | "
                  f"{f'{speed[k]:.2f}' if k in speed else 'not measured'} |"
                  for k, old, new, w in worse]
    times = {k[len("time_"):-len("_s")]: v for k, v in sorted(results.items())
             if k.startswith("time_")}
    if times:
        lines += ["", "## Time per benchmark", "",
                  f"Sum: {sum(times.values()):.0f} s (scripts; cli_help adds about 1 s). "
                  "The reference workload's time around each script shows the machine's "
                  "speed then (lower: faster).", "",
                  "| script | s | reference workload, us |", "|---|---|---|"]
        lines += [f"| {k} | {v:.1f} | "
                  f"{'' if speed_key(k) not in results else f'{results[speed_key(k)] * 1e6:.1f}'} |"
                  for k, v in times.items()]
    lines += ["", "## All figures", "", "| key | value |", "|---|---|"]
    lines += [f"| {k} | {v:.6g} |" for k, v in sorted(results.items())
              if not k.startswith(("time_", "speed_ref_"))]
    if failures:
        lines += ["", "## Failed benchmarks", ""]
        lines += [f"- {k}: {v}" for k, v in failures.items()]
    (HERE / report_name).write_text("\n".join(lines) + "\n")
    print((HERE / report_name).read_text())
    for k, old, new, w in worse:
        machine = f"; reference workload {speed[k]:.2f} x as long" if k in speed else ""
        print(f"WORSE: {k} {old:.4g} -> {new:.4g} ({w:.0%} worse than committed{machine})",
              flush=True)


if __name__ == "__main__":
    signal.signal(signal.SIGTERM, _terminated)
    try:
        sys.exit(main())
    except KeyboardInterrupt:
        code = 130
    except SystemExit as exc:
        if exc.code != 128 + signal.SIGTERM:
            raise
        code = exc.code
    print("run.py: stopped; the benchmark running was stopped and no results were written",
          file=sys.stderr)
    sys.exit(code)
