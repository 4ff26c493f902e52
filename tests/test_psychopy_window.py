"""tactorbelt.psychopy with PsychoPy's own ``visual.Window`` (docs/psychopy.md, "Tests").

Each test runs a PsychoPy script in its own process, on a private X server (Xvfb, Mesa's
llvmpipe: ``support.xvfb``), as a lab's script runs: the onset on the flip's clock,
arguments refused before they reach a flip, a device error at a flip, SIGTERM while a
stimulus plays, and the example experiment with a mouse button held from the fixation
(XTEST input: ``support.xinput``). Skipped, with the reason, without Xvfb or without
PsychoPy's window (``pip install psychopy``; Mesa's libGL and libGLU).

Xvfb has no vertical blank: ``flip()`` returns when the frame is drawn (a few hundred
microseconds), not at 60 Hz. "Within one frame" is a 60 Hz display's frame.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from support.recordingbelt import motors_on_at_end, read_commands
from support.xvfb import Xvfb

TESTS = str(Path(__file__).resolve().parent)
EXAMPLE = Path(TESTS).parent / "examples" / "psychopy" / "tactile_localisation.py"
FRAME_S = 1 / 60  # one frame of a 60 Hz display

#: Put at the top of every script: tests/ on the path, PsychoPy's window and the helper.
PRELUDE = f"""
import json, sys, time
sys.path.insert(0, {TESTS!r})
from psychopy import constants, core, logging, visual
from tactorbelt import ConfigError, DeviceError
from tactorbelt.psychopy import TactileBelt
logging.console.setLevel(logging.ERROR)  # no 'dropped frame' warnings (Xvfb has no vsync)
win = visual.Window(size=(320, 240), units="height", fullscr=False, waitBlanking=True)
"""


@pytest.fixture(scope="module")
def display() -> Iterator[str]:
    """An Xvfb display where PsychoPy's window module imports (else the tests skip)."""
    if not Xvfb.available():
        pytest.skip("Xvfb is not installed (apt-get install xvfb)")
    with Xvfb() as d:
        reason = _no_window(d)
        if reason:
            pytest.skip(reason)
        yield d


def _no_window(display: str) -> str:
    """Why PsychoPy cannot open a window on ``display``, or ''."""
    proc = subprocess.run([sys.executable, "-c", "import psychopy.visual"],
                          capture_output=True, text=True, timeout=120,
                          env={**os.environ, "DISPLAY": display})
    if proc.returncode == 0:
        return ""
    last = (proc.stderr.strip().splitlines() or ["?"])[-1]
    return f"PsychoPy's window is not available (pip install psychopy): {last}"


def _run(display: str, body: str, tmp_path: Path, timeout: float = 120) -> dict[str, Any]:
    """Run PRELUDE + body; the script prints one JSON line starting with 'RESULT '."""
    script = PRELUDE + textwrap.dedent(body)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=timeout, cwd=tmp_path,
                          env={**os.environ, "DISPLAY": display})
    assert proc.returncode == 0, proc.stderr[-3000:]
    (line,) = [x for x in proc.stdout.splitlines() if x.startswith("RESULT ")]
    result: dict[str, Any] = json.loads(line[len("RESULT "):])
    return result


