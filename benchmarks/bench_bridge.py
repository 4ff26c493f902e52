"""Benchmark of the browser bridge (``tactorbelt serve``) from a Python page on loopback.

Starts ``tactorbelt serve --belt sim`` (wall clock) in its own process and drives it
with a WebSocket client that behaves as the jsPsych plugin does (answers every ping at
once). The client's "page clock" is ``time.perf_counter`` plus a fixed offset; the
bridge stamps with ``time.perf_counter_ns`` too, and on Linux both read the same
CLOCK_MONOTONIC, so the true offset is known and the handshake's error can be measured,
not only its claimed bound. What a real browser adds (its event loop, its
``performance.now()`` resolution) is measured by the headless Chromium benchmark.

- ``bridge_handshake_uncertainty_ms``: the median, over ``--handshakes`` hellos, of the
  uncertainty the handshake reports (half the least of 16 round trips);
  ``bridge_handshake_uncertainty_max_ms`` the largest;
  ``bridge_handshake_error_max_ms``: the largest |estimated - true offset|, which must
  stay within the reported uncertainty (``bridge_handshake_within`` = fraction that do).
- ``bridge_play_to_onset_p99_ms`` (and p50): from the page's clock just before it sends
  a ``play`` to the onset the bridge reports on the page's clock (the belt's command
  time on the sim belt), over ``--plays`` plays of the paper schedule's stimuli, each
  answered (``trial``) so the store writes between plays as in a session;
  ``bridge_play_reply_p99_ms``: send to the reply's arrival (what the page waits);
  ``bridge_play_to_receipt_p99_ms`` the part before the bridge read the request (the
  loopback and the bridge's wake-up) and ``bridge_receipt_to_onset_p99_ms`` the bridge's
  own part (its reply's ``received_ms`` to the onset). ``--gap-ms`` waits between trials
  as a study's response and interval do (plays far apart wake an idle process).

Prints one JSON object as its last line. Run alone:
``.venv/bin/python benchmarks/bench_bridge.py`` (about 15 s).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

OFFSET_MS = 98_765.4321


def page_ms() -> float:
    return time.perf_counter_ns() / 1e6 + OFFSET_MS


class _Page:
    def __init__(self, ws: Any) -> None:
        self.ws = ws
        self.waiting: dict[int, asyncio.Future[tuple[dict[str, Any], float]]] = {}
        self.next_id = 0
        self.reader = asyncio.create_task(self._read())

    async def _read(self) -> None:
        from websockets.exceptions import ConnectionClosed

        try:
            async for raw in self.ws:
                got = page_ms()
                msg = json.loads(raw)
                if msg["type"] == "ping":
                    await self.ws.send(json.dumps({"type": "pong", "seq": msg["seq"],
                                                   "t_page_ms": page_ms()}))
                    continue
                fut = self.waiting.pop(msg.get("id"), None)
                if fut is not None:
                    fut.set_result((msg, got))
        except ConnectionClosed:
            pass

    async def request(self, msg: dict[str, Any]) -> tuple[dict[str, Any], float, float]:
        """The reply, the page time just before sending and at the reply's arrival."""
        self.next_id += 1
        fut: asyncio.Future[tuple[dict[str, Any], float]] = (
            asyncio.get_running_loop().create_future())
        self.waiting[self.next_id] = fut
        sent = page_ms()
        await self.ws.send(json.dumps({**msg, "id": self.next_id}))
        reply, got = await asyncio.wait_for(fut, 30)
        return reply, sent, got


async def _measure(ws_url: str, handshakes: int, plays: int, gap_ms: float
                   ) -> dict[str, float]:
    from websockets.asyncio.client import connect

    unc: list[float] = []
    err: list[float] = []
    for k in range(handshakes):
        async with connect(ws_url) as ws:
            page = _Page(ws)
            w, _, _ = await page.request({"type": "hello", "participant": f"H{k:03d}"})
            unc.append(w["clock"]["uncertainty_ms"])
            err.append(abs(w["clock"]["offset_ms"] - OFFSET_MS))
            await page.request({"type": "end", "status": "aborted"})
    to_onset: list[float] = []
    reply: list[float] = []
    transport: list[float] = []
    own: list[float] = []
    async with connect(ws_url) as ws:
        page = _Page(ws)
        w, _, _ = await page.request({"type": "hello", "participant": "P01"})
        schedule = w["schedule"]
        for i in range(min(plays, len(schedule))):
            t = schedule[i]
            played, sent, got = await page.request({"type": "play", "index": t["index"]})
            if played["type"] != "played":
                raise SystemExit(f"play {i}: {played}")
            to_onset.append(played["onset_ms"] - sent)
            reply.append(got - sent)
            transport.append(played["received_ms"] - sent)
            own.append(played["onset_ms"] - played["received_ms"])
            await page.request({"type": "trial", "index": t["index"],
                                "play_id": played["id"],
                                "response": {"target": t["target"], "rt_ms": 700.0,
                                             "device": "mouse"}})
            if gap_ms:
                await asyncio.sleep(gap_ms / 1000)
    u, e = np.array(unc), np.array(err)
    return {
        "bridge_handshake_uncertainty_ms": float(np.median(u)),
        "bridge_handshake_uncertainty_max_ms": float(u.max()),
        "bridge_handshake_error_max_ms": float(e.max()),
        "bridge_handshake_within": float(np.mean(e <= u + 1e-6)),
        "bridge_play_to_onset_p50_ms": float(np.percentile(to_onset, 50)),
        "bridge_play_to_onset_p99_ms": float(np.percentile(to_onset, 99)),
        "bridge_play_reply_p99_ms": float(np.percentile(reply, 99)),
        "bridge_play_to_receipt_p99_ms": float(np.percentile(transport, 99)),
        "bridge_receipt_to_onset_p99_ms": float(np.percentile(own, 99)),
        "bridge_plays": float(len(to_onset)),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--handshakes", type=int, default=20)
    ap.add_argument("--plays", type=int, default=288)
    ap.add_argument("--gap-ms", type=float, default=0.0,
                    help="Wait this long after each trial before the next play (a study's "
                         "response and ITI; 0: back to back).")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        proc = subprocess.Popen(
            [sys.executable, "-m", "tactorbelt", "serve", "--belt", "sim", "--store",
             str(Path(tmp) / "bench.sqlite"), "--port", "0"],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            assert proc.stdout is not None
            line = proc.stdout.readline()
            if not line.startswith("open: "):
                raise SystemExit(f"tactorbelt serve did not start: {line!r}")
            url = line.removeprefix("open: ").strip()
            hostport = url.split("//", 1)[1].split("/", 1)[0]
            token = url.rsplit("token=", 1)[1]
            figures = asyncio.run(_measure(f"ws://{hostport}/ws?token={token}",
                                           args.handshakes, args.plays, args.gap_ms))
        finally:
            proc.terminate()
            try:
                proc.communicate(timeout=20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.communicate()
    print(json.dumps({k: round(v, 4) for k, v in figures.items()}))


if __name__ == "__main__":
    main()
