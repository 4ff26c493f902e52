"""Benchmark of protocol v1 on the host: frame coding, and the emulator over its pseudo-terminal.

Prints one JSON object:

- ``wire_encode_decode_per_s``: SET_AMPLITUDES packets (6 channels) built, framed
  (COBS + 0x00) and decoded again by the incremental FrameDecoder, per second;
- ``emulator_ping_p50_ms``, ``emulator_ping_p99_ms``: PING round trips (1000) through
  the serial backend to the firmware emulator;
- ``emulator_stream_frames_per_s``: SET_AMPLITUDES frames written back to back for
  about a second, counted up to the GET_STATUS answer that follows them (the serial
  link is in order, so the emulator has handled every frame by then), with the
  emulator's framing/CRC errors and sequence gaps during the run (all should be 0).

Run alone: ``.venv/bin/python benchmarks/bench_wire.py``. The emulator figures are left
out (with ``emulator_error``) when it cannot be built (no g++).
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np


def bench_wire(seconds: float = 1.0) -> float:
    from tactorbelt.devices import wire

    rng = np.random.default_rng(0)
    frames = [[int(v) for v in rng.integers(0, 65536, 6)] for _ in range(256)]
    decoder = wire.FrameDecoder()
    n = 0
    t0 = time.perf_counter()
    deadline = t0 + seconds
    while time.perf_counter() < deadline:
        for seq, levels in enumerate(frames):
            data = wire.encode_frame(wire.set_amplitudes(seq, levels))
            (packet,) = decoder.feed(data)
            assert packet.seq == seq
        n += len(frames)
    return n / (time.perf_counter() - t0)


def bench_emulator(pings: int = 1000, stream_s: float = 1.0) -> dict[str, float]:
    from tactorbelt.devices import open_belt

    out: dict[str, float] = {}
    with open_belt("emulator") as belt:
        rtts = np.array([belt.ping() for _ in range(pings)]) * 1000.0  # type: ignore[attr-defined]
        out["emulator_ping_p50_ms"] = float(np.percentile(rtts, 50))
        out["emulator_ping_p99_ms"] = float(np.percentile(rtts, 99))
        before = belt.status()  # type: ignore[attr-defined]
        frame = np.full(belt.n_tactors, 0.5)
        n = 0
        t0 = time.perf_counter()
        deadline = t0 + stream_s
        while time.perf_counter() < deadline:
            for _ in range(100):
                belt.set_amplitudes(frame)
            n += 100
        after = belt.status()  # type: ignore[attr-defined]
        elapsed = time.perf_counter() - t0
        out["emulator_stream_frames_per_s"] = n / elapsed
        out["emulator_stream_errors"] = float(
            after.crc_errors + after.framing_errors - before.crc_errors - before.framing_errors)
        out["emulator_stream_seq_gaps"] = float(after.seq_gaps - before.seq_gaps)
    return out


def main() -> None:
    result: dict[str, object] = {"wire_encode_decode_per_s": bench_wire()}
    try:
        result.update(bench_emulator())
    except Exception as exc:  # no g++, no firmware tree: report, do not fail the run
        result["emulator_error"] = f"{type(exc).__name__}: {exc}"
        print(f"emulator benchmark skipped: {exc}", file=sys.stderr)
    print(json.dumps(result))


if __name__ == "__main__":
    main()
