"""A session under cognitive load through the experiment window (SDL's dummy video and
audio drivers, simulated clock), with a person at the keyboard and mouse.

The test plays the participant from the window's ``on_frame`` hook: it goes on from the
waiting screens, presses the task's button after each item it judges a go item from the
stimuli alone (as the window showed or played them), and rates every test block on the
NASA-TLX screen with the arrow keys, the mouse or the stick. What the window took from
SDL's event queue must reach the store (task events, ratings) and be read back.
"""

from __future__ import annotations

import collections
from pathlib import Path
from typing import Any

import numpy as np
import pygame
import pytest

from support.inputs import FakeBackend, FakeStick
from support.studies import make_study
from support.tasks import judge
from tactorbelt._errors import ConfigError, DeviceError
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.experiment.schedule import make_schedule
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import Study, TaskSpec
from tactorbelt.gui.tlx import TLX_SCALES, TlxForm
from tactorbelt.gui.window import ExperimentWindow, run_with_window
from tactorbelt.inputs.joystick import JoystickCursor
from tactorbelt.inputs.kinds import JoystickConfig
from tactorbelt.inputs.scripted import ScriptedCursor
from tactorbelt.tasks import TLX_ITEMS, TLX_SCALE, WorkloadInfo
from tactorbelt.tasks.audio import SilentTaskAudio

SIZE = (640, 480)
MS = 1_000_000
RT_NS = 350 * MS
#: what the participant marks on the TLX: 50 + 5 * steps right of the middle
STEPS = (3, -8, 1, -5, 4, -2)
WANT = {item: 50.0 + 5 * k for item, k in zip(TLX_ITEMS, STEPS, strict=True)}


def load_study(**kw: Any) -> Study:
    """Two test blocks with a task each: visual 1-back (J key) and auditory 2-back (right
    mouse button), each with practice and a baseline; the TLX after every block."""
    return make_study(
        minimal=True, name="window-load", tactors=4, targets=8, iti_s=0.4, break_every=0,
        training=0, timeout_s=3.0, max_presentation_s=2.0,
        blocks=[{"name": "letters", "condition": "static", "repetitions": 1, "load": "vis"},
                {"name": "tones", "condition": "dynamic", "repetitions": 1, "load": "aud"}],
        tasks={"vis": {"kind": "nback", "n": 1, "modality": "visual", "interval_s": 0.9,
                       "stimulus_s": 0.4, "response": "key:j", "practice": 5,
                       "baseline": 4, "match_rate": 0.5},
               "aud": {"kind": "nback", "n": 2, "modality": "auditory", "interval_s": 1.1,
                       "stimulus_s": 0.3, "response": "mouse:right", "practice": 6,
                       "baseline": 5, "match_rate": 0.5}},
        questionnaire={"tlx": True}, **kw)


def _key(key: int, down: bool = True) -> None:
    pygame.event.post(pygame.event.Event(pygame.KEYDOWN if down else pygame.KEYUP, key=key,
                                         mod=0, unicode="", scancode=0))


def _click(button: int, pos: tuple[int, int] = (5, 5)) -> None:
    for t in (pygame.MOUSEBUTTONDOWN, pygame.MOUSEBUTTONUP):
        pygame.event.post(pygame.event.Event(t, button=button, pos=pos, touch=False))


