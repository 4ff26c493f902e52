"""Lab Streaming Layer: `tactorbelt run --lsl` as a lab records it (docs/lsl.md).

A real LSL inlet in another process, on the loopback interface only
(support/lsl.py), records a short model-participant session run with ``--lsl``; every
marker must arrive once, in order, saying what the store says, stamped within 1 ms of
the store's times mapped to LSL's clock.
"""

from __future__ import annotations

import bisect
import json
import re
import sqlite3
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from support.lsl import inlet_result, loopback_env, pylsl_or_skip, start_inlet
from support.studies import write_study
from tactorbelt.experiment.listeners import NullListener, NullObserver, NullOperator
from tactorbelt.lsl import MARKER_EVENTS, LslListener, load_pylsl, marker


@pytest.fixture(autouse=True, scope="module")
def _lsl_on_loopback(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """The outlets this process opens stay on this machine (liblsl reads its config at
    its first use in a process)."""
    env = loopback_env(tmp_path_factory.mktemp("lsl"))
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("LSLAPICFG", env["LSLAPICFG"])
        yield


def _run(*args: str, env: dict[str, str], timeout: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "tactorbelt", *args], capture_output=True,
                          text=True, env=env, timeout=timeout)


def _clock_offset(pylsl: Any) -> float:
    """LSL's clock minus the runner's (time.perf_counter), read in this process."""
    best = None
    for _ in range(5):
        a = pylsl.local_clock()
        c = time.perf_counter()
        b = pylsl.local_clock()
        if best is None or b - a < best[0]:
            best = (b - a, (a + b) / 2 - c)
    assert best is not None
    return best[1]


def _expected(trials: list[dict[str, Any]], status: str) -> list[tuple[str, int | None]]:
    """(event, trial_index or block_index) of every marker, in order, from the store."""
    want: list[tuple[str, int | None]] = [("session_start", None)]
    block = None
    for t in trials:
        if t["block_index"] != block:
            if block is not None:
                want.append(("block_end", block))
            block = t["block_index"]
            want.append(("block_start", block))
        i = t["trial_index"]
        want += [("trial_start", i), ("stimulus_onset", i)]
        want.append(("response", i) if t["status"] == "done" else ("timeout", i))
        want.append(("trial_end", i))
    return [*want, ("block_end", block), ("session_end", None)]


def _key(m: dict[str, Any]) -> tuple[str, int | None]:
    return m["event"], m.get("trial_index", m.get("block_index"))


