"""A throwaway PostgreSQL server for the tests (initdb into a temporary folder).

:func:`server` starts one per test process on first use (a Unix socket in a temporary
folder, ``listen_addresses=''``, so nothing listens on the network) and stops it at exit;
None when the binaries are missing (tests skip). As root (CI) the server runs as the
``postgres`` user (``runuser``), which owns the temporary folder.

Roles: ``tbadmin`` (superuser, trusted over the socket), ``tbsecret`` (password
``s3cret``: the wrong-credentials tests). :meth:`PgServer.new_database` gives each test a
fresh database.
"""

from __future__ import annotations

import atexit
import contextlib
import glob
import os
import pwd
import shutil
import subprocess
import tempfile
import uuid
from pathlib import Path

__all__ = ["PgServer", "server", "skip_reason"]

ADMIN = "tbadmin"
PASSWORD_ROLE, PASSWORD = "tbsecret", "s3cret"
_HBA = f"""local all {PASSWORD_ROLE} scram-sha-256
local all all trust
"""


def _bindir() -> Path | None:
    for cand in [os.environ.get("TACTORBELT_TEST_PG_BINDIR", ""),
                 *sorted(glob.glob("/usr/lib/postgresql/*/bin"), reverse=True)]:
        if cand and (Path(cand) / "initdb").is_file():
            return Path(cand)
    found = shutil.which("initdb")
    return Path(found).parent if found else None


class PgServer:
    """One running throwaway server; :meth:`stop` ends it and removes its folder."""

    def __init__(self, bindir: Path) -> None:
        self.bindir = bindir
        self.root = Path(tempfile.mkdtemp(prefix="tbpg-"))  # short: socket path limit
        self.data = self.root / "data"
        self.sock = self.root / "sock"
        self.sock.mkdir()
        self.user: str | None = None
        if os.geteuid() == 0:  # postgres refuses to run as root
            self.user = "postgres"
            pw = pwd.getpwnam(self.user)
            for p in (self.root, self.sock):
                os.chown(p, pw.pw_uid, pw.pw_gid)
        self._run("initdb", "-D", str(self.data), "-U", ADMIN, "-A", "trust", "--no-sync",
                  "-E", "UTF8", "--locale=C")
        (self.data / "pg_hba.conf").write_text(_HBA)
        self.start()
        self.admin("CREATE ROLE " + PASSWORD_ROLE + " LOGIN PASSWORD '" + PASSWORD + "'")

    def _run(self, tool: str, *args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
        cmd = [str(self.bindir / tool), *args]
        if self.user is not None:
            cmd = ["runuser", "-u", self.user, "--", *cmd]
        return subprocess.run(cmd, capture_output=True, text=True, check=check, timeout=120,
                              cwd=self.root)

    def start(self) -> None:
        """Start (or restart) the server and wait until it accepts connections."""
        opts = (f"-c listen_addresses='' -k {self.sock} -c fsync=off "
                "-c full_page_writes=off -c max_connections=60")
        self._run("pg_ctl", "-D", str(self.data), "-l", str(self.root / "log"), "-o", opts,
                  "-w", "-t", "60", "start")

    def start_if_stopped(self) -> None:
        """Start the server unless it runs (after a test that stopped it failed)."""
        if self._run("pg_ctl", "-D", str(self.data), "status", check=False).returncode != 0:
            self.start()

    def stop(self, mode: str = "fast") -> None:
        """Stop the server (``fast``: disconnect every client)."""
        self._run("pg_ctl", "-D", str(self.data), "-m", mode, "-w", "stop", check=False)

    def url(self, dbname: str = "postgres", user: str = ADMIN) -> str:
        from urllib.parse import quote

        return f"postgresql://{user}@{quote(str(self.sock), safe='')}/{dbname}"

    def admin(self, sql: str, dbname: str = "postgres") -> None:
        """Run SQL statements (``;``-separated) as the superuser."""
        import psycopg

        with psycopg.connect(self.url(dbname), autocommit=True) as conn:
            for stmt in sql.split("; "):
                conn.execute(stmt)  # type: ignore[arg-type]

    def new_database(self) -> str:
        """A fresh empty database; its URL (as the admin)."""
        name = "t_" + uuid.uuid4().hex[:12]
        self.admin(f"CREATE DATABASE {name}")
        return self.url(name)

    def destroy(self) -> None:
        self.stop("immediate")
        shutil.rmtree(self.root, ignore_errors=True)


_SERVER: list[PgServer | None] = []
_REASON: list[str] = []


def skip_reason() -> str | None:
    """Why there is no test server (None when there is one)."""
    server()
    return _REASON[0] if _REASON else None


def server() -> PgServer | None:
    """The process's throwaway server, started on first use; None when unavailable."""
    if not _SERVER:
        bindir = _bindir()
        srv: PgServer | None = None
        try:
            import psycopg  # noqa: F401
        except ImportError:
            _REASON.append("psycopg is not installed (pip install 'tactorbelt[postgresql]')")
        else:
            if bindir is None:
                _REASON.append("PostgreSQL server binaries (initdb, pg_ctl) not found; "
                               "apt-get install postgresql")
            else:
                try:
                    srv = PgServer(bindir)
                except (OSError, subprocess.SubprocessError, KeyError) as exc:
                    detail = getattr(exc, "stderr", "") or str(exc)
                    _REASON.append(f"cannot start a throwaway PostgreSQL server: {detail}")
                else:
                    atexit.register(srv.destroy)
        _SERVER.append(srv)
    return _SERVER[0]


def contract_url() -> str | None:
    """A fresh database for the store contract suite: ``TACTORBELT_TEST_POSTGRESQL_URL``
    (a server whose role may CREATE DATABASE) or the throwaway server; None: skip."""
    given = os.environ.get("TACTORBELT_TEST_POSTGRESQL_URL")
    if given:
        import psycopg

        name = "t_" + uuid.uuid4().hex[:12]
        with psycopg.connect(given, autocommit=True) as conn:
            conn.execute(f"CREATE DATABASE {name}")  # type: ignore[arg-type]
        from urllib.parse import urlsplit, urlunsplit

        parts = urlsplit(given)
        return urlunsplit(parts._replace(path="/" + name))
    srv = server()
    return None if srv is None else srv.new_database()


def set_schema_version(url: str, version: int) -> None:
    import psycopg

    with psycopg.connect(url, autocommit=True) as conn, contextlib.suppress(Exception):
        conn.execute("UPDATE tactorbelt.meta SET value=%s WHERE key='schema_version'",
                     (str(version),))


def run_sql(url: str, *statements: str) -> None:
    """Run statements on the store's database (as its owner), e.g. to make an old schema."""
    import psycopg

    with psycopg.connect(url, autocommit=True) as conn:
        for stmt in statements:
            conn.execute(stmt)  # type: ignore[arg-type]
