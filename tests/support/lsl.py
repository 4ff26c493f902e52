"""Lab Streaming Layer on the loopback interface, for tests: a config and a real inlet.

    from support.lsl import loopback_env, pylsl_or_skip, start_inlet

    pylsl = pylsl_or_skip()                    # skips, with the reason, without liblsl
    env = loopback_env(tmp_path)               # LSLAPICFG: this machine only, own session
    inlet = start_inlet(env, timeout_s=60)     # a recorder in another process
    inlet = start_inlet(env, streams=("tactorbelt-markers",))   # one that takes the markers
    ...                                        # run tactorbelt with --lsl and env
    got = inlet_result(inlet)                  # {"markers": [[ts, text], ...], ...}

``loopback_env`` writes an ``lsl_api.cfg`` that keeps LSL on this machine
(``ResolveScope = machine``, IPv4 only) and gives the test its own LSL session id, so
no stream of another program (or another test run) is seen, and none of the test's
leaves the machine. The inlet process resolves the two tactorbelt streams, connects,
pulls until the ``session_end`` marker (or its time limit) and prints one JSON object:
``markers`` (``[timestamp, text]`` in arrival order), ``cursor`` (``[timestamp, x, y]``),
``time_correction`` (the sender's clock minus the receiver's, seconds) and
``marker_xml`` (the marker stream's description). With ``streams`` it connects to
those streams only (``cursor`` is then empty when the cursor stream is not among them).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import uuid
from pathlib import Path
from typing import Any

import pytest

__all__ = ["inlet_result", "loopback_env", "pylsl_or_skip", "start_inlet"]

INLET = r"""
import json, sys
import pylsl, pylsl.util

limit = float(sys.argv[1])
names = sys.argv[2].split(",")
end = pylsl.local_clock() + limit
inlets = {}
for name in names:
    found = pylsl.resolve_byprop("name", name, 1, max(end - pylsl.local_clock(), 0.1))
    if not found:
        print(json.dumps({"error": f"no LSL stream {name} within {limit} s"}))
        sys.exit(1)
    inlets[name] = pylsl.StreamInlet(found[0], max_buflen=60)
markers, cursor = inlets["tactorbelt-markers"], inlets.get("tactorbelt-cursor")
for inlet in inlets.values():
    inlet.open_stream(max(end - pylsl.local_clock(), 0.1))
xml = markers.info(5.0).as_xml()
tc = markers.time_correction(5.0)
got, samples, done = [], [], False
while pylsl.local_clock() < end and not done:
    try:
        sample, ts = markers.pull_sample(0.02)
    except pylsl.util.LostError:
        print(json.dumps({"error": "the marker stream was lost", "markers": got}))
        sys.exit(1)
    if sample is not None:
        got.append([ts, sample[0]])
        done = json.loads(sample[0])["event"] == "session_end"
    if cursor is not None:
        chunk, stamps = cursor.pull_chunk(0.0)
        samples += [[t, x, y] for t, (x, y) in zip(stamps, chunk)]
if cursor is not None:
    chunk, stamps = cursor.pull_chunk(0.5)
    samples += [[t, x, y] for t, (x, y) in zip(stamps, chunk)]
print(json.dumps({"markers": got, "cursor": samples, "time_correction": tc,
                  "marker_xml": xml, "complete": done}))
"""


def pylsl_or_skip() -> Any:
    """The pylsl module, or skip the test saying why it cannot load."""
    try:
        import pylsl
    except (ImportError, RuntimeError, OSError) as exc:
        pytest.skip(f"pylsl with liblsl is not available here ({type(exc).__name__}: "
                    f"{str(exc).strip().splitlines()[0] if str(exc).strip() else ''}); "
                    "pip install 'tactorbelt[lsl]'")
    return pylsl


def loopback_env(directory: Path) -> dict[str, str]:
    """The environment for LSL on this machine only, in a session of the test's own."""
    cfg = Path(directory) / "lsl_api.cfg"
    cfg.write_text("[ports]\nIPv6 = disable\n\n[multicast]\nResolveScope = machine\n\n"
                   f"[lab]\nSessionID = tactorbelt-test-{uuid.uuid4().hex}\n\n"
                   "[log]\nlevel = -2\n")
    env = dict(os.environ)
    env["LSLAPICFG"] = str(cfg)
    return env


def start_inlet(env: dict[str, str], timeout_s: float = 60.0,
                streams: tuple[str, ...] = ("tactorbelt-markers", "tactorbelt-cursor")
                ) -> subprocess.Popen[str]:
    """Start the recorder process (module doc), connecting to ``streams``; it gives up
    after ``timeout_s``."""
    return subprocess.Popen([sys.executable, "-c", INLET, str(timeout_s), ",".join(streams)],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def inlet_result(proc: subprocess.Popen[str], timeout_s: float = 90.0) -> dict[str, Any]:
    """What the recorder process received (fails the test when it failed)."""
    try:
        out, err = proc.communicate(timeout=timeout_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        out, err = proc.communicate()
        pytest.fail(f"the LSL inlet did not finish: {err[-2000:]}")
    assert proc.returncode == 0, (out, err[-2000:])
    result: dict[str, Any] = json.loads(out.strip().splitlines()[-1])
    return result