@pytest.mark.slow
@pytest.mark.parametrize("belt, cursor, window", [
    ("sim", "model", False),
    # the experiment window's observer behind the LSL one (SDL's dummy video driver)
    ("sim", "scripted", True),
    # firmware 1.1 reports device-true onsets: the onset marker carries the device's
    pytest.param("emulator", "scripted", False, marks=pytest.mark.emulator),
])
def test_run_with_lsl_streams_every_marker_once_in_order_on_lsl_time(
        tmp_path: Path, belt: str, cursor: str, window: bool,
        request: pytest.FixtureRequest) -> None:
    pylsl = pylsl_or_skip()
    if belt == "emulator":
        request.getfixturevalue("emulator_exe")  # built, or skipped with the reason
    study = write_study(tmp_path, name="lsl-check", targets=4, repetitions=1, training=0,
                        conditions=["dynamic"], iti_s=0.1, break_every=0)
    db = tmp_path / "s.sqlite"
    env = loopback_env(tmp_path)
    if window:
        env.update(SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy")
    inlet = start_inlet(env, timeout_s=90)
    proc = _run("run", str(study), "-p", "P07", *([] if window else ["--headless"]),
                "--input", cursor, "--belt", belt, "--db", str(db), "--lsl", "--lsl-wait",
                "60", env=env)
    got = inlet_result(inlet)
    assert proc.returncode == 0, proc.stderr
    assert "warning" not in proc.stderr, proc.stderr
    offset = _clock_offset(pylsl)
    con = sqlite3.connect(db)
    con.row_factory = sqlite3.Row
    trials = [dict(r) for r in con.execute("SELECT * FROM trials ORDER BY trial_index")]
    samples = con.execute("SELECT t.onset_ns, s.t_s, s.x, s.y FROM samples s JOIN trials t "
                          "USING (trial_id)").fetchall()
    assert len(trials) == 4 and got["complete"]

    markers = [(ts + got["time_correction"], json.loads(text)) for ts, text in got["markers"]]
    assert [_key(m) for _, m in markers] == _expected(trials, "complete")
    by = {_key(m): (ts, m) for ts, m in markers}
    assert by[("session_end", None)][1]["status"] == "complete"
    assert by[("session_start", None)][1]["participant"] == "P07"
    for t in trials:
        i = t["trial_index"]
        ts, onset = by[("stimulus_onset", i)]
        assert onset["target_deg"] == pytest.approx(t["target_deg"])
        device = belt == "emulator"
        assert (onset["condition"], onset["n_targets"], onset["load"], onset["onset_clock"]) \
            == (t["condition"], t["n_targets"], t["load"], "device" if device else "host")
        assert (t["device_onset_ns"] is not None) == device
        stored = t["device_onset_ns"] if device else t["onset_ns"]
        assert abs(ts - (stored / 1e9 + offset)) < 1e-3
        ts, resp = by[("response", i)]
        assert abs(ts - (t["acquired_ns"] / 1e9 + offset)) < 1e-3
        assert resp["correct"] == bool(t["correct"])
        assert resp["response_deg"] == pytest.approx(t["response_deg"])
        assert resp["rt_s"] == pytest.approx(t["rt_s"])
        assert by[("trial_end", i)][1]["status"] == "done"
    # markers are stamped in the order they happened
    stamps = [ts for ts, _ in markers]
    assert stamps == sorted(stamps)

    # every stored cursor sample is in the cursor stream, at its time, with its position
    stream = sorted((ts + got["time_correction"], x, y) for ts, x, y in got["cursor"])
    stream_t = [c[0] for c in stream]
    for onset_ns, t_s, x, y in samples:
        want = onset_ns / 1e9 + t_s + offset
        k = bisect.bisect_left(stream_t, want)
        k = min((j for j in (k - 1, k) if 0 <= j < len(stream)),
                key=lambda j: abs(stream_t[j] - want))
        assert abs(stream[k][0] - want) < 1e-3, (want, stream[k])
        assert stream[k][1] == pytest.approx(x, abs=1e-6)
        assert stream[k][2] == pytest.approx(y, abs=1e-6)

    xml = got["marker_xml"]
    for text in ("<type>Markers</type>", "<participant>P07</participant>",
                 "<name>lsl-check</name>", "<angle_deg>330</angle_deg>",
                 "<marker_format>tactorbelt-markers/1</marker_format>"):
        assert text in xml, text


def test_lsl_without_liblsl_says_how_to_install_it(tmp_path: Path) -> None:
    # pylsl raises RuntimeError at import when it finds no liblsl: a stand-in that does
    fake = tmp_path / "fake" / "pylsl"
    fake.mkdir(parents=True)
    (fake / "__init__.py").write_text(
        "raise RuntimeError('LSL binary library file was not found. Please make sure that "
        "the binary file can be found in the package lib folder')\n")
    study = write_study(tmp_path, targets=4, repetitions=1, training=0)
    db = tmp_path / "s.sqlite"
    env = loopback_env(tmp_path)
    env["PYTHONPATH"] = str(tmp_path / "fake")
    proc = _run("run", str(study), "-p", "P01", "--headless", "--input", "model", "--db",
                str(db), "--lsl", env=env)
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: --lsl: pylsl cannot load the liblsl library "
                                  "(LSL binary library file was not found."), proc.stderr
    assert "pip install 'tactorbelt[lsl]'" in proc.stderr and "Traceback" not in proc.stderr
    assert not db.exists()


def test_lsl_wait_needs_lsl(tmp_path: Path) -> None:
    study = write_study(tmp_path, targets=4, repetitions=1, training=0)
    proc = _run("run", str(study), "-p", "P01", "--headless", "--lsl-wait", "5",
                env=loopback_env(tmp_path))
    assert proc.returncode == 2 and "--lsl-wait is for --lsl" in proc.stderr


