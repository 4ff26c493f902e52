"""The validator and the drive: ``validate onsets --drive/--tune`` and ``validate stimulus``
on the sim belt's model, as a user runs them."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from support.cli import tactorbelt
from tactorbelt import ConfigError
from tactorbelt.devices.calibration import Calibration
from tactorbelt.experiment.study import paper_study
from tactorbelt.validation.run import OnsetSettings, run_onsets
from tactorbelt.validation.stimulus import run_stimulus

PNG = b"\x89PNG\r\n\x1a\n"


def _by_level(doc: dict, key: str, level: float) -> float:
    values = [p[key] for p in doc["pulses"] if p["level"] == level]
    return sum(values) / len(values)


def test_onsets_name_the_drive_and_shaping_speeds_the_rise_and_fall(tmp_path: Path) -> None:
    settings = OnsetSettings(pulses=1, levels=(0.5, 1.0))
    plain, _ = run_onsets("sim:virtual", tmp_path / "plain", settings=settings, drive="plain")
    shaped, _ = run_onsets("sim:virtual", tmp_path / "shaped", settings=settings)
    p = json.loads((tmp_path / "plain" / "validation.json").read_text())
    s = json.loads((tmp_path / "shaped" / "validation.json").read_text())
    assert (p["drive"], s["drive"]) == ("plain", "shaped")  # the belt's default: shaped
    assert _by_level(p, "rise_ms", 1.0) == pytest.approx(102.7, abs=0.2)  # as before
    assert _by_level(p, "fall_ms", 1.0) == pytest.approx(54.9, abs=0.2)
    for level in (0.5, 1.0):
        assert _by_level(s, "fall_ms", level) <= 30.0
        assert _by_level(s, "rise_ms", level) < _by_level(p, "rise_ms", level) / 2
    assert _by_level(s, "rise_ms", 0.5) <= 30.0
    assert _by_level(s, "latency_ms", 1.0) < _by_level(p, "latency_ms", 1.0)


def test_tune_fits_the_time_constants_writes_them_and_validates_shaped(
        tmp_path: Path) -> None:
    cal = tmp_path / "belt.toml"
    proc = tactorbelt("validate", "onsets", "--belt", "sim:virtual", "--pulses", "1",
                      "--levels", "0.5,1.0", "--tune", "--calibration", str(cal),
                      "-o", str(tmp_path / "out"))
    assert proc.returncode == 0, proc.stderr
    assert "plain:" in proc.stdout and "shaped, with them:" in proc.stdout
    assert "rise 39.7, fall 50.0" in proc.stdout  # the model's 40 and 50 ms
    doc = json.loads((tmp_path / "out" / "validation.json").read_text())
    assert doc["drive"] == "shaped" and doc["plain"]["drive"] == "plain"
    assert [f["tactor"] for f in doc["shaping"]] == list(range(6))
    assert doc["shaping"][0]["rise_tau_ms"] == pytest.approx(40.0, rel=0.01)
    assert doc["shaping"][0]["fall_tau_ms"] == pytest.approx(50.0, rel=0.01)
    taus = Calibration.load(cal).shaping_taus()
    assert taus is not None and taus[0][0] == pytest.approx(0.040, rel=0.01)
    assert (tmp_path / "out" / "onsets.png").read_bytes()[:8] == PNG
    # the belt opened through the file shapes with its constants
    assert "rise_tau_ms" in cal.read_text()
    with pytest.raises(ConfigError, match="--calibration"):
        run_onsets("sim:virtual", tmp_path / "x", tune=True)


def test_stimulus_writes_the_contracts_json_and_figure(tmp_path: Path) -> None:
    proc = tactorbelt("validate", "stimulus", "--belt", "sim:virtual", "--target", "3",
                      "--condition", "static", "--drive", "shaped", "-o", str(tmp_path / "s"))
    assert proc.returncode == 0, proc.stderr
    doc = json.loads((tmp_path / "s" / "stimulus.json").read_text())
    assert doc["drive"] == "shaped" and doc["condition"] == "static"
    assert isinstance(doc["rms_error"], float)
    (target,) = doc["targets"]
    assert target["target"] == 3 and target["target_deg"] == 45.0
    assert {"target", "rms_error", "tactors"} <= set(target)
    assert len(target["tactors"]) == 6
    for t in target["tactors"]:
        assert {"tactor", "rms_error", "onset_error_ms", "offset_error_ms"} <= set(t)
    driven = [t for t in target["tactors"] if t["driven"]]
    assert [t["tactor"] for t in driven] == [0, 1]  # target 45 deg: between 30 and 90
    assert (tmp_path / "s" / "stimulus.png").read_bytes()[:8] == PNG
    proc = tactorbelt("validate", "stimulus", "--belt", "sim:virtual", "--condition",
                      "static", "-o", str(tmp_path / "t"))
    assert proc.returncode != 0 and "--target N or --all" in proc.stderr


def test_shaping_brings_the_felt_stimulus_to_the_intended_one(tmp_path: Path) -> None:
    between = [k for k in range(24) if k % 4 != 2]  # the paper's 18 between-tactor targets
    errors = {}
    for url, drive in (("sim:virtual", "plain"), ("sim:virtual", "shaped"),
                       ("sim:virtual?overdrive=2", "shaped")):
        res, _ = run_stimulus(url, tmp_path / f"{drive}{len(errors)}", targets=between,
                              condition="dynamic", drive=drive)
        errors[url, drive] = res.rms_error
    plain = errors["sim:virtual", "plain"]
    assert errors["sim:virtual", "shaped"] * 2 <= plain  # overdrive to 3.6 V
    assert errors["sim:virtual?overdrive=2", "shaped"] * 3 <= plain  # to 6 V
    static, _ = run_stimulus("sim:virtual?overdrive=2", tmp_path / "static", targets=between,
                             condition="static", drive="shaped")
    assert static.drive == "shaped"
    plain, _ = run_stimulus("sim:virtual", tmp_path / "paper", targets=[1],
                            condition="static")
    assert plain.drive == "plain"  # the paper study's drive, as its sessions play
    onsets = [t["onset_error_ms"] for r in static.targets for t in r["tactors"]
              if t["driven"]]
    assert max(onsets) <= 10.0


def test_stimulus_refuses_a_target_the_study_does_not_have(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="target 24 is not one of"):
        run_stimulus("sim:virtual", tmp_path / "x", targets=[24], condition="static",
                     study=paper_study())
    assert not (tmp_path / "x").exists()