class Person:
    """The participant, acting from ``on_frame``: see the module docstring."""

    def __init__(self, tlx: str = "keys") -> None:
        self.kinds: collections.Counter[str] = collections.Counter()
        self.tlx = tlx
        self.seen = 0
        self.history: dict[tuple[str | None, str | None], list[str]] = {}
        self.due: list[tuple[int, str]] = []  # (press at, response)
        self.pressed: list[int] = []  # when the presses were posted (sim ns)
        self.rated = 0
        self.subtitles: list[str] = []
        self.prompts: set[str] = set()
        self.intros: list[list[str]] = []
        self.abort_tlx = False
        self._tlx_sent = False

    def __call__(self, win: ExperimentWindow, kind: str) -> None:
        self.kinds[kind] += 1
        now = win.clock.now_ns()
        view = win.view(now)
        if kind == "task_alone":
            self.prompts.add(view.prompt)
        if kind == "task" and (not self.intros or view.modal_lines != self.intros[-1]):
            self.intros.append(list(view.modal_lines))
        if kind in ("instructions", "block", "break", "end", "task"):
            _key(pygame.K_SPACE)
        tasks = win.tasks
        # judge the items announced since the last frame, from their stimuli only
        for item, onset in tasks.items[self.seen:]:
            spec = win.study.tasks[tasks.name or ""] if tasks.name else None
            if spec is None:
                continue
            run = self.history.setdefault((tasks.name, tasks.phase), [])
            if judge(spec, run, item.stimulus):
                self.due.append((onset + RT_NS, spec.response))
            run.append(item.stimulus)
        self.seen = len(tasks.items)
        for at, response in [d for d in self.due if d[0] <= now]:
            self.due.remove((at, response))
            if response == "key:j":
                _key(pygame.K_j)
                _key(pygame.K_j, down=False)
            else:
                _click(3)
            self.pressed.append(now)
        if kind == "tlx" and not self._tlx_sent:
            self._tlx_sent = True
            self.rate(win)
        elif kind != "tlx":
            self._tlx_sent = False

    def rate(self, win: ExperimentWindow) -> None:
        assert win._tlx is not None
        self.subtitles.append(win._tlx.subtitle)
        if self.abort_tlx:  # the experimenter stops the session on the TLX screen
            _key(pygame.K_ESCAPE)
            _key(pygame.K_ESCAPE)
            return
        self.rated += 1
        if self.tlx == "keys":
            for k in STEPS:
                _key(pygame.K_RIGHT)  # marks the middle
                for _ in range(abs(k)):
                    _key(pygame.K_RIGHT if k > 0 else pygame.K_LEFT)
                _key(pygame.K_DOWN)
            _key(pygame.K_SPACE)
        else:  # the mouse: click each track where the value lies, then Done
            tlx = win._tlx
            assert tlx is not None
            for i, item in enumerate(TLX_ITEMS):
                r = tlx.rects[f"track{i}"]
                x = r.left + round(r.width * WANT[item] / 100)
                _click(1, (x, r.centery))
            _click(1, tlx.rects["done"].center)


def _run(study: Study, store: Store, on_frame: Any, **kw: Any) -> Any:
    """The session through the window on a simulated clock; ``on_frame`` acts."""
    clock = SimClock()
    sched = make_schedule(study, "P01")
    cursor = ScriptedCursor(answers={t.trial_index: t.target_deg for t in sched})
    with open_belt("sim", clock=clock, layout=study.layout_obj()) as belt:
        return run_with_window(study, "P01", belt, "scripted", store, clock=clock,
                               cursor=cursor, size=SIZE, auto_continue_s=None,
                               on_frame=on_frame, **kw)


@pytest.fixture(autouse=True)
def _clean_pygame() -> Any:
    yield
    pygame.display.quit()