def test_the_lsl_listener_wraps_nothing_and_answers_no_query() -> None:
    # it is one listener beside the window: the window gets the events and answers the
    # queries itself, whatever the LSL listener does
    assert issubclass(LslListener, NullListener) and not issubclass(LslListener, NullOperator)
    assert "inner" not in LslListener.__init__.__code__.co_varnames


def test_markers_are_compact_json_in_the_documented_shape() -> None:
    text = marker("stimulus_onset", trial_index=3, target_deg=15.0, on_tactor=False,
                  condition="dynamic", n_targets=24, load="none", block="test",
                  onset_clock="device")
    assert text == ('{"event":"stimulus_onset","trial_index":3,"target_deg":15.0,'
                    '"on_tactor":false,"condition":"dynamic","n_targets":24,"load":"none",'
                    '"block":"test","onset_clock":"device"}')
    assert json.loads(marker("response", trial_index=1, rt_s=float("nan")))["rt_s"] is None
    with pytest.raises(ValueError):
        marker("stimulus_onset", response_deg=1.0)
    docs = (Path(__file__).resolve().parents[1] / "docs" / "lsl.md").read_text()
    for event, fields in MARKER_EVENTS.items():
        assert f"`{event}`" in docs, event
        for f in fields:
            assert f"`{f}`" in docs, (event, f)


def test_load_pylsl_is_the_real_module_here() -> None:
    pylsl_or_skip()
    assert load_pylsl().library_version() >= 114


class _Window(NullObserver):
    """A window stand-in: presses the button 0.5 s after each go item, answers the TLX."""

    def __init__(self, tlx: dict[str, float]) -> None:
        self.due: list[int] = []
        self.tlx = tlx

    def on_task_item(self, item: Any, onset_ns: int, spec: Any) -> None:
        if item.target:
            self.due.append(onset_ns + 500_000_000)

    def task_presses(self, now_ns: int) -> list[int]:
        out = [p for p in self.due if p <= now_ns]
        self.due = [p for p in self.due if p > now_ns]
        return out

    def ask_workload(self, info: Any) -> dict[str, float] | None:
        return self.tlx


def test_secondary_task_items_presses_and_ratings_are_markers_at_their_times(
        tmp_path: Path) -> None:
    pylsl = pylsl_or_skip()
    from support.studies import make_study
    from tactorbelt.clock import SimClock
    from tactorbelt.devices import open_belt
    from tactorbelt.experiment.runner import run_session
    from tactorbelt.experiment.schedule import make_schedule
    from tactorbelt.experiment.store import Store
    from tactorbelt.inputs.scripted import ScriptedCursor
    from tactorbelt.tasks import TLX_ITEMS

    study = make_study(
        minimal=True, name="load", tactors=4, targets=8, iti_s=0.5, break_every=0,
        training=0, timeout_s=3.0, max_presentation_s=2.0,
        blocks=[{"name": "calm", "condition": "static", "repetitions": 1},
                {"name": "busy", "condition": "dynamic", "repetitions": 1, "load": "nb2"}],
        tasks={"nb2": {"kind": "nback", "n": 2, "interval_s": 1.0, "practice": 8}},
        questionnaire={"tlx": True})
    tlx = dict.fromkeys(TLX_ITEMS, 40.0)
    cursor = ScriptedCursor(answers={t.trial_index: t.target_deg
                                     for t in make_schedule(study, "P01")})
    clock = SimClock()
    with open_belt("sim", clock=clock, layout=study.layout_obj()) as belt, \
            Store.open(tmp_path / "s.sqlite") as store, \
            LslListener(clock, belt, pylsl=pylsl) as lsl:
        res = run_session(study, "P01", belt, cursor, store, clock, listeners=[lsl],
                          observer=_Window(tlx))
        events = store.task_events(res.session_id)
    assert res.status == "complete"
    offset = lsl.to_lsl.fixed
    assert offset is not None
    sent = [(ts - offset, json.loads(text)) for ts, text in lsl.sent]
    assert [t for t, _ in sent] == sorted(t for t, _ in sent)
    # every item shown, once, at its onset, with what the store says of it
    items = [(m["phase"], m["item_index"], m["stimulus"], m["go"], t) for t, m in sent
             if m["event"] == "task_item"]
    stored = [(e["phase"], e["item_index"], e["stimulus"], bool(e["target"]), e["t_ns"] / 1e9)
              for e in events if e["item_index"] >= 0]
    # (an item whose response window the block's end cut short, without a press, was
    # shown, so it is a marker; the store leaves it unscored)
    assert len(stored) <= len(items) <= len(stored) + 1
    assert [i[:4] for i in items[:len(stored)]] == [s[:4] for s in stored]
    assert [i[4] for i in items[:len(stored)]] == pytest.approx([s[4] for s in stored],
                                                                 abs=1e-6)
    assert {i[0] for i in items} == {"practice", "dual"}
    # the window's presses, at the times the store scored them
    presses = [t for t, m in sent if m["event"] == "task_press"]
    hits = sorted(e["t_ns"] / 1e9 + e["rt_s"] for e in events if e["response"] == "press")
    assert presses and presses == pytest.approx(hits, abs=1e-6)
    phases = [(m["event"], m["phase"]) for _, m in sent if m["event"] in ("task_start",
                                                                          "task_end")]
    assert phases == [("task_start", "practice"), ("task_end", "practice"),
                      ("task_start", "dual"), ("task_end", "dual")]
    ratings = [m for _, m in sent if m["event"] == "workload"]
    assert [r["ratings"] for r in ratings] == [tlx, tlx]  # after each test block


