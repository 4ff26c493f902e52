"""Haptic patterns (docs/patterns.md): the tactorbelt.pattern/1 format, import of AHAP,
.haptic and .tact, export to AHAP, CSV and WAV, the figure, playback on a belt, and the
refusals a user sees (file, field, reason, exit 2)."""

from __future__ import annotations

import json
import wave
from pathlib import Path
from typing import Any

import click
import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from tactorbelt.cli import main
from tactorbelt.geometry import Layout
from tactorbelt.laws import amplitudes
from tactorbelt.patterns import schema
from tactorbelt.patterns.ahap import CURVE_POINTS, pattern_from_ahap, pattern_to_ahap
from tactorbelt.patterns.io import export_pattern, read_any
from tactorbelt.patterns.model import (
    FORMAT,
    Event,
    Pattern,
    PatternFileError,
    pattern_from_dict,
    pattern_to_dict,
    save_pattern,
)
from tactorbelt.patterns.render import PatternPlayback, render_pattern

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "examples" / "patterns"
AHAP = SAMPLES / "knock-and-swell.ahap"
HAPTIC = SAMPLES / "heartbeat.haptic"
TACT = SAMPLES / "front-sweep.tact"
NATIVE = SAMPLES / "circle.json"


@click.command(context_settings={"ignore_unknown_options": True, "allow_extra_args": True})
@click.pass_context
def _entry(ctx: click.Context) -> None:
    code = main(ctx.args)
    if isinstance(code, int):
        ctx.exit(code)


