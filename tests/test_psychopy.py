"""The PsychoPy helper (tactorbelt.psychopy, docs/psychopy.md) on a stand-in window:
onsets locked to flips, times converted to the experiment's clock, arguments refused
before a flip, a failed start that leaves no call queued, Builder-like status and data
columns, motors off when the window closes, at ``core.quit()`` and on SIGTERM.

``support.flipwindow.FlipWindow`` stands in for the calls the helper uses, as
``psychopy.visual.Window`` implements them, on a simulated clock: exact and fast.
tests/test_psychopy_window.py runs the same cases with PsychoPy's own window under Xvfb.
``core.quit()`` is PsychoPy's own when PsychoPy is installed (it ends with
``sys.exit(0)``), else ``sys.exit(0)``.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from support.flipwindow import FRAME_NS, FlipWindow
from support.recordingbelt import RecordingBelt, motors_on_at_end, read_commands
from tactorbelt import ConfigError, DeviceError, TactorbeltError
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.psychopy import FINISHED, NOT_STARTED, STARTED, TactileBelt


@pytest.fixture
def rig() -> Any:
    clock = SimClock(start_ns=5 * FRAME_NS + 123)
    win = FlipWindow(clock)
    belt = open_belt("sim", clock=clock)
    helper = TactileBelt(win, belt, clock=clock)
    yield clock, win, belt, helper
    helper.close()


def _onset_s(win: Any, belt: Any) -> float:
    """The onset of a stimulus started at the last flip: on the shaped sim belt (the
    default) its pre-roll after the flip (``Belt.preroll_ns``, docs/belts.md)."""
    return (win.flips[-1] + belt.preroll_ns) / 1e9


def _starts(belt: Any) -> list[tuple[int, float]]:
    """(time, target) of every stimulus the belt was given."""
    return [(c.t_ns, c.stimulus.target_deg) for c in belt.commands() if c.stimulus is not None]


def test_present_starts_the_stimulus_on_the_next_flip_not_before(rig: Any) -> None:
    clock, win, belt, helper = rig
    helper.present(45.0, "dynamic")
    clock.sleep_until_ns(clock.now_ns() + 5_000_000)  # drawing the frame
    assert _starts(belt) == [] and helper.onset_s is None
    win.flip()
    assert _starts(belt) == [(win.flips[-1], 45.0)]
    assert belt.preroll_ns == 3_000_000
    assert helper.onset_s == _onset_s(win, belt) and helper.playing
    win.flip()
    win.flip()  # later frames start nothing more
    assert len(_starts(belt)) == 1


def test_each_trial_starts_on_its_own_flip(rig: Any) -> None:
    clock, win, belt, helper = rig
    onsets = []
    for target in (0.0, 90.0, 202.5):
        for _ in range(30):  # inter-trial frames
            win.flip()
        helper.present(target, "static", duration_s=0.2)
        win.flip()
        onsets.append(helper.onset_s)
    starts = _starts(belt)
    assert [t for t, _ in starts] == [round(s * 1e9) - belt.preroll_ns for s in onsets]
    assert [t for t, _ in starts] == win.flips[30::31]
    assert [a for _, a in starts] == [0.0, 90.0, 202.5]


def test_stop_on_flip_turns_the_motors_off_with_the_frame(rig: Any) -> None:
    clock, win, belt, helper = rig
    helper.present(30.0)
    win.flip()
    assert np.max(belt.levels) > 0.5
    helper.stop_on_flip()
    assert np.max(belt.levels) > 0.5  # not before the flip
    win.flip()
    assert np.all(belt.levels == 0) and not helper.playing


def test_closing_the_window_mid_stimulus_turns_the_motors_off(rig: Any) -> None:
    clock, win, belt, helper = rig
    helper.present(30.0, "dynamic")
    win.flip()
    clock.sleep_until_ns(clock.now_ns() + 300_000_000)
    assert np.max(belt.levels) > 0
    win.close()
    assert win.closed  # PsychoPy's own close still runs
    assert np.all(belt.levels == 0)
    with pytest.raises(TactorbeltError, match="closed"):
        helper.present(30.0)


def test_a_bad_mode_fails_when_asked_not_at_the_flip(rig: Any) -> None:
    _, win, _, helper = rig
    with pytest.raises(TactorbeltError, match="mode"):
        helper.present(30.0, "wobbly")
    win.flip()  # nothing scheduled, nothing raised


def test_times_are_reported_on_the_timebase_the_flips_are_on(tmp_path: Path) -> None:
    # PsychoPy's clock counts from its import (or is PTB's GetSecs): here 1000 s ahead
    # of the clock the belt is played on
    clock = SimClock(start_ns=5 * FRAME_NS + 123)
    win = FlipWindow(clock)
    experiment_clock = lambda: clock.now_ns() / 1e9 + 1000.0  # noqa: E731
    with TactileBelt(win, open_belt("sim", clock=clock), clock=clock,
                     timebase=experiment_clock) as helper:
        helper.present(45.0, duration_s=0.5)
        win.flip()
        assert helper.onset_s == pytest.approx(_onset_s(win, helper.belt) + 1000.0, abs=1e-9)
        assert helper.tStart == helper.onset_s and helper.now() == experiment_clock()
        clock.advance(100_000_000)
        helper.stop()
        assert helper.onset_s is not None
        # stopped 100 ms after the flip (the command): the pre-roll less after the onset
        assert helper.tStop == pytest.approx(win.flips[-1] / 1e9 + 1000.0 + 0.1, abs=1e-6)


class _Clock:
    """A PsychoPy-like clock object (getTime)."""

    def __init__(self, clock: SimClock) -> None:
        self.clock = clock

    def getTime(self) -> float:
        return self.clock.now_ns() / 1e9 - 7.0


def test_a_psychopy_clock_object_is_a_timebase(rig: Any) -> None:
    clock, win, belt, _ = rig
    with TactileBelt(win, belt, clock=clock, timebase=_Clock(clock)) as helper:
        helper.present(10.0)
        win.flip()
        assert helper.onset_s == pytest.approx(_onset_s(win, belt) - 7.0, abs=1e-9)


@pytest.mark.parametrize("bad", [
    {"duration_s": -1}, {"duration_s": 0}, {"duration_s": float("nan")},
    {"duration_s": float("inf")}, {"duration_s": "2"}, {"duration_s": True},
    {"mode": "wobbly"}, {"target_deg": float("nan")}, {"target_deg": "45"},
    {"target_deg": True}, {"target_deg": None},
], ids=lambda b: f"{next(iter(b))}={next(iter(b.values()))!r}")
def test_a_bad_argument_is_refused_at_present_and_later_flips_work(
        rig: Any, bad: dict[str, Any]) -> None:
    clock, win, belt, helper = rig
    args = {"target_deg": 0.0, "mode": "static", **bad}
    with pytest.raises(ConfigError, match=next(iter(bad)).split("_")[0]):
        helper.present(**args)
    assert win._toCall == []  # nothing queued for the flip
    win.flip()
    win.flip()
    helper.present(0.0, "static", duration_s=0.2)
    win.flip()
    assert helper.playing and helper.onset_s == _onset_s(win, belt)


@pytest.mark.parametrize("bad", [
    {"duration_s": 0}, {"duration_s": -1.0}, {"duration_s": float("nan")},
    {"law": "loud"}, {"falloff_deg": 0}, {"period_s": 0}, {"transit_s": -0.1},
    {"name": ""}, {"clock": "perf_counter"}, {"timebase": 12.0}, {"belt": 3},
    {"layout": [0, 90, 180, 270]},
], ids=lambda b: next(iter(b)))
def test_a_bad_argument_is_refused_when_the_helper_is_made(
        rig: Any, bad: dict[str, Any]) -> None:
    clock, win, _, _ = rig
    args: dict[str, Any] = {"belt": "sim", **bad}
    with pytest.raises(ConfigError):
        TactileBelt(win, **args)
    win.flip()


def test_layout_or_calibration_with_a_belt_opened_already_is_refused(rig: Any) -> None:
    from tactorbelt.geometry import Layout

    clock, win, belt, _ = rig
    with pytest.raises(ConfigError, match="open_belt"):
        TactileBelt(win, belt, clock=clock, layout=Layout.even(6))


def test_a_window_without_callonflip_is_refused() -> None:
    with pytest.raises(ConfigError, match="callOnFlip"):
        TactileBelt(object(), "sim")


def test_a_device_error_at_a_flip_comes_out_of_it_once_and_later_flips_work(
        tmp_path: Path) -> None:
    clock = SimClock(start_ns=5 * FRAME_NS)
    win = FlipWindow(clock)
    belt = RecordingBelt(tmp_path / "belt.log", clock=clock)
    with TactileBelt(win, belt, clock=clock) as helper:
        ran: list[str] = []
        win.callOnFlip(ran.append, "before")
        belt.unplugged = True
        helper.present(90.0, "dynamic")
        win.callOnFlip(ran.append, "after")
        with pytest.raises(DeviceError, match="unplugged"):
            win.flip()
        assert ran == ["before"]  # PsychoPy stops at the call that raised
        assert helper.onset_s is None and helper.status == FINISHED
        assert isinstance(helper.error, DeviceError) and not helper.playing
        win.flip()  # the call after it runs now, once; the failed one never again
        win.flip()
        assert ran == ["before", "after"] and win._toCall == []
        belt.unplugged = False
        helper.present(90.0, "dynamic")
        win.flip()
        assert helper.onset_s == _onset_s(win, belt) and helper.error is None
    assert [c for c in read_commands(tmp_path / "belt.log") if c[0] == "play"] == [
        ("play", 90.0)]


def test_status_and_times_follow_builders_component(rig: Any) -> None:
    clock, win, belt, helper = rig
    assert (NOT_STARTED, STARTED, FINISHED) == (0, 1, -1)  # psychopy.constants
    assert helper.status == NOT_STARTED and helper.name == "belt"
    helper.present(30.0, duration_s=0.5)
    assert helper.status == NOT_STARTED  # not before the flip
    win.flip()
    assert helper.status == STARTED and helper.tStart == _onset_s(win, belt)
    clock.advance(600_000_000)  # the duration ran out
    assert helper.status == FINISHED
    assert helper.tStop == pytest.approx(helper.tStart + 0.5)
    # a Builder routine resets its components at its start
    helper.status = NOT_STARTED
    helper.tStart = helper.tStop = None
    assert helper.status == NOT_STARTED
    helper.present(60.0)
    win.flip()
    assert helper.status == STARTED
    helper.stop_on_flip()
    win.flip()
    assert helper.status == FINISHED and helper.tStop == win.flips[-1] / 1e9


class _Rows:
    """ExperimentHandler's addData and nextEntry."""

    def __init__(self) -> None:
        self.rows: list[dict[str, Any]] = [{}]

    def addData(self, name: str, value: Any) -> None:
        self.rows[-1][name] = value

    def nextEntry(self) -> None:
        self.rows.append({})