class _Experimenter(NullObserver):
    """Pauses during the second trial's stimulus, resumes, then aborts in the fourth."""

    def __init__(self) -> None:
        self.trial = -1
        self.stimulus = False
        self.polls_paused = 0
        self.done = False

    def on_trial_state(self, trial: Any, state: Any, now_ns: int) -> None:
        self.trial, self.stimulus = trial.trial_index, state == "stimulus"

    def poll(self, now_ns: int) -> Any:
        from tactorbelt.experiment.listeners import Command

        if self.polls_paused or (self.trial == 1 and self.stimulus and not self.done):
            self.polls_paused += 1
            if self.polls_paused == 1:
                return Command.PAUSE
            if self.polls_paused == 50:
                self.done, self.polls_paused = True, 0
                return Command.RESUME
        if self.trial == 3 and self.stimulus:
            return Command.ABORT
        return None


@pytest.mark.timeout(60)
def test_pause_resume_and_abort_are_markers_and_the_aborted_trial_ends(tmp_path: Path) -> None:
    pylsl = pylsl_or_skip()
    from support.studies import make_study
    from tactorbelt.clock import SimClock
    from tactorbelt.devices import open_belt
    from tactorbelt.experiment.runner import run_session
    from tactorbelt.experiment.schedule import make_schedule
    from tactorbelt.experiment.store import Store
    from tactorbelt.inputs.scripted import ScriptedCursor

    study = make_study(tactors=4, targets=8, repetitions=1, training=0, conditions=["static"],
                       iti_s=0.2, break_every=0)
    cursor = ScriptedCursor(answers={t.trial_index: t.target_deg
                                     for t in make_schedule(study, "P01")})
    clock = SimClock()
    with open_belt("sim", clock=clock, layout=study.layout_obj()) as belt, \
            Store.open(tmp_path / "s.sqlite") as store, \
            LslListener(clock, belt, pylsl=pylsl) as lsl:
        res = run_session(study, "P01", belt, cursor, store, clock, listeners=[lsl],
                          observer=_Experimenter())
    assert res.status == "aborted"
    got = [json.loads(text) for _, text in lsl.sent]
    seq = [(m["event"], m.get("trial_index"), m.get("status")) for m in got
           if m["event"] not in ("stimulus_onset", "response", "block_start", "block_end")]
    assert seq == [
        ("session_start", None, None),
        ("trial_start", 0, None), ("trial_end", 0, "done"),
        ("trial_start", 1, None), ("pause", None, None), ("trial_end", 1, "aborted"),
        ("resume", None, None),
        ("trial_start", 1, None), ("trial_end", 1, "done"),  # run again after the pause
        ("trial_start", 2, None), ("trial_end", 2, "done"),
        ("trial_start", 3, None), ("abort", None, None), ("trial_end", 3, "aborted"),
        ("session_end", None, "aborted"),
    ]


