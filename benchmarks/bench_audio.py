"""Benchmark: the audio belt's callback load and underruns, through a real JACK server.

Plays a dynamic stimulus on an 8-channel ``audio:`` belt at 48 kHz through PortAudio's
JACK host API for ``--seconds`` (default 60) with JACK's period at 256 frames (a JACK
dummy server, with realtime scheduling as jackd's default, is started if none runs, and
stopped at the end), and prints one JSON
object:

- ``audio_callback_cpu_pct``: the callback's CPU time (its thread's) over the audio
  time it rendered, in % of one core (goal: under 5 %);
- ``audio_underruns_60s``: output underflows PortAudio reported, scaled to 60 s (goal 0);
- ``jack_server_xruns_60s``: the baseline in the same run: xruns the JACK server itself
  reported to an idle client over the same time (cycles the server ran late whatever
  the clients did; PortAudio reports each of them as an underflow too);
- ``audio_render_block_us``: CPU time to render one 256-frame block of the dynamic
  stimulus, measured off the stream (the part the machine's load does not change much);
- ``audio_latency_ms``: PortAudio's reported output latency of the stream.

Run alone: ``.venv/bin/python benchmarks/bench_audio.py [--seconds 60]``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

# the tests' JACK server (dummy backend) and its PortAudio-safe shutdown
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))


class _XrunCounter:
    """A JACK client that counts the server's own xruns: the baseline in the same run
    (a cycle the dummy backend itself ran late, whatever its clients do)."""

    def __init__(self) -> None:
        import jack

        self.count = 0
        self.client = jack.Client("tactorbelt-bench-xruns")
        self.client.set_xrun_callback(self._xrun)
        self.client.activate()

    def _xrun(self, _delay_usecs: float) -> None:
        self.count += 1

    def close(self) -> None:
        self.client.deactivate()
        self.client.close()


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
    import pytest

    from support.audio import ensure_jack, missing, stop_jack

    reason = missing()
    if reason is None:
        try:
            ensure_jack(realtime=True)
        except pytest.skip.Exception as exc:
            reason = str(exc)
    if reason is not None:  # the runner reports the figures as not measured
        print(f"bench_audio: not measured: {reason}", file=sys.stderr)
        print("{}")
        return
    xruns = _XrunCounter()
    try:
        from tactorbelt.devices import open_belt
        from tactorbelt.stimuli import make_stimulus

        with open_belt("audio:system?channels=8&carrier_hz=250") as belt:
            stimulus = make_stimulus(belt.layout, 10.0, "dynamic")
            belt.play(stimulus, None)
            time.sleep(args.seconds)
            # the callback's CPU time over the audio time it rendered (0..1 of one core)
            load = belt._busy_ns / 1e9 / (belt._frame / belt.samplerate) if belt._frame else 0.0
            underruns = belt.underruns
            latency_ms = belt.latency_s * 1000
            block_us = render_block_us(belt, stimulus)
        server_xruns = xruns.count
    finally:
        xruns.close()
        stop_jack()  # only a server it started; PortAudio leaves JACK first
    print(json.dumps({
        "audio_callback_cpu_pct": 100.0 * load,
        "audio_underruns_60s": underruns * 60.0 / args.seconds,
        "jack_server_xruns_60s": server_xruns * 60.0 / args.seconds,
        "audio_render_block_us": block_us,
        "audio_latency_ms": latency_ms,
    }))


if __name__ == "__main__":
    main()
