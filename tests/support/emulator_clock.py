"""The emulator's clock zero on the host's clock, for checking device-time stamps (the
emulator's levels log, its onsets) against host time in tests and benchmarks."""

from __future__ import annotations

import os
import select
import time

from tactorbelt import DeviceError
from tactorbelt.devices import wire


def clock_offset_bracket(pty: str, pings: int = 200) -> tuple[int, int]:
    """``[lo, hi]`` (ns on ``time.perf_counter_ns``) holding the emulator clock's zero.

    Measured on a fresh connection to an emulator's pseudo-terminal with ``pings``
    PING/PONG round trips: each bounds the zero by its send and receive times minus the
    device time in the PONG. For checking device-time stamps (its levels log, onsets)
    against host time in tests and benchmarks.

    The bracket is where the most round trips agree (Marzullo's algorithm): on a loaded
    machine the emulator can stamp a PING with the start of a read loop that began
    before the PING arrived, and such a round trip's bounds lie past the others'; with
    every round trip consistent it is their intersection.

    Raises:
        DeviceError: the emulator did not answer a PING within 2 s, or no bracket holds
            more than half of the round trips.
    """
    fd = os.open(pty, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    dec = wire.FrameDecoder()
    bounds: list[tuple[int, int]] = []
    try:
        for i in range(pings):
            # the emulator stamps every request of one read loop with the time the loop
            # began: let it return to waiting, so the stamp is the arrival's
            time.sleep(0.002)
            send = time.perf_counter_ns()
            os.write(fd, b"\x00" + wire.encode_frame(wire.ping(i & 0xFF, i)))
            pong = None
            deadline = time.monotonic() + 2.0
            while pong is None and time.monotonic() < deadline:
                select.select([fd], [], [], 0.05)
                try:
                    data = os.read(fd, 4096)
                except BlockingIOError:
                    continue
                recv = time.perf_counter_ns()
                for p in dec.feed(data):
                    reply = wire.parse_reply(p)
                    if isinstance(reply, wire.Pong) and reply.nonce == i:
                        pong = reply
            if pong is None:
                raise DeviceError(f"the emulator on {pty} did not answer a PING")
            d_ns = pong.device_time_us * 1000
            bounds.append((send - d_ns - 999, recv - d_ns))
    finally:
        os.close(fd)
    agree, lo, hi = most_agreed(bounds)
    if 2 * agree <= len(bounds):
        raise DeviceError(f"inconsistent clock offset bracket on {pty}: at most {agree} of "
                          f"{len(bounds)} round trips agree")
    return lo, hi


def most_agreed(bounds: list[tuple[int, int]]) -> tuple[int, int, int]:
    """Marzullo's algorithm: ``(count, lo, hi)`` of the interval that the most of
    ``bounds`` (closed intervals) hold."""
    events = sorted([(lo, 0) for lo, _ in bounds] + [(hi, 1) for _, hi in bounds])
    best, count, best_lo, best_hi = 0, 0, 0, 0
    for i, (x, kind) in enumerate(events):
        if kind == 0:  # a start (sorted before an end at the same time: closed intervals)
            count += 1
            if count > best:
                best, best_lo, best_hi = count, x, events[i + 1][0]
        else:
            count -= 1
    return best, best_lo, best_hi
