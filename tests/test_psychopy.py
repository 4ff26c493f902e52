"""The PsychoPy helper (tactorbelt.psychopy, docs/psychopy.md): onsets locked to flips,
motors off when the window closes and at ``core.quit()``.

PsychoPy's window needs OpenGL and a display, so ``support.flipwindow.FlipWindow`` stands
in for the calls the helper uses, as ``psychopy.visual.Window`` implements them.
``core.quit()`` is PsychoPy's own when PsychoPy is installed (it ends with
``sys.exit(0)``), else ``sys.exit(0)``.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from support.flipwindow import FRAME_NS, FlipWindow
from tactorbelt import TactorbeltError
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.psychopy import TactileBelt


@pytest.fixture
def rig() -> Any:
    clock = SimClock(start_ns=5 * FRAME_NS + 123)
    win = FlipWindow(clock)
    belt = open_belt("sim", clock=clock)
    helper = TactileBelt(win, belt, clock=clock)
    yield clock, win, belt, helper
    helper.close()


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
    assert helper.onset_s == win.flips[-1] / 1e9 and helper.playing
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
    assert [t for t, _ in starts] == [round(s * 1e9) for s in onsets]
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
#: stimuli, and a mouse that clicks on its third poll of each trial.
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
    def __init__(self, win=None):
        self.polls = 0
    def clickReset(self):
        self.polls = 0
    def getPressed(self):
        self.polls += 1
        return [self.polls >= 3, 0, 0]
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
