"""The experiment window, headless (SDL's dummy video driver), on a simulated clock.

Sessions run through the window exactly as ``tactorbelt run`` runs them: the runner in
the main thread, the window drawing and handling keys in ``poll``. Keys and joystick
hot-plug events are posted into pygame's real event queue from the ``on_frame`` hook.
"""

from __future__ import annotations

import collections
import math
from pathlib import Path
from typing import Any, cast

import numpy as np
import pygame
import pytest

from support.inputs import FakeBackend, FakeStick
from support.studies import study_toml
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.devices.base import Belt
from tactorbelt.devices.sim import SimBelt
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.schedule import make_schedule
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import Study
from tactorbelt.geometry import TargetSet
from tactorbelt.gui.render import COLORS
from tactorbelt.gui.window import SCREEN_KINDS, ExperimentWindow, run_with_window
from tactorbelt.inputs.base import TrialCue
from tactorbelt.inputs.joystick import JoystickCursor
from tactorbelt.inputs.kinds import JoystickConfig
from tactorbelt.inputs.mouse import MouseCursor
from tactorbelt.inputs.screen import target_positions
from tactorbelt.inputs.scripted import ScriptedCursor, ScriptedResponse

SMALL = study_toml(minimal=True, name="small", tactors=4, targets=8,
                   max_presentation_s=2.0, timeout_s=3.0, iti_s=0.3, break_every=5,
                   training=1, training_conditions=["static"], repetitions=1)

SIZE = (400, 300)


@pytest.fixture
def study() -> Study:
    return Study.from_toml(SMALL)


@pytest.fixture(autouse=True)
def _clean_pygame() -> Any:
    yield
    pygame.display.quit()


def _cursor(study: Study, participant: str = "P01") -> ScriptedCursor:
    """Right on even trials, 90 deg off on odd ones (so some answers are wrong)."""
    answers = {t.trial_index: t.target_deg for t in make_schedule(study, participant)}

    def answer(cue: TrialCue) -> float:
        a = answers[cue.trial_index]
        return a if cue.trial_index % 2 == 0 else (a + 90.0) % 360

    return ScriptedCursor(ScriptedResponse(answer=answer, reaction_s=0.2, movement_s=0.3))


def _belt(study: Study, clock: SimClock) -> Belt:
    return open_belt("sim", clock=clock, layout=study.layout_obj())


def _levels(belt: Belt) -> Any:
    """The sim belt's drive levels now."""
    return cast(SimBelt, belt).levels


def _key(key: int, mod: int = 0) -> None:
    pygame.event.post(pygame.event.Event(pygame.KEYDOWN, key=key, mod=mod, unicode="",
                                         scancode=0))


class Participant:
    """An on_frame hook that presses Space on every waiting screen, and counts frames."""

    def __init__(self) -> None:
        self.kinds: collections.Counter[str] = collections.Counter()

    def __call__(self, win: ExperimentWindow, kind: str) -> None:
        self.kinds[kind] += 1
        if kind in ("instructions", "block", "break", "end"):
            _key(pygame.K_SPACE)


def _pixel(surface: Any, x: float, y: float) -> tuple[int, int, int]:
    c = surface.get_at((round(x), round(y)))
    return (c.r, c.g, c.b)


def _count(surface: Any, color: tuple[int, int, int]) -> int:
    a = pygame.surfarray.array3d(surface)
    return int(np.all(a == np.array(color), axis=-1).sum())


def _trial_rows(store: Store, session_id: int) -> list[tuple[Any, ...]]:
    cols = ("trial_index", "block", "condition", "target_deg", "on_tactor", "response_deg",
            "response_target_deg", "correct", "rt_s", "status")
    return [tuple(r[c] for c in cols) for r in store.trials(session_id)]


# -- drawing ---------------------------------------------------------------------------------
def test_targets_are_drawn_where_the_geometry_puts_them(study: Study) -> None:
    clock = SimClock()
    win = ExperimentWindow(study, clock, size=(640, 480))
    try:
        win.draw(0)
        g = win.renderer.geometry
        targets = TargetSet.even(study.targets.count)
        on = targets.on_tactor(study.layout_obj())
        pos = target_positions(targets.angles_deg, (g.cx, g.cy), g.rx, g.ry)
        for (px, py), is_on in zip(pos, on, strict=True):
            want = COLORS["on_tactor"] if is_on else COLORS["between"]
            assert _pixel(win.surface, px, py) == want
        # both colours are used, and the front target is at the top centre
        assert on.any() and (~on).any()
        assert pos[0][0] == pytest.approx(g.cx) and pos[0][1] == pytest.approx(g.cy - g.ry)
        # the cursor is at the centre, inside the home zone
        assert _pixel(win.surface, g.cx, g.cy) == COLORS["cursor"]
    finally:
        win.close()


