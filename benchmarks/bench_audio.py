"""Benchmark: the audio belt's callback load and underruns, through a real JACK server.

Plays a dynamic stimulus on an 8-channel ``audio:`` belt at 48 kHz through PortAudio's
JACK host API for ``--seconds`` (default 60) with JACK's period at 256 frames (a JACK
dummy server is started if none runs, and stopped at the end), and prints one JSON
object:

- ``audio_callback_cpu_pct``: the callback's CPU time (its thread's) over the audio
  time it rendered, in % of one core (goal: under 5 %);
- ``audio_underruns_60s``: output underflows PortAudio reported, scaled to 60 s (goal 0);
- ``audio_render_block_us``: CPU time to render one 256-frame block of the dynamic
  stimulus, measured off the stream (the part the machine's load does not change much);
- ``audio_latency_ms``: PortAudio's reported output latency of the stream.

Run alone: ``.venv/bin/python benchmarks/bench_audio.py [--seconds 60]``.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time

import numpy as np


class _NotHere(Exception):
    """JACK, PortAudio or their Python packages are missing: nothing is measured."""


def _jack_running() -> bool:
    try:
        import jack
    except (ImportError, OSError) as exc:
        raise _NotHere(f"JACK-Client cannot be imported: {exc}") from None

    try:
        jack.Client("tactorbelt-bench-probe", no_start_server=True).close()
    except jack.JackError:
        return False
    return True


def start_jack() -> subprocess.Popen[bytes] | None:
    """A JACK dummy server (48 kHz, 256 frames, 8 outputs) unless one runs."""
    if _jack_running():
        return None
    if shutil.which("jackd") is None:
        raise _NotHere("jackd is not installed (Debian: apt install jackd2)")
    proc = subprocess.Popen(
        ["jackd", "--no-realtime", "-d", "dummy", "-r", "48000", "-p", "256", "-P", "8",
         "-C", "2"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        env=dict(os.environ, JACK_NO_AUDIO_RESERVATION="1"), start_new_session=True)
    end = time.monotonic() + 15
    while not _jack_running():
        if proc.poll() is not None or time.monotonic() > end:
            proc.kill()
            raise _NotHere("jackd -d dummy did not start")
        time.sleep(0.1)
    return proc


def render_block_us(belt, stimulus, blocks: int = 2000) -> float:
    """CPU time per 256-frame block of the callback's rendering, off the stream."""
    out = np.zeros((256, belt.channels), dtype=np.float32)
    belt.play(stimulus, None)
    belt._stream.stop()  # the callback must not run concurrently
    belt._render(out, 256)  # takes the program
    t0 = time.thread_time()
    for _ in range(blocks):
        belt._render(out, 256)
    return (time.thread_time() - t0) / blocks * 1e6


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    args = ap.parse_args()
    try:
        server = start_jack()
    except _NotHere as exc:  # the runner reports the figures as not measured
        print(f"bench_audio: not measured: {exc}", file=sys.stderr)
        print("{}")
        return
    try:
        from tactorbelt.devices import open_belt
        from tactorbelt.stimuli import make_stimulus

        with open_belt("audio:system?channels=8&carrier_hz=250") as belt:
            stimulus = make_stimulus(belt.layout, 10.0, "dynamic")
            belt.play(stimulus, None)
            time.sleep(args.seconds)
            load = belt.callback_load
            underruns = belt.underruns
            latency_ms = belt.latency_s * 1000
            block_us = render_block_us(belt, stimulus)
    finally:
        if server is not None:
            server.terminate()
            server.wait(10)
    print(json.dumps({
        "audio_callback_cpu_pct": 100.0 * load,
        "audio_underruns_60s": underruns * 60.0 / args.seconds,
        "audio_render_block_us": block_us,
        "audio_latency_ms": latency_ms,
    }))


if __name__ == "__main__":
    main()
