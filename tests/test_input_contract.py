"""The input kinds' contract: every registered kind (tactorbelt.inputs.kinds) makes what
it declares, behaves as it declares, and runs where it says it can; a new kind is
covered the day its registry line is written (the toy kind below: its module and one
line, nothing else)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import pytest

from support.studies import study_toml
from tactorbelt import ConfigError, DeviceError
from tactorbelt.app.run import RunRequest, run_study
from tactorbelt.calibration.perceptual import Respondent
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.experiment.recorder import SessionRecorder
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import Study
from tactorbelt.inputs import kinds, make_cursor
from tactorbelt.inputs.base import CursorSample, CursorSource, TrialCue
from tactorbelt.inputs.kinds import INPUT_KINDS, InputContext, InputKind

SMALL = study_toml(minimal=True, name="small", tactors=4, targets=4, max_presentation_s=1.0,
                   timeout_s=2.0, iti_s=0.2, break_every=0, training=1,
                   training_conditions=["static"], repetitions=1)
TOY = InputKind("toy", "support.toy_input", "a toy cursor (tests)", simulated_time=True,
                calibration=False)
ALL = [*INPUT_KINDS.names(), "toy"]


@pytest.fixture(autouse=True)
def _toy_registered(monkeypatch: pytest.MonkeyPatch) -> None:
    # the toy kind's one registry line
    monkeypatch.setattr(kinds, "INPUT_KINDS",
                        kinds.Registry("input", [*INPUT_KINDS.values(), TOY]))


@pytest.fixture
def study() -> Study:
    return Study.from_toml(SMALL)


def _needs(kind: InputKind) -> None:
    """Skip, with the reason, where the kind needs what this machine lacks."""
    if kind.display:
        pytest.importorskip("pygame", reason=f"--input {kind.name} needs pygame's window")
        if not (os.environ.get("SDL_VIDEODRIVER") or os.environ.get("DISPLAY")):
            pytest.skip(f"--input {kind.name} needs a display (SDL_VIDEODRIVER=dummy "
                        "stands in for one)")


def _cursor(kind: InputKind, study: Study, belt: Any, clock: SimClock) -> CursorSource:
    schedule = SessionRecorder.schedule_for(study, "P01", 1)[0]
    if not kind.display:
        return make_cursor(kind.name, study=study, belt=belt, clock=clock, participant="P01",
                           seed=1, schedule=schedule)
    from tactorbelt.gui.window import session_window

    win = session_window(study, input=kind.name, clock=clock, size=(320, 240),
                         joystick="no such stick")
    assert win.cursor is not None  # the window makes a display kind's cursor
    return win.cursor


@pytest.mark.parametrize("name", ALL)
def test_a_session_kind_gives_a_cursor_that_behaves_as_declared(name: str,
                                                                 study: Study) -> None:
    kind = kinds.INPUT_KINDS[name]
    if not kind.session:
        with pytest.raises(ConfigError, match=f"unknown input '{name}'; allowed: "):
            kinds.input_kind(name)
        return
    _needs(kind)
    clock = SimClock()
    with open_belt("sim", clock=clock, layout=study.layout_obj()) as belt:
        cur = _cursor(kind, study, belt, clock)
        try:
            assert isinstance(cur, CursorSource)
            assert cur.person or not kind.live  # a person: each trial committed at once
            assert not cur.reads_runs or kind.simulated_time
            cue = TrialCue(0, "training", "static", (0.0, 90.0, 180.0, 270.0),
                           belt.layout, 90.0)
            s = cur.read(clock.now_ns())
            assert isinstance(s, CursorSample) and s.x ** 2 + s.y ** 2 <= 1.0 + 1e-9
            cur.trial_started(cue, clock.now_ns())
            clock.sleep_until_ns(clock.now_ns() + 50_000_000)
            s = cur.read(clock.now_ns())
            assert s.x ** 2 + s.y ** 2 <= 1.0 + 1e-9
            cur.trial_ended(clock.now_ns())
        finally:
            cur.close()


@pytest.mark.parametrize("name", ALL)
def test_a_kind_on_simulated_time_runs_a_whole_session_headless(name: str, study: Study,
                                                                 tmp_path: Path) -> None:
    kind = kinds.INPUT_KINDS[name]
    if not (kind.session and kind.simulated_time):
        pytest.skip(f"--input {name} does not run on simulated time")
    clock = SimClock()
    with Store.open(tmp_path / "s.sqlite") as store, \
            open_belt("sim", clock=clock, layout=study.layout_obj()) as belt:
        cur = _cursor(kind, study, belt, clock)
        res = run_session(study, "P01", belt, cur, store, clock, seed=1, input_name=name)
        assert res.status == "complete" and res.n_done == res.n_total
        assert store.session(res.session_id)["input"] == name


@pytest.mark.parametrize("name", ALL)
def test_run_study_takes_every_kind_by_what_it_declares(name: str, study: Study,
                                                        tmp_path: Path) -> None:
    """``tactorbelt run``'s library: a kind that runs without the window runs headless on
    simulated time; a window kind is refused headless with the kinds that can."""
    kind = kinds.INPUT_KINDS[name]
    path = tmp_path / "small.toml"
    path.write_text(SMALL)
    req = RunRequest(path, "P01", db=tmp_path / "s.sqlite", input_kind=name, headless=True)
    if not kind.session:
        with pytest.raises(ConfigError, match=f"unknown input '{name}'"):
            run_study(req)
    elif kind.display:
        with pytest.raises(ConfigError, match=f"--input {name} needs the experiment window; "
                           "drop --headless, or use --input model or --input scripted or "
                           "--input toy"):
            run_study(req)
    else:
        out = run_study(req)
        assert out.result.status == "complete"
        assert out.db == tmp_path / "s.sqlite"


@pytest.mark.parametrize("name", ALL)
def test_a_calibration_kind_gives_a_respondent(name: str) -> None:
    from tactorbelt.app.wearer import make_respondent

    kind = kinds.INPUT_KINDS[name]
    if not kind.calibration:
        with pytest.raises(ConfigError, match=f"unknown input '{name}'"):
            make_respondent(name, None, seed=0, read_key=lambda: "q",  # type: ignore[arg-type]
                            say=lambda text: None)
        return
    _needs(kind)
    with open_belt("sim") as belt:
        try:
            r = make_respondent(name, belt, seed=0, read_key=lambda: "q",
                                say=lambda text: None)
        except DeviceError as exc:  # live hardware this machine lacks (a joystick)
            pytest.skip(f"--input {name} needs its hardware: {exc}")
        try:
            assert isinstance(r, Respondent)
        finally:
            r.close()


def test_a_kinds_module_makes_its_cursor_from_one_context() -> None:
    from support.toy_input import ToyCursor

    assert isinstance(TOY.cursor(InputContext()), ToyCursor)
    with pytest.raises(ConfigError, match="scripted cursor needs the session's schedule"):
        kinds.input_kind("scripted").cursor(InputContext())
