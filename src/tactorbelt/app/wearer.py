"""``tactorbelt calibrate perceptual``, wired: choose who answers (the keyboard, the
experiment window's joystick or mouse, the model participant), open the belt on the
right clock, run the perceptual calibration (:mod:`tactorbelt.calibration.perceptual`)
and keep the wearer's profile in a store or a file.

Use-case layer: may import every layer below it (devices, calibration, inputs, gui, the
experiment's store and runner).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from .._errors import ConfigError
from ..calibration.perceptual import (
    PerceptualResult,
    Respondent,
    run_perceptual_calibration,
)
from ..clock import SimClock, WallClock
from ..devices import open_belt, runs_on_simulated_time
from ..experiment.runner import check_participant
from ..experiment.store import open_store
from ..experiment.store.base import utc_now
from ..gui.perceptual import WindowRespondent
from ..inputs import kinds
from .display import has_display

if TYPE_CHECKING:
    from ..devices.base import Belt

__all__ = ["calibrate_wearer", "make_respondent"]


def make_respondent(kind: str, belt: Belt, *, seed: int, read_key: Callable[[], str],
                    say: Callable[[str], None]) -> Respondent:
    """The respondent for ``--input KIND``: a kind that needs the window answers in the
    experiment window's respondent; any other kind's module makes its own
    (:mod:`tactorbelt.inputs.kinds`).

    Raises:
        ConfigError: an unknown kind, a window kind without a display, or the model on a
            belt that models no vibration; DeviceError: ``joystick`` without a joystick.
    """
    k = kinds.input_kind(kind, calibration=True)
    if not k.display:
        return k.respondent(kinds.InputContext(belt=belt, seed=seed, read_key=read_key, say=say))
    if not has_display():
        raise ConfigError(f"no display (DISPLAY and WAYLAND_DISPLAY are not set) for the "
                          f"window --input {kind} answers in; answer in the terminal "
                          "with --input keyboard")
    return WindowRespondent(belt.layout, joystick=k.stick)


def calibrate_wearer(belt_url: str, participant: str, *, input_kind: str = "keyboard",
                     db: str | None = None, out: str | None = None, seed: int = 0,
                     read_key: Callable[[], str] = lambda: "q",
                     say: Callable[[str], None] = lambda text: None) -> PerceptualResult:
    """``tactorbelt calibrate perceptual``: open the belt, run the procedure, keep the
    profile with the participant in the store ``db`` and/or write it to ``out``.

    Raises:
        ConfigError: a bad participant id or input; StoreError: the store cannot be written.
    """
    who = check_participant(participant)
    # an input that runs on simulated time (the model) on the sim belt runs on a simulated
    # clock: nothing waits in real time (its backend declares that it can:
    # Backend.simulated_time)
    sim = kinds.input_kind(input_kind, calibration=True).simulated_time and runs_on_simulated_time(
        belt_url)
    options: dict[str, Any] = {"clock": SimClock()} if sim else {}
    with open_belt(belt_url, **options) as belt:
        clock = belt.clock or WallClock()
        respondent = make_respondent(input_kind, belt, seed=seed, read_key=read_key, say=say)
        try:
            result = run_perceptual_calibration(belt, clock, respondent, participant=who,
                                                seed=seed, created=utc_now())
        finally:
            respondent.close()
    if db is not None:
        with open_store(db) as store:
            store.save_wearer_profile(who, result.profile.to_toml())
    if out is not None:
        result.profile.save(out)
    return result