def test_the_resume_command_keeps_the_lsl_streams() -> None:
    from tactorbelt.app.run import RunRequest, resume_command

    req = RunRequest(Path("s.toml"), "P01", lsl=True, lsl_wait=30.0)
    assert resume_command(req).endswith(" --lsl --lsl-wait 30 --resume")
    req.lsl_wait_all = True
    assert resume_command(req).endswith(" --lsl --lsl-wait 30 --lsl-wait-all --resume")
    assert "--lsl" not in resume_command(RunRequest(Path("s.toml"), "P01"))


# -- waiting for the recorder ------------------------------------------------------------------
def _wait_study(tmp_path: Path) -> Path:
    return write_study(tmp_path, name="lsl-wait", targets=4, repetitions=1, training=0,
                       conditions=["static"], iti_s=0.1, break_every=0)


@pytest.mark.slow
def test_a_recorder_of_the_markers_alone_starts_the_session_at_once(tmp_path: Path) -> None:
    pylsl_or_skip()
    env = loopback_env(tmp_path)
    inlet = start_inlet(env, timeout_s=90, streams=("tactorbelt-markers",))
    t0 = time.monotonic()
    proc = _run("run", str(_wait_study(tmp_path)), "-p", "P01", "--headless", "--input",
                "scripted", "--db", str(tmp_path / "s.sqlite"), "--lsl", "--lsl-wait", "60",
                env=env)
    took = time.monotonic() - t0
    got = inlet_result(inlet)
    assert proc.returncode == 0, proc.stderr
    lines = [line for line in proc.stderr.splitlines() if line.startswith("LSL: ")]
    assert lines[0] == ("LSL: waiting up to 60 s for a recorder (LabRecorder) on "
                        "tactorbelt-markers; the session starts as soon as tactorbelt-markers "
                        "has a consumer")
    assert re.fullmatch(r"LSL: tactorbelt-markers has a consumer, tactorbelt-cursor has none; "
                        r"\d+ s left", lines[1]), lines
    started = re.fullmatch(r"LSL: starting after ([\d.]+) s; tactorbelt-markers has a "
                           r"consumer, tactorbelt-cursor has none \(tactorbelt-cursor: .*"
                           r"--lsl-wait-all waits for every stream\)", lines[-1])
    assert started, lines
    assert float(started.group(1)) < 20 and took < 50  # not the whole minute
    assert "warning" not in proc.stderr, proc.stderr
    assert got["complete"] and got["cursor"] == []
    events = [json.loads(text)["event"] for _, text in got["markers"]]
    assert events[0] == "session_start" and events[-1] == "session_end"


@pytest.mark.slow
def test_lsl_wait_all_waits_for_every_stream_and_names_the_one_nobody_took(
        tmp_path: Path) -> None:
    pylsl_or_skip()
    env = loopback_env(tmp_path)
    inlet = start_inlet(env, timeout_s=90, streams=("tactorbelt-markers",))
    proc = _run("run", str(_wait_study(tmp_path)), "-p", "P01", "--headless", "--input",
                "scripted", "--db", str(tmp_path / "s.sqlite"), "--lsl", "--lsl-wait", "4",
                "--lsl-wait-all", env=env)
    inlet_result(inlet)
    assert proc.returncode == 0, proc.stderr
    assert ("on tactorbelt-markers and tactorbelt-cursor; the session starts as soon as every "
            "stream has a consumer") in proc.stderr
    assert ("warning: no LSL consumer connected to tactorbelt-cursor within 4 s"
            in proc.stderr), proc.stderr
    started = re.search(r"LSL: starting after ([\d.]+) s", proc.stderr)
    assert started and float(started.group(1)) >= 4.0


def test_lsl_wait_all_needs_lsl_wait(tmp_path: Path) -> None:
    proc = _run("run", str(_wait_study(tmp_path)), "-p", "P01", "--headless", "--lsl",
                "--lsl-wait-all", env=loopback_env(tmp_path))
    assert proc.returncode == 2 and "--lsl-wait-all is for --lsl-wait" in proc.stderr


class _WaitWindow(NullObserver):
    """A window stand-in: shows the wait; the experimenter stops it at the third frame."""

    def __init__(self) -> None:
        self.shown: list[tuple[str | None, list[str]]] = []

    def show_wait(self, title: str | None, lines: list[str]) -> bool:
        self.shown.append((title, lines))
        return len(self.shown) >= 3


