"""The PostgreSQL store on a real (throwaway) server: runs that push each trial, sync,
several sites at once, a server restarted mid-session, a runner killed and resumed,
bad URLs and credentials, and row-level security between sites.

The store contract itself runs in tests/test_store_contract.py (both backends).
"""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from support.stores import make_result, make_session
from support.studies import make_study, write_study
from tactorbelt import StoreError
from tactorbelt.experiment.store import open_store
from tactorbelt.tasks.schedule import TaskEvent

pytest.importorskip("psycopg")


def _cli(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "tactorbelt", *args], capture_output=True,
                          text=True, check=False, env=env, timeout=240)


def _study(tmp: Path) -> Path:
    return write_study(tmp, training=0, repetitions=2, targets=8, iti_s=0.05)


def _run_args(study: Path, pid: str, db: Path, url: str, *extra: str) -> list[str]:
    return ["run", str(study), "--participant", pid, "--headless", "--input", "model",
            "--db", str(db), "--push", url, *extra]


def _remote(url: str) -> dict[str, Any]:
    """{participant: (session row, {trial_index: status}, n_samples)} of a shared store."""
    out: dict[str, Any] = {}
    with open_store(url, create=False, readonly=True) as s:
        for row in s.sessions():
            trials = s.trials(row["session_id"])
            n = len(s.samples_of([t["trial_id"] for t in trials]))
            out[row["participant"]] = (row, {t["trial_index"]: t["status"] for t in trials}, n)
    return out


def _local(db: Path) -> dict[str, Any]:
    out: dict[str, Any] = {}
    with open_store(db, create=False, readonly=True) as s:
        for row in s.sessions():
            trials = s.trials(row["session_id"])
            n = len(s.samples_of([t["trial_id"] for t in trials]))
            out[row["participant"]] = (row, {t["trial_index"]: t["status"] for t in trials}, n)
    return out


def _same(db: Path, url: str) -> None:
    local, remote = _local(db), _remote(url)
    for pid, (row, trials, n) in local.items():
        rrow, rtrials, rn = remote[pid]
        assert rtrials == trials and rn == n
        for col in ("session_uuid", "site", "status", "ended_at", "seed", "study_sha256",
                    "schedule_json", "host", "package_version"):
            assert rrow[col] == row[col], col


def test_a_run_pushes_every_trial_and_sync_changes_nothing_after(
        tmp_path: Path, pg_url: str) -> None:
    study, db = _study(tmp_path), tmp_path / "local.sqlite"
    out = _cli(*_run_args(study, "P01", db, pg_url, "--site", "lyon"))
    assert out.returncode == 0, out.stderr
    assert f"pushed to {pg_url}" in out.stderr
    _same(db, pg_url)
    row, trials, n = _remote(pg_url)["P01"]
    assert row["site"] == "lyon" and row["status"] == "complete" and n > 0
    assert set(trials.values()) <= {"done", "timeout"}
    for _ in range(2):  # idempotent: nothing missing, nothing written
        again = _cli("sync", str(db), pg_url)
        assert again.returncode == 0, again.stderr
        assert "up to date" in again.stdout
    _same(db, pg_url)


def test_sync_pushes_an_offline_run_and_the_site_comes_from_the_environment(
        tmp_path: Path, pg_url: str) -> None:
    study, db = _study(tmp_path), tmp_path / "local.sqlite"
    env = dict(os.environ, TACTORBELT_SITE="oslo")
    out = _cli(*_run_args(study, "P02", db, pg_url, "--offline"), env=env)
    assert out.returncode == 0, out.stderr
    assert "offline" in out.stderr and "tactorbelt sync" in out.stderr
    with open_store(pg_url) as s:
        assert s.sessions() == []
    first = _cli("sync", str(db), pg_url)
    assert first.returncode == 0 and "1 new session(s)" in first.stdout, first.stderr
    assert _remote(pg_url)["P02"][0]["site"] == "oslo"
    _same(db, pg_url)
    second = _cli("sync", str(db), pg_url)
    assert "up to date" in second.stdout


def test_db_postgresql_keeps_the_local_store_next_to_the_study_file(
        tmp_path: Path, pg_url: str) -> None:
    study = _study(tmp_path)
    out = _cli("run", str(study), "--participant", "P03", "--headless", "--input", "model",
               "--db", pg_url, "--limit", "3")
    assert out.returncode == 0, out.stderr
    local = study.with_suffix(".sqlite")
    assert local.is_file()
    _same(local, pg_url)


