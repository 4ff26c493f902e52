"""What callers ask of a belt's backend is declared, not found by looking at its URL or
type: which backends can run on a simulated clock, and which belts drive a sound output."""

from __future__ import annotations

import pytest

from tactorbelt import ConfigError
from tactorbelt.devices import BACKENDS, open_belt, runs_on_simulated_time


@pytest.mark.parametrize(("url", "simulated"), [
    ("sim", True), ("sim:virtual", True), ("sim:8", True), ("emulator", False),
    ("serial:/dev/ttyACM0", False), ("ble:belt", False), ("audio:default", False)])
def test_only_the_sim_belt_runs_on_simulated_time(url: str, simulated: bool) -> None:
    assert runs_on_simulated_time(url) is simulated


def test_a_new_backend_declares_simulated_time_in_its_registry_line() -> None:
    assert [b.scheme for b in BACKENDS.values() if b.simulated_time] == ["sim"]
    with pytest.raises(ConfigError, match="unknown belt URL"):
        runs_on_simulated_time("tape:1")


def test_a_belt_that_is_not_a_sound_card_says_so() -> None:
    with open_belt("sim") as belt:
        assert belt.uses_sound_output is False
