"""A study file names a haptic pattern as a stimulus (docs/study.md, "Pattern stimuli"):
validated at load (file, line, field, reason), played turned to each trial's target,
kept with the session in the store, exported."""

from __future__ import annotations

import json
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from tactorbelt import StudyFileError
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.experiment.study import Study, load_study, paper_study
from tactorbelt.geometry import Layout
from tactorbelt.patterns.model import Event, Pattern
from tactorbelt.patterns.stimulus import PatternStimulus
from tactorbelt.stimuli import make_stimulus

EXAMPLES = Path(__file__).resolve().parents[1] / "examples" / "patterns"

STUDY = """\
name = "pattern localisation"

[layout]
tactors = 6

[targets]
count = 12

[stimulus]
pattern = "patterns/knock-and-swell.ahap"
max_presentation_s = 3.0

[response]
timeout_s = 4.0

[session]
iti_s = 0.5

[training]
passes = 0

[[test]]
condition = "static"
repetitions = 2
"""


def _write(tmp_path: Path, text: str = STUDY) -> Path:
    (tmp_path / "patterns").mkdir(exist_ok=True)
    for f in EXAMPLES.iterdir():
        shutil.copy(f, tmp_path / "patterns" / f.name)
    path = tmp_path / "study.toml"
    path.write_text(text, encoding="utf-8")
    return path


def _error(path: Path) -> StudyFileError:
    with pytest.raises(StudyFileError) as info:
        load_study(path)
    return info.value


def test_a_pattern_file_beside_the_study_is_read_and_kept_with_it(tmp_path: Path) -> None:
    study = load_study(_write(tmp_path))
    name = "patterns/knock-and-swell.ahap"
    assert study.stimulus.pattern == name and set(study.patterns) == {name}
    pattern = study.pattern(name)
    assert len(pattern.events) == 3 and pattern.duration_s == pytest.approx(1.3)
    # the study's own TOML holds the pattern: it reads back equal, with no file beside it
    again = Study.from_toml(study.to_toml())
    assert again == study and again.pattern(name) == pattern
    from tactorbelt.experiment.description import describe

    assert (f"  pattern     {name} (3 events, 1.3 s; at each target) in [stimulus]"
            in describe(study).to_text().splitlines())


def test_a_study_without_patterns_is_as_before() -> None:
    study = paper_study()
    assert study.patterns == {} and "patterns" not in study.to_toml()
    text = "# my study\n" + study.to_toml()
    assert study.session_toml(text) == text  # the stored text, byte for byte
    spec = study.trial_stimulus("static")
    layout = study.layout_obj()
    for target in (0.0, 15.0, 30.0):
        for condition in ("static", "dynamic"):
            assert study.make_stimulus(spec, layout, target, condition) == make_stimulus(
                layout, target, condition, spec.law, spec.falloff_deg, spec.period_s,
                spec.transit_s)


@pytest.mark.parametrize(("edit", "at", "field", "reason"), [
    (lambda t: t.replace("knock-and-swell.ahap", "missing.json"), "missing", "stimulus.pattern",
     "no such pattern file: "),
    (lambda t: t + '\n[[test]]\nname = "b"\ncondition = "static"\nrepetitions = 1\n'
     'pattern = "nope.ahap"\n', "nope.ahap", "test[1].pattern", "no such pattern file: "),
    (lambda t: t.replace("knock-and-swell.ahap", "bad.json"), "bad.json", "stimulus.pattern",
     "bad.json: events[0].intensity: must be in [0, 1]"),
    (lambda t: t.replace("knock-and-swell.ahap", "v2.json"), "v2.json", "stimulus.pattern",
     "v2.json: format: "),
    (lambda t: t.replace("knock-and-swell.ahap", "empty.json"), "empty.json", "stimulus.pattern",
     "the pattern has no events"),
    (lambda t: t.replace("knock-and-swell.ahap", "head.tact"), "head.tact", "stimulus.pattern",
     "a Head layout cannot be shown on a belt"),
    (lambda t: t + "\n[calibration]\nperceptual = true\n", "perceptual", "calibration.perceptual",
     "a wearer profile is not applied to a pattern stimulus"),
    (lambda t: t.replace('pattern = "patterns/knock-and-swell.ahap"', 'pattern = "tap"')
     + '\n[patterns.tap]\nformat = "tactorbelt.pattern/1"\nevents = [{at_ms = 0, '
     "duration_ms = 100, tactor = 2}]\n", "[patterns.tap]", "patterns.tap",
     "tap: events[0].tactor: "),
])
def test_a_bad_pattern_is_refused_with_file_line_field_and_reason(
        tmp_path: Path, edit: Any, at: str, field: str, reason: str) -> None:
    text = edit(STUDY)
    path = _write(tmp_path, text)
    line = next(i for i, x in enumerate(text.splitlines(), 1) if at in x)
    pats = tmp_path / "patterns"
    (pats / "bad.json").write_text(json.dumps({"format": "tactorbelt.pattern/1", "events": [
        {"at_ms": 0, "duration_ms": 100, "intensity": 1.5, "angle_deg": 0}]}))
    (pats / "v2.json").write_text(json.dumps({"format": "tactorbelt.pattern/2", "events": []}))
    (pats / "empty.json").write_text(json.dumps({"format": "tactorbelt.pattern/1",
                                                 "events": []}))
    tact = json.loads((EXAMPLES / "front-sweep.tact").read_text())
    tracks = tact["project"]["tracks"]
    effect = tracks[0]["effects"][0]
    effect["modes"]["Head"] = next(iter(effect["modes"].values()))
    (pats / "head.tact").write_text(json.dumps(tact))
    err = _error(path)
    assert err.path == str(path) and err.field == field, str(err)
    assert err.line == line, str(err)
    assert reason in err.reason, str(err)