@pytest.mark.parametrize("tlx", ["keys", "mouse"])
def test_a_windowed_load_session_stores_the_presses_and_the_ratings(tmp_path: Path,
                                                                    tlx: str) -> None:
    study = load_study()
    person = Person(tlx)
    with Store.open(tmp_path / "s.sqlite") as store:
        res = _run(study, store, person)
        sid = res.session_id
    # read back from the file, as the analysis does
    with Store.open(tmp_path / "s.sqlite") as store:
        events = store.task_events(sid)
        ratings = store.ratings(sid)
    assert res.status == "complete"
    items = [e for e in events if e["item_index"] >= 0]
    count = collections.Counter((e["task"], e["phase"]) for e in items)
    assert count[("vis", "practice")] == 5 and count[("vis", "baseline")] == 4
    assert count[("aud", "practice")] == 6 and count[("aud", "baseline")] == 5
    assert count[("vis", "dual")] >= 2 and count[("aud", "dual")] >= 2
    # every go item was answered by the button the study names, nothing else pressed
    assert all(e["correct"] for e in events), [e for e in events if not e["correct"]]
    hits = [e for e in items if e["target"]]
    assert len(hits) >= 4 and all(e["response"] == "press" for e in hits)
    assert not [e for e in events if e["item_index"] < 0]  # no extra presses
    # the press time: the poll that took it from SDL's queue, within one 10 ms tick of
    # the frame that posted it (the first at or after the item's onset plus RT_NS; in a
    # trial the frames are its ticks, from the stimulus's onset, which a shaped belt's
    # pre-roll puts 3 ms after the command)
    assert len(person.pressed) == len(hits)
    for e, posted in zip(hits, person.pressed, strict=True):
        taken = e["t_ns"] + round(e["rt_s"] * 1e9)
        assert e["rt_s"] >= RT_NS / 1e9 and 0 <= taken - posted <= 11 * MS, (e, posted)
    # the NASA-TLX after both test blocks, as marked on the screen
    assert person.rated == 2
    by_block: dict[int, dict[str, float]] = collections.defaultdict(dict)
    for r in ratings:
        assert r["scale"] == TLX_SCALE
        by_block[int(r["block_index"])][r["item"]] = r["value"]
    assert list(by_block.values()) == [WANT, WANT]
    assert [t.split(" is over")[0] for t in person.subtitles] == ["Test block 1 of 2",
                                                                  "Test block 2 of 2"]
    for kind in ("task", "task_alone", "tlx", "test", "block"):
        assert person.kinds[kind] > 0, kind
    # practice feedback, then how the practice went on the baseline's screen
    assert "Right: that was a match" in person.prompts
    assert not {p for p in person.prompts if p.startswith(("Missed", "Not a match"))}
    baseline_intros = [lines for lines in person.intros if any("once more" in x for x in lines)]
    assert len(baseline_intros) == 2
    assert all(lines[0].startswith("In the practice you caught") and
               lines[0].endswith("matches and never pressed wrongly.")
               for lines in baseline_intros)


def test_visual_items_show_at_their_onset_and_auditory_ones_are_scheduled_for_it(
        tmp_path: Path) -> None:
    study = load_study()
    person = Person()
    seen: dict[str, Any] = {}

    def hook(win: ExperimentWindow, kind: str) -> None:
        person(win, kind)
        seen["win"] = win
        glyph = win.view(win.clock.now_ns()).glyph
        if glyph is not None and kind in ("test", "task_alone"):
            # two copies, left and right of the ellipse, clear of it, same height
            left, right = win.renderer.glyph_rects(glyph)
            g = win.renderer.geometry
            assert left.right < g.cx - g.rx and right.left > g.cx + g.rx
            assert left.centery == right.centery == round(g.cy)
            assert (g.cx - left.centerx) == pytest.approx(right.centerx - g.cx, abs=1)

    with Store.open(tmp_path / "s.sqlite") as store:
        res = _run(study, store, hook)
        events = store.task_events(res.session_id)
    win: ExperimentWindow = seen["win"]
    items = {(e["task"], e["phase"], e["item_index"]): e for e in events
             if e["item_index"] >= 0}
    # every visual item was drawn at the sampling tick nearest its onset (within 5 ms)
    vis_onsets = sorted(e["t_ns"] for k, e in items.items() if k[0] == "vis")
    shown = dict(win.tasks.glyph_frames)
    assert sorted(shown) == vis_onsets
    assert all(abs(shown[t] - t) <= 5 * MS for t in vis_onsets)
    # every auditory item was handed to the sound output for its onset (simulated
    # clock: the silent output records it; tests/test_task_audio.py plays real ones)
    audio = win.tasks.audio
    assert isinstance(audio, SilentTaskAudio)
    aud = sorted((e["t_ns"], e["stimulus"]) for k, e in items.items() if k[0] == "aud")
    assert sorted((p.onset_ns, p.label) for p in audio.played) == aud
    assert all(p.label.startswith("tone") for p in audio.played)