def test_tactors_are_hidden_until_the_overlay_key(study: Study) -> None:
    win = ExperimentWindow(study, SimClock(), size=(640, 480))
    try:
        win.draw(0)
        assert _count(win.surface, COLORS["tactor"]) == 0
        _key(pygame.K_F1)
        win.step(10**9)
        assert win.overlay
        assert _count(win.surface, COLORS["tactor"]) > 0
        _key(pygame.K_TAB)
        win.step(2 * 10**9)
        assert not win.overlay
        assert _count(win.surface, COLORS["tactor"]) == 0
    finally:
        win.close()


# -- sessions through the window ----------------------------------------------------------------
def test_window_session_stores_the_same_trials_as_a_headless_run(study: Study, tmp_path: Path
                                                                 ) -> None:
    clock_a = SimClock()
    with Store.open(tmp_path / "a.sqlite") as store, \
            _belt(study, clock_a) as belt:
        head = run_session(study, "P01", belt, _cursor(study), store, clock_a, seed=7)
        rows_a = _trial_rows(store, head.session_id)
        samples_a = [store.samples(int(r["trial_id"])) for r in store.trials(head.session_id)]

    clock_b = SimClock()
    person = Participant()
    with Store.open(tmp_path / "b.sqlite") as store, \
            _belt(study, clock_b) as belt:
        res = run_with_window(study, "P01", belt, "scripted", store, clock=clock_b,
                              cursor=_cursor(study), seed=7, size=SIZE,
                              auto_continue_s=None, on_frame=person)
        rows_b = _trial_rows(store, res.session_id)
        samples_b = [store.samples(int(r["trial_id"])) for r in store.trials(res.session_id)]
        assert not _levels(belt).any()

    assert res.status == "complete" and head.status == "complete"
    assert rows_b == rows_a
    assert samples_b == samples_a
    assert len(rows_a) == study.n_trials()
    assert {r[7] for r in rows_a if r[1] == "test"} == {0, 1}  # right and wrong answers
    # every screen the participant goes through was drawn
    for kind in ("instructions", "training", "feedback", "block", "test", "break", "end"):
        assert person.kinds[kind] > 0, kind


def test_training_highlights_the_target_only_while_it_plays(study: Study, tmp_path: Path
                                                            ) -> None:
    seen: collections.Counter[str] = collections.Counter()

    def hook(win: ExperimentWindow, kind: str) -> None:
        if kind in ("instructions", "block", "break", "end"):
            _key(pygame.K_SPACE)
        cur = win.current
        if cur is None or cur.phase != "stimulus":
            return
        x, y = win.view(0).cursor or (0, 0)
        if math.hypot(x, y) > 0.6:  # the cursor is not yet over the target
            return
        g = win.renderer.geometry
        (px, py), = g.targets([cur.trial.target_deg])
        color = _pixel(win.surface, px, py)
        if kind == "training":
            assert color == COLORS["highlight"]
            seen["training"] += 1
        elif kind == "test":
            assert color in (COLORS["on_tactor"], COLORS["between"])
            seen["test"] += 1

    clock = SimClock()
    with Store.open(tmp_path / "s.sqlite") as store, \
            _belt(study, clock) as belt:
        res = run_with_window(study, "P01", belt, "scripted", store, clock=clock,
                              cursor=_cursor(study), size=SIZE, limit=3, on_frame=hook)
    assert res.status == "interrupted"  # --limit: resumable
    assert seen["training"] > 0 and seen["test"] > 0