def test_two_sites_run_at_once_and_a_participant_id_belongs_to_one_site(
        tmp_path: Path, pg_url: str) -> None:
    study = _study(tmp_path)
    env = dict(os.environ, TACTORBELT_TEST_SLOW_TRIAL_S="0.01")
    procs = [subprocess.Popen([sys.executable, "-m", "tactorbelt",
                               *_run_args(study, pid, tmp_path / f"{site}.sqlite", pg_url,
                                          "--site", site)],
                              env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True)
             for pid, site in (("A01", "lyon"), ("B01", "oslo"))]
    for p in procs:
        _, err = p.communicate(timeout=240)
        assert p.returncode == 0, err
    _same(tmp_path / "lyon.sqlite", pg_url)
    _same(tmp_path / "oslo.sqlite", pg_url)
    remote = _remote(pg_url)
    assert {remote["A01"][0]["site"], remote["B01"][0]["site"]} == {"lyon", "oslo"}
    # A01 is lyon's: oslo may not run it (refused before anything is written)
    out = _cli(*_run_args(study, "A01", tmp_path / "oslo.sqlite", pg_url, "--site", "oslo",
                          "--new-session"))
    assert out.returncode == 2
    assert "already taken at site 'lyon'" in out.stderr and "Traceback" not in out.stderr
    # an offline run of A01 at oslo is refused when it is pushed, the rest goes through
    other = tmp_path / "oslo2.sqlite"
    assert _cli(*_run_args(study, "A01", other, pg_url, "--site", "oslo", "--offline",
                           "--limit", "1")).returncode == 0
    synced = _cli("sync", str(other), pg_url)
    assert synced.returncode == 2 and "already taken at site 'lyon'" in synced.stderr
    assert len(_remote(pg_url)) == 2
    # analysis from the shared store: a per-site table, --site, complete sessions only
    assert _cli(*_run_args(study, "C01", tmp_path / "lyon.sqlite", pg_url, "--site", "lyon",
                           "--limit", "1")).returncode == 0  # left interrupted
    rep = _cli("analyze", pg_url, "--out", str(tmp_path / "all"))
    assert rep.returncode == 0, rep.stderr
    html = (tmp_path / "all" / "report.html").read_text()
    assert "Per site" in html and "lyon" in html and "oslo" in html
    notes = json.loads((tmp_path / "all" / "summary.json").read_text())["notes"]
    assert any("1 session(s)" in n and "not complete" in n for n in notes), notes
    assert _participants(tmp_path / "all") == 2
    rep = _cli("analyze", pg_url, "--out", str(tmp_path / "lyon"), "--site", "lyon",
               "--include-running")
    assert rep.returncode == 0, rep.stderr
    assert _participants(tmp_path / "lyon") == 2  # A01 and the running C01
    out = _cli("export", pg_url, str(tmp_path / "csv"))
    assert out.returncode == 0, out.stderr


def _participants(report_dir: Path) -> int:
    counts = json.loads((report_dir / "summary.json").read_text())["counts"]
    return int(counts["participants"])


def _wait_trials(db: Path, n: int, proc: subprocess.Popen[str], limit_s: float = 120) -> int:
    deadline = time.monotonic() + limit_s
    got = 0
    while got < n and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.05)
        if db.exists():
            conn = sqlite3.connect(db, timeout=1)
            try:
                got = conn.execute("SELECT COUNT(*) FROM trials").fetchone()[0]
            except sqlite3.Error:
                got = 0
            finally:
                conn.close()
    return got


