"""Resume: exactly the stored schedule's unfinished trials, in order, never duplicated,
also after the process is killed with SIGKILL."""

from __future__ import annotations

import os
import re
import shlex
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from support.studies import study_toml
from tactorbelt import StoreError
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.schedule import make_schedule
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import Study
from tactorbelt.inputs.scripted import ScriptedCursor

STUDY = study_toml(minimal=True, name="resume", tactors=6, targets=12, iti_s=0.2,
                   break_every=0, training=1, training_conditions=["static"],
                   repetitions=2)  # 12 training + 48 test = 60 trials


def _cursor(study: Study, participant: str, seed: int = 1) -> ScriptedCursor:
    return ScriptedCursor(answers={t.trial_index: t.target_deg
                                   for t in make_schedule(study, participant, seed)})


def _check_complete(db: Path, participant: str, study: Study, seed: int = 1) -> dict[str, Any]:
    with Store.open(db, readonly=True) as store:
        (sess,) = store.sessions(participant)
        rows = store.trials(sess["session_id"])
        sched = store.schedule(sess["session_id"])
        assert sched == make_schedule(study, participant, seed)
        # every scheduled trial exactly once, in schedule order
        assert [r["trial_index"] for r in rows] == [t.trial_index for t in sched]
        assert {r["status"] for r in rows} <= {"done", "timeout"}
        assert [(r["target_deg"], r["condition"]) for r in rows] == [
            (t.target_deg, t.condition) for t in sched]
        # no orphan samples
        n = store.conn.execute("SELECT COUNT(*) FROM samples WHERE trial_id NOT IN "
                               "(SELECT trial_id FROM trials)").fetchone()[0]
        assert n == 0
        assert sum(r["n_samples"] for r in rows) == store.conn.execute(
            "SELECT COUNT(*) FROM samples").fetchone()[0]
        return sess


def test_resume_runs_exactly_the_unfinished_trials(tmp_path: Path) -> None:
    study = Study.from_toml(STUDY)
    db = tmp_path / "s.sqlite"
    clock = SimClock()
    with Store.open(db) as store, open_belt("sim", clock=clock) as belt:
        first = run_session(study, "P07", belt, _cursor(study, "P07"), store, clock, limit=10)
        assert first.n_done == 22 and first.status == "interrupted"
        second = run_session(study, "P07", belt, _cursor(study, "P07"), store, clock,
                             resume=True)
        assert second.session_id == first.session_id
        assert second.n_run == 38 and second.status == "complete"
        assert [r.trial.trial_index for r in second.results] == list(range(22, 60))
    sess = _check_complete(db, "P07", study)
    assert sess["resumed"] == 1 and sess["status"] == "complete"


def test_resume_uses_the_stored_seed(tmp_path: Path) -> None:
    study = Study.from_toml(STUDY)
    db = tmp_path / "s.sqlite"
    clock = SimClock()
    with Store.open(db) as store, open_belt("sim", clock=clock) as belt:
        run_session(study, "P01", belt, _cursor(study, "P01", 99), store, clock, seed=99,
                    limit=5)
        run_session(study, "P01", belt, _cursor(study, "P01", 99), store, clock, seed=3,
                    resume=True)
    _check_complete(db, "P01", study, seed=99)


def test_nothing_to_resume(tmp_path: Path) -> None:
    study = Study.from_toml(STUDY)
    clock = SimClock()
    with (Store.open(tmp_path / "s.sqlite") as store, open_belt("sim", clock=clock) as belt,
          pytest.raises(StoreError, match="no unfinished session")):
        run_session(study, "P01", belt, _cursor(study, "P01"), store, clock, resume=True)