def test_pause_key_turns_the_motors_off_at_once_and_resume_goes_on(study: Study,
                                                                  tmp_path: Path) -> None:
    clock = SimClock()
    log: dict[str, Any] = {"pause_frames": 0}

    with Store.open(tmp_path / "s.sqlite") as store, \
            _belt(study, clock) as belt:

        def hook(win: ExperimentWindow, kind: str) -> None:
            if kind in ("instructions", "block", "break", "end"):
                _key(pygame.K_SPACE)
            if "pressed" not in log and kind == "test" and _levels(belt).any():
                _key(pygame.K_p)
                log["pressed"] = win.current.trial.trial_index  # type: ignore[union-attr]
            elif kind == "pause":
                if log["pause_frames"] == 0:
                    log["levels_at_pause"] = _levels(belt).copy()
                log["pause_frames"] += 1
                assert not _levels(belt).any()  # motors stay off while paused
                if log["pause_frames"] == 30:
                    _key(pygame.K_r)

        res = run_with_window(study, "P01", belt, "scripted", store, clock=clock,
                              cursor=_cursor(study), size=SIZE, on_frame=hook)
        rows = store.trials(res.session_id)

    assert "pressed" in log
    assert not np.any(log["levels_at_pause"])
    assert log["pause_frames"] >= 30
    aborted = [r for r in res.results if r.status == "aborted"]
    assert [r.trial.trial_index for r in aborted] == [log["pressed"]]
    assert aborted[0].abort_reason == "paused"
    # the paused trial ran again after resume; the session completed
    assert res.status == "complete"
    assert {r["status"] for r in rows} == {"done"}
    assert len(rows) == study.n_trials()


def test_esc_once_warns_and_esc_twice_aborts_resumably(study: Study, tmp_path: Path) -> None:
    clock = SimClock()
    log: dict[str, Any] = {}

    def hook(win: ExperimentWindow, kind: str) -> None:
        if kind in ("instructions", "block", "break", "end"):
            _key(pygame.K_SPACE)
        if kind == "test" and "first" not in log:
            _key(pygame.K_ESCAPE)
            log["first"] = clock.now_ns()
        elif "first" in log and "banner" not in log:
            log["banner"] = win.view(clock.now_ns()).banner
        elif "first" in log and "second" not in log \
                and clock.now_ns() - log["first"] > 2_500_000_000:
            assert not win.abort_requested  # one Esc alone never aborts
            _key(pygame.K_ESCAPE)
            _key(pygame.K_ESCAPE)
            log["second"] = True

    with Store.open(tmp_path / "s.sqlite") as store, \
            _belt(study, clock) as belt:
        res = run_with_window(study, "P01", belt, "scripted", store, clock=clock,
                              cursor=_cursor(study), size=SIZE, on_frame=hook)
        assert not _levels(belt).any()
        assert res.status == "aborted"
        assert "Esc again" in log["banner"]
        resumable = store.find_resumable("P01")
        assert resumable is not None and resumable["session_id"] == res.session_id
        n_before = len(store.finished_indices(res.session_id))
        assert 0 < n_before < study.n_trials()

    # and it resumes, through the window, to the end
    with Store.open(tmp_path / "s.sqlite") as store, \
            _belt(study, clock) as belt:
        res2 = run_with_window(study, "P01", belt, "scripted", store, clock=clock,
                               cursor=_cursor(study), size=SIZE, resume=True,
                               on_frame=Participant())
        assert res2.status == "complete"
        assert res2.session_id == res.session_id


def test_ctrl_q_aborts(study: Study, tmp_path: Path) -> None:
    clock = SimClock()

    def hook(win: ExperimentWindow, kind: str) -> None:
        if kind in ("instructions", "block", "break", "end"):
            _key(pygame.K_SPACE)
        if kind == "feedback":
            _key(pygame.K_q, pygame.KMOD_LCTRL)

    with Store.open(tmp_path / "s.sqlite") as store, \
            _belt(study, clock) as belt:
        res = run_with_window(study, "P01", belt, "scripted", store, clock=clock,
                              cursor=_cursor(study), size=SIZE, on_frame=hook)
        assert res.status == "aborted"
        assert store.find_resumable("P01") is not None


# -- joystick hot-plug -------------------------------------------------------------------------


