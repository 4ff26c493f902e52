"""A hostile site on a real (throwaway) PostgreSQL server: what a site's writer role may try
against another site's data, each refused by the database itself.

The store is set up as docs/multisite.md says: a database owned by a role that is not a
superuser, the schema created by its first open, ``setup_access`` with the writers
``lyon_writer`` and ``oslo_writer`` and the ``analyst``. The hostile site is
``oslo_writer``, connected with psycopg as that role (its own SQL, not tactorbelt's
client); after every attack, what lyon wrote and the participant ids are unchanged.
Then the same attacks through the command line (a run for another site, a taken id, a
sync), a store written before the rule (schema 3) migrated by its owner, and the
analyst's analysis and BIDS export of two sites against each site's own local store.
"""

from __future__ import annotations

import csv
import filecmp
import json
import os
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from support.stores import make_result, make_session
from support.studies import write_study
from tactorbelt import StoreError
from tactorbelt.experiment.store import open_store

psycopg = pytest.importorskip("psycopg")

OWNER, LYON, OSLO, ANALYST = "study_owner", "lyon_writer", "oslo_writer", "analyst"


@dataclass
class Study:
    """One shared store: its database and a URL per role."""

    server: Any
    name: str

    def url(self, role: str) -> str:
        return str(self.server.url(self.name, role))

    def connect(self, role: str) -> Any:
        return psycopg.connect(self.url(role), autocommit=True)


def _ensure_roles(server: Any) -> None:
    """The roles of docs/multisite.md, once per server (roles belong to the cluster)."""
    with psycopg.connect(server.url()) as conn:
        conn.autocommit = True
        have = {r[0] for r in conn.execute("SELECT rolname FROM pg_roles")}
        for role, extra in ((OWNER, " CREATEROLE"), (LYON, ""), (OSLO, ""), (ANALYST, "")):
            if role not in have:
                conn.execute(f"CREATE ROLE {role} LOGIN{extra}")


@pytest.fixture
def study(pg_server: Any) -> Study:
    """A fresh shared store owned by ``study_owner``, with lyon's session L01 (a trial)
    and oslo's session O01, each written by its own site's writer."""
    _ensure_roles(pg_server)
    name = pg_server.new_database().rsplit("/", 1)[1]
    pg_server.admin(f"ALTER DATABASE {name} OWNER TO {OWNER}")
    s = Study(pg_server, name)
    from tactorbelt.experiment.store.postgresql import setup_access

    with open_store(s.url(OWNER)) as owner:
        setup_access(owner, writers={LYON: "lyon", OSLO: "oslo"},  # type: ignore[arg-type]
                     analysts=[ANALYST])
    with open_store(s.url(LYON)) as lyon:
        sid = make_session(lyon, "L01", site="lyon")
        lyon.write_trial(sid, make_result(0))
        lyon.write_trial(sid, make_result(1))
    with open_store(s.url(OSLO)) as oslo:
        sid = make_session(oslo, "O01", site="oslo")
        oslo.write_trial(sid, make_result(0))
    return s


def _snapshot(s: Study) -> dict[str, Any]:
    """Everything in the store, as the owner sees it (no row-level security)."""
    out: dict[str, Any] = {}
    with s.connect(OWNER) as conn:
        for table, order in (("sessions", "session_id"), ("trials", "trial_id"),
                             ("samples", "trial_id, sample_index"),
                             ("participants", "participant"), ("site_writers", "role_name"),
                             ("meta", "key")):
            out[table] = conn.execute(
                f"SELECT * FROM tactorbelt.{table} ORDER BY {order}").fetchall()
    return out


def _own_ids(conn: Any) -> tuple[int, int]:
    """(session_id, trial_id) of the writer's own session and trial."""
    sid, tid = conn.execute("SELECT s.session_id, t.trial_id FROM tactorbelt.sessions s"
                            " JOIN tactorbelt.trials t USING (session_id)").fetchone()
    return int(sid), int(tid)


