"""Study files: the paper's protocol, TOML round trips, and one clear error per bad input."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from support.studies import make_study, study_toml, write_study
from tactorbelt import StudyFileError
from tactorbelt.experiment.study import PAPER_STUDY_TOML, Study, load_study, paper_study

#: only the required keys: every table's defaults apply
MINIMAL = study_toml(minimal=True, name="mini")


def test_paper_study_is_the_papers_protocol() -> None:
    s = paper_study()
    assert s.layout_obj().angles_deg == (30.0, 90.0, 150.0, 210.0, 270.0, 330.0)
    assert s.targets.count == 24
    assert (s.stimulus.law, s.stimulus.falloff_deg) == ("paper", 15.0)
    assert (s.stimulus.period_s, s.stimulus.transit_s) == (1.0, 0.1)
    assert [(b.condition, b.repetitions) for b in s.test] == [("static", 5), ("dynamic", 5)]
    assert s.n_test_trials() == 240
    assert s.n_training_trials() == 48
    assert s.training.passes == 1


def test_to_toml_reads_back_equal() -> None:
    s = paper_study()
    assert Study.from_toml(s.to_toml()) == s
    m = Study.from_toml(MINIMAL)
    assert Study.from_toml(m.to_toml()) == m


def test_defaults_fill_missing_tables() -> None:
    s = Study.from_toml(MINIMAL)
    assert s.response.threshold == 0.9
    assert s.session.sample_rate_hz == 100.0
    assert [b.label for b in s.test] == ["static", "dynamic"]


def test_explicit_uneven_angles() -> None:
    s = make_study(minimal=True, tactors=[0, 80, 180, 280])
    assert s.layout_obj().angles_deg == (0.0, 80.0, 180.0, 280.0)


def test_load_study_reads_a_file(tmp_path: Path) -> None:
    p = tmp_path / "s.toml"
    p.write_text(PAPER_STUDY_TOML)
    assert load_study(p) == paper_study()
    small = write_study(tmp_path, "small.toml", tactors=4, targets=8, repetitions=1, training=0)
    assert load_study(small).n_trials() == 16


def test_missing_file_names_it(tmp_path: Path) -> None:
    with pytest.raises(StudyFileError, match=r"nope\.toml.*study init"):
        load_study(tmp_path / "nope.toml")


def _replace(old: str, new: str) -> str:
    assert old in PAPER_STUDY_TOML
    return PAPER_STUDY_TOML.replace(old, new, 1)


def _line_of(text: str, needle: str, nth: int = 1) -> int:
    seen = 0
    for i, line in enumerate(text.splitlines(), start=1):
        if needle in line:
            seen += 1
            if seen == nth:
                return i
    raise AssertionError(needle)


# (text, field, needle for the expected line (nth occurrence), message fragment)
BAD = {
    "malformed TOML": (_replace("[stimulus]", "[stimulus"), None, ("[stimulus", 1),
                       "not valid TOML"),
    "unknown key": (_replace("law = \"paper\"", "law = \"paper\"\nlaww = 1"),
                    "stimulus.laww", ("laww", 1),
                    "unknown key 'laww' (did you mean 'law'?); allowed here: law, falloff_deg"),
    "unknown table": (PAPER_STUDY_TOML + "\n[extras]\nx = 1\n", "extras", ("[extras]", 1),
                      "unknown key 'extras'"),
    "wrong type": (_replace("count = 24", "count = \"24\""), "targets.count",
                   ("count = \"24\"", 1), "must be an integer"),
    "float for int": (_replace("count = 24", "count = 24.0"), "targets.count",
                      ("count = 24.0", 1), "must be an integer"),
    "no targets": (_replace("count = 24", "count = 0"), "targets.count", ("count = 0", 1),
                   "must be in [1, 360]"),
    "zero repetitions": (_replace("repetitions = 5           # every",
                                  "repetitions = 0           # every"),
                         "test[0].repetitions", ("repetitions = 0", 1), "must be in [1, 1000]"),
    "zero repetitions in 2nd block": (
        PAPER_STUDY_TOML[::-1].replace("5 = snoititeper", "0 = snoititeper", 1)[::-1],
        "test[1].repetitions", ("repetitions = 0", 1), "must be in [1, 1000]"),
    "threshold zero": (_replace("threshold = 0.9", "threshold = 0.0"), "response.threshold",
                       ("threshold = 0.0", 1), "must be in (0, 1]"),
    "threshold above one": (_replace("threshold = 0.9", "threshold = 1.5"),
                            "response.threshold", ("threshold = 1.5", 1), "must be in (0, 1]"),
    "unknown law": (_replace("law = \"paper\"", "law = \"cubic\""), "stimulus.law",
                    ("law = \"cubic\"", 1), "'paper', 'linear' or 'energy'"),
    "unknown condition": (_replace("condition = \"dynamic\"", "condition = \"wobbly\""),
                          "test[1].condition", ("wobbly", 1), "'static' or 'dynamic'"),
    "transit too long": (_replace("transit_s = 0.1", "transit_s = 0.6"), "stimulus",
                         ("[stimulus]", 1), "2*transit_s"),
    "home beyond threshold": (_replace("home_radius = 0.15", "home_radius = 0.95"),
                              "response", ("[response]", 1), "home_radius"),
    "one tactor": (_replace("tactors = 6", "tactors = 1"), "layout.tactors",
                   ("tactors = 1", 1), "must be in [2, 64]"),
    "negative ITI": (_replace("iti_s = 1.0", "iti_s = -1.0"), "session.iti_s",
                     ("iti_s = -1.0", 1), "must be in [0, 60]"),
    "bad order rule": (_replace("condition_order = \"alternate\"", "condition_order = \"zig\""),
                       "session.condition_order", ("zig", 1), "'fixed', 'alternate' or 'latin'"),
}


@pytest.mark.parametrize("case", list(BAD))
def test_bad_input_gives_one_clear_error(case: str) -> None:
    text, field, (needle, nth), fragment = BAD[case]
    with pytest.raises(StudyFileError) as info:
        Study.from_toml(text, path="my.toml")
    err = info.value
    assert err.path == "my.toml"
    assert err.field == field
    assert err.line == _line_of(text, needle, nth), str(err)
    assert fragment in str(err)
    assert str(err).startswith(f"my.toml:{err.line}: ")


def test_no_test_blocks() -> None:
    text = PAPER_STUDY_TOML.split("# Test blocks")[0]
    with pytest.raises(StudyFileError, match="test: required but missing"):
        Study.from_toml(text, path="x.toml")


def test_duplicate_block_names() -> None:
    text = PAPER_STUDY_TOML.replace('name = "dynamic"', 'name = "static"')
    with pytest.raises(StudyFileError, match="distinct names"):
        Study.from_toml(text)


def test_layout_needs_count_or_angles() -> None:
    text = study_toml(minimal=True, tactors=None)
    with pytest.raises(StudyFileError, match="tactor count") as info:
        Study.from_toml(text, path="m.toml")
    assert info.value.line == _line_of(text, "[layout]")


def test_duplicate_tactor_angles() -> None:
    with pytest.raises(StudyFileError, match="duplicate tactor angles"):
        make_study(minimal=True, tactors=[10, 10, 200])


def test_duration_estimate_counts_breaks() -> None:
    s = paper_study()
    # 288 trials x (2 s + 1 s ITI) + 5 breaks x 60 s
    assert s.estimate_duration_s() == pytest.approx(288 * 3.0 + 5 * 60.0)


@pytest.mark.parametrize("key, where", [('"[" = []', "name = "), ('"a[b" = 1', "passes = ")])
def test_an_unknown_key_with_a_bracket_is_named(key: str, where: str) -> None:
    """An unknown key holding '[' (which pydantic's own labels also hold) is reported as
    the unknown key it is, not as a crash."""
    text = PAPER_STUDY_TOML.replace(where, f"{key}\n{where}", 1)
    name = key.split(" = ")[0].strip('"')
    with pytest.raises(StudyFileError, match=rf"unknown key '{re.escape(name)}'; allowed"):
        Study.from_toml(text, path="s.toml")