def test_add_data_puts_the_onset_columns_in_the_row(rig: Any) -> None:
    clock, win, belt, helper = rig
    exp = _Rows()
    helper.add_data(exp)  # before any stimulus: empty columns
    exp.nextEntry()
    helper.present(45.0, "dynamic", duration_s=1.0)
    win.flip()
    helper.add_data(exp)
    assert set(exp.rows[0]) == set(exp.rows[1])
    assert exp.rows[0]["belt.started"] is None
    assert exp.rows[1] == {
        "belt.started": _onset_s(win, belt), "belt.startedRefresh": None,
        "belt.stopped": None, "belt.target_deg": 45.0, "belt.mode": "dynamic",
        "belt.duration_s": 1.0}


def test_the_helper_hands_sigterm_back_when_it_closes(rig: Any) -> None:
    clock, win, belt, helper = rig
    assert signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL
    helper.close()
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL


def test_a_sigterm_handler_of_the_script_is_left_alone(rig: Any) -> None:
    clock, win, belt, helper = rig
    helper.close()
    mine = lambda signum, frame: None  # noqa: E731
    old = signal.signal(signal.SIGTERM, mine)
    try:
        with TactileBelt(win, open_belt("sim", clock=clock), clock=clock):
            assert signal.getsignal(signal.SIGTERM) is mine
        assert signal.getsignal(signal.SIGTERM) is mine
    finally:
        signal.signal(signal.SIGTERM, old)