def _lyon_ids(s: Study) -> tuple[int, int, str]:
    with s.connect(OWNER) as conn:
        sid, tid, uuid = conn.execute(
            "SELECT s.session_id, t.trial_id, s.session_uuid FROM tactorbelt.sessions s JOIN"
            " tactorbelt.trials t USING (session_id) WHERE s.site='lyon' LIMIT 1").fetchone()
    return int(sid), int(tid), str(uuid)


_SESSION_COLS = ("participant, session_number, study_name, study_sha256, study_toml, seed,"
                 " condition_order, schedule_json, n_trials, started_at, status, site,"
                 " session_uuid")


def _session_values(participant: str, site: str, uuid: str = "") -> tuple[Any, ...]:
    import uuid as uuidlib

    return (participant, 1, "s", "0" * 64, "", 1, "[]", "[]", 0, "2026-01-01T00:00:00Z",
            "complete", site, uuid or str(uuidlib.uuid4()))


def _insert_session(extra: str = "") -> str:
    """An INSERT of a whole session row (:func:`_session_values`)."""
    return (f"INSERT INTO tactorbelt.sessions({_SESSION_COLS}) VALUES "
            f"({', '.join(['%s'] * 13)}){extra}")


def _attacks(s: Study, own_sid: int, own_tid: int
             ) -> list[tuple[str, str, tuple[Any, ...], str]]:
    """(what, SQL, args, why): what a hostile writer tries; each must raise an error
    whose first line holds ``why``."""
    lyon_sid, lyon_tid, lyon_uuid = _lyon_ids(s)
    ins = _insert_session()
    return [
        # the participant id of another site, as in issue reports
        ("take lyon's participant id for its own session",
         "UPDATE tactorbelt.sessions SET participant='L01' WHERE session_id=%s", (own_sid,),
         "permission denied for table sessions"),
        ("insert a session at its own site under lyon's id", ins,
         _session_values("L01", "oslo"),
         "sessions_participant_site"),
        ("insert a session at its own site under an id it did not claim", ins,
         _session_values("Z77", "oslo"),
         "sessions_participant_site"),
        ("claim a participant id for another site",
         "SELECT tactorbelt.claim_participant('Q01', 'lyon')", (),
         "its own site only"),
        ("claim a participant id for no site",
         "SELECT tactorbelt.claim_participant('Q02', NULL)", (),
         "its own site only"),
        ("move its session to another site",
         "UPDATE tactorbelt.sessions SET site='lyon' WHERE session_id=%s", (own_sid,),
         "permission denied for table sessions"),
        ("insert a session of another site", ins, _session_values("Q03", "lyon"),
         "row-level security"),
        ("overwrite lyon's session by its uuid",
         _insert_session(" ON CONFLICT (session_uuid) DO UPDATE SET"
                         " status='aborted'"), _session_values("O01", "oslo", lyon_uuid),
         "row-level security"),
        ("choose a session id (taking ids ahead of another site)",
         f"INSERT INTO tactorbelt.sessions(session_id, {_SESSION_COLS}) VALUES "
         f"({', '.join(['%s'] * 14)})", (own_sid + 1000, *_session_values("O01", "oslo")),
         "permission denied for table sessions"),
        ("choose a trial id",
         "INSERT INTO tactorbelt.trials(trial_id, session_id, trial_index, block,"
         " block_index, block_name, condition, repetition, target_deg, on_tactor, n_samples,"
         " status, recorded_at) VALUES (%s, %s, 99, 'test', 0, 'b', 'static', 0, 0, 1, 0,"
         " 'done', 'now')", (own_tid + 1000, own_sid),
         "permission denied for table trials"),
        ("insert a trial into lyon's session",
         "INSERT INTO tactorbelt.trials(session_id, trial_index, block, block_index,"
         " block_name, condition, repetition, target_deg, on_tactor, n_samples, status,"
         " recorded_at) VALUES (%s, 99, 'test', 0, 'b', 'static', 0, 0, 1, 0, 'done', 'now')",
         (lyon_sid,),
         "row-level security"),
        ("move its trial into lyon's session",
         "UPDATE tactorbelt.trials SET session_id=%s WHERE trial_id=%s", (lyon_sid, own_tid),
         "permission denied for table trials"),
        ("insert samples into lyon's trial",
         "INSERT INTO tactorbelt.samples(trial_id, sample_index, t_s, x, y, buttons)"
         " VALUES (%s, 99, 0, 0, 0, 0)", (lyon_tid,),
         "row-level security"),
        ("read who holds the participant ids",
         "SELECT * FROM tactorbelt.participants", (),
         "permission denied"),
        ("register a participant id directly",
         "INSERT INTO tactorbelt.participants VALUES ('Q04', 'oslo')", (),
         "permission denied"),
        ("take over lyon's participant ids",
         "UPDATE tactorbelt.participants SET site='oslo'", (),
         "permission denied"),
        ("become lyon's writer", "UPDATE tactorbelt.site_writers SET site='lyon'", (),
         "permission denied"),
        ("add itself as a writer of lyon",
         "INSERT INTO tactorbelt.site_writers VALUES ('oslo_writer2', 'lyon')", (),
         "permission denied"),
        ("change the schema version", "UPDATE tactorbelt.meta SET value='1'", (),
         "permission denied"),
        ("drop the site rule",
         "ALTER TABLE tactorbelt.sessions DROP CONSTRAINT sessions_participant_site", (),
         "must be owner"),
        ("disable the rule's triggers",
         "ALTER TABLE tactorbelt.sessions DISABLE TRIGGER ALL", (),
         "must be owner"),
        ("replace the claim function",
         "CREATE OR REPLACE FUNCTION tactorbelt.claim_participant(p TEXT, s TEXT) RETURNS"
         " BOOLEAN LANGUAGE sql AS 'SELECT true'", (),
         "permission denied for schema"),
        ("shadow a function in the store's schema",
         "CREATE FUNCTION tactorbelt.site_of(p TEXT) RETURNS TEXT LANGUAGE sql"
         " AS 'SELECT p'", (),
         "permission denied for schema"),
        ("skip foreign keys (replica mode)", "SET session_replication_role = replica", (),
         "permission denied to set parameter"),
        ("turn row-level security off", "ALTER TABLE tactorbelt.sessions DISABLE ROW LEVEL"
         " SECURITY", (),
         "must be owner"),
        ("drop a policy", "DROP POLICY site_writer ON tactorbelt.sessions", (),
         "must be owner"),
        ("truncate", "TRUNCATE tactorbelt.trials", (),
         "permission denied"),
        ("drop a table", "DROP TABLE tactorbelt.samples", (),
         "must be owner"),
        ("become another role", "SET ROLE lyon_writer", (),
         "permission denied to set role"),
        ("bulk load sessions", "COPY tactorbelt.sessions(participant) FROM STDIN", (),
         "row-level security"),
        ("move the id sequence",
         "SELECT setval(pg_get_serial_sequence('tactorbelt.trials', 'trial_id'), 1000000)",
         (),
         "permission denied for sequence"),
    ]