def test_resume_with_a_changed_study_is_refused(tmp_path: Path) -> None:
    study = Study.from_toml(STUDY)
    clock = SimClock()
    with Store.open(tmp_path / "s.sqlite") as store, open_belt("sim", clock=clock) as belt:
        run_session(study, "P01", belt, _cursor(study, "P01"), store, clock, limit=1)
        changed = Study.from_toml(STUDY.replace("iti_s = 0.2", "iti_s = 0.3"))
        with pytest.raises(StoreError, match="study changed"):
            run_session(changed, "P01", belt, _cursor(study, "P01"), store, clock, resume=True)
        # the same study with other formatting resumes fine
        same = Study.from_toml(STUDY.replace("iti_s = 0.2", "iti_s  =  0.2  # s"))
        res = run_session(same, "P01", belt, _cursor(study, "P01"), store, clock, resume=True)
        assert res.status == "complete"


def _tactorbelt() -> list[str]:
    return [sys.executable, "-m", "tactorbelt"]


def test_sigkill_then_resume(tmp_path: Path) -> None:
    study_file = tmp_path / "study.toml"
    study_file.write_text(STUDY)
    db = tmp_path / "s.sqlite"
    args = [*_tactorbelt(), "run", str(study_file), "--participant", "P03", "--headless",
            "--input", "scripted", "--db", str(db)]
    env = dict(os.environ, TACTORBELT_TEST_SLOW_TRIAL_S="0.05")
    proc = subprocess.Popen(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        n = 0
        deadline = time.monotonic() + 60
        while n < 15 and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.02)
            if db.exists():
                conn = sqlite3.connect(db, timeout=1)
                try:
                    n = conn.execute("SELECT COUNT(*) FROM trials").fetchone()[0]
                except sqlite3.Error:
                    n = 0
                finally:
                    conn.close()
        assert proc.poll() is None, proc.stderr.read() if proc.stderr else ""
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait()
        if proc.stdout:
            proc.stdout.close()
        if proc.stderr:
            proc.stderr.close()
    assert proc.returncode == -signal.SIGKILL
    with Store.open(db, readonly=True) as store:
        (sess,) = store.sessions()
        assert sess["status"] == "running"  # killed: never marked
        killed_at = len(store.trials())
        assert 15 <= killed_at < 60
    # without --resume: refused, with a hint
    out = subprocess.run(args, capture_output=True, text=True, check=False)
    assert out.returncode == 2
    assert "--resume" in out.stderr and "Traceback" not in out.stderr
    out = subprocess.run([*args, "--resume"], capture_output=True, text=True, check=False)
    assert out.returncode == 0, out.stderr
    sess = _check_complete(db, "P03", Study.from_toml(STUDY))
    assert sess["resumed"] == 1


# -- SIGTERM, SIGHUP and Ctrl-C on a real process ------------------------------------------------
def _count(db: Path, sql: str) -> int:
    if not db.exists():
        return 0
    conn = sqlite3.connect(db, timeout=1)
    try:
        return int(conn.execute(sql).fetchone()[0])
    except sqlite3.Error:
        return 0
    finally:
        conn.close()


def _run_then_signal(args: list[str], db: Path, sig: int, env: dict[str, str],
                     after_trials: int = 1) -> tuple[int, str, float]:
    """Start ``args``; once ``after_trials`` trials are stored (and the next one is under
    way), send ``sig``; return (exit code, stderr, seconds from the signal to the exit)."""
    proc = subprocess.Popen(args, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    try:
        deadline = time.monotonic() + 90
        while (_count(db, "SELECT COUNT(*) FROM trials") < after_trials
               and time.monotonic() < deadline and proc.poll() is None):
            time.sleep(0.05)
        assert proc.poll() is None, proc.communicate()[1]
        time.sleep(0.3)  # into the next trial
        sent = time.monotonic()
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=20)
        took = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    return proc.returncode, err, took


def _env(window: bool) -> dict[str, str]:
    env = dict(os.environ)
    env.pop("TACTORBELT_TEST_SLOW_TRIAL_S", None)
    if window:
        env["SDL_VIDEODRIVER"] = "dummy"
    return env