def test_the_pattern_is_played_turned_to_the_trials_target() -> None:
    layout = Layout.from_angles([0.0, 90.0, 180.0, 270.0])
    knock = Pattern(events=(Event(at_ms=0, duration_ms=100, intensity=0.8, angle_deg=0.0),
                            Event(at_ms=200, duration_ms=100, intensity=0.5,
                                  path=(0.0, 90.0))))
    stim = PatternStimulus(knock, layout, 90.0, law="paper", name="knock")
    amps = stim.amplitudes(np.array([0.05, 0.25, 0.299, 0.35]))
    assert amps.shape == (4, 4)
    np.testing.assert_allclose(amps[0], [0.0, 0.8, 0.0, 0.0], atol=0.005)  # 0 deg at 90
    assert amps[1, 1] > 0 and amps[1, 2] > 0  # the path runs from 90 towards 180
    assert amps[2, 2] > amps[2, 1]
    np.testing.assert_allclose(amps[3], 0.0)  # silent after the pattern
    assert stim.amplitudes(0.05).shape == (4,)
    assert not stim.is_dynamic and stim.describe()["pattern"] == "knock"


def _session(study: Study, text: str, store_path: Path, belt_url: str = "sim") -> list[Any]:
    """A model-participant session through the session runner; the stimuli it made."""
    from tactorbelt.experiment.runner import SessionRunner
    from tactorbelt.experiment.store import Store
    from tactorbelt.inputs.model import make_model_cursor

    clock = SimClock()
    with Store.open(store_path) as store, open_belt(belt_url, clock=clock,
                                                    layout=study.layout_obj()) as belt:
        runner = SessionRunner(study, "P01", belt, make_model_cursor(belt, clock, seed=3),
                               store, clock, seed=1, study_toml=text)
        runner.run()
    return list(runner._stimuli.values())


def test_a_model_session_with_a_pattern_stimulus_stores_it(tmp_path: Path) -> None:
    path = _write(tmp_path)
    study = load_study(path)
    db = tmp_path / "s.sqlite"
    made = _session(study, path.read_text(), db)
    assert len(made) == 12 and all(isinstance(s, PatternStimulus) for s in made)
    assert sorted(s.target_deg for s in made) == [30.0 * k for k in range(12)]
    with sqlite3.connect(db) as con:
        (text, status), = con.execute("SELECT study_toml, status FROM sessions")
        rows = con.execute("SELECT status, correct FROM trials").fetchall()
    assert status == "complete" and len(rows) == 24
    assert all(s in ("done", "timeout") for s, _ in rows)
    # the model participant felt the knock where it was played: far above chance (1/12)
    assert np.mean([c or 0 for _, c in rows]) > 0.5
    # the stored study holds the pattern it played: it reads with the file gone
    shutil.rmtree(tmp_path / "patterns")
    assert text.startswith(STUDY)
    stored = Study.from_toml(text, path="stored")
    assert stored == study
    assert stored.pattern("patterns/knock-and-swell.ahap") == study.pattern(
        "patterns/knock-and-swell.ahap")
    with pytest.raises(StudyFileError, match="no such pattern file"):
        load_study(path)
    # and the exports read the session
    from tactorbelt.experiment.export import export_bids, export_csv

    export_csv(db, tmp_path / "csv")
    with open(tmp_path / "csv" / "trials.csv") as f:
        assert len(f.readlines()) == 25
    export_bids(db, tmp_path / "bids", authors=["A. Author", "B. Author"])
    assert list((tmp_path / "bids").glob("sub-P01/ses-1/beh/*_beh.tsv"))


def test_a_pattern_the_navibelt_cannot_show_is_refused_before_the_session(
        tmp_path: Path) -> None:
    pytest.importorskip("pybelt", reason="pip install 'tactorbelt[navibelt]'")
    path = _write(tmp_path, STUDY.replace("knock-and-swell.ahap", "six.json")
                  .replace("tactors = 6", "angles_deg = [0, 45, 90, 135, 180, 225, 270, 315]"
                           "\n# the naviBelt's 16 motors, every other one")
                  .replace("[layout]", "[layout]\n"))
    events = [{"at_ms": 100, "duration_ms": 200, "intensity": 0.1 * (k + 1),
               "angle_deg": 45 * k} for k in range(6)]
    (tmp_path / "patterns" / "six.json").write_text(json.dumps(
        {"format": "tactorbelt.pattern/1", "events": events}))
    study = load_study(path)  # the study's layout shows it; the naviBelt does not
    from tactorbelt.patterns.model import PatternFileError

    with open_belt("navibelt:emulator?motors=0,2,4,6,8,10,12,14") as belt, \
            pytest.raises(PatternFileError, match="needs 6 different intensities at once"):
        study.check_belt(belt)


def test_run_command_plays_a_pattern_study(tmp_path: Path) -> None:
    path = _write(tmp_path)
    db = tmp_path / "s.sqlite"
    proc = subprocess.run([sys.executable, "-m", "tactorbelt", "run", str(path), "-p", "P01",
                           "--headless", "--input", "model", "--belt", "sim", "--db", str(db)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    with sqlite3.connect(db) as con:
        (text,), = con.execute("SELECT study_toml FROM sessions")
        n, = con.execute("SELECT count(*) FROM trials WHERE status != 'aborted'").fetchone()
    assert n == 24 and '[patterns."patterns/knock-and-swell.ahap"]' in text