def test_every_hostile_writer_action_is_refused_by_the_database(study: Study) -> None:
    before = _snapshot(study)
    with study.connect(OSLO) as conn:
        own_sid, own_tid = _own_ids(conn)
        refused = []
        for what, sql, args, why in _attacks(study, own_sid, own_tid):
            try:
                with conn.transaction():
                    conn.execute(sql, args)
            except psycopg.Error as exc:
                assert why in str(exc).splitlines()[0], (what, str(exc))
                refused.append(what)
            else:
                pytest.fail(f"a hostile writer could {what}")
        # row-level security off for the session: refused, not silently filtered
        conn.execute("SET row_security = off")
        with pytest.raises(psycopg.Error, match="row-level security"):
            conn.execute("SELECT * FROM tactorbelt.sessions")
    assert len(refused) == len(_attacks(study, own_sid, own_tid))
    assert _snapshot(study) == before


def test_what_a_writer_changes_stays_in_its_own_site(study: Study) -> None:
    before = _snapshot(study)
    with study.connect(OSLO) as conn:
        # statements over "all" rows reach only its own
        assert conn.execute("DELETE FROM tactorbelt.sessions WHERE site='lyon'").rowcount == 0
        assert conn.execute("DELETE FROM tactorbelt.samples WHERE trial_id IN (SELECT trial_id"
                            " FROM tactorbelt.trials WHERE session_id <> 0)"
                            ).rowcount == 3  # its own trial's samples
        assert conn.execute("UPDATE tactorbelt.trials SET correct=0").rowcount == 1
        assert conn.execute("SELECT count(*) FROM tactorbelt.sessions").fetchone()[0] == 1
    after = _snapshot(study)
    lyon = [r for r in before["sessions"] if "lyon" in r]
    assert [r for r in after["sessions"] if "lyon" in r] == lyon
    assert after["participants"] == before["participants"]
    lyon_trials = {r[0] for r in before["trials"] if r[1] == _lyon_ids(study)[0]}
    assert [r for r in after["trials"] if r[0] in lyon_trials] == \
        [r for r in before["trials"] if r[0] in lyon_trials]
    assert [r for r in after["samples"] if r[0] in lyon_trials] == \
        [r for r in before["samples"] if r[0] in lyon_trials]