SIGTERM_SCRIPT = """
import sys, time
sys.path.insert(0, {tests!r})
from support.flipwindow import FlipWindow
from support.recordingbelt import RecordingBelt
from tactorbelt.clock import WallClock
from tactorbelt.psychopy import TactileBelt

win = FlipWindow(WallClock())
belt = TactileBelt(win, RecordingBelt("belt.log"))
belt.present(60.0, "dynamic", duration_s=60.0)
win.flip()
try:
    print("playing", flush=True)
    while True:
        win.flip()
finally:
    print("finally ran", flush=True)
"""


def test_sigterm_ends_the_script_like_sys_exit_143_with_the_motors_off(
        tmp_path: Path) -> None:
    script = SIGTERM_SCRIPT.format(tests=str(Path(__file__).resolve().parent))
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=tmp_path)
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().strip() == "playing"
        assert motors_on_at_end(read_commands(tmp_path / "belt.log"))
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 143, err
    assert "finally ran" in out and "Traceback" not in err  # unwound, quietly
    commands = read_commands(tmp_path / "belt.log")
    assert not motors_on_at_end(commands) and commands[-1] == ("closed", None)


SCRIPT = """
import atexit, sys, time
import numpy as np
sys.path.insert(0, {tests!r})
from support.flipwindow import FlipWindow
from tactorbelt.clock import WallClock
from tactorbelt.devices import open_belt
from tactorbelt.psychopy import TactileBelt

belt = open_belt("sim")
# registered first, so it runs after the helper's handler (atexit is last in, first out)
atexit.register(lambda: print("levels at exit", float(np.max(belt.levels)), flush=True))
win = FlipWindow(WallClock())
helper = TactileBelt(win, belt)
helper.present(60.0, "dynamic")
win.flip()
time.sleep(0.05)
print("levels playing", float(np.max(belt.levels)), flush=True)
{quit}
"""


