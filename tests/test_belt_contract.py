"""The Belt contract, for every registered backend (and the firmware over a loop transport).

Iterates the backend registry: a scheme registered without a harness factory in
tests/support/belts.py fails :func:`test_every_registered_backend_has_a_harness`, so a
new backend is covered as soon as it is registered. Backends that cannot run here
(the emulator without a compiler) are skipped with the reason.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from functools import partial

import numpy as np
import pytest

from support.belts import EXTRA_FACTORIES, FACTORIES, Harness, url_harness
from tactorbelt import ConfigError, TactorbeltError
from tactorbelt.clock import Clock
from tactorbelt.devices.calibration import Calibration, TactorCalibration
from tactorbelt.devices.registry import BACKENDS
from tactorbelt.player import Player
from tactorbelt.stimuli import make_stimulus

CASES = sorted(BACKENDS) + sorted(EXTRA_FACTORIES)
#: one 16-bit device step, and a little more
TOL = 2.0 / 65535.0


def _factory(case: str):  # type: ignore[no-untyped-def]
    factory = FACTORIES.get(case) or EXTRA_FACTORIES.get(case)
    if factory is None and case in BACKENDS and BACKENDS[case].contract_url is not None:
        return partial(url_harness, BACKENDS[case].contract_url)
    if factory is None:
        pytest.fail(f"belt backend {case!r} is registered with no contract_url and "
                    "tests/support/belts.py has no harness factory for it: add one")
    return factory


@pytest.fixture(params=CASES)
def harness(request: pytest.FixtureRequest) -> Iterator[Harness]:
    h = _factory(request.param)()
    try:
        yield h
    finally:
        h.belt.close()
        h.cleanup()


def _off(h: Harness) -> bool:
    return max(h.device_levels()) == 0.0


def test_every_registered_backend_has_a_harness() -> None:
    missing = [s for s in BACKENDS if s not in FACTORIES and BACKENDS[s].contract_url is None]
    assert not missing, (f"registered belt backend(s) {missing} have no harness factory in "
                         "tests/support/belts.py FACTORIES; the contract suite cannot cover them")


# -- motors off --------------------------------------------------------------------------------
def test_motors_are_off_after_the_with_block(harness: Harness) -> None:
    with harness.belt as belt:
        belt.set_amplitudes([0.5] * belt.n_tactors)
        assert harness.device_levels() == pytest.approx([0.5] * belt.n_tactors, abs=TOL)
    assert belt.closed
    assert _off(harness)


@pytest.mark.parametrize("error", [RuntimeError, KeyboardInterrupt])
def test_motors_are_off_after_an_error_or_ctrl_c(harness: Harness,
                                                 error: type[BaseException]) -> None:
    with pytest.raises(error), harness.belt as belt:
        belt.set_amplitudes([1.0] * belt.n_tactors)
        raise error()
    assert belt.closed
    assert _off(harness)


# -- frames ------------------------------------------------------------------------------------
@pytest.mark.parametrize("bad", ["count", "nan", "inf", "above", "below", "nested"])
def test_bad_frames_are_refused_and_the_belt_stays_usable(harness: Harness, bad: str) -> None:
    belt = harness.belt
    n = belt.n_tactors
    frame = {"count": [0.1] * (n + 1), "nan": [math.nan] + [0.0] * (n - 1),
             "inf": [math.inf] + [0.0] * (n - 1), "above": [1.01] + [0.0] * (n - 1),
             "below": [-0.01] + [0.0] * (n - 1), "nested": [[0.0] * n]}[bad]
    belt.set_amplitudes([0.25] * n)
    with pytest.raises(ConfigError):
        belt.set_amplitudes(frame)
    assert belt.levels is None or np.allclose(belt.levels, 0.25)  # nothing was written
    belt.set_amplitudes([0.0] * n)
    assert _off(harness)


@pytest.mark.parametrize("case", CASES)
def test_the_calibration_is_applied_to_every_frame(case: str) -> None:
    cal = Calibration(tuple(TactorCalibration(start=0.2) for _ in range(6)))
    h = _factory(case)(calibration=cal)
    try:
        a = np.array([0.0, 0.25, 0.5, 0.75, 1.0, 0.1])
        h.belt.set_amplitudes(a)
        want = cal.apply(a)
        assert want[1] != a[1]  # the calibration changes the levels
        assert h.belt.levels is not None
        assert np.allclose(h.belt.levels, want)
        assert h.device_levels() == pytest.approx(list(want), abs=TOL)
        # a device that would ignore the calibration is streamed to instead
        assert Player(h.belt).device_render == (h.belt.can_render() and h.belt.renders_calibrated)
    finally:
        h.belt.close()
        h.cleanup()


# -- capabilities ------------------------------------------------------------------------------
def test_capabilities_are_declared_and_consistent(harness: Harness) -> None:
    belt = harness.belt
    assert math.isfinite(belt.stream_rate_hz) and belt.stream_rate_hz > 0
    assert belt.clock is None or isinstance(belt.clock, Clock)
    a = [0.0, 0.5] + [0.0] * (belt.n_tactors - 2)
    belt.set_amplitudes(a)
    assert belt.levels is None or np.allclose(belt.levels, a)
    belt.stop()
    assert belt.levels is None or np.all(belt.levels == 0.0)
    if belt.models_vibration:
        t, vib = belt.vibration(0, 10_000_000)
        assert vib.shape == (t.shape[0], belt.n_tactors)
    else:
        with pytest.raises(TactorbeltError, match="models no vibration"):
            belt.vibration(0, 10_000_000)


@pytest.mark.parametrize("mode", ["static", "dynamic"])
def test_a_stimulus_the_belt_can_render_plays(harness: Harness, mode: str) -> None:
    belt = harness.belt
    stim = make_stimulus(belt.layout, 45.0, mode)
    if not belt.can_render(stim):
        with pytest.raises((TactorbeltError, ConfigError)):
            belt.play(stim, 0.5)
        return
    assert belt.can_render()
    belt.play(stim, 0.5)
    assert belt.levels is None or belt.levels.shape == (belt.n_tactors,)
    belt.stop()
    assert _off(harness)


def test_a_stimulus_for_another_layout_is_not_rendered(harness: Harness) -> None:
    from tactorbelt import Layout

    other = make_stimulus(Layout.even(harness.belt.n_tactors + 1), 45.0)
    assert not harness.belt.can_render(other)


# -- stop, close -------------------------------------------------------------------------------
def test_stop_and_close_are_idempotent(harness: Harness) -> None:
    belt = harness.belt
    belt.set_amplitudes([0.3] * belt.n_tactors)
    belt.stop()
    belt.stop()
    assert _off(harness)
    belt.close()
    belt.close()
    belt.stop()  # a no-op on a closed belt
    assert belt.closed


def test_a_closed_belt_refuses_to_play(harness: Harness) -> None:
    belt = harness.belt
    belt.close()
    with pytest.raises(TactorbeltError, match="closed"):
        belt.set_amplitudes([0.0] * belt.n_tactors)
    with pytest.raises(TactorbeltError, match="closed"):
        belt.play(make_stimulus(belt.layout, 45.0), 0.1)


# -- the player --------------------------------------------------------------------------------
def test_the_player_streams_to_the_belt(harness: Harness) -> None:
    belt = harness.belt
    player = Player(belt, device_render=False)
    stats = player.play(make_stimulus(belt.layout, 30.0), 0.2)
    assert stats.frames >= 1
    assert stats.frames + stats.missed == round(0.2 * player.rate_hz)
    assert _off(harness)


def test_the_player_renders_on_the_device_when_it_can(harness: Harness) -> None:
    belt = harness.belt
    player = Player(belt)
    stim = make_stimulus(belt.layout, 30.0, "dynamic")
    assert player.renders_on_device(stim) == (belt.can_render(stim) and (
        belt.calibration.is_identity or belt.renders_calibrated))
    stats = player.play(stim, 0.1)
    assert (stats.frames == 0) == player.renders_on_device(stim)
    assert _off(harness)


# -- the registry ------------------------------------------------------------------------------
def test_url_options_reach_the_backend() -> None:
    from tactorbelt.devices import open_belt

    with open_belt("sim:8,virtual?horizon_s=5") as belt:
        assert (belt.n_tactors, belt.horizon_s, belt.url) == (8, 5.0, "sim:8,virtual")
        assert belt.clock is not None and belt.clock.simulated


@pytest.mark.parametrize(("url", "message"), [
    ("sim?bogus=1", "unknown option 'bogus' in belt URL 'sim\\?bogus=1'; allowed: horizon_s"),
    ("sim?horizon_s=abc", "'horizon_s' of belt URL .* must be a number, got 'abc'"),
    ("sim?horizon_s=-1", "must be in"),
    ("sim?horizon_s", "expected key=value"),
    ("emulator?tactors=2.5", "must be an integer"),
    ("serial:auto?timeout_s=fast", "must be a number"),
    ("ble:auto?heartbeat_ms=10", "must be in 50..2000"),
    ("ble:auto?keepalive=0", "unknown option 'keepalive'"),
    ("x", "unknown belt URL 'x'; allowed: sim, emulator, serial:PORT, serial:auto, "
          "ble:NAME_OR_ADDRESS"),
    ("serial", "needs a target, e.g. serial:auto"),
    ("ble:", "needs a target, e.g. ble:auto"),
])
def test_bad_urls_fail_before_anything_is_opened(url: str, message: str) -> None:
    from tactorbelt.devices import open_belt

    with pytest.raises(ConfigError, match=message):
        open_belt(url)


def test_an_option_in_the_url_and_as_a_keyword_is_refused() -> None:
    from tactorbelt.devices import open_belt

    with pytest.raises(ConfigError, match="given both"):
        open_belt("sim?horizon_s=5", horizon_s=3)


def test_the_registry_imports_no_backend_library() -> None:
    import subprocess
    import sys

    code = ("import sys\nfrom tactorbelt.devices import BACKENDS, parse_url\n"
            "from tactorbelt.devices.registry import belt_url_help\n"
            "belt_url_help(); parse_url('serial:auto?timeout_s=1')\n"
            "print(sorted(m for m in ('numpy', 'serial', 'bleak') if m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize("command", ["play", "belt-test", "calibrate", "point", "run"])
def test_every_command_lists_every_registered_backend_in_its_belt_help(command: str) -> None:
    from click.testing import CliRunner

    from tactorbelt.cli import cli

    result = CliRunner().invoke(cli, [command, "--help"], terminal_width=1000)
    assert result.exit_code == 0, result.output
    for backend in BACKENDS.values():
        for example in backend.examples:
            assert example in result.output, (command, example)


def test_a_backend_with_a_contract_url_is_covered_with_no_test_code(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Registering a backend (with a URL that opens without hardware) is all it takes."""
    from tactorbelt.devices.registry import Backend

    monkeypatch.setitem(BACKENDS, "newbelt", Backend(
        "newbelt", "tactorbelt.devices.sim:open_sim", "a new backend", ("newbelt",),
        contract_url="newbelt"))
    h = _factory("newbelt")()
    try:
        with h.belt as belt:
            belt.set_amplitudes([0.5] * belt.n_tactors)
            assert h.device_levels() == pytest.approx([0.5] * belt.n_tactors)
        assert _off(h)
    finally:
        h.cleanup()
