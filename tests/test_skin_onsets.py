"""Skin onsets as a lab meets them (issue 40, part 3: "the results are used").

The belt's calibration gets its latencies from the real command (``tactorbelt validate
onsets --belt sim:virtual --calibration FILE``); a session on the sim belt with that
calibration stores, per trial, the stored onset plus the starting tactor's latency;
``tactorbelt analyze`` counts RTs from it (``--rt-from skin``, the default then) or from
the command (``--rt-from command``: today's numbers); the BIDS sidecar and the LSL
description carry the latencies.
"""

from __future__ import annotations

import json
import math
import sqlite3
from pathlib import Path
from typing import Any

import pytest

from support.cli import tactorbelt
from support.studies import write_study
from tactorbelt import open_belt
from tactorbelt.clock import SimClock
from tactorbelt.devices.calibration import Calibration
from tactorbelt.experiment.runner import run_session, skin_latency, starting_tactors
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import load_study
from tactorbelt.inputs.model import make_model_cursor
from tactorbelt.stimuli import make_stimulus


def _session(tmp: Path, study: Path, db: Path, cal: Calibration | None, pid: str = "P01",
             seed: int = 3) -> None:
    s = load_study(study)
    with Store.open(db) as store:
        clock = SimClock()
        with open_belt("sim:virtual", clock=clock, layout=s.layout_obj(),
                       calibration=cal) as belt:
            run_session(s, pid, belt, make_model_cursor(belt, clock, seed=seed), store, clock,
                        seed=seed)


def _trials(db: Path) -> list[dict[str, Any]]:
    con = sqlite3.connect(db)
    con.row_factory = sqlite3.Row
    try:
        return [dict(r) for r in con.execute("SELECT * FROM trials ORDER BY trial_id")]
    finally:
        con.close()