def test_joystick_unplugged_mid_trial_pauses_until_it_is_back(study: Study, tmp_path: Path
                                                              ) -> None:
    clock = SimClock()
    backend = FakeBackend()
    stick = JoystickCursor(JoystickConfig(device="warthog"), backend=backend)
    assert stick.connected
    log: dict[str, Any] = {"pause_frames": 0}

    with Store.open(tmp_path / "s.sqlite") as store, \
            _belt(study, clock) as belt:

        def hook(win: ExperimentWindow, kind: str) -> None:
            if kind in ("instructions", "block", "break", "end"):
                backend.stick.buttons[0] = 0
                pygame.event.post(pygame.event.Event(pygame.JOYBUTTONDOWN, button=0,
                                                     instance_id=backend.stick.instance_id,
                                                     joy=0))
            cur = win.current
            # the participant: push forward while the stimulus plays, else let go
            forward = cur is not None and cur.phase == "stimulus"
            backend.stick.axes[1] = -1.0 if forward else 0.0
            if kind == "test" and "unplugged" not in log and _levels(belt).any():
                backend.plugged = False
                pygame.event.post(pygame.event.Event(pygame.JOYDEVICEREMOVED,
                                                     instance_id=backend.stick.instance_id))
                log["unplugged"] = cur.trial.trial_index  # type: ignore[union-attr]
            elif kind == "pause":
                log["pause_frames"] += 1
                assert win.device_paused
                assert not _levels(belt).any()
                log["title"] = win.view(clock.now_ns()).modal_title
                if log["pause_frames"] == 20:
                    backend.plugged = True
                    backend.stick = FakeStick(101)  # SDL gives a new instance id
                    pygame.event.post(pygame.event.Event(pygame.JOYDEVICEADDED,
                                                         device_index=0))

        res = run_with_window(study, "P01", belt, "joystick", store, clock=clock,
                              cursor=stick, size=SIZE, limit=4, on_frame=hook)
        rows = store.trials(res.session_id)

    assert log["title"] == "Joystick disconnected"
    assert log["pause_frames"] >= 20
    assert stick.connected and stick.instance_id == 101
    aborted = [r for r in res.results if r.status == "aborted"]
    assert [r.trial.trial_index for r in aborted] == [log["unplugged"]]
    # answers came from the (fake) stick, pushed forward: the front target
    done = [r for r in rows if r["status"] == "done"]
    assert done and all(r["response_target_deg"] == 0.0 for r in done)
    assert res.n_run == study.n_training_trials() + 4


def test_mouse_position_maps_to_cursor_units(study: Study) -> None:
    win = ExperimentWindow(study, SimClock(), input_kind="mouse", size=(640, 480))
    try:
        g = win.renderer.geometry
        mouse = MouseCursor(g)
        mouse.place(g.cx + g.rx / 2, g.cy)
        assert mouse.read(5).x == pytest.approx(0.5) and mouse.read(5).y == pytest.approx(0)
        mouse.place(g.cx, g.cy - 3 * g.ry, buttons=1)  # far above: clamped to the front
        s = mouse.read(7)
        assert (s.t_ns, s.x, s.y, s.buttons) == (7, pytest.approx(0), pytest.approx(1), 1)
        # attached to the window, read() follows the real pointer
        win.attach_cursor(mouse)
        s = mouse.read(9)
        want = g.from_pixels(*pygame.mouse.get_pos())
        assert (s.x, s.y) == pytest.approx(want)
    finally:
        win.close()


# -- screenshots --------------------------------------------------------------------------------
def test_screenshot_dir_gets_every_kind_of_screen(study: Study, tmp_path: Path) -> None:
    clock = SimClock()
    shots = tmp_path / "shots"
    with Store.open(tmp_path / "s.sqlite") as store, \
            _belt(study, clock) as belt:
        run_with_window(study, "P01", belt, "scripted", store, clock=clock,
                        cursor=_cursor(study), size=SIZE, limit=2, screenshot_dir=shots,
                        auto_continue_s=0.5)
    names = sorted(p.name for p in shots.glob("*.png"))
    assert names == sorted(f"window-{k}.png" for k in SCREEN_KINDS)
    img = pygame.image.load(str(shots / "window-test.png"))
    assert img.get_size() == SIZE