def test_claim_participant_tells_a_writer_only_whether_an_id_is_free_for_it(
        study: Study) -> None:
    with study.connect(OSLO) as conn:
        claim = "SELECT tactorbelt.claim_participant(%s, 'oslo')"
        assert conn.execute(claim, ("L01",)).fetchone() == (False,)  # lyon's: no site named
        assert conn.execute(claim, ("O01",)).fetchone() == (True,)   # its own already
        assert conn.execute(claim, ("O02",)).fetchone() == (True,)   # free: now its own
        with pytest.raises(psycopg.errors.InsufficientPrivilege, match="its own site"):
            conn.execute("SELECT tactorbelt.claim_participant('Q01', 'lyon')")
    with study.connect(ANALYST) as conn, pytest.raises(psycopg.errors.InsufficientPrivilege):
        conn.execute("SELECT tactorbelt.claim_participant('Q05', 'lyon')")
    with study.connect(OWNER) as conn:
        assert dict(conn.execute("SELECT participant, site FROM tactorbelt.participants")
                    .fetchall()) == {"L01": "lyon", "O01": "oslo", "O02": "oslo"}
    # through the store: the writer learns "another site", the owner which one
    with open_store(study.url(OSLO)) as oslo, \
            pytest.raises(StoreError, match="already taken at another site;"):
        oslo.claim_participant("L01", "oslo")
    with open_store(study.url(OWNER)) as owner, \
            pytest.raises(StoreError, match="already taken at site 'lyon'"):
        owner.claim_participant("L01", "oslo")


def test_the_rule_binds_the_owner_too(study: Study) -> None:
    """The foreign key holds for every role, row-level security or not."""
    with study.connect(OWNER) as conn:
        sid = conn.execute("SELECT session_id FROM tactorbelt.sessions WHERE site='oslo'"
                           ).fetchone()[0]
        for sql, args in (
                ("UPDATE tactorbelt.sessions SET participant='L01' WHERE session_id=%s",
                 (sid,)),
                ("UPDATE tactorbelt.sessions SET site='lyon' WHERE session_id=%s", (sid,)),
                ("UPDATE tactorbelt.sessions SET site=NULL WHERE session_id=%s", (sid,)),
                (_insert_session(), _session_values("L01", "oslo"))):
            with pytest.raises(psycopg.errors.ForeignKeyViolation), conn.transaction():
                conn.execute(sql, args)


def test_the_analyst_writes_nothing(study: Study) -> None:
    before = _snapshot(study)
    with study.connect(ANALYST) as conn:
        assert conn.execute("SELECT count(*) FROM tactorbelt.sessions").fetchone()[0] == 2
        for sql, args in ((_insert_session(), _session_values("Q06", "lyon")),
                          ("UPDATE tactorbelt.sessions SET status='aborted'", ()),
                          ("DELETE FROM tactorbelt.trials", ()),
                          ("INSERT INTO tactorbelt.participants VALUES ('Q07', 'lyon')", ())):
            with pytest.raises(psycopg.Error), conn.transaction():
                conn.execute(sql, args)
    assert _snapshot(study) == before


