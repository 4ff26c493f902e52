"""The rules of `tactorbelt run`'s options (tactorbelt.app.request), without a session:
what a resumed run reuses, the defaults, the clock and what the run says about them."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from tactorbelt import ConfigError
from tactorbelt.app.request import RunRequest, pick_clock, resolve, reuse_lines

STUDY = Path("exp/study.toml")
#: what a headless scripted session on a simulated clock stored
STORED: dict[str, Any] = {"belt_url": "sim", "calibration": None, "input_kind": "scripted",
                          "headless": True, "clock": "sim", "fullscreen": False,
                          "joystick": {"device": "2", "axes": "2,3", "dead_zone": None,
                                       "invert_x": True, "invert_y": None}}
SESSION = {"session_id": 4, "seed": 7, "n_trials": 30}


def _req(**given: Any) -> RunRequest:
    return RunRequest(STUDY, "P01", resume=True, **given)


def test_the_request_takes_the_command_lines_names() -> None:
    req = RunRequest(STUDY, "P01", db="postgresql://u@h/d", realtime=True)
    assert (req.db, req.push, req.clock) == (Path("exp/study.sqlite"), "postgresql://u@h/d",
                                             "wall")
    with pytest.raises(ConfigError, match="--push takes a postgresql"):
        RunRequest(STUDY, "P01", push="http://h")
    assert RunRequest(STUDY, "P01", axes="1,0").joystick().axis_x == 1
    with pytest.raises(ConfigError, match="--axes: expected two axis indices"):
        RunRequest(STUDY, "P01", axes="1").joystick()


def test_a_resumed_run_reuses_what_is_not_given_again() -> None:
    r = resolve(_req(belt_url="emulator", axes="0,1"), STORED)
    assert (r.input_kind, r.headless, r.belt_url, r.clock) == ("scripted", True, "emulator", "sim")
    assert (r.joystick_device, r.axes, r.invert_x) == ("2", "0,1", True)
    assert r.stored()["joystick"] == {"device": "2", "axes": "0,1", "dead_zone": None,
                                      "invert_x": True, "invert_y": None}
    # a live input given again brings the window back; nothing stored: the defaults
    assert resolve(_req(input_kind="mouse"), STORED).headless is False
    new = resolve(RunRequest(STUDY, "P01"), {})
    assert (new.input_kind, new.headless, new.belt_url, new.fullscreen) == (
        "joystick", False, "sim", False)
    assert resolve(RunRequest(STUDY, "P01", headless=True), {}).input_kind == "model"


@pytest.mark.parametrize(("given", "keep", "kind"), [
    ({}, "sim", "sim"),                                    # the stored clock still fits
    ({"belt_url": "emulator"}, None, "wall"),              # a real belt: the default
    ({"lsl": True}, None, "wall"),                         # LSL runs on the wall clock
    ({"clock": "wall"}, "wall", "wall"),                   # given again
])
def test_a_stored_simulated_clock_is_kept_where_it_fits(given: dict[str, Any],
                                                        keep: str | None, kind: str) -> None:
    req = _req(**given)
    assert pick_clock(req, resolve(req, STORED)) == (keep, kind)


def test_a_simulated_clock_given_where_it_cannot_be_is_refused() -> None:
    req = _req(belt_url="emulator", clock="sim")
    with pytest.raises(ConfigError, match="here the belt emulator runs in real time"):
        pick_clock(req, resolve(req, STORED))


def test_a_resumed_run_says_where_each_option_comes_from() -> None:
    req = _req(belt_url="emulator")
    r = resolve(req, STORED)
    lines = reuse_lines(req, r, STORED, SESSION, 12, pick_clock(req, r)[1])
    assert lines[0] == "resuming session 4 of P01 (12/30 trials done) with these options:"
    rows = {line.split()[0]: line for line in lines[1:]}
    assert "given (stored: sim)" in rows["belt"]
    assert "default (stored sim does not fit)" in rows["clock"]
    assert rows["clock"].endswith("override: none (the belt emulator runs in real time)")
    assert rows["input"].endswith("override: --input joystick|mouse|model")
    assert "joystick" not in rows  # scripted has no stick