def run(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(_entry, list(args), catch_exceptions=False)
    return result.exit_code, result.stdout, result.stderr


def _same_events(a: Pattern, b: Pattern) -> None:
    """Event times within 1 ms and intensities (and envelope gains) within 1/255."""
    assert len(a.events) == len(b.events)
    for x, y in zip(a.events, b.events, strict=True):
        assert abs(x.at_ms - y.at_ms) <= 1.0
        assert abs(x.duration_ms - y.duration_ms) <= 1.0
        assert abs(x.intensity - y.intensity) <= 1 / 255
        assert x.transient == y.transient
        assert len(x.envelope) == len(y.envelope)
        for (t1, g1), (t2, g2) in zip(x.envelope, y.envelope, strict=True):
            assert abs(t1 - t2) <= 1.0 and abs(g1 - g2) <= 1 / 255


# -- the samples ------------------------------------------------------------------------------
def test_an_ahap_file_is_placed_at_the_angle_asked_for() -> None:
    p = read_any(AHAP, angle_deg=90.0)
    assert [e.transient for e in p.events] == [True, True, False]
    assert {e.angle_deg for e in p.events} == {90.0}
    swell = p.events[2]
    assert (swell.at_ms, swell.duration_ms, swell.intensity) == (500.0, 800.0, 0.9)
    # the intensity curve is the envelope: 0.2 at the start, 1 from 300 to 600 ms, 0 at the end
    assert swell.envelope[0] == (0.0, 0.2) and swell.envelope[-1] == (800.0, 0.0)
    assert any("AttackTime" in d for d in p.dropped)
    navibelt = Layout(tuple(k * 22.5 for k in range(16)))
    on_belt = PatternPlayback(p, navibelt).amplitudes(np.array([0.9]))[0]
    assert np.argmax(on_belt) == 4  # 90 deg is motor 4 of a naviBelt's 16


def test_a_haptic_file_becomes_one_envelope_and_its_emphases_transients() -> None:
    p = read_any(HAPTIC)
    cont = [e for e in p.events if not e.transient]
    taps = [e for e in p.events if e.transient]
    assert len(cont) == 1 and cont[0].duration_ms == pytest.approx(900.0)
    assert [(e.at_ms, e.intensity) for e in taps] == [(50.0, 1.0), (250.0, 0.8)]
    assert any("frequency envelope" in d for d in p.dropped)


def test_a_tact_file_keeps_its_layouts_places() -> None:
    p = read_any(TACT)
    assert p.layout_deg == (60.0, 20.0, 340.0, 300.0, 240.0, 200.0, 160.0, 120.0)
    dots = [e for e in p.events if e.tactor is not None]
    # back panel, x = 0 and x = 1: the wearer's left (240) and right (120) behind
    assert {p.layout_deg[e.tactor] for e in dots} == {240.0, 120.0}  # type: ignore[index]
    paths = [e for e in p.events if e.path is not None]
    assert paths[0].path == (60.0, 0.0) and paths[1].path == pytest.approx((0.0, -60.0))
    # on its own places each dot drives one tactor alone, at its intensity
    pb = PatternPlayback(p, Layout(p.layout_deg))
    frame = pb.amplitudes(np.array([0.75]))[0]
    assert frame[4] == 1.0 and frame[7] == 1.0 and frame[:4].max() == 0.0


def test_a_path_is_felt_moving_between_the_motors() -> None:
    layout = Layout.even(6)  # 30, 90, ...
    p = Pattern((Event(0.0, 1000.0, 1.0, path=(30.0, 90.0)),))
    t, amps = render_pattern(PatternPlayback(p, layout), 1000.0)
    want = amplitudes(layout, 30.0 + 60.0 * t)
    assert np.allclose(amps, want)
    assert amps[0, 0] > amps[0, 1] and amps[999, 1] > amps[999, 0]
    assert amps[500, 0] == pytest.approx(amps[500, 1])  # halfway: between the two
    full = Pattern((Event(0.0, 1000.0, path=(0.0, 360.0)),))  # a whole turn, clockwise
    _, turn = render_pattern(PatternPlayback(full, layout), 1000.0)
    assert list(np.argmax(turn[::100], axis=1)) == [0, 0, 1, 1, 2, 2, 3, 4, 4, 5]


def test_overlapping_events_combine_by_the_maximum_and_stay_in_range() -> None:
    p = Pattern((Event(0.0, 100.0, 0.7, tactor=0), Event(50.0, 100.0, 0.9, tactor=0)),
                layout_deg=(30.0, 210.0))
    a = PatternPlayback(p, Layout((30.0, 210.0))).amplitudes(np.array([0.02, 0.07, 0.12, 0.2]))
    assert list(a[:, 0]) == [0.7, 0.9, 0.9, 0.0]


# -- round trips ---------------------------------------------------------------------------------
def test_import_export_ahap_import_keeps_times_and_intensities(tmp_path: Path) -> None:
    first = read_any(AHAP)
    assert export_pattern(first, "ahap", tmp_path / "out.ahap") == []
    again = read_any(tmp_path / "out.ahap")
    _same_events(first, again)
    t1, a1 = render_pattern(PatternPlayback(first, Layout.even(6)))
    t2, a2 = render_pattern(PatternPlayback(again, Layout.even(6)))
    assert t1.shape == t2.shape and np.max(np.abs(a1 - a2)) <= 1 / 255


def test_a_haptic_file_through_ahap_keeps_its_envelope_and_says_what_ahap_cannot(
        tmp_path: Path) -> None:
    first = read_any(HAPTIC)
    notes = export_pattern(first, "ahap", tmp_path / "out.ahap")
    # its emphases sit on the amplitude envelope, which AHAP's intensity control also
    # applies to them: they cannot be written at full strength, and the export says so
    assert notes == ["the full intensity of 2 transient(s) under an envelope (AHAP's "
                     "intensity control scales them too)"]
    again = read_any(tmp_path / "out.ahap")
    keep = [e for e in first.events if not e.transient]
    _same_events(Pattern(tuple(keep)), Pattern(tuple(e for e in again.events
                                                     if not e.transient)))
    assert [e.at_ms for e in again.events if e.transient] == [50.0, 250.0]


def test_a_transient_under_an_envelope_is_written_louder_by_as_much(tmp_path: Path) -> None:
    p = Pattern((Event(0.0, 400.0, 1.0, angle_deg=0.0, envelope=((0.0, 0.5), (400.0, 0.5))),
                 Event(100.0, 30.0, 0.3, angle_deg=0.0, transient=True)))
    doc, notes = pattern_to_ahap(p)
    assert notes == []
    _same_events(p, pattern_from_ahap(doc))


def test_a_long_envelope_is_split_into_curves_core_haptics_takes(tmp_path: Path) -> None:
    env = tuple((float(k * 10), float(abs(np.sin(k / 5.0)))) for k in range(41))
    p = Pattern((Event(100.0, 400.0, 0.8, angle_deg=0.0, envelope=env),))
    doc, _ = pattern_to_ahap(p)
    curves = [i["ParameterCurve"] for i in doc["Pattern"] if "ParameterCurve" in i]
    assert len(curves) > 1
    assert all(len(c["ParameterCurveControlPoints"]) <= CURVE_POINTS for c in curves)
    _same_events(p, pattern_from_ahap(json.loads(json.dumps(doc))))


@pytest.mark.parametrize("sample", [TACT, NATIVE, AHAP], ids=["tact", "native", "ahap"])
def test_the_pattern_json_reads_back_as_written(sample: Path, tmp_path: Path) -> None:
    p = read_any(sample)
    save_pattern(p, tmp_path / "p.json")
    back = read_any(tmp_path / "p.json")
    assert pattern_to_dict(back) == pattern_to_dict(p)
    _same_events(p, back)


def test_every_sample_fits_the_published_schema() -> None:
    s = schema()
    assert s["properties"]["format"]["const"] == FORMAT
    event_keys = set(s["$defs"]["event"]["properties"])
    for sample in (AHAP, HAPTIC, TACT, NATIVE):
        doc = pattern_to_dict(read_any(sample))
        assert set(doc) <= set(s["properties"]) and set(s["required"]) <= set(doc)
        for e in doc["events"]:
            assert set(e) <= event_keys and {"at_ms", "duration_ms"} <= set(e)


# -- exports ---------------------------------------------------------------------------------
def test_the_wav_export_carries_each_tactors_amplitude(tmp_path: Path) -> None:
    p = read_any(TACT)
    export_pattern(p, "wav", tmp_path / "level.wav", carrier_hz=0.0)
    with wave.open(str(tmp_path / "level.wav")) as w:
        assert (w.getnchannels(), w.getsampwidth(), w.getframerate()) == (8, 2, 48000)
        pcm = np.frombuffer(w.readframes(w.getnframes()), "<i2").reshape(-1, 8) / 32767.0
    t = np.arange(pcm.shape[0]) / 48000.0
    want = PatternPlayback(p, Layout(p.layout_deg)).amplitudes(t)
    assert pcm.shape[0] == 48000 and np.max(np.abs(pcm - want)) <= 1 / 32767 + 1e-12
    export_pattern(p, "wav", tmp_path / "carrier.wav")  # 250 Hz carrier
    with wave.open(str(tmp_path / "carrier.wav")) as w:
        pcm = np.frombuffer(w.readframes(w.getnframes()), "<i2").reshape(-1, 8) / 32767.0
    assert np.abs(pcm[:, 4]).max() == pytest.approx(1.0, abs=1e-3)  # the back dots, full


def test_the_csv_export_has_the_render_header(tmp_path: Path) -> None:
    code, out, err = run("pattern", "export", str(NATIVE), "--format", "csv", "--tactors", "8",
                         "-o", str(tmp_path / "c.csv"))
    assert code == 0, err
    lines = (tmp_path / "c.csv").read_text().splitlines()
    assert lines[0] == "t_s," + ",".join(f"tactor_{k}" for k in range(8))
    assert len(lines) == 1 + 2600 and lines[1].startswith("0.000000000,")


# -- the command line ------------------------------------------------------------------------
def test_import_says_what_maps_where_and_what_is_dropped(tmp_path: Path) -> None:
    code, out, err = run("pattern", "import", str(AHAP), "--angle", "45",
                         "-o", str(tmp_path / "k.json"))
    assert code == 0, err
    assert "placed at 45 deg" in out and "dropped: AttackTime" in out
    assert json.loads((tmp_path / "k.json").read_text())["format"] == FORMAT


def test_play_runs_on_the_simulated_belt_and_ends_with_the_motors_off(
        monkeypatch: pytest.MonkeyPatch) -> None:
    from tactorbelt.devices import sim as sim_module

    opened: list[Any] = []
    real = sim_module.open_sim
    monkeypatch.setattr(sim_module, "open_sim",
                        lambda target="", **o: opened.append(real(target, **o)) or opened[-1])
    code, out, err = run("pattern", "play", str(TACT), "--belt", "sim:virtual", "--stats")
    assert code == 0, err
    stats = json.loads(out.strip().splitlines()[-1])
    assert stats["frames"] + stats["missed"] == 1000  # 1 s at the sim belt's 1 kHz
    assert "done: motors off" in out
    belt = opened[0]
    assert belt.closed and not np.any(belt.levels)


def test_show_draws_a_png(tmp_path: Path) -> None:
    code, out, err = run("pattern", "show", str(HAPTIC), "--tactors", "16",
                         "-o", str(tmp_path / "h.png"))
    assert code == 0, err
    assert (tmp_path / "h.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _write(tmp_path: Path, name: str, doc: Any) -> Path:
    p = tmp_path / name
    p.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    return p


_AHAP_OK = {"Version": 1, "Pattern": [{"Event": {"Time": 0, "EventType": "HapticContinuous",
                                                 "EventDuration": 0.1}}]}
_HAPTIC_OK = {"version": {"major": 1}, "signals": {"continuous": {"envelopes": {
    "amplitude": [{"time": 0, "amplitude": 0.5}, {"time": 0.1, "amplitude": 0.2}]}}}}
_HEAD_DOT = {"startTime": 0, "endTime": 100, "pointList": [{"index": 0, "intensity": 1}]}
_TACT_HEAD = {"project": {"tracks": [{"effects": [{"startTime": 0, "offsetTime": 100, "modes": {
    "Head": {"mode": "DOT_MODE", "dotMode": {"feedback": [_HEAD_DOT]}}}}]}]}}


@pytest.mark.parametrize(("name", "doc", "field", "reason"), [
    ("v2.json", {"format": "tactorbelt.pattern/2", "events": []}, "format",
     "expected 'tactorbelt.pattern/1'"),
    ("nokey.json", {"format": FORMAT}, None, "missing key 'events'"),
    ("high.json", {"format": FORMAT, "events": [{"at_ms": 0, "duration_ms": 10,
                                                 "intensity": 1.5, "angle_deg": 0}]},
     "events[0].intensity", "must be in [0, 1], got 1.5"),
    ("noplace.json", {"format": FORMAT, "events": [{"at_ms": 0, "duration_ms": 10}]},
     "events[0]", "needs exactly one place"),
    ("tactor.json", {"format": FORMAT, "layout_deg": [0, 180],
                     "events": [{"at_ms": 0, "duration_ms": 10, "tactor": 2}]},
     "events[0].tactor", "not in the pattern's layout_deg"),
    ("v2.ahap", {**_AHAP_OK, "Version": 2}, "Version", "expected 1"),
    ("nopattern.ahap", {"Version": 1}, None, "missing key 'Pattern'"),
    ("loud.ahap", {"Version": 1, "Pattern": [{"Event": {
        "Time": 0, "EventType": "HapticTransient",
        "EventParameters": [{"ParameterID": "HapticIntensity", "ParameterValue": 2}]}}]},
     "Pattern[0].Event.EventParameters[0].ParameterValue", "must be in [0, 1], got 2"),
    ("nodur.ahap", {"Version": 1, "Pattern": [{"Event": {"Time": 0,
                                                         "EventType": "HapticContinuous"}}]},
     "Pattern[0].Event", "missing key 'EventDuration'"),
    ("v2.haptic", {**_HAPTIC_OK, "version": {"major": 2}}, "version.major", "expected 1"),
    ("empty.haptic", {"version": {"major": 1}, "signals": {"continuous": {"envelopes": {
        "amplitude": []}}}}, "signals.continuous.envelopes.amplitude", "empty"),
    ("back.haptic", {"version": {"major": 1}, "signals": {"continuous": {"envelopes": {
        "amplitude": [{"time": 0.2, "amplitude": 0.1}, {"time": 0.1, "amplitude": 0.1}]}}}},
     "signals.continuous.envelopes.amplitude[1].time", "must not decrease"),
    ("head.tact", _TACT_HEAD, "project.tracks[0].effects[0].modes.Head",
     "a Head layout cannot be shown on a belt"),
    ("broken.json", '{"format": "tactorbelt.pattern/1",\n "events": [}', None,
     "not valid JSON: Expecting value at line 2"),
])
def test_bad_files_are_refused_with_the_file_the_field_and_the_reason(
        tmp_path: Path, name: str, doc: Any, field: str | None, reason: str) -> None:
    path = _write(tmp_path, name, doc)
    with pytest.raises(PatternFileError) as info:
        read_any(path)
    assert info.value.path == str(path) and info.value.field == field
    assert reason in info.value.reason
    code, _, err = run("pattern", "import", str(path), "-o", str(tmp_path / "out.json"))
    assert code == 2
    assert err.startswith(f"error: {path}: ") and reason in err
    assert "Traceback" not in err and not (tmp_path / "out.json").exists()


def test_an_empty_pattern_imports_but_cannot_be_played_exported_or_drawn(
        tmp_path: Path) -> None:
    path = _write(tmp_path, "empty.ahap", {"Version": 1, "Pattern": []})
    code, out, _ = run("pattern", "import", str(path), "-o", str(tmp_path / "e.json"))
    assert code == 0 and ": 0 events" in out
    assert read_any(tmp_path / "e.json").events == ()
    for args in (["play", "--belt", "sim:virtual"], ["export", "--format", "wav", "-o",
                                                      str(tmp_path / "e.wav")],
                 ["show", "-o", str(tmp_path / "e.png")]):
        code, _, err = run("pattern", args[0], str(tmp_path / "e.json"), *args[1:])
        assert code == 2, args
        assert f"{tmp_path / 'e.json'}: events: the pattern has no events" in err


def test_an_unknown_file_kind_is_named(tmp_path: Path) -> None:
    with pytest.raises(PatternFileError, match=r"other\.txt: not a pattern file"):
        read_any(_write(tmp_path, "other.txt", {"tracks": []}))
    assert read_any(_write(tmp_path, "knock.txt", _AHAP_OK)).source["format"] == "ahap"


def test_a_pattern_dict_is_checked_when_built_from_code() -> None:
    with pytest.raises(PatternFileError, match=r"events\[0\].envelope\[1\]\[0\]: times must"):
        pattern_from_dict({"format": FORMAT, "events": [
            {"at_ms": 0, "duration_ms": 100, "angle_deg": 0,
             "envelope": [[50, 1], [10, 0.5]]}]})


# -- properties ------------------------------------------------------------------------------

@st.composite
def _patterns(draw: st.DrawFn) -> Pattern:
    """Continuous events one after another (each with its own envelope: AHAP has one
    intensity control), transients in the gaps between them."""
    events = []
    t = draw(st.floats(0, 500))
    for _ in range(draw(st.integers(1, 4))):
        dur = draw(st.floats(20, 800))
        n = draw(st.integers(0, 40))
        cuts = sorted(set(draw(st.lists(st.integers(0, int(dur)), min_size=n, max_size=n))))
        env = tuple((float(c), draw(st.floats(0, 1))) for c in cuts)
        events.append(Event(round(t, 3), round(dur, 3), draw(st.floats(0, 1)), angle_deg=0.0,
                            envelope=env))
        gap = draw(st.floats(40, 300))
        if draw(st.booleans()):
            events.append(Event(round(t + dur + 5.0, 3), 30.0, draw(st.floats(0, 1)),
                                angle_deg=0.0, transient=True))
        t += dur + gap
    return Pattern(tuple(events))


@settings(max_examples=60)
@given(_patterns())
def test_any_pattern_of_one_place_survives_ahap(p: Pattern) -> None:
    doc, notes = pattern_to_ahap(p)
    assert notes == []
    again = pattern_from_ahap(json.loads(json.dumps(doc)))
    assert len(again.events) == len(p.events)
    for x, y in zip(p.events, again.events, strict=True):
        assert abs(x.at_ms - y.at_ms) <= 1.0 and abs(x.duration_ms - y.duration_ms) <= 1.0
        assert abs(x.intensity - y.intensity) <= 1 / 255 and x.transient == y.transient
    layout = Layout.even(6)
    _, a1 = render_pattern(PatternPlayback(p, layout))
    _, a2 = render_pattern(PatternPlayback(again, layout))
    assert a1.shape == a2.shape and np.max(np.abs(a1 - a2), initial=0.0) <= 1 / 255


@settings(max_examples=60)
@given(_patterns())
def test_any_pattern_reads_back_from_its_json(p: Pattern) -> None:
    back = pattern_from_dict(json.loads(json.dumps(pattern_to_dict(p))))
    _same_events(p, back)