def test_the_tlx_is_operable_with_the_stick_alone(tmp_path: Path) -> None:
    study = load_study()
    clock = SimClock()
    stick = FakeStick(100)
    cursor = JoystickCursor(JoystickConfig(), backend=FakeBackend(stick))
    moves = iter([(0.0, 0.0)] * 3 + [
        *[m for k in STEPS for m in [(1.0, 0.0), (0.0, 0.0)]
          + [(1.0 if k > 0 else -1.0, 0.0), (0.0, 0.0)] * abs(k)
          + [(0.0, 1.0), (0.0, 0.0)]]])
    state: dict[str, Any] = {"confirmed": False}

    def hook(win: ExperimentWindow, kind: str) -> None:
        assert kind == "tlx"
        nxt = next(moves, None)
        if nxt is not None:
            stick.axes[0], stick.axes[1] = nxt  # SDL: + is right, + is pulled back
            return
        if not state["confirmed"]:
            state["confirmed"] = True
            pygame.event.post(pygame.event.Event(pygame.JOYBUTTONDOWN, button=0,
                                                 instance_id=100, joy=0))

    win = ExperimentWindow(study, clock, input_kind="joystick", size=SIZE, on_frame=hook)
    try:
        win.attach_cursor(cursor)
        info = WorkloadInfo(1, "letters", "static", 8, "vis", study.tasks["vis"])
        answer = win.ask_workload(info)
    finally:
        win.close()
    # each (0, 1) above pulls the stick back (SDL's + y): down to the next scale
    assert answer == WANT


def test_confirming_with_a_scale_unmarked_selects_it_and_says_so() -> None:
    form = TlxForm()
    form.select(2)
    form.move(1)
    assert form.values[2] == 50 and not form.confirm()
    assert form.selected == 0 and form.hint is not None and "6" not in form.hint
    assert "5 not yet marked" in form.hint
    for i in range(len(TLX_SCALES)):
        form.set(i, 0.333)
    assert form.values == [35] * 6 and form.confirm()
    assert form.result() == dict.fromkeys(TLX_ITEMS, 35.0)
    # the standard anchors
    anchors = {s.item: (s.low, s.high) for s in TLX_SCALES}
    assert anchors["performance"] == ("Perfect", "Failure")
    assert all(v == ("Very low", "Very high") for k, v in anchors.items()
               if k != "performance")


def test_a_task_on_an_experimenter_key_is_refused_when_the_window_opens() -> None:
    study = load_study()
    spec = study.tasks["vis"].model_copy(update={"response": "key:p"})
    bad = study.model_copy(update={"tasks": {"vis": spec, "aud": study.tasks["aud"]}})
    with pytest.raises(ConfigError, match="experimenter's keys"):
        ExperimentWindow(bad, SimClock(), size=SIZE)
    assert isinstance(spec, TaskSpec)


def test_the_analysis_reads_the_windowed_sessions_task_events_and_ratings(
        tmp_path: Path) -> None:
    tasks_analysis = pytest.importorskip(
        "tactorbelt.analysis.tables.tasks", reason="the analysis of secondary tasks (load-model)")
    study = load_study()
    with Store.open(tmp_path / "s.sqlite") as store:
        sid = _run(study, store, Person()).session_id
    with Store.open(tmp_path / "s.sqlite") as store:
        events = [dict(e, participant="P01") for e in store.task_events(sid)]
        trials = store.trials(sid)
        ratings = store.ratings(sid)
    rows = {(r["task"], r["phase"]): r for r in tasks_analysis.secondary_task_rows(events)}
    assert set(rows) == {(t, p) for t in ("vis", "aud") for p in ("practice", "baseline",
                                                                   "dual")}
    assert rows[("vis", "practice")]["items"] == 5 and rows[("aud", "baseline")]["items"] == 5
    for r in rows.values():  # the person pressed on every match and only then
        assert r["misses"] == r["false_alarms"] == r["extra_presses"] == 0
        # posted at the first frame at or after onset + 350 ms, taken at the next tick
        assert r["median_rt_s"] is None or 0.35 <= r["median_rt_s"] <= 0.371
    block = {int(t["block_index"]): (t["load"], t["condition"]) for t in trials}
    tlx = tasks_analysis.tlx_rows([
        dict(r, participant="P01", load=block[int(r["block_index"])][0],
             condition=block[int(r["block_index"])][1]) for r in ratings])
    assert [(r["load"], r["raw_tlx"]) for r in tlx] == [
        ("vis", sum(WANT.values()) / 6), ("aud", sum(WANT.values()) / 6)]