def _psychopy(*modules: str) -> bool:
    """True when these PsychoPy modules import here (PsychoPy is not a dependency)."""
    proc = subprocess.run([sys.executable, "-c", f"import {', '.join(modules)}"],
                          capture_output=True, timeout=60)
    return proc.returncode == 0


@pytest.mark.parametrize("quit", [
    "sys.exit(0)  # how core.quit() ends",
    "from psychopy import core; core.quit()",
], ids=["sys-exit", "psychopy-core-quit"])
def test_core_quit_turns_the_motors_off(quit: str) -> None:
    if "psychopy" in quit and not _psychopy("psychopy.core"):
        pytest.skip("PsychoPy is not installed (pip install psychopy)")
    tests = str(Path(__file__).resolve().parent)
    script = textwrap.dedent(SCRIPT).format(tests=tests, quit=quit)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 0, proc.stderr
    lines = dict(line.rsplit(" ", 1) for line in proc.stdout.splitlines() if "levels" in line)
    assert float(lines["levels playing"]) > 0
    assert float(lines["levels at exit"]) == 0.0


EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "psychopy" / "tactile_localisation.py"

#: Runs the example with PsychoPy's own core and data (ExperimentHandler, TrialHandler,
#: the data file) and stand-ins for what needs a display: the window (FlipWindow), text
#: stimuli, and a mouse whose button is down from the fixation, then up, then down on
#: its fifth poll of each trial (the response: 2 frames after the prompt's).
EXAMPLE_HARNESS = """
import runpy, sys, types
sys.path.insert(0, {tests!r})
import psychopy, psychopy.core, psychopy.data
from support.flipwindow import FlipWindow
from tactorbelt.clock import WallClock

class Window(FlipWindow):
    def __init__(self, **kwargs):
        super().__init__(WallClock())

class TextStim:
    def __init__(self, win, **kwargs):
        pass
    def draw(self):
        pass

class Mouse:
    # the left button held from the fixation (first two polls), released, then pressed
    def __init__(self, win=None):
        self.polls = 0
    def clickReset(self):
        self.polls = 0
    def getPressed(self):
        self.polls += 1
        return [self.polls in (1, 2) or self.polls >= 5, 0, 0]
    def getPos(self):
        return (0.2, 0.2)

visual = types.ModuleType("psychopy.visual")
visual.Window, visual.TextStim = Window, TextStim
event = types.ModuleType("psychopy.event")
event.Mouse, event.getKeys = Mouse, lambda keys=None: []
sys.modules["psychopy.visual"], sys.modules["psychopy.event"] = visual, event
psychopy.visual, psychopy.event = visual, event
psychopy.core.wait = lambda s, hogCPUperiod=0.2: None
sys.argv = ["tactile_localisation.py", "--belt", "sim", "--participant", "P09",
            "--repetitions", "1"]
runpy.run_path({example!r}, run_name="__main__")
"""


def test_the_example_experiment_runs_with_psychopys_data_handlers(tmp_path: Path) -> None:
    if not _psychopy("psychopy.core", "psychopy.data"):
        pytest.skip("PsychoPy is not installed (pip install psychopy)")
    tests = str(Path(__file__).resolve().parent)
    script = EXAMPLE_HARNESS.format(tests=tests, example=str(EXAMPLE))
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=120, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    (data_file,) = (tmp_path / "data").glob("P09_tactile-localisation_*.csv")
    import pandas as pd

    d = pd.read_csv(data_file)
    assert len(d) == 16  # 8 directions x 2 modes, once each
    assert sorted(zip(d["target_deg"], d["mode"], strict=True)) == sorted(
        (k * 45.0, m) for k in range(8) for m in ("static", "dynamic"))
    assert d["belt.started"].notna().all() and (d["belt.started"].diff().dropna() > 0).all()
    assert (d["response.deg"] == 45.0).all() and (d["participant"] == "P09").all()
    # the button held from the fixation did not count: the press 4 frames later did
    assert (d["response.rt"] > 3 * FRAME_NS / 1e9).all()
