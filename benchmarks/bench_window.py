"""The 100 Hz cursor sampling while the experiment window draws at 60 Hz.

Runs a real session on the wall clock (sim belt, scripted cursor) through the
experiment window (SDL's dummy video driver unless a display is set), exactly as
``tactorbelt run`` does: the runner's loop and the window in the main thread, a frame
drawn in ``poll`` whenever one is due. Measures every interval between two successive
cursor samples of a trial; the error of an interval is ``|interval - 10 ms|``.

Prints one JSON object:

- ``window_sample_p99_ms``: p99 of the interval error with the window (goal <= 1 ms);
- ``window_sample_max_ms``: the worst interval error with the window;
- ``headless_sample_p99_ms``: the same session without a window (baseline);
- ``sleep_loop_100hz_p99_ms``: a bare 100 Hz loop on the wall clock, nothing else
  (the machine's own wake-up jitter: on a loaded machine every figure above is at
  least this);
- ``window_fps``: frames drawn per second of session;
- ``frame_ms_mean`` / ``frame_ms_p99``: time to draw one frame (the cost inside poll);
- ``samples``: intervals measured with the window.

Run alone: ``python benchmarks/bench_window.py`` (about a minute).
"""

from __future__ import annotations

import json
import os
import time
from typing import Any

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

import numpy as np

from tactorbelt.clock import WallClock
from tactorbelt.devices import open_belt
from tactorbelt.experiment.listeners import NullListener, NullOperator
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import Study
from tactorbelt.gui.window import session_window
from tactorbelt.inputs.scripted import ScriptedCursor, ScriptedResponse

STUDY = """\
name = "bench-window"
[layout]
tactors = 6
[targets]
count = 12
[stimulus]
max_presentation_s = 5.0
[session]
iti_s = 0.2
break_every = 0
[training]
passes = 0
[[test]]
condition = "dynamic"
repetitions = 1
"""

PERIOD_NS = 10_000_000


class Recorder(NullListener):
    """A listener beside the window: records the sample times of each stimulus."""

    def __init__(self) -> None:
        self.trials: list[list[int]] = []
        self.in_stimulus = False
        self.poll_ns: list[int] = []

    def on_trial_state(self, trial: Any, state: Any, now_ns: int) -> None:
        self.in_stimulus = str(getattr(state, "value", state)) == "stimulus"
        if self.in_stimulus:
            self.trials.append([])

    def on_sample(self, sample: Any) -> None:
        if self.in_stimulus:  # the runner also reports samples while waiting for home
            self.trials[-1].append(sample.t_ns)

    def errors_ms(self) -> np.ndarray:
        errs = [np.abs(np.diff(np.asarray(t, dtype=np.int64)) - PERIOD_NS)
                for t in self.trials if len(t) > 1]
        return np.concatenate(errs) / 1e6 if errs else np.zeros(0)


def _cursor() -> ScriptedCursor:
    # 1.6 s at home, then 0.5 s out: about 210 samples per trial
    return ScriptedCursor(ScriptedResponse(answer=lambda cue: 45.0, reaction_s=1.6,
                                           movement_s=0.5))


class _TimedWindow:
    """The window as the operator, its polls that drew a frame timed (the rest of the
    operator's queries go to the window as they are)."""

    def __init__(self, window: Any, rec: Recorder) -> None:
        self.window, self.rec = window, rec

    def __getattr__(self, name: str) -> Any:
        return getattr(self.window, name)

    def poll(self, now_ns: int) -> Any:
        t0 = time.perf_counter_ns()
        frames = self.window.frames
        cmd = self.window.poll(now_ns)
        if self.window.frames != frames:
            self.rec.poll_ns.append(time.perf_counter_ns() - t0)
        return cmd


def _session(study: Study, window: bool, db: str) -> tuple[Recorder, float, int]:
    clock = WallClock()
    rec = Recorder()
    with Store.open(db) as store, open_belt("sim", clock=clock,
                                            layout=study.layout_obj()) as belt:
        if not window:
            t0 = time.perf_counter()
            run_session(study, "B01", belt, _cursor(), store, clock, listeners=[rec],
                        operator=NullOperator())
            return rec, time.perf_counter() - t0, 0
        with session_window(study, input="scripted", participant="B01", clock=clock,
                            belt=belt, auto_continue_s=0.0, fps=60.0) as win:
            win.window.overlay = True  # the heaviest frame: text panel and bars too
            t0 = time.perf_counter()
            win.run(lambda: run_session(study, "B01", belt, _cursor(), store, clock,
                                        listeners=[rec, win.observer],
                                        operator=_TimedWindow(win.observer, rec)))
            return rec, time.perf_counter() - t0, win.window.frames


def _bare_loop_ms(seconds: float = 5.0) -> np.ndarray:
    clock = WallClock()
    n = round(seconds * 1e9 / PERIOD_NS)
    t0 = clock.now_ns()
    ts = np.empty(n, dtype=np.int64)
    for k in range(n):
        clock.sleep_until_ns(t0 + k * PERIOD_NS)
        ts[k] = clock.now_ns()
    return np.abs(np.diff(ts) - PERIOD_NS) / 1e6


def main() -> None:
    import tempfile

    study = Study.from_toml(STUDY)
    bare = _bare_loop_ms()
    with tempfile.TemporaryDirectory() as tmp:
        head, _, _ = _session(study, False, os.path.join(tmp, "h.sqlite"))
        rec, seconds, frames = _session(study, True, os.path.join(tmp, "w.sqlite"))
    err_w = rec.errors_ms()
    err_h = head.errors_ms()
    draw = np.asarray(rec.poll_ns, dtype=float) / 1e6
    out = {
        "window_sample_p99_ms": round(float(np.percentile(err_w, 99)), 4),
        "window_sample_max_ms": round(float(err_w.max()), 4),
        "headless_sample_p99_ms": round(float(np.percentile(err_h, 99)), 4),
        "sleep_loop_100hz_p99_ms": round(float(np.percentile(bare, 99)), 4),
        "window_fps": round(frames / seconds, 1),
        "frame_ms_mean": round(float(draw.mean()), 3),
        "frame_ms_p99": round(float(np.percentile(draw, 99)), 3),
        "samples": int(err_w.size),
    }
    print(json.dumps(out))


if __name__ == "__main__":
    main()