@pytest.mark.parametrize("window", [False, True], ids=["headless", "window"])
def test_sigterm_ends_a_realtime_run_with_the_trial_stored_aborted(tmp_path: Path,
                                                                   window: bool) -> None:
    study_file = tmp_path / "study.toml"
    study_file.write_text(STUDY)
    db = tmp_path / "s.sqlite"
    args = [*_tactorbelt(), "run", str(study_file), "-p", "P07", "--input", "model",
            "--realtime", "--db", str(db), *([] if window else ["--headless"])]
    code, err, took = _run_then_signal(args, db, signal.SIGTERM, _env(window))
    assert code == 143, err
    assert took < 2.0
    assert "error:" not in err and "Traceback" not in err
    with Store.open(db, readonly=True) as store:
        (sess,) = store.sessions()
        assert sess["status"] == "interrupted"
        aborted = [t for t in store.trials() if t["status"] == "aborted"]
        assert [t["abort_reason"] for t in aborted] == ["terminated (SIGTERM)"]
    # the printed hint resumes with the stored input, belt and window options
    hint = err.split("continue with '")[1].split("'")[0]
    assert hint.startswith("tactorbelt run ") and hint.endswith(" --resume")
    resumed = [*_tactorbelt(), *shlex.split(hint)[1:]]
    code, err, took = _run_then_signal(resumed, db, signal.SIGHUP, _env(window),
                                       after_trials=len(aborted) + 2)
    assert code == 129, err
    assert took < 2.0
    with Store.open(db, readonly=True) as store:
        (sess,) = store.sessions()
        assert sess["resumed"] == 1 and sess["status"] == "interrupted"
        assert sess["input"] == "model"
        reasons = [t["abort_reason"] for t in store.trials() if t["status"] == "aborted"]
        assert reasons[-1] == "terminated (SIGHUP)"


def test_ctrl_c_exits_130_without_an_error_line(tmp_path: Path) -> None:
    study_file = tmp_path / "study.toml"
    study_file.write_text(STUDY)
    db = tmp_path / "s.sqlite"
    args = [*_tactorbelt(), "run", str(study_file), "-p", "P08", "--headless", "--input",
            "model", "--realtime", "--db", str(db)]
    code, err, _ = _run_then_signal(args, db, signal.SIGINT, _env(False))
    assert code == 130
    assert "error:" not in err and "Traceback" not in err
    assert "interrupted: motors off" in err and "--resume'" in err


# -- the clock of a resumed run --------------------------------------------------------------
CLOCK_STUDY = study_toml(minimal=True, name="clock", tactors=6, targets=6, iti_s=0.2,
                         break_every=0, training=0, repetitions=1)  # 12 test trials


def _kill_after(args: list[str], db: Path, n: int) -> None:
    """Start ``args``; once ``n`` trials are stored, SIGKILL it (nothing is marked)."""
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 90
        while (_count(db, "SELECT COUNT(*) FROM trials") < n and time.monotonic() < deadline
               and proc.poll() is None):
            time.sleep(0.05)
        assert proc.poll() is None, proc.communicate()[1]
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.communicate()


def _timed(args: list[str]) -> tuple[subprocess.CompletedProcess[str], float]:
    t0 = time.monotonic()
    out = subprocess.run(args, capture_output=True, text=True, check=False, timeout=120)
    return out, time.monotonic() - t0


def _clock_span_s(db: Path, after: int) -> float:
    """Seconds of the session's clock from the first onset to the last acquisition of the
    trials stored after the first ``after`` (the ones a resumed run ran)."""
    with Store.open(db, readonly=True) as store:
        rows = sorted(store.trials(), key=lambda t: t["trial_id"])[after:]
    assert rows
    return (max(t["acquired_ns"] or t["onset_ns"] for t in rows)
            - min(t["onset_ns"] for t in rows)) / 1e9