@pytest.mark.parametrize("builder_clock", [False, True], ids=["core-clock", "builder-clock"])
def test_the_onset_is_within_a_frame_of_the_flip_on_psychopys_clock(
        display: str, tmp_path: Path, builder_clock: bool) -> None:
    # builder-clock: a Builder script's globalClock, reset at the start, as the clock of
    # flip() (logging.setDefaultClock): the helper follows it
    body = """
    if BUILDER:
        globalClock = core.Clock()
        core.wait(0.2)
        globalClock.reset()
        logging.setDefaultClock(globalClock)
    from psychopy import data
    exp = data.ExperimentHandler(name="onsets", dataFileName="onsets")
    belt = TactileBelt(win, "sim", duration_s=0.5)
    assert belt.status == constants.NOT_STARTED
    trials = []
    for k in range(12):
        for _ in range(3):
            win.flip()
        belt.present(k * 30.0, "dynamic")
        flipped = win.flip()
        after = logging.defaultClock.getTime()
        trials.append({"flip": flipped, "after": after, "onset": belt.onset_s,
                       "tStart": belt.tStart, "tStartRefresh": belt.tStartRefresh,
                       "status": belt.status, "preroll": belt.belt.preroll_ns / 1e9})
        belt.add_data(exp)
        exp.nextEntry()
    belt.stop_on_flip()
    win.flip()
    exp.saveAsWideText("onsets.csv", delim=",")
    exp.abort()
    print("RESULT " + json.dumps({
        "trials": trials, "finished": belt.status, "tStop": belt.tStop,
        "constants": [constants.NOT_STARTED, constants.STARTED, constants.FINISHED]}))
    """.replace("BUILDER", str(builder_clock))
    r = _run(display, body, tmp_path)
    from tactorbelt.psychopy import FINISHED, NOT_STARTED, STARTED

    assert r["constants"] == [NOT_STARTED, STARTED, FINISHED]
    for t in r["trials"]:
        # the same clock: the command lies between the flip and the next reading of it,
        # the onset the shaped sim belt's pre-roll (3 ms, docs/belts.md) after it
        assert t["preroll"] == 0.003
        assert t["flip"] <= t["onset"] - t["preroll"] <= t["after"]
        assert 0 <= t["onset"] - t["flip"] < FRAME_S
        assert t["tStart"] == t["onset"] and t["tStartRefresh"] == t["flip"]
        assert t["status"] == STARTED
    last = r["trials"][-1]  # stopped at the next flip: after the command
    assert r["finished"] == FINISHED and r["tStop"] >= last["onset"] - last["preroll"]
    if builder_clock:  # counted from the reset, not from PsychoPy's import
        assert r["trials"][0]["flip"] < 60
    import pandas as pd

    d = pd.read_csv(tmp_path / "onsets.csv")
    assert len(d) == 12
    assert ((d["belt.started"] - d["belt.startedRefresh"]).between(0, FRAME_S)).all()
    assert list(d["belt.target_deg"]) == [k * 30.0 for k in range(12)]
    assert (d["belt.mode"] == "dynamic").all() and (d["belt.duration_s"] == 0.5).all()


def test_a_bad_duration_is_refused_at_present_and_later_flips_work(
        display: str, tmp_path: Path) -> None:
    body = """
    refused = []
    try:
        TactileBelt(win, "sim", duration_s=0)
    except ConfigError as exc:
        refused.append(str(exc))
    belt = TactileBelt(win, "sim")
    for bad in ({"duration_s": -1}, {"duration_s": float("nan")}, {"duration_s": "2"},
                {"mode": "wobbly"}, {"target_deg": float("inf")}, {"target_deg": True}):
        args = {"target_deg": 0, "mode": "static", **bad}
        try:
            belt.present(**args)
        except ConfigError as exc:
            refused.append(str(exc))
    flips = [win.flip() for _ in range(5)]  # nothing was queued: no flip raises
    belt.present(0, "static", duration_s=0.3)
    started = win.flip()
    print("RESULT " + json.dumps({"refused": refused, "flips": len(flips),
                                  "started": started, "onset": belt.onset_s,
                                  "playing": belt.playing}))
    win.close()
    """
    r = _run(display, body, tmp_path)
    assert len(r["refused"]) == 7, r["refused"]
    assert "duration_s" in r["refused"][0] and "duration_s" in r["refused"][1]
    assert r["flips"] == 5 and r["playing"]
    assert 0 <= r["onset"] - r["started"] < FRAME_S


def test_a_device_error_at_a_flip_comes_out_of_that_flip_and_later_flips_work(
        display: str, tmp_path: Path) -> None:
    # a belt that stops answering (pulled cable) when the stimulus should start
    body = """
    from support.recordingbelt import RecordingBelt
    belt = TactileBelt(win, RecordingBelt("belt.log"))
    ran = []
    win.callOnFlip(ran.append, "before")     # another component's call, before the belt's
    belt.belt.unplugged = True
    belt.present(90, "dynamic", duration_s=1.0)
    win.callOnFlip(ran.append, "after")      # and one after it
    errors = []
    try:
        win.flip()
    except DeviceError as exc:
        errors.append(str(exc))
    state = {"onset": belt.onset_s, "status": belt.status, "error": repr(belt.error)}
    for _ in range(5):
        win.flip()                           # no flip raises again
    belt.belt.unplugged = False
    belt.present(90, "dynamic", duration_s=1.0)
    flipped = win.flip()
    print("RESULT " + json.dumps({"errors": errors, "ran": ran, "failed": state,
                                  "flip": flipped, "onset": belt.onset_s,
                                  "playing": belt.playing}))
    win.close()
    """
    r = _run(display, body, tmp_path)
    assert len(r["errors"]) == 1 and "unplugged" in r["errors"][0]
    # every other call ran once: "before" with the failed flip, "after" with the next
    assert r["ran"] == ["before", "after"]
    assert r["failed"]["onset"] is None and r["failed"]["status"] == -1
    assert "DeviceError" in r["failed"]["error"]
    assert r["playing"] and 0 <= r["onset"] - r["flip"] < FRAME_S
    commands = read_commands(tmp_path / "belt.log")
    assert [w for w, _ in commands if w == "play"] == ["play"]  # the second start only
    assert not motors_on_at_end(commands)  # closed at the end