def test_the_block_after_a_practice_run_shows_its_own_targets_and_task(tmp_path: Path) -> None:
    study = make_study(
        minimal=True, name="calm-then-busy", tactors=4, targets=8, iti_s=0.3,
        break_every=0, training=0, timeout_s=3.0, max_presentation_s=2.0,
        blocks=[{"name": "calm", "condition": "static", "repetitions": 1},
                {"name": "busy", "condition": "static", "repetitions": 1, "targets": 12,
                 "load": "vis"}],
        tasks={"vis": {"kind": "nback", "n": 1, "modality": "visual", "interval_s": 0.9,
                       "stimulus_s": 0.4, "response": "key:j", "practice": 3}})
    person = Person()
    blocks: list[tuple[int, list[str]]] = []
    last = [""]

    def hook(win: ExperimentWindow, kind: str) -> None:
        if kind == "block" and last[0] != "block":  # each block screen once
            blocks.append((win._n_targets, list(win.view(0).modal_lines)))
        last[0] = kind
        person(win, kind)

    with Store.open(tmp_path / "s.sqlite") as store:
        res = _run(study, store, hook)
    assert res.status == "complete"
    assert person.kinds["task"] > 0 and person.kinds["task_alone"] > 0
    (n_calm, calm), (n_busy, busy) = blocks
    assert n_calm == 8 and not any("also do the task" in line for line in calm)
    assert n_busy == 12 and any("also do the task: 1-back (letters)" in line for line in busy)


def test_a_session_stopped_on_the_tlx_screen_asks_it_first_when_resumed(
        tmp_path: Path) -> None:
    study = load_study()
    first = Person()
    first.abort_tlx = True
    with Store.open(tmp_path / "s.sqlite") as store:
        res = _run(study, store, first)
        assert res.status == "aborted" and store.ratings(res.session_id) == []
        again = Person()
        res2 = _run(study, store, again, resume=True)
        ratings = store.ratings(res2.session_id)
        events = store.task_events(res2.session_id)
    assert res2.status == "complete" and res2.session_id == res.session_id
    assert first.subtitles[0].startswith("Test block 1 of 2")
    # resumed: the first block is rated first, then the second after its trials
    assert [t.split(" is over")[0] for t in again.subtitles] == ["Test block 1 of 2",
                                                                 "Test block 2 of 2"]
    assert len(ratings) == 12 and {r["value"] for r in ratings} == set(WANT.values())
    # the practice and baseline of the first task were not run again
    count = collections.Counter((e["task"], e["phase"]) for e in events
                                if e["item_index"] >= 0)
    assert count[("vis", "practice")] == 5 and count[("vis", "baseline")] == 4


def test_pause_and_abort_silence_the_task_sounds_at_once() -> None:
    class Output(SilentTaskAudio):
        stops = 0

        def stop(self) -> None:
            self.stops += 1

    clock = SimClock()
    win = ExperimentWindow(load_study(), clock, size=SIZE)
    try:
        out = Output(clock)
        win.tasks.audio = out
        _key(pygame.K_p)
        win.step(10 * MS)
        assert win.user_paused and out.stops == 1
        _key(pygame.K_r)
        win.step(20 * MS)
        _key(pygame.K_ESCAPE)
        _key(pygame.K_ESCAPE)
        win.step(30 * MS)
        assert win.abort_requested and out.stops == 2
    finally:
        win.close()