# -- the entry point tactorbelt run uses ------------------------------------------------------
def test_session_window_makes_the_live_sources(study: Study) -> None:
    from tactorbelt import ConfigError
    from tactorbelt.gui import session_window

    with session_window(study, input="mouse", clock=SimClock(), size=SIZE) as win:
        assert isinstance(win.cursor, MouseCursor)
        assert win.observer is win.window
    with session_window(study, input="joystick", clock=SimClock(), size=SIZE,
                        joystick="no such stick") as win:
        assert isinstance(win.cursor, JoystickCursor)
        assert not win.cursor.connected  # waits for it (the session would pause)
    with session_window(study, input="model", clock=SimClock(), size=SIZE) as win:
        assert win.cursor is None  # the caller makes the model participant
        assert win.window.auto_continue_s == 2.0
    with pytest.raises(ConfigError, match="unknown input"):
        session_window(study, input="keyboard", clock=SimClock())


# -- what the screens say and hide ---------------------------------------------------------------
def test_end_screen_after_esc_esc_drops_the_press_esc_again_line(study: Study,
                                                                 tmp_path: Path) -> None:
    clock = SimClock()
    seen: dict[str, Any] = {}

    def hook(win: ExperimentWindow, kind: str) -> None:
        if kind in ("instructions", "block", "break"):
            _key(pygame.K_SPACE)
        if kind == "test" and "esc" not in seen:
            _key(pygame.K_ESCAPE)
            _key(pygame.K_ESCAPE)
            seen["esc"] = True
        if kind == "end" and "end" not in seen:
            v = win.view(clock.now_ns())
            seen["end"] = (v.modal_title, v.banner)
            _key(pygame.K_SPACE)

    with Store.open(tmp_path / "s.sqlite") as store, _belt(study, clock) as belt:
        res = run_with_window(study, "P01", belt, "scripted", store, clock=clock,
                              cursor=_cursor(study), size=SIZE, on_frame=hook)
    assert res.status == "aborted"
    assert seen["end"] == ("Session stopped", None)


def test_resumed_instructions_do_not_announce_training_that_is_done(study: Study,
                                                                    tmp_path: Path) -> None:
    clock = SimClock()
    said: list[str] = []

    def hook(win: ExperimentWindow, kind: str) -> None:
        if kind == "instructions":
            said.append(" ".join(win.view(clock.now_ns()).modal_lines))
        if kind in ("instructions", "block", "break", "end"):
            _key(pygame.K_SPACE)

    with Store.open(tmp_path / "s.sqlite") as store, _belt(study, clock) as belt:
        first = run_with_window(study, "P01", belt, "scripted", store, clock=clock,
                                cursor=_cursor(study), size=SIZE, limit=1, on_frame=hook)
        assert first.status == "interrupted"
        res = run_with_window(study, "P01", belt, "scripted", store, clock=clock,
                              cursor=_cursor(study), size=SIZE, resume=True, on_frame=hook)
    assert res.status == "complete"
    first_text, resumed_text = said[0], said[-1]
    assert "training" in first_text and "Resuming" not in first_text
    assert "training" not in resumed_text.lower() and "Resuming: 9 of 24" in resumed_text


@pytest.mark.parametrize("size", [(1280, 800), (1024, 768), (800, 600)])
def test_overlay_panel_hides_no_target_label_or_prompt(size: tuple[int, int]) -> None:
    from tactorbelt.experiment.study import paper_study
    from tactorbelt.gui.render import Renderer, View

    paper = paper_study()
    layout, targets = paper.layout_obj(), TargetSet.even(paper.targets.count)
    pygame.display.init()
    pygame.font.init()
    surface = pygame.Surface(size)
    renderer = Renderer(size)
    lines = ["participant P01  session 1  done 40/264",
             "trial 41 (index 40)  block static (test)  condition static  rep 1",
             "target 210 deg (between-tactor)  state stimulus  t  0.42 s",
             "last: answer 195 deg (wrong), RT 1.234 s",
             "input joystick 'Thrustmaster HOTAS Warthog Joystick'  raw (+0.01, -0.02)  "
             "cursor (+0.01, +0.02)",
             "samples this trial 42, worst interval error 0.31 ms",
             "P pause  R resume  Esc Esc / Ctrl-Q abort  F1/Tab overlay  F12 shot"]
    view = View(targets_deg=targets.angles_deg,
                on_tactor=tuple(bool(b) for b in targets.on_tactor(layout)),
                tactors_deg=layout.angles_deg, cursor=(0.0, 0.0), highlight_deg=210.0,
                prompt="Move to where you feel the vibration", overlay=True,
                overlay_lines=lines, levels=[0.0, 0.0, 0.0, 0.7, 0.4, 0.0])
    renderer.draw(surface, view)
    panel = renderer.rects["overlay"]
    assert renderer.rects["prompt"].colliderect(panel) is False
    g = renderer.geometry
    r = renderer.target_radius
    for (px, py) in g.targets(targets.angles_deg).tolist():
        marker = pygame.Rect(round(px - 1.6 * r), round(py - 1.6 * r), round(3.2 * r),
                             round(3.2 * r))
        assert not marker.colliderect(panel), (size, px, py)
    for (px, py) in g.targets(layout.angles_deg).tolist():  # the tactor labels (T0 ...)
        dx, dy = px - g.cx, py - g.cy
        d = math.hypot(dx, dy)
        lx, ly = px + dx / d * 2.6 * r, py + dy / d * 2.6 * r
        assert not pygame.Rect(round(lx - 2 * r), round(ly - r), 4 * r, 2 * r).colliderect(panel)
    assert panel.right <= size[0] and panel.bottom <= size[1]


