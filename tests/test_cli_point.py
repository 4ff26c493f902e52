"""``tactorbelt point``: bad input is an error (exit 2), good input runs with motors off at the end.

Runs use ``--belt sim:virtual`` (the sim belt on a simulated clock), so nothing sleeps.
"""

from __future__ import annotations

import io
import subprocess
import sys

import pytest

from tactorbelt.cli import main


def run(argv: list[str], capsys) -> tuple[int, str]:
    try:
        main(argv)
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    err = capsys.readouterr().err
    return code, err


@pytest.fixture
def headings_csv(tmp_path):
    p = tmp_path / "track.csv"
    p.write_text("t_s,heading_deg\n" + "".join(f"{i * 0.1:.1f},{(i * 3) % 360}\n"
                                               for i in range(40)))
    return p


@pytest.mark.parametrize("argv, message", [
    (["point"], "give --bearing"),
    (["point", "--bearing", "10", "--sweep"], "not both"),
    (["point", "--sweep", "--heading-from", "x.txt"], "needs --bearing"),
    (["point", "--bearing", "north"], "--bearing"),
    (["point", "--bearing", "10", "--seconds", "-1"], "--seconds"),
    (["point", "--sweep", "--sweep-period", "0"], "--sweep-period"),
    (["point", "--bearing", "10", "--falloff", "0"], "falloff"),
    (["point", "--bearing", "10", "--period", "0.1"], "transit"),
    (["point", "--bearing", "10", "--heading-from", "/nonexistent/h.txt"], "cannot read"),
    (["point", "--bearing", "10", "--belt", "sim:virtual"], "--seconds"),
    (["point", "--bearing", "10", "--belt", "nowhere:1"], "unknown belt URL"),
])
def test_bad_options_exit_2_with_a_message(argv, message, capsys):
    code, err = run(argv, capsys)
    assert code == 2
    assert err.startswith("error: ") or "\nerror: " in err
    assert message in err
    assert "Traceback" not in err


@pytest.mark.parametrize("content, message", [
    ("10\n20\nabc\n", "line 3: heading 'abc' is not a number"),
    ("# a comment\n10\n\n20,5\n", "line 4: expected one heading"),
    ("t_s,heading_deg\n0,10\n0.5,nan\n", "line 3: heading 'nan'"),
    ("t_s,heading_deg\n0,10\n0.5,x\n", "line 3"),
    ("t_s,heading_deg\n1.0,10\n0.5,20\n", "line 3: time 0.5 s is earlier"),
    ("t_s,heading_deg\n0,10\n0.5\n", "line 3: expected 2 fields"),
    ("time,direction\n0,10\n", "line 1: 'time' is not a heading"),
    ("\n# nothing\n", "no headings"),
])
def test_bad_heading_files_name_the_line(tmp_path, content, message, capsys):
    p = tmp_path / "h.txt"
    p.write_text(content)
    code, err = run(["point", "--bearing", "30", "--heading-from", str(p),
                     "--belt", "sim:virtual"], capsys)
    assert code == 2
    assert message in err
    assert "Traceback" not in err


def test_replays_a_timed_heading_file(headings_csv, capsys):
    code, err = run(["point", "--bearing", "30", "--heading-from", str(headings_csv),
                     "--belt", "sim:virtual", "--mode", "dynamic"], capsys)
    assert code == 0, err
    assert "40 headings" in err and "motors off" in err
    assert "done after 4.0 s" in err  # 3.9 s of headings, then the last one held 0.1 s


def test_seconds_bounds_a_replay(headings_csv, capsys):
    code, err = run(["point", "--bearing", "30", "--heading-from", str(headings_csv),
                     "--belt", "sim:virtual", "--seconds", "1"], capsys)
    assert code == 0, err
    assert "done after 1.0 s" in err


def test_plain_numbers_from_stdin(monkeypatch, capsys):
    monkeypatch.setattr(sys, "stdin", io.StringIO("10\n12\n\n# turn\n90\n"))
    code, err = run(["point", "--bearing", "45", "--heading-from", "-",
                     "--belt", "sim:virtual", "--stream"], capsys)
    assert code == 0, err
    assert "3 headings" in err and "frames" in err


def test_bad_stdin_line_names_the_line(monkeypatch, capsys):
    monkeypatch.setattr(sys, "stdin", io.StringIO("10\n12\n1e\n"))
    code, err = run(["point", "--bearing", "45", "--heading-from", "-",
                     "--belt", "sim:virtual"], capsys)
    assert code == 2
    assert "stdin line 3" in err


def test_sweep_runs_for_the_given_seconds(capsys):
    code, err = run(["point", "--sweep", "--sweep-period", "4", "--seconds", "4",
                     "--belt", "sim:virtual", "--mode", "dynamic", "--stream"], capsys)
    assert code == 0, err
    assert "done after 4.0 s" in err and "4000 frames" in err


def test_quiet_prints_nothing(capsys):
    code, err = run(["point", "--bearing", "10", "--seconds", "0.5", "--belt", "sim:virtual",
                     "-q"], capsys)
    assert code == 0 and err == ""


def test_help_in_a_fresh_process():
    proc = subprocess.run([sys.executable, "-m", "tactorbelt", "point", "--help"],
                          capture_output=True, text=True)
    assert proc.returncode == 0
    for option in ("--bearing", "--heading-from", "--sweep", "--sweep-period", "--seconds",
                   "--mode", "--law"):
        assert option in proc.stdout