def test_auditory_sums_longer_than_the_interval_are_refused_when_the_window_opens() -> None:
    study = make_study(minimal=True, name="sums", tactors=4, targets=8, training=0,
                       blocks=[{"condition": "static", "repetitions": 1, "load": "sums"}],
                       tasks={"sums": {"kind": "arithmetic", "modality": "auditory",
                                       "interval_s": 0.8, "stimulus_s": 0.5,
                                       "response": "key:j"}})
    with pytest.raises(ConfigError, match=r"tasks\.sums: an auditory sum lasts up to 0\.90 s"):
        ExperimentWindow(study, SimClock(), size=SIZE)


def test_the_task_button_of_the_participants_stick_is_a_press_and_nothing_else() -> None:
    study = load_study()
    spec = study.tasks["vis"].model_copy(update={"response": "joystick:1"})
    stick = FakeStick(100)
    cursor = JoystickCursor(JoystickConfig(), backend=FakeBackend(stick))
    win = ExperimentWindow(study, SimClock(), input_kind="joystick", size=SIZE)

    def button(b: int, joy: int = 100, down: bool = True) -> None:
        t = pygame.JOYBUTTONDOWN if down else pygame.JOYBUTTONUP
        pygame.event.post(pygame.event.Event(t, button=b, instance_id=joy, joy=0))

    try:
        win.attach_cursor(cursor)
        win.on_task_phase("vis", spec, "dual")
        button(1)
        button(1, down=False)
        button(1, joy=200)  # another stick (the experimenter's): not the participant's
        win.step(40 * MS)
        assert win.task_presses(50 * MS) == [40 * MS]
        assert not win._continue  # the task's button does not go on from a screen
        button(0)
        win.step(60 * MS)
        assert win.task_presses(70 * MS) == [] and win._continue
        win.on_task_phase(None, None, None)  # no task: button 1 is just a button again
        win._continue = False
        button(1)
        win.step(80 * MS)
        assert win.task_presses(90 * MS) == [] and win._continue
    finally:
        win.close()


def test_practice_feedback_says_right_missed_and_not_a_match() -> None:
    from tactorbelt.gui.taskview import PracticeCoach

    coach = PracticeCoach(1000 * MS)
    coach.item(0, True)
    coach.item(1000 * MS, False)
    coach.item(2000 * MS, True)
    coach.press(400 * MS)
    coach.tick(450 * MS)
    assert coach.text == "Right: that was a match"
    coach.press(500 * MS)  # a second press of the same item: nothing new
    coach.press(1300 * MS)
    coach.tick(1350 * MS)
    assert coach.text == "Not a match: no press needed"
    coach.tick(3000 * MS)  # the second match's time is over, not pressed
    assert coach.text == "Missed: that was a match"
    coach.tick(3000 * MS + 900 * MS)
    assert coach.text is None
    assert coach.summary() == ("In the practice you caught 1 of 2 matches and pressed 1 "
                               "time when there was none.")


def test_a_held_stick_repeats_after_a_delay() -> None:
    from tactorbelt.gui.tlx import REPEAT_DELAY_NS, REPEAT_NS, TlxScreen

    form = TlxForm()
    screen = TlxScreen(form, "t", stick=True)
    screen.stick_at(0.9, 0.1, 0)  # pushed right: marks the middle
    assert form.values[0] == 50
    screen.stick_at(0.9, 0.0, REPEAT_DELAY_NS - 1)  # held, not yet repeating
    assert form.values[0] == 50
    for k in range(3):
        screen.stick_at(0.9, 0.0, REPEAT_DELAY_NS + k * REPEAT_NS)
    assert form.values[0] == 65
    screen.stick_at(0.0, 0.0, 10**10)  # released
    screen.stick_at(0.0, -0.9, 10**10 + 1)  # pulled back (cursor y down): next scale
    assert form.selected == 1
    screen.stick_at(0.3, 0.2, 10**10 + 2)  # a small deflection does nothing
    assert form.selected == 1 and form.values[1] is None


