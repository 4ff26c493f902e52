"""Every command follows the same option conventions (docs/cli.md).

Walks ``tactorbelt --help`` and each command's ``--help`` in a real process, as a user
reads them: outputs are ``-o/--output`` (the old ``--out`` works but is not shown),
numbers are typed FLOAT or INTEGER and fail with one wording, one ``--seed``, one
spelling of "analyze", and docs/cli.md lists every option of every command.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from support.cli import tactorbelt
from tactorbelt.cli import COMMANDS

DOCS = Path(__file__).resolve().parents[1] / "docs" / "cli.md"
GROUPS = {"figure": ["amplitudes"], "study": ["init", "check"],
          "calibrate": [None, "perceptual"], "firmware": ["export", "build", "upload"],
          "validate": ["onsets"], "pattern": ["import", "play", "export", "show"]}
COMMAND_PATHS = [[c, *([s] if s else [])] for c in COMMANDS for s in GROUPS.get(c, [None])]
#: commands that write files, and so have -o/--output
WRITERS = {"render", "figure amplitudes", "calibrate", "calibrate perceptual", "export", "demo",
           "power", "analyze", "validate onsets", "pattern import", "pattern export",
           "pattern show"}
#: options whose value is text that is not a number
TEXT_OPTIONS = {"--tactor-angles", "--participant", "--joystick", "--axes", "--participants",
                "--port"}


def _options(help_text: str) -> list[tuple[str, str]]:
    """(the option's spellings, its metavar) of each option line of a help text."""
    section = help_text.split("Options:", 1)[1]
    found = []
    for line in section.splitlines():
        m = re.match(r"^  (-\w, )?(--[\w-]+)(?: (\S+(?: RANGE)?))?", line)
        if m:
            found.append(((m.group(1) or "") + m.group(2), m.group(3) or ""))
    return found


@pytest.fixture(scope="module")
def helps() -> dict[str, str]:
    out = {}
    for path in [[], *COMMAND_PATHS]:
        proc = tactorbelt(*path, "--help")
        assert proc.returncode == 0, proc.stderr
        out[" ".join(path)] = proc.stdout
    return out


def test_outputs_are_dash_o_output(helps: dict[str, str]) -> None:
    for name, text in helps.items():
        assert not re.search(r"--out(?![\w-])", text), f"{name} shows --out"
        assert "--seconds-each" not in text
        spellings = [o for o, _ in _options(text)] if name else []
        if name in WRITERS:
            assert "-o, --output" in spellings, name
        assert not [o for o in spellings if "output" in o and o != "-o, --output"], name


def test_numbers_are_typed(helps: dict[str, str]) -> None:
    for name, text in helps.items():
        if not name:
            continue
        for option, metavar in _options(text):
            assert "RANGE" not in metavar, (name, option, metavar)
            if metavar == "TEXT":
                assert option.split(", ")[-1] in TEXT_OPTIONS, (name, option)
            if option == "--seed":
                assert metavar == "INTEGER", name


def test_one_spelling_of_analyze(helps: dict[str, str]) -> None:
    for name, text in helps.items():
        assert not re.search(r"\banalys(e|ed|es|ing)\b", text, re.I), name
    assert "analyze" in helps[""]


def test_the_exit_code_rule_is_in_the_main_help(helps: dict[str, str]) -> None:
    assert "Exit status: 0 finished" in helps[""]
    assert "2 usage or user error" in helps[""]


@pytest.mark.parametrize("argv, option", [
    (["play", "15", "--seconds", "-1"], "--seconds"),
    (["render", "15", "--rate", "fast"], "--rate"),
    (["render", "15", "--tactors", "2.5"], "--tactors"),
    (["belt-test", "--level", "2"], "--level"),
    (["point", "--bearing", "north"], "--bearing"),
    (["demo", "--seed", "-1"], "--seed"),
    (["devices", "--timeout", "0"], "--timeout"),
    (["run", "x.toml", "-p", "P01", "--dead-zone", "1"], "--dead-zone"),
])
def test_bad_numbers_fail_with_one_wording(argv: list[str], option: str) -> None:
    proc = tactorbelt(*argv)
    assert proc.returncode == 2
    assert re.match(rf"error: Invalid value for '{option}': must be (a (whole |finite )?number|"
                    r"more than|at least|at most|less than|in [\[(])", proc.stderr), proc.stderr
    assert ", got '" in proc.stderr and "Traceback" not in proc.stderr


def test_old_spellings_still_work(tmp_path: Path) -> None:
    proc = tactorbelt("figure", "amplitudes", "--out", str(tmp_path / "a.png"))
    assert proc.returncode == 0, proc.stderr
    proc = tactorbelt("belt-test", "--belt", "sim:virtual", "--seconds-each", "0.1")
    assert proc.returncode == 0, proc.stderr


def test_docs_list_every_option_of_every_command(helps: dict[str, str]) -> None:
    docs = DOCS.read_text()
    for name, text in helps.items():
        if not name:
            continue
        section = docs.split(f"### `tactorbelt {name}`", 1)
        assert len(section) == 2, f"docs/cli.md has no section for {name}"
        body = section[1].split("\n### ", 1)[0]
        for option, _ in _options(text):
            if option.endswith("--help"):
                continue
            assert f"`{option.split(', ')[-1]}" in body, (name, option)


def test_errors_name_the_option_as_help_shows_it(tmp_path: Path) -> None:
    proc = tactorbelt("render", "10", "--format", "png", "-o", str(tmp_path))
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: Invalid value for '-o' / '--output': ")
    proc = tactorbelt("belt-test", "--seconds-each", "x")
    assert proc.stderr.startswith("error: Invalid value for '--seconds': must be a number")