SIGTERM_SCRIPT = """
import sys
sys.path.insert(0, {tests!r})
from psychopy import visual
from support.recordingbelt import RecordingBelt
from tactorbelt.psychopy import TactileBelt
win = visual.Window(size=(320, 240), fullscr=False)
belt = TactileBelt(win, RecordingBelt("belt.log"))
belt.present(60.0, "dynamic", duration_s=60.0)
win.flip()
print("playing", flush=True)
while True:  # waiting for a response
    win.flip()
"""


def _wait_for_line(proc: subprocess.Popen[str], text: str, timeout_s: float) -> bool:
    """True when ``proc`` prints the line ``text`` within ``timeout_s`` (False when it
    ends first or the time runs out); other lines are skipped, and so is the rest."""
    assert proc.stdout is not None
    seen = threading.Event()

    def read(stream: Any) -> None:
        for line in stream:
            if line.strip() == text:
                seen.set()

    threading.Thread(target=read, args=(proc.stdout,), daemon=True).start()
    deadline = time.monotonic() + timeout_s
    while not seen.wait(0.1):
        if proc.poll() is not None or time.monotonic() > deadline:
            return seen.is_set()
    return True


def test_sigterm_while_a_stimulus_plays_exits_143_with_the_motors_off(
        display: str, tmp_path: Path) -> None:
    # the belt's log of the commands it received tells, after the process ended
    env = {**os.environ, "DISPLAY": display}
    script = SIGTERM_SCRIPT.format(tests=TESTS)
    err = tmp_path / "stderr.txt"
    with open(err, "w") as stderr_file:
        proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                                stderr=stderr_file, text=True, cwd=tmp_path, env=env)
    try:
        assert _wait_for_line(proc, "playing", timeout_s=120), "the stimulus never played"
        time.sleep(0.2)
        assert motors_on_at_end(read_commands(tmp_path / "belt.log"))
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    stderr = err.read_text()
    assert proc.returncode == 143, stderr[-3000:]
    assert "Traceback" not in stderr
    commands = read_commands(tmp_path / "belt.log")
    assert ("play", 60.0) in commands
    assert not motors_on_at_end(commands) and commands[-1] == ("closed", None)


def test_the_example_ignores_a_button_held_from_the_fixation(
        display: str, tmp_path: Path) -> None:
    """A participant holds the left button through the fixation into the prompt: the
    response is the press after they let go, not the button already down."""
    from support.xinput import XUser

    env = {**os.environ, "DISPLAY": display}
    proc = subprocess.Popen([sys.executable, str(EXAMPLE), "--belt", "sim", "--participant",
                             "P07", "--trials", "1"], cwd=tmp_path, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        with XUser(display) as user:
            x, y, w, h = user.wait_for_window(60, alive=lambda: proc.poll() is None)
            user.move(x + w // 2 + h // 4, y + h // 2)  # right of the centre: 90 degrees
            prompt_area = (x, y + int(h * 0.8), w, int(h * 0.15))  # pos (0, -0.4)
            assert user.brightest(*prompt_area) < 200  # no prompt yet
            user.press(1)  # during the fixation, and held
            deadline = time.monotonic() + 60
            # until the prompt is on the screen (or the trial ended without waiting)
            while user.brightest(*prompt_area) < 200 and proc.poll() is None:
                assert time.monotonic() < deadline, "no prompt within 60 s"
                time.sleep(0.01)
            time.sleep(0.3)
            user.release(1)
            time.sleep(0.4)
            user.press(1)  # the response
            time.sleep(0.05)
            user.release(1)
        out, _ = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 0, out[-3000:]
    (data_file,) = (tmp_path / "data").glob("P07_tactile-localisation_*.csv")
    import pandas as pd

    d = pd.read_csv(data_file)
    assert len(d) == 1
    # the held button did not count (it gave ~0.0001 s); the press did, 0.7 s after the
    # prompt was seen (less the time to see it)
    assert 0.6 < d["response.rt"].iloc[0] < 5.0
    assert abs(d["response.deg"].iloc[0] - 90.0) < 2.0
    assert 0 <= d["belt.started"].iloc[0] - d["belt.startedRefresh"].iloc[0] < FRAME_S