def test_run_command_exits_130_when_the_experimenter_aborts_in_the_window(
        study: Study, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    from tactorbelt.app import run as launch
    from tactorbelt.cli import main
    from tactorbelt.gui.window import session_window

    def hook(win: ExperimentWindow, kind: str) -> None:
        if kind in ("training", "feedback", "test"):
            _key(pygame.K_ESCAPE)
            _key(pygame.K_ESCAPE)
        if kind == "end":
            _key(pygame.K_SPACE)

    def factory(input_kind: str, note: Any) -> Any:
        return lambda *a, **k: session_window(*a, **k, size=SIZE, auto_continue_s=0.0,
                                              on_frame=hook)

    monkeypatch.setattr(launch, "_window_factory", factory)
    study_file = tmp_path / "small.toml"
    study_file.write_text(SMALL)
    db = tmp_path / "s.sqlite"
    with pytest.raises(SystemExit) as exc:
        main(["run", str(study_file), "-p", "P01", "--input", "scripted", "--db", str(db)])
    out, err = capsys.readouterr()
    assert exc.value.code == 130
    assert "aborted" in out and "error" not in err
    assert f"tactorbelt run {study_file} --participant P01 --db {db} --resume" in err
    with Store.open(db, readonly=True) as store:
        (s,) = store.sessions()
        assert s["status"] == "aborted"


FACTORIAL = study_toml(minimal=True, name="factorial", tactors=4, targets=8,
                       max_presentation_s=2.0, timeout_s=3.0, iti_s=0.3, break_every=0,
                       training=0, design={"targets": [4, 8], "condition": ["static"],
                                           "repetitions": 1, "order": "fixed"})


def test_the_window_draws_each_blocks_own_target_set(tmp_path: Path) -> None:
    study = Study.from_toml(FACTORIAL)
    seen: dict[int, int] = collections.Counter()
    drawn = (COLORS["on_tactor"], COLORS["between"], COLORS["highlight"])

    def hook(win: ExperimentWindow, kind: str) -> None:
        if kind in ("instructions", "block", "break", "end"):
            _key(pygame.K_SPACE)
        cur = win.current
        if kind != "test" or cur is None or cur.phase != "stimulus":
            return
        x, y = win.view(0).cursor or (0, 0)
        if math.hypot(x, y) > 0.3:  # the cursor would cover a target
            return
        g = win.renderer.geometry
        n = cur.trial.n_targets
        for k in range(8):  # every direction of the finer set
            (px, py), = g.targets([k * 45.0])
            if k * 45.0 in cur.trial.target_set().angles_deg:
                assert _pixel(win.surface, px, py) in drawn, (n, k)
            else:  # a target of the other block is not drawn
                assert _pixel(win.surface, px, py) not in drawn, (n, k)
        seen[n] += 1

    clock = SimClock()
    with Store.open(tmp_path / "s.sqlite") as store, _belt(study, clock) as belt:
        res = run_with_window(study, "P01", belt, "scripted", store, clock=clock,
                              cursor=_cursor(study), size=(640, 480),
                              auto_continue_s=None, on_frame=hook)
        rows = store.trials(res.session_id)
    assert res.status == "complete"
    assert seen[4] > 0 and seen[8] > 0
    # the answers snap to the block's targets (4 targets: 90 deg apart)
    assert {r["response_target_deg"] % 90 for r in rows if r["n_targets"] == 4} == {0.0}