def test_a_wall_clock_run_killed_then_resumed_keeps_its_clock_unless_told_otherwise(
        tmp_path: Path) -> None:
    study_file = tmp_path / "study.toml"
    study_file.write_text(CLOCK_STUDY)
    db = tmp_path / "s.sqlite"
    _kill_after([*_tactorbelt(), "run", str(study_file), "-p", "P05", "--headless", "--input",
                 "model", "--clock", "wall", "--db", str(db)], db, 2)
    resume = [*_tactorbelt(), "run", str(study_file), "-p", "P05", "--db", str(db), "--resume"]
    n = _count(db, "SELECT COUNT(*) FROM trials")

    # resumed as it was started: on the wall clock, and it says so, with the override
    out, took = _timed([*resume, "--limit", "2"])
    assert out.returncode == 0, out.stderr
    lines = out.stderr.splitlines()
    assert lines[0] == f"resuming session 1 of P05 ({n}/12 trials done) with these options:"
    assert re.search(r"^  clock +wall \(real time\) +stored +override: --clock sim$",
                     out.stderr, re.M), out.stderr
    assert re.search(r"^  input +model +stored +override: --input joystick\|mouse\|scripted$",
                     out.stderr, re.M), out.stderr
    assert re.search(r"^  window +none \(headless\) +stored +override: --window$", out.stderr,
                     re.M), out.stderr
    assert re.search(r"^  belt +sim +stored +override: --belt URL$", out.stderr, re.M)
    span = _clock_span_s(db, n)
    assert 0 < span <= took  # the model answered in real time

    # --clock sim on resume overrides the stored wall clock: simulated time, fast
    n = _count(db, "SELECT COUNT(*) FROM trials")
    out, took = _timed([*resume, "--clock", "sim"])
    assert out.returncode == 0, out.stderr
    assert "complete, 12/12 trials done" in out.stdout
    assert re.search(r"^  clock +sim \(simulated time\) +given \(stored: wall\) +override: "
                     r"--clock wall$", out.stderr, re.M), out.stderr
    assert _clock_span_s(db, n) > took  # more session time than real time went by
    with Store.open(db, readonly=True) as store:
        (sess,) = store.sessions()
        assert store.run_options(sess["session_id"])["clock"] == "sim"  # stored in its place
    _check_complete(db, "P05", Study.from_toml(CLOCK_STUDY))


def test_a_stored_simulated_clock_gives_way_to_the_window(tmp_path: Path) -> None:
    """A session started with --clock sim and resumed in the window runs on the wall
    clock (the window is real time), and says so; --clock sim given then is refused."""
    study_file = tmp_path / "study.toml"
    study_file.write_text(CLOCK_STUDY)
    db = tmp_path / "s.sqlite"
    base = [*_tactorbelt(), "run", str(study_file), "-p", "P06", "--db", str(db)]
    out, _ = _timed([*base, "--headless", "--input", "scripted", "--clock", "sim", "--limit",
                     "10"])
    assert out.returncode == 0, out.stderr
    env = _env(window=True)
    out = subprocess.run([*base, "--resume", "--window", "--clock", "sim"], env=env,
                         capture_output=True, text=True, check=False, timeout=120)
    assert out.returncode == 2
    assert out.stderr.startswith("error: --clock sim is for a headless run") and \
        "the experiment window runs in real time" in out.stderr, out.stderr
    out = subprocess.run([*base, "--resume", "--window"], env=env, capture_output=True,
                         text=True, check=False, timeout=120)
    assert out.returncode == 0, out.stderr
    assert re.search(r"^  window +yes +given \(stored: none\) +override: --headless, "
                     r"--fullscreen$", out.stderr, re.M), out.stderr
    assert re.search(r"^  clock +wall \(real time\) +default \(stored sim does not fit\) +"
                     r"override: none \(the experiment window runs in real time\)$",
                     out.stderr, re.M), out.stderr
    assert "complete, 12/12 trials done" in out.stdout
