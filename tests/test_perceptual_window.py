"""The perceptual calibration answered in the window (SDL's dummy video driver): a
person's clicks, keys and stick give the answers the procedure records, the profile
follows them, Esc Esc writes nothing, and the window closes on every exit path."""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from typing import Any

import pytest

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

pygame = pytest.importorskip("pygame")

from tactorbelt.calibration.motor import CalibrationQuit  # noqa: E402
from tactorbelt.calibration.perceptual import CalibrationSettings, run_perceptual_calibration  # noqa: E402
from tactorbelt.devices import open_belt  # noqa: E402
from tactorbelt.gui.perceptual import ChoiceState, WindowRespondent  # noqa: E402

QUICK = CalibrationSettings()  # the defaults: every question a person gets


def _scripted(answer: Callable[[WindowRespondent, str], list[Any]]
              ) -> Callable[[WindowRespondent], Callable[[], Sequence[Any]]]:
    """An event source that answers each question once it has been drawn."""

    def make(resp: WindowRespondent) -> Callable[[], Sequence[Any]]:
        def events() -> Sequence[Any]:
            kind = resp.drawn
            if kind is None:
                return []
            resp.drawn = None
            return answer(resp, kind)

        return events

    return make


class _Probe(WindowRespondent):
    """The window respondent, noting which question was last drawn."""

    drawn: str | None = None

    def __init__(self, layout: Any,
                 script: Callable[[WindowRespondent], Callable[[], Sequence[Any]]]) -> None:
        super().__init__(layout, events=lambda: self._script(), on_frame=self._frame)
        self._script = script(self)

    def _frame(self, surface: Any, kind: str) -> None:
        self.drawn = kind


def _click(resp: WindowRespondent, index: int) -> Any:
    return pygame.event.Event(pygame.MOUSEBUTTONDOWN, button=1,
                              pos=resp._boxes()[index].center)


def _key(name: str) -> Any:
    return pygame.event.Event(pygame.KEYDOWN, key=pygame.key.key_code(name), mod=0)


def test_clicks_and_keys_are_the_answers_and_the_profile_follows_them() -> None:
    # "the second was stronger" by a mouse click, "nearer b" by the key b
    def answer(resp: WindowRespondent, kind: str) -> list[Any]:
        return [_click(resp, 1)] if kind == "stronger" else [_key("b")]

    with open_belt("sim:virtual") as belt:
        resp = _Probe(belt.layout, _scripted(answer))
        try:
            res = run_perceptual_calibration(belt, belt.clock, resp, participant="P01",
                                             settings=QUICK)
        finally:
            resp.close()
    assert res.n_trials == len(resp.answers) and resp.answers
    assert set(resp.answers) == {1}
    # always "nearer b": every pair's quarter point is rendered close to tactor a
    assert all(w.rendered[0] < 0.1 for w in res.profile.warps)
    assert resp.closed and not pygame.display.get_init()


def test_the_stick_selects_and_a_button_confirms() -> None:
    def answer(resp: WindowRespondent, kind: str) -> list[Any]:
        return [pygame.event.Event(pygame.JOYAXISMOTION, axis=0, value=-0.9, instance_id=0),
                pygame.event.Event(pygame.JOYBUTTONDOWN, button=0, instance_id=0)]

    with open_belt("sim:virtual") as belt:
        resp = _Probe(belt.layout, _scripted(answer))
        try:
            run_perceptual_calibration(belt, belt.clock, resp, participant="P02",
                                       settings=QUICK)
        finally:
            resp.close()
    assert resp.answers and set(resp.answers) == {0}


def test_a_push_alone_never_answers() -> None:
    s = ChoiceState()
    s.stick(0.3)
    assert s.selected is None and s.answer is None
    s.stick(0.95)
    assert s.selected == 1 and s.answer is None
    s.button()
    assert s.answer == 1
    s = ChoiceState()
    s.button()
    assert s.answer is None  # nothing selected: a button does nothing


def test_esc_esc_quits_and_closes_the_window() -> None:
    def answer(resp: WindowRespondent, kind: str) -> list[Any]:
        return [_key("escape"), _key("escape")]

    with open_belt("sim:virtual") as belt:
        resp = _Probe(belt.layout, _scripted(answer))
        with pytest.raises(CalibrationQuit, match="nothing was written"):
            try:
                run_perceptual_calibration(belt, belt.clock, resp, participant="P03",
                                           settings=QUICK)
            finally:
                resp.close()
        assert belt.levels is None or max(belt.levels) == 0.0  # motors off
    assert resp.answers == [] and not pygame.display.get_init()