@pytest.mark.timeout(30)
def test_the_window_shows_the_wait_and_esc_esc_ends_it() -> None:
    pylsl = pylsl_or_skip()
    from tactorbelt.clock import WallClock
    from tactorbelt.devices import open_belt

    said: list[str] = []
    window = _WaitWindow()
    clock = WallClock()
    with open_belt("sim", clock=clock) as belt:
        lsl = LslListener(clock, belt, wait_s=20, report=said.append, operator=window,
                          pylsl=pylsl)
        for name, kind in (("tactorbelt-markers", "Markers"), ("tactorbelt-cursor", "Position")):
            outlet = pylsl.StreamOutlet(pylsl.StreamInfo(name, kind, 1))
            setattr(lsl, "markers" if kind == "Markers" else "cursor", outlet)
        t0 = time.monotonic()
        have = lsl.wait_for_consumers()
        lsl.close()
    assert time.monotonic() - t0 < 5
    assert have == {"tactorbelt-markers": False, "tactorbelt-cursor": False}
    title, lines = window.shown[0]
    assert title == "Waiting for the recorder"
    assert "tactorbelt-markers: no recorder yet" in lines and "20 s left" in lines
    assert window.shown[-1] == (None, [])  # the wait screen taken down
    assert said[-1].startswith("LSL: the wait was stopped in the window after ")


def test_a_calibrated_belt_streams_its_latencies_and_marks_the_skin_onsets(
        tmp_path: Path) -> None:
    """The description carries each tactor's measured latency; ``skin_onset`` markers are
    stamped at the stored skin onsets (docs/lsl.md)."""
    pylsl = pylsl_or_skip()
    from tactorbelt import open_belt
    from tactorbelt.clock import SimClock
    from tactorbelt.devices.calibration import Calibration
    from tactorbelt.experiment.runner import run_session
    from tactorbelt.experiment.store import Store
    from tactorbelt.experiment.study import load_study
    from tactorbelt.inputs.model import make_model_cursor

    study = load_study(write_study(tmp_path, name="lsl-skin", targets=4, repetitions=1,
                                   training=0, conditions=["static"], iti_s=0.1,
                                   break_every=0))
    cal = Calibration.identity(6).with_timing(
        [{"latency_ms": 15.0 + k, "latency_sd_ms": 0.5, "rise_ms": 100.0 + k}
         for k in range(6)], "2026-01-01T00:00:00+00:00", "test")
    clock = SimClock()
    xml = ""
    with Store.open(tmp_path / "s.sqlite") as store, open_belt(
            "sim:virtual", clock=clock, layout=study.layout_obj(), calibration=cal) as belt:
        obs = LslListener(clock, belt, pylsl=pylsl)
        orig = obs.on_session_start

        def start(info: Any, schedule: Any) -> None:
            nonlocal xml
            orig(info, schedule)
            xml = obs.markers.get_info().as_xml()

        obs.on_session_start = start  # type: ignore[method-assign]
        with obs:
            res = run_session(study, "P01", belt, make_model_cursor(belt, clock, seed=2),
                              store, clock, seed=2, listeners=[obs])
        trials = store.trials(res.session_id)
    for k in range(6):
        assert f"<latency_ms>{15 + k:g}</latency_ms>" in xml
        assert f"<rise_ms>{100 + k:g}</rise_ms>" in xml
    assert "<timing_validated>2026-01-01T00:00:00+00:00</timing_validated>" in xml
    skin = {m["trial_index"]: (ts, m) for ts, text in obs.sent
            if (m := json.loads(text))["event"] == "skin_onset"}
    assert len(skin) == len(trials) == 4
    offset = obs.to_lsl.fixed
    assert offset is not None
    for t in trials:
        ts, m = skin[t["trial_index"]]
        assert ts == pytest.approx(t["skin_onset_ns"] / 1e9 + offset, abs=1e-6)
        assert m["latency_ms"] == pytest.approx((t["skin_onset_ns"] - t["onset_ns"]) / 1e6)
        assert m["sd_ms"] == pytest.approx(t["skin_onset_sd_ns"] / 1e6)