# -- through the command line ------------------------------------------------------------
def _cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "tactorbelt", *args], capture_output=True,
                          text=True, check=False, timeout=300, cwd=cwd,
                          env={k: v for k, v in os.environ.items() if k != "TACTORBELT_SITE"})


def _study_file(tmp: Path) -> Path:
    return write_study(tmp, training=0, repetitions=2, targets=8, iti_s=0.05)


def _participants(s: Study) -> dict[str, str]:
    with s.connect(OWNER) as conn:
        return dict(conn.execute("SELECT participant, site FROM tactorbelt.participants")
                    .fetchall())


def test_a_run_for_another_site_is_refused_before_anything_is_written(
        study: Study, tmp_path: Path) -> None:
    toml = _study_file(tmp_path)
    local = toml.with_suffix(".sqlite")
    before = _snapshot(study)
    cases = [
        (OSLO, "O02", "lyon", "writes the sessions of site 'oslo', not 'lyon'"),
        (OSLO, "L01", "oslo", "'L01' is already taken at another site"),
        (ANALYST, "A01", "lyon", "may not write sessions of site 'lyon'"),
    ]
    for role, pid, site, message in cases:
        out = _cli("run", str(toml), "-p", pid, "--input", "model", "--headless",
                   "--db", study.url(role), "--site", site)
        assert out.returncode == 2, (role, out.stderr)
        assert message in out.stderr and "Traceback" not in out.stderr, out.stderr
        assert out.stderr.startswith("error: "), out.stderr
        assert not local.exists()  # no local store, no trial
        # with a local store given, it is not created either
        other = tmp_path / f"{role}-{pid}.sqlite"
        out = _cli("run", str(toml), "-p", pid, "--input", "model", "--headless",
                   "--db", str(other), "--push", study.url(role), "--site", site)
        assert out.returncode == 2 and message in out.stderr, out.stderr
        assert not other.exists()
    assert _snapshot(study) == before  # no participants row either
    # the right site goes through
    out = _cli("run", str(toml), "-p", "O02", "--input", "model", "--headless", "--db",
               study.url(OSLO), "--site", "oslo", "--limit", "2")
    assert out.returncode == 0, out.stderr
    assert _participants(study)["O02"] == "oslo"


def test_sync_of_another_sites_sessions_is_refused_and_pushes_nothing(
        study: Study, tmp_path: Path) -> None:
    toml = _study_file(tmp_path)
    local = tmp_path / "lyon-lab.sqlite"
    out = _cli("run", str(toml), "-p", "L02", "--input", "model", "--headless",
               "--db", str(local), "--site", "lyon", "--limit", "2")
    assert out.returncode == 0, out.stderr
    before = _snapshot(study)
    out = _cli("sync", str(local), study.url(OSLO))
    assert out.returncode == 2, out.stderr
    assert "writes the sessions of site 'oslo', not 'lyon'" in out.stderr
    assert "Nothing was pushed" in out.stderr and "session 1 (L02)" in out.stderr
    assert _snapshot(study) == before
    out = _cli("sync", str(local), study.url(LYON))
    assert out.returncode == 0 and "1 new session(s)" in out.stdout, out.stderr


# -- a store written before the rule -----------------------------------------------------
#: The claim function of schema 3: any site, and it named the site holding an id.
_OLD_CLAIM = """CREATE FUNCTION tactorbelt.claim_participant(p TEXT, s TEXT) RETURNS TEXT
    LANGUAGE plpgsql SECURITY DEFINER SET search_path = tactorbelt, pg_temp AS $$
DECLARE owner TEXT;
BEGIN
    INSERT INTO tactorbelt.participants(participant, site) VALUES (p, s)
        ON CONFLICT (participant) DO NOTHING;
    SELECT participants.site INTO owner FROM tactorbelt.participants WHERE participant = p;
    RETURN owner;
END $$"""


