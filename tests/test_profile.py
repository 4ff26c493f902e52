"""Wearer profiles (tactorbelt.wearer): TOML round trip, validation, and the stimulus
engine rendering a stimulus for a wearer (docs/calibration-perceptual.md)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tactorbelt import ConfigError
from tactorbelt.devices.sim import SimBelt
from tactorbelt.geometry import Layout
from tactorbelt.player import Player
from tactorbelt.stimuli import make_stimulus, render_batch
from tactorbelt.wearer import PairWarp, WearerProfile, isotonic

LAYOUT = Layout((30.0, 90.0, 150.0, 210.0, 270.0, 330.0))


def _profile() -> WearerProfile:
    warps = [PairWarp((0.25, 0.5, 0.75), (0.33 + 0.01 * k, 0.5, 0.66)) for k in range(6)]
    return WearerProfile(LAYOUT.angles_deg, (1.0, 1.1, 0.9, 1.0, 1.2, 0.8), tuple(warps),
                         participant="P01", belt="sim", fit=({"pair": 0, "pse": 0.33},))


def test_a_profile_round_trips_through_toml(tmp_path: Path) -> None:
    p = _profile()
    path = p.save(tmp_path / "P01.toml")
    back = WearerProfile.load(path)
    assert back == p
    assert back.participant == "P01" and back.fit[0]["pse"] == 0.33


def test_an_identity_profile_renders_exactly_the_law() -> None:
    ident = WearerProfile.identity(LAYOUT)
    assert ident.is_identity
    t = np.linspace(0, 1, 101)
    for x in (15.0, 30.0, 45.0, 100.0, 352.5):
        for mode in ("static", "dynamic"):
            a = make_stimulus(LAYOUT, x, mode).amplitudes(t)
            b = make_stimulus(LAYOUT, x, mode, profile=ident).amplitudes(t)
            np.testing.assert_array_equal(a, b)


def test_the_warp_moves_points_within_their_gap_and_keeps_tactors() -> None:
    p = _profile()
    x = np.linspace(0, 360, 3601, endpoint=False)
    y = p.warp_deg(LAYOUT, x)
    np.testing.assert_allclose(p.warp_deg(LAYOUT, LAYOUT.angles), LAYOUT.angles, atol=1e-9)
    # monotone around the belt: the rendered position never goes back
    step = np.mod(np.diff(np.append(y, y[0] + 360.0)), 360.0)
    assert np.all(step >= 0) and np.all(step < 1.0)
    # pair 0 (30 -> 90): the quarter point is rendered at 0.33 of the gap
    assert p.warp_deg(LAYOUT, 45.0) == pytest.approx(30.0 + 0.33 * 60.0)


def test_a_static_point_is_rendered_at_the_warped_position_with_the_gains() -> None:
    p = _profile()
    got = make_stimulus(LAYOUT, 45.0, profile=p).amplitudes(0.0)
    law = make_stimulus(LAYOUT, 30.0 + 0.33 * 60.0).amplitudes(0.0)
    np.testing.assert_allclose(got, np.clip(law * np.array(p.gains), 0, 1))
    _, batch = render_batch([make_stimulus(LAYOUT, 45.0, profile=p)], 1000.0, 0.01)
    np.testing.assert_allclose(batch[0, 0], got)


@pytest.mark.parametrize("edit, field", [
    (lambda d: d.update(gains=[1.0] * 5), "gains"),
    (lambda d: d["pair"].pop(), "pair"),
    (lambda d: d["pair"][2].update(rendered=[0.4, 0.3, 0.7]), "pair[2].rendered"),
    (lambda d: d["pair"][1].update(rendered=[0.2, 0.5, 1.0]), "pair[1].rendered"),
    (lambda d: d["pair"][0].update(intended=[0.25, 0.5]), "pair[0].rendered"),
    (lambda d: d.update(gains=[1.0, 0.0, 1, 1, 1, 1]), "gains[1]"),
])
def test_bad_profiles_are_refused_naming_file_and_field(tmp_path: Path, edit, field) -> None:
    import tomli_w

    doc = _profile().to_mapping()
    edit(doc)
    path = tmp_path / "bad.toml"
    path.write_text(tomli_w.dumps(doc))
    with pytest.raises(ConfigError) as err:
        WearerProfile.load(path)
    assert str(err.value).startswith(f"{path}: {field}: "), str(err.value)


def test_a_profile_for_another_belt_is_refused() -> None:
    with pytest.raises(ConfigError, match="the profile has 6 tactors but the belt has 8"):
        make_stimulus(Layout.even(8), 45.0, profile=_profile())


def test_belts_that_cannot_apply_a_profile_stream_it() -> None:
    belt = SimBelt(layout=LAYOUT)
    plain = make_stimulus(LAYOUT, 45.0, "dynamic")
    assert belt.can_render(plain)
    assert belt.can_render(plain.with_profile(WearerProfile.identity(LAYOUT)))
    assert not belt.can_render(plain.with_profile(_profile()))
    assert not Player(belt).renders_on_device(plain.with_profile(_profile()))


def test_isotonic_makes_measured_points_a_strictly_increasing_warp() -> None:
    got = isotonic([0.3, 0.2, 0.8])
    assert got == pytest.approx([0.25, 0.26, 0.8])
    assert isotonic([0.0, 0.5, 1.0]) == pytest.approx([0.01, 0.5, 0.99])
    PairWarp((0.25, 0.5, 0.75), tuple(isotonic([0.9, 0.1, 0.2])))


def test_a_profile_round_trips_through_the_store(tmp_path: Path) -> None:
    from tactorbelt.experiment.store import open_store

    p = _profile()
    with open_store(tmp_path / "s.sqlite") as store:
        assert store.wearer_profile("P01") is None
        store.save_wearer_profile("P01", p.to_toml())
        store.set_session_profile(3, p.to_toml())
    with open_store(tmp_path / "s.sqlite") as store:
        text = store.wearer_profile("P01")
        assert text is not None and WearerProfile.from_toml(text) == p
        assert store.session_profile(3) == text


def test_calibrate_perceptual_keeps_the_models_profile(tmp_path: Path) -> None:
    from support.cli import tactorbelt

    proc = tactorbelt("calibrate", "perceptual", "-p", "M01", "--input", "model",
                      "--db", str(tmp_path / "s.sqlite"), "-o", str(tmp_path / "M01.toml"))
    assert proc.returncode == 0, proc.stderr
    assert "gains: 1.00," in proc.stdout and "pair 5: 0.25 -> " in proc.stdout
    assert WearerProfile.load(tmp_path / "M01.toml").participant == "M01"



def test_window_answers_without_a_display_are_a_clear_error() -> None:
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items()
           if k not in ("DISPLAY", "WAYLAND_DISPLAY", "SDL_VIDEODRIVER")}
    proc = subprocess.run([sys.executable, "-m", "tactorbelt", "calibrate", "perceptual",
                           "-p", "M01", "--input", "mouse"], env=env, capture_output=True,
                          text=True, timeout=60, check=False)
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: no display")
    assert "--input keyboard" in proc.stderr


def test_a_person_answers_with_keys_and_q_writes_nothing(tmp_path: Path) -> None:
    from support.cli import tactorbelt

    out = tmp_path / "P01.toml"
    # always "the second was stronger" and "nearer tactor b": a valid, extreme profile
    proc = tactorbelt("calibrate", "perceptual", "--belt", "sim:virtual", "-p", "P01",
                      "-o", str(out), input="2b" * 300)
    assert proc.returncode == 0, proc.stderr
    assert "[1] which was stronger: [1] first or [2] second?" in proc.stderr
    assert "nearer [a] tactor 0 (30 deg) or [b] tactor 1 (90 deg) than 45 deg?" in proc.stderr
    profile = WearerProfile.load(out)
    assert all(w.rendered[0] < 0.05 for w in profile.warps)
    proc = tactorbelt("calibrate", "perceptual", "--belt", "sim:virtual", "-p", "P02",
                      "-o", str(tmp_path / "P02.toml"), input="12q")
    assert proc.returncode == 1 and "abandoned (q); nothing was written" in proc.stderr
    assert "error:" not in proc.stderr and not (tmp_path / "P02.toml").exists()


def test_play_renders_for_a_wearer_and_refuses_another_belts_profile(tmp_path: Path) -> None:
    from support.cli import tactorbelt

    path = _profile().save(tmp_path / "P01.toml")
    proc = tactorbelt("play", "45", "--belt", "sim:virtual", "--profile", str(path),
                      "--seconds", "0.2")
    assert proc.returncode == 0, proc.stderr
    assert "streamed at 1000 Hz, for wearer P01" in proc.stdout
    proc = tactorbelt("play", "45", "--belt", "sim:8,virtual", "--profile", str(path))
    assert proc.returncode == 2
    assert proc.stderr.startswith(f"error: {path}: tactor_angles_deg: the profile has 6 "
                                  "tactors but the belt has 8")


@pytest.mark.parametrize("mode", ["static", "dynamic"])
def test_the_direction_display_shows_a_wearers_stimulus(mode: str) -> None:
    from tactorbelt.clock import SimClock
    from tactorbelt.display import DirectionDisplay

    clock = SimClock()
    with SimBelt(layout=LAYOUT, clock=clock) as belt:
        d = DirectionDisplay(belt, mode=mode, profile=_profile())
        assert not d.device_render  # the profile is streamed
        t0 = clock.now_ns()
        d.show(45.0)
        d.pump(t0 + 2_000_000_000)
        got = belt.commanded(t0, t0 + 2_000_000_000, 1000.0)[1]
    ref = make_stimulus(LAYOUT, 45.0, mode, profile=_profile()).amplitudes(
        np.arange(2000) / 1000.0)
    np.testing.assert_allclose(got, ref, atol=1e-6)
