"""A joystick unplugged in the middle of a session: the session pauses with a message, the
motors go off at once, and it goes on by itself when the stick is back.

Headless (SDL's dummy video driver) on a simulated clock; the unplug and replug are real
SDL events (JOYDEVICEREMOVED / JOYDEVICEADDED) posted into pygame's queue, and the stick
is a fake device behind :class:`JoystickCursor`'s backend seam.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pygame
import pytest

from support.inputs import FakeBackend, FakeStick
from support.studies import study_toml
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.devices.sim import SimBelt
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import Study
from tactorbelt.gui.window import ExperimentWindow, run_with_window
from tactorbelt.inputs.joystick import JoystickCursor
from tactorbelt.inputs.kinds import JoystickConfig

STUDY = study_toml(minimal=True, name="joystick", tactors=4, targets=8,
                   max_presentation_s=2.0, timeout_s=3.0, iti_s=0.3, break_every=0,
                   training=0, repetitions=1)


@pytest.fixture(autouse=True)
def _clean_pygame() -> Any:
    yield
    pygame.display.quit()


class Participant:
    """Pushes forward while a stimulus plays, presses a button on waiting screens, and
    unplugs the stick at the chosen moment; plugs it back after ``pause_frames``."""

    def __init__(self, backend: FakeBackend, belt: SimBelt, when: str,
                 pause_frames: int = 30) -> None:
        self.backend = backend
        self.belt = belt
        self.when = when  # "stimulus" or "iti"
        self.pause_frames = pause_frames
        self.unplugged_in: int | None = None
        self.levels_while_paused: list[bool] = []
        self.acquired_while_paused = 0
        self.titles: set[str] = set()
        self.lines: list[str] = []
        self.replugged = False

    def __call__(self, win: ExperimentWindow, kind: str) -> None:
        b = self.backend
        if kind in ("instructions", "block", "break", "end"):
            pygame.event.post(pygame.event.Event(pygame.JOYBUTTONDOWN, button=0,
                                                 instance_id=b.stick.instance_id, joy=0))
        cur = win.current
        b.stick.axes[1] = -1.0 if cur is not None and cur.phase == "stimulus" else 0.0
        if (self.unplugged_in is None and kind in ("training", "test") and cur is not None
                and cur.trial.trial_index == 3 and cur.phase == self.when
                and (self.when != "stimulus" or self.belt.levels.any())):
            b.plugged = False
            pygame.event.post(pygame.event.Event(pygame.JOYDEVICEREMOVED,
                                                 instance_id=b.stick.instance_id))
            self.unplugged_in = cur.trial.trial_index
        elif kind == "pause":
            self.levels_while_paused.append(bool(self.belt.levels.any()))
            view = win.view(win.clock.now_ns())
            self.titles.add(str(view.modal_title))
            self.lines = list(view.modal_lines)
            if len(self.levels_while_paused) == self.pause_frames and not self.replugged:
                self.replugged = True
                b.plugged = True
                b.stick = FakeStick(8)  # SDL gives a replugged device a new instance id
                pygame.event.post(pygame.event.Event(pygame.JOYDEVICEADDED, device_index=0))


@pytest.mark.parametrize("when", ["stimulus", "iti"])
def test_unplugged_joystick_pauses_with_a_message_and_resumes_when_back(
    tmp_path: Path, when: str
) -> None:
    study = Study.from_toml(STUDY)
    clock = SimClock()
    backend = FakeBackend(FakeStick(7, "Fake HOTAS", n_axes=2, n_buttons=2))
    stick = JoystickCursor(JoystickConfig(device="hotas"), backend=backend)
    assert stick.connected
    with Store.open(tmp_path / "s.sqlite") as store, \
            open_belt("sim", clock=clock, layout=study.layout_obj()) as belt:
        assert isinstance(belt, SimBelt)
        who = Participant(backend, belt, when)
        res = run_with_window(study, "P01", belt, "joystick", store, clock=clock,
                              cursor=stick, size=(400, 300), on_frame=who)
        rows = store.trials(res.session_id)
        assert not belt.levels.any()
    assert who.unplugged_in == 3
    assert who.titles == {"Joystick disconnected"}
    assert any("plug it back in" in line for line in who.lines), who.lines
    assert len(who.levels_while_paused) >= who.pause_frames
    assert not any(who.levels_while_paused), "a motor ran while the session was paused"
    assert stick.connected and stick.instance_id == 8
    # every scheduled trial exactly once, all answered with the stick (pushed forward)
    assert res.status == "complete"
    assert sorted(r["trial_index"] for r in rows) == list(range(study.n_trials()))
    assert {r["status"] for r in rows} == {"done"}
    assert all(r["response_target_deg"] == 0.0 for r in rows)
    by_index = {r["trial_index"]: r for r in rows}
    if when == "stimulus":  # the trial in flight was aborted and run again
        assert by_index[3]["attempts"] == 2
        aborted = [r for r in res.results if r.status == "aborted"]
        assert [r.trial.trial_index for r in aborted] == [3]
        assert aborted[0].abort_reason == "paused"
    else:  # unplugged between trials: nothing to abort
        assert all(r["attempts"] == 1 for r in rows)
