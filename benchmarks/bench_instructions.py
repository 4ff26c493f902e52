"""What one model session costs in instructions: a figure a shared machine does not move.

- ``session_instructions``: the user-space instructions of one paper session on the fast
  path (the sessions of ``bench_sessions``: model participant, sim belt, runner, SQLite
  store), counted by valgrind's cachegrind: a process running ``1 + k`` sessions minus
  one running 1 (so start-up, imports and the first session's one-time work cancel
  out), over ``k``. Wall-time figures move 10-30 % with this machine's other load;
  this one moves by about 1 % from run to run (``PYTHONHASHSEED`` fixed), so a change
  of a few per cent in what a session costs shows here first. The kernel's share (file
  writes, about 4 % of a session) is not counted.
- ``shaped_session_instructions``: the same sessions with the study's ``[stimulus] drive``
  ``shaped`` (the sim belt's drive shaping, docs/belts.md "How it is solved"), and
  ``shaped_session_instructions_x``: it over ``session_instructions``, the same run
  (the goal: within 5 %). With ``--drive plain`` or ``shaped`` only that one is counted
  (as ``session_instructions``).
- ``session_instructions_sessions``: ``k``.

Needs valgrind (Debian: ``apt-get install valgrind``); without it the script exits with
the reason, and ``run.py`` reports the figure as not measured. Ctrl-C or SIGTERM (exit
143) stops both counted processes first.

Prints one JSON object as its last line.
Usage: python benchmarks/bench_instructions.py [--sessions 2] [--drive both|plain|shaped]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent

#: What the counted process runs: ``n`` sessions (participants 1..n) into a new store.
#: With ``--drive shaped`` the paper study's ``[stimulus] drive`` is ``shaped``.
_CHILD = """
import sys
from pathlib import Path
sys.path.insert(0, {here!r})
from bench_sessions import _sessions
from tactorbelt.experiment import study as _study
if {drive!r} == "shaped":
    _paper = _study.paper_study
    def _shaped():
        st = _paper()
        return st.model_copy(update={{"stimulus": st.stimulus.model_copy(
            update={{"drive": "shaped"}})}})
    _study.paper_study = _shaped
_sessions((Path({db!r}), list(range(1, {n} + 1)), False))
"""


def _count(valgrind: str, n: int, tmp: Path, drive: str = "plain") -> subprocess.Popen[str]:
    """Start counting the instructions of a process that runs ``n`` sessions."""
    code = _CHILD.format(here=str(HERE), db=str(tmp / f"s{n}.sqlite"), n=n, drive=drive)
    env = dict(os.environ, PYTHONHASHSEED="0")
    return subprocess.Popen(
        [valgrind, "--tool=cachegrind", "--cache-sim=no", "--cachegrind-out-file=/dev/null",
         sys.executable, "-c", code],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=env)


def _instructions(proc: subprocess.Popen[str], timeout: float) -> int:
    """The instruction count valgrind reports when ``proc`` ends."""
    try:
        out, _ = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        raise SystemExit(f"valgrind did not finish within {timeout:g} s") from None
    m = re.search(r"I\s+refs:\s+([\d,]+)", out)
    if proc.returncode != 0 or m is None:
        raise SystemExit(f"valgrind failed (exit {proc.returncode}):\n{out[-2000:]}")
    return int(m.group(1).replace(",", ""))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sessions", type=int, default=2,
                    help="sessions counted beyond the first (default 2)")
    ap.add_argument("--drive", choices=("both", "plain", "shaped"), default="both",
                    help="the sessions' drive: plain (the paper's), shaped, or both and "
                         "their ratio (default)")
    args = ap.parse_args()
    if args.sessions < 1:
        ap.error("--sessions must be at least 1")
    valgrind = shutil.which("valgrind")
    if valgrind is None:
        raise SystemExit("valgrind is not installed (Debian: apt-get install valgrind)")
    # SIGTERM as Ctrl-C: out through the finally below, which stops the valgrind children
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    out: dict[str, float] = {}
    for drive in ("plain", "shaped") if args.drive == "both" else (args.drive,):
        with tempfile.TemporaryDirectory() as tmp:
            # both at once: each is one thread, and the counts do not depend on the timing
            procs = [_count(valgrind, n, Path(tmp), drive) for n in (1, 1 + args.sessions)]
            try:
                one, more = (_instructions(p, timeout=900) for p in procs)
            finally:
                for p in procs:
                    if p.poll() is None:
                        p.kill()
                        p.wait()
        key = "shaped_session_instructions" if args.drive == "both" and drive == "shaped" \
            else "session_instructions"
        out[key] = round((more - one) / args.sessions)
    if args.drive == "both":
        out["shaped_session_instructions_x"] = round(
            out["shaped_session_instructions"] / out["session_instructions"], 4)
    print(json.dumps({**out, "session_instructions_sessions": args.sessions}))


if __name__ == "__main__":
    main()