@pytest.mark.slow
def test_a_wall_clock_session_plays_the_tones_through_sdl_audio(tmp_path: Path) -> None:
    """The same path as ``tactorbelt run`` with a person: the wall clock, SDL's dummy
    audio driver (its thread and the callback run), the TLX marked with the keys."""
    from tactorbelt.clock import WallClock
    from tactorbelt.tasks.audio import SdlTaskAudio

    study = make_study(
        minimal=True, name="live", tactors=4, targets=2, iti_s=0.2, break_every=0,
        training=0, timeout_s=2.0, max_presentation_s=1.0,
        blocks=[{"condition": "static", "repetitions": 1, "load": "aud"}],
        tasks={"aud": {"kind": "nback", "n": 1, "interval_s": 0.5, "stimulus_s": 0.15,
                       "response": "key:j", "practice": 3}},
        questionnaire={"tlx": True})
    person = Person()
    seen: dict[str, Any] = {}

    def hook(win: ExperimentWindow, kind: str) -> None:
        seen["audio"] = win.tasks.audio
        seen["items"] = len(win.tasks.items)
        person(win, kind)

    clock = WallClock()
    cursor = ScriptedCursor(answers={t.trial_index: t.target_deg
                                     for t in make_schedule(study, "P01")})
    with Store.open(tmp_path / "s.sqlite") as store, \
            open_belt("sim", clock=clock, layout=study.layout_obj()) as belt:
        res = run_with_window(study, "P01", belt, "scripted", store, clock=clock,
                              cursor=cursor, size=SIZE, auto_continue_s=None,
                              on_frame=hook)
        events = store.task_events(res.session_id)
        ratings = store.ratings(res.session_id)
    assert res.status == "complete"
    audio = seen["audio"]
    assert isinstance(audio, SdlTaskAudio) and audio.error is None
    items = [e for e in events if e["item_index"] >= 0]
    assert len([e for e in items if e["phase"] == "practice"]) == 3
    # every item of the runs was handed to SDL's callback and placed on the stream (an
    # item due just after a run ended may have been placed too: its block was filled)
    played = {(p.onset_ns, p.label) for p in audio.played}
    assert {(e["t_ns"], e["stimulus"]) for e in items} <= played
    assert len(played) - len(items) <= 2
    assert len(ratings) == 6
    with pytest.raises(DeviceError, match="closed"):
        audio.schedule(np.zeros(10, dtype=np.float32), 0)


def test_a_glyph_changes_at_the_poll_nearest_its_onset_and_end() -> None:
    from tactorbelt.gui.taskview import TaskPresenter
    from tactorbelt.tasks.schedule import TaskItem

    spec = load_study().tasks["vis"]  # stimulus_s 0.4
    p = TaskPresenter(SimClock(), tick_ns=10 * MS)
    p.start("vis", spec, "dual")
    p.item(TaskItem(0, "K", False), 23 * MS, spec)  # polls at 10, 20, 30 ... ms
    p.item(TaskItem(1, "M", False), 1027 * MS, spec)
    assert [p.glyph_at(t * MS) for t in (10, 20, 410, 420)] == [None, "K", "K", None]
    assert [p.glyph_at(t * MS) for t in (1020, 1030, 1420, 1430)] == [None, "M", "M", None]


def test_the_overlay_shows_the_running_task_and_its_last_item() -> None:
    from tactorbelt.gui.screens import overlay_lines
    from tactorbelt.tasks.schedule import TaskItem

    study = load_study()
    win = ExperimentWindow(study, SimClock(), size=SIZE)
    try:
        spec = study.tasks["vis"]
        win.on_task_phase("vis", spec, "dual")
        win.on_task_item(TaskItem(0, "K", False), 100 * MS, spec)
        win.on_task_item(TaskItem(1, "K", True), 1000 * MS, spec)
        lines = overlay_lines(win, 500 * MS)
        assert "task vis (dual): 2 items so far, last item K, response key:j" in lines
        assert any("last item K (go)" in line for line in overlay_lines(win, 1000 * MS))
    finally:
        win.close()