def _make_schema_3(s: Study, *, mixed: bool) -> None:
    """Make the store look as schema 3 left it: the old function, no foreign key, the
    writers' table-wide grants; with ``mixed``, oslo's session relabelled L01 (the attack
    schema 3 let through)."""
    with s.connect(OWNER) as conn:
        conn.execute("ALTER TABLE tactorbelt.sessions DROP CONSTRAINT sessions_participant_site")
        conn.execute("ALTER TABLE tactorbelt.participants DROP CONSTRAINT"
                     " participants_participant_site")
        conn.execute("DROP FUNCTION tactorbelt.claim_participant(TEXT, TEXT)")
        conn.execute(_OLD_CLAIM)
        for role in (LYON, OSLO):
            conn.execute(f"GRANT EXECUTE ON FUNCTION tactorbelt.claim_participant(TEXT, TEXT)"
                         f" TO {role}")
            conn.execute(f"GRANT SELECT, INSERT, UPDATE, DELETE ON tactorbelt.sessions,"
                         f" tactorbelt.trials, tactorbelt.task_events TO {role}")
        conn.execute("DELETE FROM tactorbelt.participants WHERE participant='O01'")
        conn.execute("UPDATE tactorbelt.meta SET value='3' WHERE key='schema_version'")
    if mixed:
        with s.connect(OSLO) as conn:  # as the issue found it
            conn.execute("UPDATE tactorbelt.sessions SET participant='L01'")
            assert conn.execute("SELECT tactorbelt.claim_participant('Q01', 'lyon')"
                                ).fetchone() == ("lyon",)


def test_the_owners_first_open_migrates_a_store_of_schema_3(study: Study) -> None:
    _make_schema_3(study, mixed=False)
    with pytest.raises(StoreError, match="owner"):
        open_store(study.url(OSLO))  # a writer may not migrate it: refused at open
    with open_store(study.url(OWNER)):
        pass
    with study.connect(OWNER) as conn:
        assert conn.execute("SELECT value FROM tactorbelt.meta WHERE key='schema_version'"
                            ).fetchone() == ("4",)
        assert conn.execute("SELECT convalidated FROM pg_constraint WHERE conname="
                            "'sessions_participant_site'").fetchone() == (True,)
    assert _participants(study) == {"L01": "lyon", "O01": "oslo"}  # O01 registered again
    before = _snapshot(study)
    with study.connect(OSLO) as conn:  # the migration gave the writers the new grants
        own_sid, own_tid = _own_ids(conn)
        for what, sql, args, why in _attacks(study, own_sid, own_tid):
            with pytest.raises(psycopg.Error, match=why), conn.transaction():
                conn.execute(sql, args)
                pytest.fail(what)
    assert _snapshot(study) == before
    with open_store(study.url(OSLO)) as oslo:  # and its runs go on
        sid = make_session(oslo, "O03", site="oslo")
        oslo.write_trial(sid, make_result(0))
        oslo.set_status(sid, "complete")


def test_an_old_store_with_ids_spanning_sites_is_refused_by_analysis_and_export(
        study: Study, tmp_path: Path) -> None:
    _make_schema_3(study, mixed=True)
    with open_store(study.url(OWNER)):  # migrated; the old rows cannot be validated
        pass
    with study.connect(OWNER) as conn:
        assert conn.execute("SELECT convalidated FROM pg_constraint WHERE conname="
                            "'sessions_participant_site'").fetchone() == (False,)
        conn.execute("UPDATE tactorbelt.sessions SET status='complete'")
    with study.connect(OSLO) as conn, pytest.raises(psycopg.Error):
        conn.execute("SELECT tactorbelt.claim_participant('Q02', 'lyon')")
    url = study.url(ANALYST)
    out = _cli("analyze", url, "--out", str(tmp_path / "all"))
    assert out.returncode == 2, out.stderr
    assert "used at more than one site" in out.stderr and "'L01'" in out.stderr
    assert "at lyon" in out.stderr and "at oslo" in out.stderr and "#1" in out.stderr
    assert "--site" in out.stderr and "Traceback" not in out.stderr
    assert not (tmp_path / "all" / "summary.json").exists()
    for fmt in ("bids", "csv", "tidy", "parquet", "psychopy"):
        out = _cli("export", url, "-o", str(tmp_path / fmt), "--format", fmt)
        assert out.returncode == 2, (fmt, out.stderr)
        assert "used at more than one site" in out.stderr and "session 1" in out.stderr
        assert not (tmp_path / fmt / "sub-L01").exists()
    # one site at a time is what it is
    out = _cli("analyze", url, "--site", "lyon", "--out", str(tmp_path / "lyon"))
    assert out.returncode == 0, out.stderr
    counts = json.loads((tmp_path / "lyon" / "summary.json").read_text())["counts"]
    assert counts["participants"] == 1 and counts["sessions"] == 1


