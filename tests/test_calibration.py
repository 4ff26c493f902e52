"""Motor calibration: the amplitude-to-drive mapping and its TOML file."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from tactorbelt import ConfigError
from tactorbelt.devices.calibration import Calibration, TactorCalibration

CAL = Calibration((TactorCalibration(0.2, 1.0, 0.8), TactorCalibration(0.0, 2.0, 0.5),
                   TactorCalibration(0.3, 0.5, 1.0)))


def test_zero_is_off_and_any_positive_amplitude_clears_the_dead_zone() -> None:
    drive = CAL.apply([0.0, 0.0, 0.0])
    assert np.all(drive == 0.0)
    drive = CAL.apply([1e-6, 1e-6, 1e-6])
    assert drive[0] >= 0.2 and drive[2] >= 0.3 and drive[1] > 0.0


def test_mapping_is_start_plus_span_times_amplitude_times_gain() -> None:
    drive = CAL.apply([0.5, 0.2, 0.5])
    np.testing.assert_allclose(drive, [0.2 + 0.6 * 0.5, 0.0 + 0.5 * 0.2 * 2.0,
                                       0.3 + 0.7 * 0.5 * 0.5])


def test_ceiling_clamps_high_gain() -> None:
    drive = CAL.apply([1.0, 1.0, 1.0])
    np.testing.assert_allclose(drive, [0.8, 0.5, 0.3 + 0.7 * 0.5])
    assert CAL.apply([0.0, 0.9, 0.0])[1] == 0.5  # gain 2 would give 0.9: clamped


def test_apply_works_on_many_frames_and_checks_the_count() -> None:
    frames = np.linspace(0, 1, 30).reshape(10, 3)
    assert CAL.apply(frames).shape == (10, 3)
    with pytest.raises(ConfigError, match="expected 3"):
        CAL.apply([0.1, 0.2])


def test_identity() -> None:
    ident = Calibration.identity(4)
    assert ident.is_identity and not CAL.is_identity
    np.testing.assert_array_equal(ident.apply([0, 0.25, 0.5, 1]), [0, 0.25, 0.5, 1])


@pytest.mark.parametrize("kw", [{"start": -0.1}, {"ceiling": 1.1}, {"gain": 0},
                                {"start": 0.6, "ceiling": 0.5}, {"start": math.nan}])
def test_bad_tactor_values(kw: dict[str, float]) -> None:
    with pytest.raises(ConfigError):
        TactorCalibration(**kw)


def test_toml_round_trip(tmp_path: Path) -> None:
    path = CAL.save(tmp_path / "sub" / "cal.toml", belt="serial:/dev/ttyACM0",
                    angles_deg=[30.0, 150.0, 270.0])
    assert Calibration.load(path) == CAL
    text = path.read_text()
    assert "[[tactor]]" in text and 'belt = "serial:/dev/ttyACM0"' in text
    odd = Calibration((TactorCalibration(1 / 3, 1.7, 0.9),) * 2)
    assert Calibration.from_toml(odd.to_toml()) == odd


def test_gain_may_be_left_out(tmp_path: Path) -> None:
    p = tmp_path / "c.toml"
    p.write_text("[[tactor]]\nstart = 0.1\nceiling = 0.9\n[[tactor]]\nstart = 0\nceiling = 1\n")
    cal = Calibration.load(p)
    assert cal.n == 2 and cal.tactors[0].gain == 1.0


def test_missing_file_names_it(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"nope\.toml.*not found"):
        Calibration.load(tmp_path / "nope.toml")


@pytest.mark.parametrize(("text", "where"), [
    ("[[tactor]\nstart = 0.1", "not valid TOML"),
    ("format = 'tactorbelt-calibration'\n", "tactor: missing"),
    ("tactor = 3\n", "tactor: must be a non-empty array"),
    ("[[tactor]]\nceiling = 0.9\n", r"tactor\[0\]\.start: missing"),
    ("[[tactor]]\nstart = 0.1\nceiling = 0.9\n[[tactor]]\nstart = 1.5\nceiling = 1\n",
     r"tactor\[1\]\.start: must be in \[0, 1\], got 1.5"),
    ("[[tactor]]\nstart = 'low'\nceiling = 0.9\n", r"tactor\[0\]\.start: must be a finite number"),
    ("[[tactor]]\nstart = nan\nceiling = 0.9\n", r"tactor\[0\]\.start: must be a finite number"),
    ("[[tactor]]\nstart = true\nceiling = 0.9\n", r"tactor\[0\]\.start"),
    ("[[tactor]]\nstart = 0.1\nceiling = 0.9\ngain = 0\n", r"tactor\[0\]\.gain: must be in"),
    ("[[tactor]]\nstart = 0.5\nceiling = 0.4\n", r"tactor\[0\]\.start: start \(0.5\) must not"),
    ("[[tactor]]\nstart = 0.1\nceilling = 0.9\n", r"tactor\[0\]\.ceilling: unknown key"),
    ("[[tactor]]\nindex = 1\nstart = 0.1\nceiling = 0.9\n", r"tactor\[0\]\.index: must be 0"),
    ("version = 2\n[[tactor]]\nstart = 0.1\nceiling = 0.9\n", "version: unsupported"),
    ("format = 'other'\n[[tactor]]\nstart = 0.1\nceiling = 0.9\n", "format: must be"),
    ("colour = 'red'\n[[tactor]]\nstart = 0.1\nceiling = 0.9\n", "colour: unknown key"),
])
def test_bad_files_name_the_file_and_the_field(tmp_path: Path, text: str, where: str) -> None:
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(ConfigError, match=where) as info:
        Calibration.load(p)
    assert str(p) in str(info.value)


def test_binary_file(tmp_path: Path) -> None:
    p = tmp_path / "bin.toml"
    p.write_bytes(b"\xff\xfe\x00garbage")
    with pytest.raises(ConfigError, match=r"bin\.toml"):
        Calibration.load(p)


_levels = st.floats(0.0, 1.0, allow_nan=False)


@settings(max_examples=200, deadline=None)
@given(st.lists(st.one_of(st.tuples(_levels, st.floats(0.01, 10.0), _levels),
                          st.just((0.0, 1.0, 1.0))),  # an identity tactor
                min_size=1, max_size=8),
       st.data())
def test_apply_is_the_clipped_affine_map_bit_for_bit(rows: list[tuple[float, float, float]],
                                                     data: st.DataObject) -> None:
    """apply() gives exactly ``where(a > 0, clip(start + (ceiling - start) * a * gain, 0,
    ceiling), 0)`` (the formula it computes without np.clip, and for an identity
    calibration in three operations), for any amplitudes: in range, out of range, signed
    zeros, NaN and infinities."""
    tactors = tuple(TactorCalibration(start=min(s, c), gain=g, ceiling=max(s, c))
                    for s, g, c in rows)
    cal = Calibration(tactors)
    a = np.array(data.draw(st.lists(
        st.one_of(st.floats(-2.0, 2.0), st.sampled_from([0.0, -0.0, math.inf, -math.inf])),
        min_size=len(rows), max_size=len(rows))), dtype=float)
    start = np.array([t.start for t in tactors])
    gain = np.array([t.gain for t in tactors])
    ceiling = np.array([t.ceiling for t in tactors])
    with np.errstate(invalid="ignore"):  # 0 * inf where start == ceiling
        want = np.where(a > 0.0, np.clip(start + (ceiling - start) * a * gain, 0.0, ceiling),
                        0.0)
        got = cal.apply(a)
    assert got.tobytes() == want.tobytes()


# -- measured timing (tactorbelt validate onsets) ------------------------------------------
TIMED = Calibration(
    (TactorCalibration(0.2, 1.0, 0.8, latency_ms=15.0, latency_sd_ms=0.3, rise_ms=100.0,
                       rise_sd_ms=1.0, fall_ms=55.0, fall_sd_ms=0.5),
     TactorCalibration(0.0, 2.0, 0.5, latency_ms=21.0, latency_sd_ms=0.4),
     TactorCalibration(0.3, 0.5, 1.0)),
    validated="2025-03-01T10:12:00+01:00", validation_method="model: belt.vibration at 10 kHz")


def test_timing_round_trips_through_the_file_and_leaves_apply_alone(tmp_path: Path) -> None:
    path = TIMED.save(tmp_path / "cal.toml", belt="sim")
    back = Calibration.load(path)
    assert back == TIMED
    assert back.tactors[0].rise_ms == 100.0 and back.tactors[1].fall_ms is None
    assert back.validated == "2025-03-01T10:12:00+01:00"
    assert back.has_timing and not CAL.has_timing
    frames = np.linspace(0, 1, 30).reshape(10, 3)
    np.testing.assert_array_equal(back.apply(frames), CAL.apply(frames))
    assert Calibration.identity(3).with_timing([None] * 3, "d", "m").is_identity
    text = path.read_text()
    assert "latency_ms = 15.0" in text and 'validation_method = "model' in text


def test_old_files_load_without_timing(tmp_path: Path) -> None:
    p = tmp_path / "old.toml"
    p.write_text('format = "tactorbelt-calibration"\nversion = 1\nbelt = "sim"\n\n'
                 "[[tactor]]\nindex = 0\nstart = 0.1\nceiling = 0.9\n")
    cal = Calibration.load(p)
    assert cal.validated is None and cal.tactors[0].latency_ms is None and not cal.has_timing


def test_a_toml_date_is_read_as_text(tmp_path: Path) -> None:
    p = tmp_path / "dated.toml"
    p.write_text("validated = 2025-03-01T10:12:00Z\n[[tactor]]\nstart = 0.1\nceiling = 0.9\n"
                 "latency_ms = 14\n")
    cal = Calibration.load(p)
    assert cal.validated == "2025-03-01T10:12:00+00:00" and cal.tactors[0].latency_ms == 14.0


@pytest.mark.parametrize(("row", "where"), [
    ("latency_ms = 'slow'", r"tactor\[0\]\.latency_ms: must be a finite number"),
    ("rise_ms = -1.0", r"tactor\[0\]\.rise_ms: must be in \[0, 60000\]"),
    ("fall_sd_ms = nan", r"tactor\[0\]\.fall_sd_ms: must be a finite number"),
    ("latency_ms = true", r"tactor\[0\]\.latency_ms"),
])
def test_bad_timing_names_the_field(tmp_path: Path, row: str, where: str) -> None:
    p = tmp_path / "bad.toml"
    p.write_text(f"[[tactor]]\nstart = 0.1\nceiling = 0.9\n{row}\n")
    with pytest.raises(ConfigError, match=where):
        Calibration.load(p)


def test_skin_latency_of_one_tactor_and_of_a_set() -> None:
    assert TIMED.skin_latency([0]) == pytest.approx((15.0, 0.3))
    ms, sd = TIMED.skin_latency({1, 0})
    assert ms == pytest.approx(18.0)
    # within-tactor variance (0.09 + 0.16) / 2 plus between-tactor variance 3**2
    assert sd == pytest.approx(math.sqrt(0.125 + 9.0))
    assert TIMED.skin_latency([0, 0]) == TIMED.skin_latency([0])


@pytest.mark.parametrize(("tactors", "message"), [
    ([], "at least one tactor"),
    ([3], "tactor 3 is not on this 3-tactor calibration"),
    ([0, 2], "tactor 2 has no measured latency.*validate onsets --calibration"),
])
def test_skin_latency_refuses_what_it_cannot_tell(tactors: list[int], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        TIMED.skin_latency(tactors)


def test_update_timing_keeps_the_rest_of_the_file_and_creates_a_missing_one(
        tmp_path: Path) -> None:
    from tactorbelt.devices.calibration import update_timing

    p = tmp_path / "cal.toml"
    CAL.save(p, belt="serial:/dev/ttyACM0", angles_deg=[30.0, 150.0, 270.0])
    timing = {"latency_ms": 12.5, "latency_sd_ms": 0.2, "rise_ms": 80.0, "rise_sd_ms": 1.0,
              "fall_ms": 40.0, "fall_sd_ms": 0.5}
    new = update_timing(p, 3, [timing, None, timing], "2025-01-01", "audio:USB?channel=0",
                        belt="sim")
    back = Calibration.load(p)
    assert back == new and back.validation_method == "audio:USB?channel=0"
    assert [t.start for t in back.tactors] == [t.start for t in CAL.tactors]
    assert back.tactors[2].latency_ms == 12.5 and back.tactors[1].latency_ms is None
    text = p.read_text()
    assert 'belt = "serial:/dev/ttyACM0"' in text and "angle_deg = 150.0" in text
    assert not [f for f in tmp_path.iterdir() if f.name != "cal.toml"]  # no temporary left
    fresh = update_timing(tmp_path / "new" / "cal.toml", 2, [timing, timing], "d", "m",
                          belt="sim", angles_deg=[90.0, 270.0])
    assert fresh.is_identity and fresh.skin_latency([0, 1]) == pytest.approx((12.5, 0.2))
    with pytest.raises(ConfigError, match="has 3 tactors but the belt has 6"):
        update_timing(p, 6, [timing] * 6, "d", "m")