@pytest.fixture(scope="module")
def lab(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """A calibration measured by the real command, a study, and two stores of the same
    session: on the calibrated belt, and on the bare one."""
    tmp = tmp_path_factory.mktemp("skin")
    cal_file = tmp / "belt.toml"
    proc = tactorbelt("validate", "onsets", "--belt", "sim:virtual", "--pulses", "3",
                      "--drive", "plain", "--calibration", str(cal_file), "-o",
                      str(tmp / "val"))
    assert proc.returncode == 0, proc.stderr
    cal = Calibration.load(cal_file)
    assert cal.has_timing
    study = write_study(tmp, name="skin", targets=6, repetitions=1, training=1,
                        training_conditions=["static"], break_every=0)
    skin_db, bare_db = tmp / "skin.sqlite", tmp / "bare.sqlite"
    _session(tmp, study, skin_db, cal)
    _session(tmp, study, bare_db, None)
    return {"tmp": tmp, "cal": cal, "cal_file": cal_file, "study": study, "skin": skin_db,
            "bare": bare_db}


def test_the_measured_latency_is_the_models(lab: dict[str, Any]) -> None:
    for t in lab["cal"].tactors:  # docs/validation.md: 15.18 ms at level 1
        assert t.latency_ms == pytest.approx(15.18, abs=0.05)


def test_a_calibrated_session_stores_onset_plus_the_starting_tactors_latency(
        lab: dict[str, Any]) -> None:
    cal: Calibration = lab["cal"]
    s = load_study(lab["study"])
    rows = _trials(lab["skin"])
    assert rows and all(r["onset_ns"] is not None for r in rows)
    for r in rows:
        stim = make_stimulus(s.layout_obj(), r["target_deg"], r["condition"],
                             **_stim_args(s, r["block_name"]))
        starts = starting_tactors(stim)
        if stim.is_dynamic:
            assert list(starts) == [stim.near_idx]
        lat = sum(float(cal.tactors[k].latency_ms or 0.0) * w
                  for k, w in starts.items()) / sum(starts.values())
        assert r["device_onset_ns"] is None  # the sim belt reports no device onsets
        assert r["skin_onset_ns"] == r["onset_ns"] + round(lat * 1e6)
        assert r["skin_onset_sd_ns"] == 0  # sim:virtual: every pulse alike
    # the bare belt stores none, and everything else is the same session
    bare = _trials(lab["bare"])
    assert {(r["skin_onset_ns"], r["skin_onset_sd_ns"]) for r in bare} == {(None, None)}
    keep = ("trial_index", "onset_ns", "acquired_ns", "rt_s", "response_deg", "status")
    assert [[r[k] for k in keep] for r in bare] == [[r[k] for k in keep] for r in rows]


def _stim_args(study: Any, block_name: str) -> dict[str, Any]:
    sp = study.trial_stimulus(block_name)
    return {"law": sp.law, "falloff_deg": sp.falloff_deg, "period_s": sp.period_s,
            "transit_s": sp.transit_s}


def test_which_tactors_start_a_stimulus_and_their_weighted_latency() -> None:
    from tactorbelt.geometry import Layout

    layout = Layout.even(6)
    angles = layout.angles_deg
    cal = Calibration.identity(6).with_timing(
        [{"latency_ms": 10.0 + k, "latency_sd_ms": 0.5} for k in range(6)], "2026-01-01",
        "test")
    between = angles[0] + 20.0  # nearer to tactor 0, tactor 1 farther
    dyn = make_stimulus(layout, between, "dynamic", "paper", 15.0, 1.0, 0.1)
    assert starting_tactors(dyn) == {dyn.near_idx: 1.0}
    assert skin_latency(cal, dyn) == (10.0 + dyn.near_idx, 0.5)
    on = make_stimulus(layout, angles[2], "static", "paper", 15.0, 1.0, 0.1)
    assert list(starting_tactors(on)) == [2]
    assert skin_latency(cal, on) == pytest.approx((12.0, 0.5))
    static = make_stimulus(layout, between, "static", "paper", 15.0, 1.0, 0.1)
    w = starting_tactors(static)
    assert len(w) >= 2 and all(a > 0 for a in w.values())
    mean = sum((10.0 + k) * a for k, a in w.items()) / sum(w.values())
    var = sum(a * (0.25 + (10.0 + k - mean) ** 2) for k, a in w.items()) / sum(w.values())
    ms, sd = skin_latency(cal, static) or (0.0, 0.0)
    assert (ms, sd) == pytest.approx((mean, math.sqrt(var)))
    # equal weights: Calibration.skin_latency
    two = {k: 1.0 for k in w}
    assert cal.skin_latency(two) == pytest.approx((
        sum(10.0 + k for k in two) / len(two),
        math.sqrt(0.25 + sum((10.0 + k - sum(10.0 + j for j in two) / len(two)) ** 2
                             for k in two) / len(two))))
    # a starting tactor without a latency: none
    partial = Calibration.identity(6).with_timing(
        [{"latency_ms": 10.0} if k != dyn.near_idx else None for k in range(6)],
        "2026-01-01", "test")
    assert skin_latency(partial, dyn) is None


def test_the_device_onsets_uncertainty_joins_the_latency_spread() -> None:
    from tactorbelt.experiment.runner import SessionRunner
    from tactorbelt.experiment.schedule import make_schedule
    from tactorbelt.experiment.study import paper_study
    from tactorbelt.experiment.trial import TrialResult

    study = paper_study()
    cal = Calibration.identity(6).with_timing(
        [{"latency_ms": 15.0, "latency_sd_ms": 0.3} for _ in range(6)], "2026-01-01", "t")
    clock = SimClock()
    with open_belt("sim:virtual", clock=clock, layout=study.layout_obj(),
                   calibration=cal) as belt:
        runner = SessionRunner(study, "P01", belt, make_model_cursor(belt, clock, seed=1),
                               _NoStore(), clock)  # type: ignore[arg-type]
        t = make_schedule(study, "P01", 1)[0]
        r = TrialResult(t, onset_ns=1_000_000_000)
        assert runner.skin_onset(r) == (1_015_000_000, 300_000)
        r.device_onset_ns, r.onset_uncertainty_ns = 1_000_200_000, 400_000
        assert runner.skin_onset(r) == (1_015_200_000, 500_000)  # sqrt(0.3² + 0.4²) ms
        assert runner.skin_onset(TrialResult(t)) is None  # no onset


class _NoStore:
    """What SessionRunner.__init__ needs of a store: nothing is written here."""


def _analyze(db: Path, out: Path, *extra: str) -> dict[str, Any]:
    proc = tactorbelt("analyze", str(db), "-o", str(out), "--bootstrap-sims", "0", *extra)
    assert proc.returncode == 0, proc.stderr
    return dict(json.loads((out / "summary.json").read_text()))


def test_analyze_counts_rts_from_the_skin_or_from_the_command(lab: dict[str, Any]) -> None:
    import pandas as pd

    tmp: Path = lab["tmp"]
    auto = _analyze(lab["skin"], tmp / "auto")
    skin = _analyze(lab["skin"], tmp / "skin", "--rt-from", "skin")
    command = _analyze(lab["skin"], tmp / "command", "--rt-from", "command")
    bare = _analyze(lab["bare"], tmp / "bare")
    assert (auto["rt_from"], skin["rt_from"], command["rt_from"], bare["rt_from"]) == (
        "skin", "skin", "command", "command")
    assert "every analysed trial" in auto["rt_from_reason"]
    assert "no analysed trial has a skin onset" in bare["rt_from_reason"]
    html = (tmp / "auto" / "report.html").read_text()
    assert "Response times count from the onset at the skin (rt_from: skin)" in html
    # --rt-from command reproduces today's numbers: those of the same session stored
    # without a skin onset (the seed, and so the bootstrap, is the same)
    for key in ("conditions", "cells", "rt_mixed_model"):
        assert command[key] == bare[key], key
    # --rt-from skin shifts every RT by exactly its trial's skin offset
    pt_skin = pd.read_csv(tmp / "skin" / "per_target.csv")
    pt_cmd = pd.read_csv(tmp / "command" / "per_target.csv")
    rows = [r for r in _trials(lab["skin"]) if r["status"] == "done"]
    offsets = {(r["skin_onset_ns"] - r["onset_ns"]) / 1e9 for r in rows}
    assert len(offsets) == 1  # every tactor has the same latency on the model
    (offset,) = offsets
    diff = (pt_cmd["median_rt_s"] - pt_skin["median_rt_s"]).dropna()
    assert len(diff) and diff.to_numpy() == pytest.approx(offset, abs=1e-12)
    for cond in ("static", "dynamic"):
        a = command["conditions"][cond]["between_tactor"]["median_rt_s"]
        b = skin["conditions"][cond]["between_tactor"]["median_rt_s"]
        assert a - b == pytest.approx(offset, abs=1e-12)


def test_rt_from_skin_needs_a_skin_onset_in_every_analysed_trial(
        lab: dict[str, Any]) -> None:
    proc = tactorbelt("analyze", str(lab["bare"]), "-o", str(lab["tmp"] / "no"),
                      "--bootstrap-sims", "0", "--rt-from", "skin")
    assert proc.returncode == 2
    assert "have no skin onset" in proc.stderr and "--rt-from command" in proc.stderr


def test_the_rt_shift_is_exact_per_trial(lab: dict[str, Any]) -> None:
    from tactorbelt.analysis.summary import rt_from_choice
    from tactorbelt.analysis.tables.load import load_stores

    data = load_stores([lab["skin"]])
    tr, used, _ = rt_from_choice(data.trials)
    assert used == "skin"
    stored = {r["trial_id"]: r for r in _trials(lab["skin"])}
    done = tr.loc[tr["status"] == "done"]
    assert len(done)
    for tid, rt, rt_cmd in zip(done["trial_id"], done["rt_s"], done["rt_command_s"],
                               strict=True):
        r = stored[int(tid)]
        assert rt_cmd == r["rt_s"]
        assert rt == r["rt_s"] - (r["skin_onset_ns"] - r["onset_ns"]) / 1e9
    tr, used, _ = rt_from_choice(data.trials, "command")
    assert used == "command" and tr["rt_s"].equals(data.trials["rt_s"])


def test_the_bids_sidecar_describes_the_stimulus_system(lab: dict[str, Any]) -> None:
    out = lab["tmp"] / "bids"
    proc = tactorbelt("export", str(lab["skin"]), "--format", "bids", "-o", str(out))
    assert proc.returncode == 0, proc.stderr
    (sidecar,) = out.glob("sub-*/ses-*/beh/*_task-betweentactor_beh.json")
    doc = json.loads(sidecar.read_text())
    system = doc["StimulusSystem"]
    cal: Calibration = lab["cal"]
    assert system["Belt"] == "sim:virtual"
    assert system["ActuatorType"].startswith("ERM vibration motor, simulated")
    assert system["TactorLayout"]["AnglesDeg"] == [30.0, 90.0, 150.0, 210.0, 270.0, 330.0]
    assert system["AmplitudeLaw"]["Law"] == "paper"
    tactors = system["Calibration"]["Tactors"]
    assert [t["latency_ms"] for t in tactors] == [t.latency_ms for t in cal.tactors]
    assert [t["rise_ms"] for t in tactors] == [t.rise_ms for t in cal.tactors]
    assert "nearer tactor" in system["SkinOnset"]
    for col in ("skin_onset_s", "skin_onset_sd_s"):
        assert doc[col]["Units"] == "s"
    (beh,) = out.glob("sub-*/ses-*/beh/*_task-betweentactor_beh.tsv")
    lines = [ln.split("\t") for ln in beh.read_text().splitlines()]
    head = lines[0]
    rows = {int(r[head.index("trial_index")]): r for r in lines[1:]}
    for t in _trials(lab["skin"]):
        r = rows[t["trial_index"]]
        assert float(r[head.index("skin_onset_s")]) == t["skin_onset_ns"] / 1e9
    # the bare belt's: no latency, n/a
    out2 = lab["tmp"] / "bids-bare"
    assert tactorbelt("export", str(lab["bare"]), "--format", "bids", "-o",
                      str(out2)).returncode == 0
    (beh2,) = out2.glob("sub-*/ses-*/beh/*_task-betweentactor_beh.tsv")
    lines2 = [ln.split("\t") for ln in beh2.read_text().splitlines()]
    col = lines2[0].index("skin_onset_s")
    assert {r[col] for r in lines2[1:]} == {"n/a"}
    (side2,) = out2.glob("sub-*/ses-*/beh/*_beh.json")
    assert all("latency_ms" not in t for t in json.loads(side2.read_text())[
        "StimulusSystem"]["Calibration"]["Tactors"])


def test_an_audio_belt_names_its_carrier() -> None:
    from tactorbelt.experiment.export import _stimulus_system

    system = _stimulus_system({"belt": "audio:3?channels=6&carrier_hz=175",
                               "study_toml": "", "calibration_json": None})
    assert system["CarrierFrequency"] == 175.0 and system["CarrierFrequencyUnits"] == "Hz"
    assert "sound card" in system["ActuatorType"]
    assert "CarrierFrequency" not in _stimulus_system({"belt": "serial:auto"})


def test_run_with_calibration_stores_skin_onsets_and_resume_reuses_the_file(
        lab: dict[str, Any]) -> None:
    """As a user runs it: `tactorbelt run --calibration FILE`, killed by --limit, resumed
    without the option: every trial of both runs has its skin onset."""
    tmp: Path = lab["tmp"]
    db = tmp / "cli.sqlite"
    first = tactorbelt("run", str(lab["study"]), "-p", "P09", "--headless", "--db", str(db),
                       "--calibration", str(lab["cal_file"]), "--limit", "3")
    assert first.returncode == 0, first.stderr
    again = tactorbelt("run", str(lab["study"]), "-p", "P09", "--headless", "--db", str(db),
                       "--resume")
    assert again.returncode == 0, again.stderr
    assert "calibration" in again.stdout + again.stderr
    rows = [r for r in _trials(db) if r["status"] == "done"]
    assert len(rows) > 3
    lat_ns = round(lab["cal"].tactors[0].latency_ms * 1e6)
    for r in rows:  # every tactor of the sim model has the same latency
        assert r["skin_onset_ns"] == pytest.approx(r["onset_ns"] + lat_ns, abs=1)
    bad = tactorbelt("run", str(lab["study"]), "-p", "P10", "--headless", "--db", str(db),
                     "--calibration", str(tmp / "missing.toml"))
    assert bad.returncode == 2 and "missing.toml" in bad.stderr


def test_the_csv_and_parquet_trials_carry_the_onsets(lab: dict[str, Any]) -> None:
    from tactorbelt.experiment.export_formats import read_table

    stored = {t["trial_index"]: t for t in _trials(lab["skin"])}
    for fmt in ("csv", "parquet"):
        out = lab["tmp"] / f"onsets-{fmt}"
        proc = tactorbelt("export", str(lab["skin"]), "--format", fmt, "-o", str(out))
        assert proc.returncode == 0, proc.stderr
        df = read_table(out / f"trials.{fmt}")
        for col in ("skin_onset_ns", "skin_onset_sd_ns", "device_onset_ns",
                    "onset_uncertainty_ns"):
            assert col in df.columns
        for r in df.to_dict("records"):
            assert r["skin_onset_ns"] == stored[r["trial_index"]]["skin_onset_ns"]
            assert r["skin_onset_sd_ns"] == stored[r["trial_index"]]["skin_onset_sd_ns"]