# -- two sites: the shared store is the sum of the local ones ----------------------------
def _per_target(path: Path) -> dict[str, list[dict[str, str]]]:
    with path.open(newline="") as f:
        rows = list(csv.DictReader(f))
    out: dict[str, list[dict[str, str]]] = {}
    for r in rows:
        out.setdefault(r["participant"], []).append(r)
    return out


def _same_tree(a: Path, b: Path) -> None:
    cmp = filecmp.dircmp(a, b)
    assert not cmp.left_only and not cmp.right_only, (cmp.left_only, cmp.right_only)
    _, mismatch, errors = filecmp.cmpfiles(a, b, cmp.common_files, shallow=False)
    assert not mismatch and not errors, mismatch
    for d in cmp.common_dirs:
        _same_tree(a / d, b / d)


@pytest.fixture
def two_sites(study: Study, tmp_path: Path) -> Iterator[tuple[Study, Path, Path]]:
    """Lyon's L05 and oslo's O05, each run by its own writer pushing to the shared store
    (the fixture's own sessions are removed first, so that each local store holds all of
    its site's sessions)."""
    with study.connect(OWNER) as conn:
        conn.execute("DELETE FROM tactorbelt.samples")
        conn.execute("DELETE FROM tactorbelt.trials")
        conn.execute("DELETE FROM tactorbelt.sessions")
    toml = _study_file(tmp_path)
    locals_ = []
    for role, pid, site in ((LYON, "L05", "lyon"), (OSLO, "O05", "oslo")):
        local = tmp_path / f"{site}.sqlite"
        out = _cli("run", str(toml), "-p", pid, "--input", "model", "--headless",
                   "--db", str(local), "--push", study.url(role), "--site", site)
        assert out.returncode == 0 and "pushed to" in out.stderr, out.stderr
        locals_.append(local)
    yield study, locals_[0], locals_[1]


def test_the_analysts_analysis_and_bids_export_equal_each_sites_own_store(
        two_sites: tuple[Study, Path, Path], tmp_path: Path) -> None:
    study, lyon, oslo = two_sites
    url = study.url(ANALYST)
    shared = tmp_path / "shared"
    out = _cli("analyze", url, "--out", str(shared))
    assert out.returncode == 0, out.stderr
    both = _per_target(shared / "per_target.csv")
    assert set(both) == {"L05", "O05"}
    for local, pid in ((lyon, "L05"), (oslo, "O05")):
        mine = tmp_path / local.stem
        out = _cli("analyze", str(local), "--out", str(mine))
        assert out.returncode == 0, out.stderr
        assert _per_target(mine / "per_target.csv")[pid] == both[pid]
    out = _cli("export", url, "-o", str(tmp_path / "bids-shared"), "--format", "bids")
    assert out.returncode == 0, out.stderr
    subs = sorted(p.name for p in (tmp_path / "bids-shared").glob("sub-*"))
    assert subs == ["sub-L05", "sub-O05"]
    for local, pid in ((lyon, "L05"), (oslo, "O05")):
        dest = tmp_path / f"bids-{local.stem}"
        out = _cli("export", str(local), "-o", str(dest), "--format", "bids")
        assert out.returncode == 0, out.stderr
        _same_tree(dest / f"sub-{pid}", tmp_path / "bids-shared" / f"sub-{pid}")