def test_a_server_restarted_mid_session_loses_nothing(tmp_path: Path, pg_url: str,
                                                      pg_server: Any) -> None:
    study, db = _study(tmp_path), tmp_path / "local.sqlite"
    env = dict(os.environ, TACTORBELT_TEST_SLOW_TRIAL_S="0.08")
    proc = subprocess.Popen([sys.executable, "-m", "tactorbelt",
                             *_run_args(study, "P05", db, pg_url)],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        n = _wait_trials(db, 5, proc)
        assert n >= 5
        pg_server.stop()  # clients cut off; the run goes on, the trials queue locally
        assert _wait_trials(db, n + 4, proc) >= n + 4
        assert proc.poll() is None
        pg_server.start()
        _, err = proc.communicate(timeout=240)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        pg_server.start_if_stopped()
    assert proc.returncode == 0, err
    assert "pushed to" in err
    _same(db, pg_url)


def test_sigkill_of_a_runner_then_resume_pushes_exactly_the_session(
        tmp_path: Path, pg_url: str) -> None:
    study, db = _study(tmp_path), tmp_path / "local.sqlite"
    env = dict(os.environ, TACTORBELT_TEST_SLOW_TRIAL_S="0.05")
    args = _run_args(study, "P06", db, pg_url)
    proc = subprocess.Popen([sys.executable, "-m", "tactorbelt", *args], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert _wait_trials(db, 6, proc) >= 6
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.communicate()
    assert proc.returncode == -signal.SIGKILL
    out = _cli(*args, "--resume")
    assert out.returncode == 0, out.stderr
    _same(db, pg_url)
    row, trials, _ = _remote(pg_url)["P06"]
    assert row["status"] == "complete" and row["resumed"] == 1
    assert len(trials) == row["n_trials"]


def test_an_unreachable_server_at_the_start_is_a_clear_error(tmp_path: Path) -> None:
    study, db = _study(tmp_path), tmp_path / "local.sqlite"
    url = f"postgresql://nobody@{str(tmp_path / 'nosock').replace('/', '%2F')}/study"
    out = _cli(*_run_args(study, "P07", db, url))
    assert out.returncode == 2
    assert "cannot reach the PostgreSQL server" in out.stderr and "--offline" in out.stderr
    assert "Traceback" not in out.stderr
    ok = _cli(*_run_args(study, "P07", db, url, "--offline", "--limit", "2"))
    assert ok.returncode == 0, ok.stderr


def test_credentials_never_come_from_the_url(tmp_path: Path, pg_server: Any) -> None:
    from support.pgserver import PASSWORD, PASSWORD_ROLE

    name = pg_server.new_database().rsplit("/", 1)[1]
    pg_server.admin(f"GRANT ALL ON DATABASE {name} TO {PASSWORD_ROLE}")
    pg_server.admin(f"ALTER DATABASE {name} OWNER TO {PASSWORD_ROLE}")
    url = pg_server.url(name, user=PASSWORD_ROLE)
    with pytest.raises(StoreError, match="pgpass"):
        open_store(url.replace(f"{PASSWORD_ROLE}@", f"{PASSWORD_ROLE}:{PASSWORD}@"))
    env = dict(os.environ, PGPASSWORD="wrong")
    out = _cli("sync", str(_empty_store(tmp_path)), url, env=env)
    assert out.returncode == 2 and "cannot log in" in out.stderr, out.stderr
    assert "PGPASSWORD" in out.stderr and "wrong" not in out.stderr
    pgpass = tmp_path / "pgpass"
    pgpass.write_text(f"*:*:*:{PASSWORD_ROLE}:{PASSWORD}\n")
    pgpass.chmod(0o600)
    env = {k: v for k, v in os.environ.items() if k != "PGPASSWORD"} | {
        "PGPASSFILE": str(pgpass)}
    out = _cli("sync", str(_empty_store(tmp_path)), url, env=env)
    assert out.returncode == 0, out.stderr


def _empty_store(tmp: Path) -> Path:
    p = tmp / "empty.sqlite"
    open_store(p).close()
    return p


def test_a_database_with_someone_elses_tactorbelt_schema_is_refused(
        pg_server: Any, pg_url: str) -> None:
    name = pg_url.rsplit("/", 1)[1]
    pg_server.admin("CREATE SCHEMA tactorbelt; CREATE TABLE tactorbelt.sessions(id int)",
                    dbname=name)
    with pytest.raises(StoreError, match="not a tactorbelt store"):
        open_store(pg_url)
    with pytest.raises(StoreError, match="not a tactorbelt store"):
        open_store(pg_url, create=False, readonly=True)


def test_a_site_writer_reads_nothing_of_another_site(pg_server: Any, pg_url: str) -> None:
    from tactorbelt.experiment.store.postgresql import setup_access

    name = pg_url.rsplit("/", 1)[1]
    for role in ("w_lyon", "w_oslo", "analyst1"):
        pg_server.admin(f"CREATE ROLE {role} LOGIN")  # a server per test process
    with open_store(pg_url) as owner:
        setup_access(owner, writers={"w_lyon": "lyon", "w_oslo": "oslo"},  # type: ignore[arg-type]
                     analysts=["analyst1"])
    lyon_url, oslo_url = pg_server.url(name, "w_lyon"), pg_server.url(name, "w_oslo")
    with open_store(lyon_url) as lyon:
        sid = make_session(lyon, "L01", site="lyon")
        lyon.write_trial(sid, make_result(0))
        lyon.write_task_events(sid, [TaskEvent(0, "nb", "dual", 0, 1, "K", False, "", True,
                                               None)])
        lyon.write_ratings(sid, 0, "nasa_tlx", {"mental": 50.0})
        assert [s["participant"] for s in lyon.sessions()] == ["L01"]
    with open_store(oslo_url) as oslo:
        make_session(oslo, "O01", site="oslo")
        assert [s["participant"] for s in oslo.sessions()] == ["O01"]
        assert oslo.trials() == [] and oslo.samples_of([1, 2, 3]) == []
        assert oslo.task_events() == [] and oslo.ratings() == []
        with pytest.raises(StoreError):  # nor write rows of another site's session
            oslo.write_ratings(sid, 0, "nasa_tlx", {"mental": 1.0})
        with pytest.raises(StoreError, match="no session"):
            oslo.session(sid)
        with pytest.raises(StoreError):  # writing another site's rows is refused
            make_session(oslo, "O02", site="lyon")
        with pytest.raises(StoreError, match="already taken at another site"):
            make_session(oslo, "L01", site="oslo")  # a writer learns no more
    with open_store(pg_server.url(name, "analyst1"), create=False, readonly=True) as a:
        assert sorted(s["participant"] for s in a.sessions()) == ["L01", "O01"]
        assert len(a.trials()) == 1
        assert len(a.task_events()) == 1 and len(a.ratings()) == 1
    with open_store(pg_server.url(name, "analyst1")) as a, pytest.raises(StoreError):
        make_session(a, "X01", site="lyon")


def test_db_and_push_options_resolve(tmp_path: Path) -> None:
    from tactorbelt import ConfigError
    from tactorbelt.app.request import resolve_db

    study = tmp_path / "exp" / "study.toml"
    url = "postgresql://lyon@db.example.org/study"
    assert resolve_db("lab.sqlite", None, study) == (Path("lab.sqlite"), None)
    assert resolve_db("lab.sqlite", url, study) == (Path("lab.sqlite"), url)
    assert resolve_db(url, None, study) == (tmp_path / "exp" / "study.sqlite", url)
    with pytest.raises(ConfigError, match="postgresql://"):
        resolve_db("lab.sqlite", "other.sqlite", study)
    with pytest.raises(ConfigError, match="already pushes"):
        resolve_db(url, "postgresql://x@y/z", study)


def test_a_url_with_a_password_is_refused_before_connecting(tmp_path: Path) -> None:
    with pytest.raises(StoreError, match=r"\.pgpass.*PGPASSWORD"):
        open_store("postgresql://lyon:secret@db.invalid/study")
    study = _study(tmp_path)
    out = _cli(*_run_args(study, "P01", tmp_path / "l.sqlite",
                          "postgresql://lyon:secret@db.invalid/study", "--offline"))
    assert out.returncode == 2 and "pgpass" in out.stderr and "secret" not in out.stderr


def test_sync_copies_task_events_and_ratings_once(tmp_path: Path, pg_url: str) -> None:
    from support.tasks import TaskCursor
    from tactorbelt.clock import SimClock
    from tactorbelt.devices import open_belt
    from tactorbelt.experiment.runner import run_session
    from tactorbelt.experiment.schedule import make_schedule
    from tactorbelt.experiment.sync import sync_stores
    from tactorbelt.tasks import TLX_ITEMS

    study = make_study(minimal=True, name="load", tactors=4, targets=8, training=0,
                       iti_s=0.2, break_every=0,
                       blocks=[{"name": "busy", "condition": "static", "repetitions": 1,
                                "load": "nb"}],
                       tasks={"nb": {"kind": "nback", "n": 1, "interval_s": 1.0,
                                     "practice": 4}},
                       questionnaire={"tlx": True})
    answers = {t.trial_index: t.target_deg for t in make_schedule(study, "P07")}
    db, clock = tmp_path / "local.sqlite", SimClock()
    with open_store(db) as store, open_belt("sim", clock=clock,
                                            layout=study.layout_obj()) as belt:
        run_session(study, "P07", belt, TaskCursor(answers=answers,
                                                   tlx=dict.fromkeys(TLX_ITEMS, 40.0)),
                    store, clock)

    def rows(url: str | Path) -> tuple[list[Any], list[Any]]:
        with open_store(url, create=False, readonly=True) as s:
            drop = ("session_id",)
            return ([{k: v for k, v in e.items() if k not in drop} for e in s.task_events()],
                    [{k: v for k, v in r.items() if k not in drop} for r in s.ratings()])

    first = sync_stores(db, pg_url)
    local = rows(db)
    assert len(local[0]) > 4 and len(local[1]) == 6
    assert first.task_events == len(local[0]) and first.ratings == 6
    assert rows(pg_url) == local
    again = sync_stores(db, pg_url)
    assert (again.task_events, again.ratings) == (0, 0)
    assert "up to date" in again.summary(pg_url)
    with open_store(db) as store:  # appended locally (a resumed block): copied again
        store.write_task_events(1, [TaskEvent(0, "nb", "dual", 99, 1, "tone1", False, "",
                                              True, None)])
    assert sync_stores(db, pg_url).task_events == len(local[0]) + 1
    assert rows(pg_url) == rows(db)
