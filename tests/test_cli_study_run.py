"""The command line: study init/check, run, export; clear errors and exit codes."""

from __future__ import annotations

import os
import sqlite3
from pathlib import Path
from typing import Any

import pytest

from support.studies import study_toml
from tactorbelt import DeviceError
from tactorbelt.cli import main
from tactorbelt.experiment.schedule import block_order
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import PAPER_STUDY_TOML, load_study, paper_study, template_toml

# 6 training + 24 test
SMALL = study_toml(minimal=True, name="cli", tactors=6, targets=6, break_every=0,
                   training=1, training_conditions=["static"], repetitions=2)


def run_cli(args: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    try:
        main(args)
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def small(tmp_path: Path) -> Path:
    p = tmp_path / "small.toml"
    p.write_text(SMALL)
    return p


def test_study_init_writes_the_papers_protocol(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / "paper.toml"
    code, out, _ = run_cli(["study", "init", str(p)], capsys)
    assert code == 0 and "288 trials" in out
    assert p.read_text() == PAPER_STUDY_TOML
    assert load_study(p) == paper_study()
    assert "# " in p.read_text()  # commented for the user
    code, _, err = run_cli(["study", "init", str(p)], capsys)
    assert code == 2 and "exists" in err and "--force" in err
    code, _, _ = run_cli(["study", "init", str(p), "--force"], capsys)
    assert code == 0


def test_study_check_prints_counts_and_duration(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / "paper.toml"
    p.write_text(PAPER_STUDY_TOML)
    code, out, _ = run_cli(["study", "check", str(p)], capsys)
    assert code == 0
    assert "training    48 trials" in out
    assert "static     120 trials" in out and "dynamic    120 trials" in out
    assert "total       288 trials (240 test)" in out
    assert "duration    about 19 min" in out
    code, out, _ = run_cli(["study", "check", str(p), "--participant", "P02"], capsys)
    assert "P02: dynamic -> static" in out


def test_study_init_and_check_the_resolution_template(tmp_path: Path,
                                                      capsys: pytest.CaptureFixture[str]
                                                      ) -> None:
    p = tmp_path / "resolution.toml"
    code, out, _ = run_cli(["study", "init", str(p), "--template", "resolution"], capsys)
    assert code == 0 and "720 trials (240 training, 480 test)" in out
    assert p.read_text() == template_toml("resolution")
    code, out, _ = run_cli(["study", "check", str(p), "--participant", "P03"], capsys)
    assert code == 0
    assert "design      4 target counts x 2 conditions x 1 load = 8 cells" in out
    assert "static-48    96 trials (static, 2 repetitions x 48 targets)" in out
    assert "training    240 trials (1 pass x 2 conditions x (12 + 24 + 36 + 48) targets" in out
    study = load_study(p)
    order = " -> ".join(study.test[i].label for i in block_order(study, "P03"))
    assert f"williams (balanced over 8 participants); P03: {order}" in out
    assert "duration    about 47 min" in out
    code, _, err = run_cli(["study", "init", str(tmp_path / "x.toml"), "--template", "nope"],
                           capsys)
    assert code == 2 and "resolution" in err


def test_study_check_reports_file_line_field(tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    p = tmp_path / "bad.toml"
    p.write_text(PAPER_STUDY_TOML.replace("threshold = 0.9", "threshold = 1.5"))
    code, _, err = run_cli(["study", "check", str(p)], capsys)
    line = PAPER_STUDY_TOML.splitlines().index(
        next(x for x in PAPER_STUDY_TOML.splitlines() if x.startswith("threshold"))) + 1
    assert code == 2
    assert err.startswith(f"error: {p}:{line}: response.threshold: must be in (0, 1]")
    assert "Traceback" not in err


def test_run_headless_scripted_then_export(small: Path, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    db = tmp_path / "s.sqlite"
    code, out, err = run_cli(["run", str(small), "--participant", "P01", "--headless",
                              "--input", "scripted", "--db", str(db)], capsys)
    assert code == 0, err
    assert "complete, 30/30 trials" in out and "accuracy 100.0%" in out
    with Store.open(db, readonly=True) as store:
        (s,) = store.sessions()
        assert s["clock"] == "sim" and s["input"] == "scripted"
        assert s["study_toml"] == SMALL
        assert len(store.trials()) == 30
    code, out, _ = run_cli(["export", str(db), str(tmp_path / "csv")], capsys)
    assert code == 0 and (tmp_path / "csv" / "trials.csv").exists()
    code, out, _ = run_cli(["export", str(db), str(tmp_path / "bids"), "--format", "bids"],
                           capsys)
    assert code == 0
    assert (tmp_path / "bids" / "sub-P01" / "ses-1" / "beh").is_dir()


def test_run_limit_then_resume(small: Path, tmp_path: Path,
                               capsys: pytest.CaptureFixture[str]) -> None:
    db = tmp_path / "s.sqlite"
    base = ["run", str(small), "--participant", "P02", "--headless", "--input", "scripted",
            "--db", str(db)]
    code, out, err = run_cli([*base, "--limit", "4", "--seed", "5"], capsys)
    assert code == 0 and "interrupted, 10/30" in out and "--resume" in err
    code, _, err = run_cli(base, capsys)
    assert code == 2 and "unfinished session" in err and "--resume" in err
    code, out, _ = run_cli([*base, "--resume"], capsys)
    assert code == 0 and "complete, 30/30 trials done (20 this run)" in out
    with Store.open(db, readonly=True) as store:
        (s,) = store.sessions()
        assert s["seed"] == 5
        assert [t["trial_index"] for t in store.trials()] == list(range(30))
    # a complete session is not followed by another one unasked
    code, _, err = run_cli([*base, "--limit", "1"], capsys)
    assert code == 2 and "completed session 1" in err and "--new-session" in err
    code, out, _ = run_cli([*base, "--new-session", "--limit", "1"], capsys)
    assert code == 0
    # the second one is unfinished: a third needs --new-session again
    code, out, _ = run_cli([*base, "--new-session", "--limit", "1"], capsys)
    assert code == 0
    with Store.open(db, readonly=True) as store:
        assert [s["session_number"] for s in store.sessions()] == [1, 2, 3]


def _files(d: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in d.iterdir() if p.is_file()}


def test_run_into_a_file_that_is_not_sqlite(small: Path, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    db = tmp_path / "notes.txt"
    db.write_text("not a database\n")
    before = _files(tmp_path)
    code, _, err = run_cli(["run", str(small), "-p", "P01", "--headless", "--input",
                            "scripted", "--db", str(db)], capsys)
    assert code == 2 and "not an SQLite database" in err
    assert _files(tmp_path) == before


def test_run_into_a_read_only_store(small: Path, tmp_path: Path,
                                    capsys: pytest.CaptureFixture[str]) -> None:
    db = tmp_path / "ro.sqlite"
    Store.open(db).close()
    db.chmod(0o444)
    try:
        before = _files(tmp_path)
        code, _, err = run_cli(["run", str(small), "-p", "P01", "--headless", "--input",
                                "scripted", "--db", str(db)], capsys)
        assert code == 2 and "read-only" in err
        assert _files(tmp_path) == before
    finally:
        db.chmod(0o644)


def test_run_into_a_store_in_use(small: Path, tmp_path: Path,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    db = tmp_path / "busy.sqlite"
    with Store.open(db):
        before = _files(tmp_path)
        code, _, err = run_cli(["run", str(small), "-p", "P01", "--headless", "--input",
                                "scripted", "--db", str(db)], capsys)
        assert code == 2 and "another run is using the store" in err
        assert _files(tmp_path) == before
    conn = sqlite3.connect(db)
    assert conn.execute("SELECT COUNT(*) FROM sessions").fetchone()[0] == 0
    conn.close()


def test_belt_failure_exits_3_naming_the_port(small: Path, tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str],
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    import tactorbelt.devices as devices

    real_open = devices.open_belt
    belts: list[Any] = []

    def open_failing(url: str, **kw: Any) -> Any:
        belt = real_open("sim", **kw)
        belt.url = "serial:/dev/ttyACM0"
        real_play = belt._write_play
        n = {"plays": 0}

        def play(stimulus: Any, duration_s: Any) -> None:
            n["plays"] += 1
            real_play(stimulus, duration_s)
            if n["plays"] == 4:
                raise DeviceError("no answer on /dev/ttyACM0 for 1.0 s")

        belt._write_play = play  # type: ignore[method-assign]
        belts.append(belt)
        return belt

    monkeypatch.setattr(devices, "open_belt", open_failing)
    db = tmp_path / "s.sqlite"
    code, _, err = run_cli(["run", str(small), "-p", "P01", "--headless", "--input",
                            "scripted", "--db", str(db)], capsys)
    assert code == 3
    assert err.startswith("error: belt serial:/dev/ttyACM0 failed")
    assert "--resume" in err and "Traceback" not in err
    assert belts[0].closed and not belts[0].levels.any()
    with Store.open(db, readonly=True) as store:
        (s,) = store.sessions()
        assert s["status"] == "interrupted"
        assert [t["status"] for t in store.trials()] == ["done"] * 3 + ["aborted"]
    monkeypatch.setattr(devices, "open_belt", real_open)
    code, out, _ = run_cli(["run", str(small), "-p", "P01", "--headless", "--input",
                            "scripted", "--db", str(db), "--resume"], capsys)
    assert code == 0 and "complete, 30/30" in out


def test_headless_needs_model_or_scripted(small: Path, tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str],
                                          monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)  # the default --db, study.sqlite, is opened first
    for kind in ("joystick", "mouse"):
        code, _, err = run_cli(["run", str(small), "-p", "P01", "--headless", "--input", kind],
                               capsys)
        assert code == 2 and "needs the experiment window" in err


def test_model_participant_runs_headless_on_a_sim_clock(
        small: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    db = tmp_path / "s.sqlite"
    code, out, err = run_cli(["run", str(small), "-p", "P01", "--headless", "--input", "model",
                              "--db", str(db), "--limit", "6"], capsys)
    assert code == 0, err
    assert "12/30 trials done" in out
    with Store.open(db, readonly=True) as store:
        (s,) = store.sessions()
        assert (s["input"], s["clock"]) == ("model", "sim")
        assert {t["status"] for t in store.trials()} <= {"done", "timeout"}


def test_bad_arguments(small: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["run", str(small), "-p", " ", "--headless"], capsys)
    assert code == 2 and "--participant" in err
    code, _, err = run_cli(["run", str(tmp_path / "none.toml"), "-p", "P1", "--headless"],
                           capsys)
    assert code == 2 and "no such file" in err
    code, _, err = run_cli(["run", str(small), "-p", "P1", "--headless", "--belt", "usb:x"],
                           capsys)
    assert code == 2 and "unknown belt URL" in err
    code, _, err = run_cli(["run", str(small), "-p", "P1", "--resume", "--new-session"], capsys)
    assert code == 2 and "exclude" in err


@pytest.mark.parametrize("cmd", [["study"], ["study", "init"], ["study", "check"], ["run"],
                                 ["export"]])
def test_help(cmd: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_cli([*cmd, "--help"], capsys)
    assert code == 0 and "Usage:" in out


def test_cwd_default_db(small: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                        monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.chdir(tmp_path)
    code, _, _ = run_cli(["run", str(small), "-p", "P01", "--headless", "--input", "scripted",
                          "--limit", "0"], capsys)
    assert code == 0 and os.path.exists(tmp_path / "study.sqlite")


# -- what users met ------------------------------------------------------------------------------
def test_no_display_fails_at_once_instead_of_an_invisible_window(small: Path,
                                                                 tmp_path: Path) -> None:
    import subprocess
    import sys
    import time

    env = {k: v for k, v in os.environ.items()
           if k not in ("DISPLAY", "WAYLAND_DISPLAY", "SDL_VIDEODRIVER")}
    t0 = time.monotonic()
    out = subprocess.run([sys.executable, "-m", "tactorbelt", "run", str(small), "-p", "P09",
                          "--input", "mouse", "--db", str(tmp_path / "s.sqlite")],
                         env=env, capture_output=True, text=True, timeout=30, check=False)
    took = time.monotonic() - t0
    assert out.returncode == 2, out.stderr
    assert out.stderr.startswith("error: no display")
    assert "use --headless with --input model or scripted" in out.stderr
    assert took < 1.5  # python's own start included (about 0.3 s); nothing else runs
    assert not (tmp_path / "s.sqlite").exists()


def test_resume_reuses_the_sessions_input_and_counts_session_totals(
        small: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    db = tmp_path / "s.sqlite"
    code, out, err = run_cli(["run", str(small), "-p", "P04", "--headless", "--input",
                              "scripted", "--db", str(db), "--limit", "6"], capsys)
    assert code == 0 and "12/30 trials done (12 this run)" in out
    # no --headless, no --input: the stored ones (a window with a joystick would fail)
    code, out, err = run_cli(["run", str(small), "-p", "P04", "--db", str(db), "--resume"],
                             capsys)
    assert code == 0, err
    assert "complete, 30/30 trials done (18 this run)" in out
    assert "  session static     12 test trials, accuracy 100.0%" in out
    assert "  session dynamic    12 test trials, accuracy 100.0%" in out
    this_run = [line.split() for line in out.splitlines() if line.startswith("  this run ")]
    assert sorted(int(w[3]) for w in this_run) == [6, 12]  # 18 test trials, 6 + 12
    with Store.open(db, readonly=True) as store:
        (s,) = store.sessions()
        assert s["input"] == "scripted" and s["clock"] == "sim"


@pytest.mark.parametrize("pid", ["P 01/x", "P01/x", "../P01", "P01 ", "Jörg", "-P01"])
def test_participant_ids_that_do_not_round_trip_are_refused(
        pid: str, small: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = run_cli(["run", str(small), "-p", pid, "--headless", "--input", "scripted",
                            "--db", str(tmp_path / "s.sqlite")], capsys)
    if pid == "P01 ":  # surrounding spaces are stripped
        assert code == 0, err
        return
    assert code == 2
    assert err.startswith("error: participant id") and "letters, digits" in err


def test_exit_codes_are_documented_in_the_help(capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_cli(["--help"], capsys)
    assert code == 0
    text = " ".join(out.split())
    for part in ("0 finished", "130 stopped by the user", "143 terminated by SIGTERM",
                 "129 by SIGHUP", "2 usage", "3 device"):
        assert part in text


@pytest.mark.parametrize("bad", [["--input", "mouse", "--headless"], ["--belt", "usb:x"],
                                 ["--input", "telepathy"]])
def test_a_usage_error_leaves_no_store_behind(small: Path, tmp_path: Path, bad: list[str],
                                              capsys: pytest.CaptureFixture[str]) -> None:
    db = tmp_path / "never.sqlite"
    code, _, err = run_cli(["run", str(small), "-p", "P01", "--headless", "--db", str(db),
                            *bad], capsys)
    assert code == 2 and err.startswith("error:")
    assert not db.exists() and not list(tmp_path.glob("never.sqlite*"))


def test_the_clock_option_and_the_old_realtime_spelling(
        small: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_cli(["run", "--help"], capsys)
    assert code == 0 and "--clock [sim|wall]" in out and "--realtime" not in out
    assert "--headless / --window" in out and "--lsl-wait-all" in out
    db = tmp_path / "s.sqlite"
    base = ["run", str(small), "-p", "P01", "--db", str(db), "--headless"]
    code, _, err = run_cli([*base, "--realtime", "--clock", "sim"], capsys)
    assert code == 2 and "--realtime is --clock wall" in err
    code, _, err = run_cli([*base, "--clock", "sim", "--lsl"], capsys)
    assert code == 2 and "--lsl runs on the wall clock" in err
    code, _, err = run_cli([*base, "--clock", "sim", "--belt", "emulator"], capsys)
    assert code == 2 and err.startswith("error: --clock sim is for a headless run") and \
        "use --clock wall" in err
    assert not db.exists()  # refused before the store is written
    code, out, err = run_cli([*base, "--input", "scripted", "--clock", "sim", "--limit", "1"],
                             capsys)
    assert code == 0, err
    with Store.open(db, readonly=True) as store:
        (s,) = store.sessions()
        assert s["clock"] == "sim" and store.run_options(s["session_id"])["clock"] == "sim"


def test_options_stored_before_the_clock_option_resume_on_their_clock() -> None:
    from tactorbelt.app.request import stored_options

    class Old:
        def __init__(self, opts: dict[str, Any]) -> None:
            self.opts = opts

        def run_options(self, session_id: int) -> dict[str, Any]:
            return dict(self.opts)

    row = {"session_id": 1}
    assert stored_options(Old({"realtime": True}), row)["clock"] == "wall"  # type: ignore[arg-type]
    assert stored_options(Old({"realtime": False}), row)["clock"] is None  # type: ignore[arg-type]
    assert stored_options(Old({"clock": "sim"}), row)["clock"] == "sim"  # type: ignore[arg-type]
