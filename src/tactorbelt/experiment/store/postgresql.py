"""The PostgreSQL store: several labs' sessions in one database (psycopg 3).

URL: ``postgresql://user@host/dbname`` (any libpq URL, e.g.
``postgresql://writer@/study?host=/run/postgresql`` for a Unix socket). Credentials come
from the standard libpq environment (``PGPASSWORD``, ``PGUSER``, ...) or a ``.pgpass``
file, never from the URL: a URL with a password is refused.

Everything lives in the database schema ``tactorbelt`` (the database may hold other
schemas): the tables of :mod:`.schema`, declared once for both stores, in the
:data:`~.schema.POSTGRESQL` dialect. Beyond the SQLite store's, ``samples.sample_index``
and ``ratings.rating_order`` keep the order rows were written in (no rowid here), and
the multi-site tables: ``run_options(session_id, options)`` (a site's writer may not
write ``meta``), ``participants(participant, site)`` (who may run a participant id: one
site per id) and ``site_writers(role_name, site)`` (row-level security: a writer role's
site). ``meta`` holds ``application`` = ``tactorbelt`` and ``schema_version``
(:data:`PG_SCHEMA_VERSION`).

The database itself holds the site rules (:func:`_site_rules`, schema 4): a session's
``(participant, site)`` must be registered in ``participants`` (a foreign key, checked on
every INSERT and on every UPDATE of either column, for every role); the
``claim_participant`` function registers an id for the calling role's own site only and
answers only whether the id is free for it; a writer role inserts no identity column
and updates only a session's status, end and resume count. :meth:`check_site` says
before a run whether the login may write a site.

The schema is created (or migrated: tables and columns added, :func:`~.schema.migrate`)
on first use by a role that may create it, in one transaction under an advisory lock; a
newer schema is refused for writing, a ``tactorbelt`` schema that is not a tactorbelt
store is refused.

Guarantees as the SQLite store (the same code: :class:`~.sql.Store`): each trial
(row and samples) is one transaction; an ``aborted`` row is replaced when the trial is
run again (found under a row lock: several writers); a final row is never written
twice. Several writers may use the store at once (``exclusive_writer`` is False);
a participant id belongs to the site that first used it (:meth:`create_session` and
:meth:`import_session` refuse it at another site, and so does the database).

:meth:`import_session` / :meth:`import_trial` / :meth:`sync_state` take sessions copied
from another store (``tactorbelt sync``, the runner's background push), keyed by the
session's globally unique ``session_uuid``, so copying twice changes nothing.

:func:`setup_access` creates the row-level security policies (a writer role per site,
analyst roles that read everything); see docs/multisite.md.

I/O edge of the experiment package: imports psycopg (only when a PostgreSQL URL is
opened) and the pure experiment modules.
"""

from __future__ import annotations

import contextlib
import uuid
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from ..._errors import StoreError
from ..provenance import default_site
from ..trial import TrialResult
from .base import RATING_COLUMNS, SCHEMA_VERSION, TASK_EVENT_COLUMNS, StoreCapabilities
from .schema import POSTGRESQL, columns, migrate, missing_columns
from .sql import Store

__all__ = ["PG_SCHEMA", "PostgreSQLStore", "check_url", "setup_access"]

#: The database schema (namespace) holding a tactorbelt store.
PG_SCHEMA = POSTGRESQL.namespace
#: Seconds to wait for a server when connecting.
CONNECT_TIMEOUT_S = 5

#: The schema version of a PostgreSQL store: the tables of :data:`SCHEMA_VERSION`, and
#: one more: the site rules the database itself holds (:data:`_SITE_RULES`: a session's
#: participant id is registered to the session's site, ``claim_participant`` claims for
#: the caller's own site and answers only whether an id is free for it, a writer's
#: INSERT and UPDATE by column). A tactorbelt from before them refuses to write here.
PG_SCHEMA_VERSION = SCHEMA_VERSION + 1

#: After the tables: the function through which a writer claims a participant id. It
#: runs as the store's owner (a writer may not read ``participants``); the caller is
#: ``session_user`` (``current_user`` is the owner inside it). A role of
#: ``site_writers`` claims for its own site only; a role that is not one claims for any
#: site only when it is (a member of) the table's owner. Returns whether the id is now
#: the site's (true: claimed now or before; false: another site has it), nothing more.
_CLAIM = """CREATE OR REPLACE FUNCTION tactorbelt.claim_participant(p TEXT, s TEXT)
    RETURNS BOOLEAN LANGUAGE plpgsql SECURITY DEFINER
    SET search_path = tactorbelt, pg_catalog, pg_temp AS $$
DECLARE mine TEXT; holder TEXT;
BEGIN
    SELECT site_writers.site INTO mine FROM tactorbelt.site_writers
        WHERE role_name = session_user;
    IF FOUND THEN
        IF s IS DISTINCT FROM mine THEN
            RAISE EXCEPTION
                'role % writes site %, not %: it claims participant ids for its own site only',
                session_user, quote_literal(mine), coalesce(quote_literal(s), 'NULL')
                USING ERRCODE = 'insufficient_privilege';
        END IF;
    ELSIF NOT pg_has_role(session_user, (SELECT relowner FROM pg_catalog.pg_class
            WHERE oid = 'tactorbelt.participants'::regclass), 'USAGE') THEN
        RAISE EXCEPTION 'role % writes no site of this store (it is not in site_writers)',
            session_user USING ERRCODE = 'insufficient_privilege';
    END IF;
    IF p IS NULL OR s IS NULL THEN
        RAISE EXCEPTION 'a participant id and a site are needed'
            USING ERRCODE = 'null_value_not_allowed';
    END IF;
    INSERT INTO tactorbelt.participants(participant, site) VALUES (p, s)
        ON CONFLICT (participant) DO NOTHING;
    SELECT participants.site INTO holder FROM tactorbelt.participants WHERE participant = p;
    RETURN holder = s;
END $$"""
#: The foreign key that binds a session to its participant id's site (MATCH FULL: a
#: session without a site is refused too). Added NOT VALID, so that an old store whose
#: sessions break the rule is still opened; every INSERT, and every UPDATE of
#: ``participant`` or ``site``, is checked from then on, and the rows already there are
#: validated when they allow it (:func:`_site_rules`).
_SESSION_SITE_FK = "sessions_participant_site"
#: Identity columns a writer never gives (it could take ids ahead of another site's
#: next rows), and the columns it may UPDATE (all others are written once).
_WRITER_NO_INSERT = {"sessions": ("session_id",), "trials": ("trial_id",),
                     "task_events": ("event_id",)}
_WRITER_UPDATE = {"sessions": ("status", "ended_at", "resumed"), "task_events": ()}
#: Session columns copied by :meth:`PostgreSQLStore.import_session` (session_id is the
#: target store's own).
_SESSION_COPY = tuple(c.name for c in columns(POSTGRESQL, "sessions")
                      if c.name != "session_id")
#: Session columns that change after creation (a sync updates them).
_SESSION_MUTABLE = ("ended_at", "status", "resumed")


def check_url(url: str) -> dict[str, str]:
    """The libpq connection parameters of a ``postgresql://`` URL.

    Raises:
        StoreError: the URL holds a password (credentials belong in PGPASSWORD or
            ~/.pgpass), or it cannot be parsed.
    """
    from psycopg.conninfo import conninfo_to_dict

    text = "postgresql://" + url.split("://", 1)[1] if "://" in url else url
    try:
        params = {k: str(v) for k, v in conninfo_to_dict(text).items() if v is not None}
    except Exception as exc:  # psycopg.ProgrammingError
        raise StoreError(f"not a PostgreSQL URL: {exc}") from None
    if params.get("password"):
        raise StoreError(
            "the PostgreSQL URL holds a password; never put one on the command line or in "
            "a store: give it in ~/.pgpass (host:port:dbname:user:password, mode 0600) or "
            "the PGPASSWORD environment variable, and drop it from the URL")
    return params


def _connect_error(url: str, exc: Exception, create: bool, readonly: bool) -> StoreError:
    msg = str(exc).strip()
    first = " ".join(line.strip() for line in msg.splitlines()[:1]) or type(exc).__name__
    low = msg.lower()
    if "password authentication failed" in low or "no password supplied" in low \
            or ("role" in low and "does not exist" in low) or "authentication failed" in low:
        return StoreError(
            f"cannot log in to {url}: {first}; check the user name in the URL and "
            "the password in ~/.pgpass or PGPASSWORD")
    if "database" in low and "does not exist" in low:
        if not create or readonly:
            return StoreError(f"{url}: no such store ({first})")
        return StoreError(f"{url}: {first}; create the database first "
                          "(createdb NAME, by its owner)")
    return StoreError(
        f"cannot reach the PostgreSQL server of {url}: {first}; check that it runs "
        "and the URL (host, port, database), or run with --offline to write the local store "
        "alone and push it later with 'tactorbelt sync'")


class PostgreSQLStore(Store):
    """A store in a PostgreSQL database (see the module doc). Open with :func:`open_store`."""

    capabilities = StoreCapabilities(backend="postgresql", file=False, exclusive_writer=False,
                                     sync_target=True)
    dialect = POSTGRESQL

    def __init__(self, url: str, conn: Any, readonly: bool) -> None:
        super().__init__(url, None, conn, readonly)
        self._trial_columns: set[str] | None = None
        self._row_security: bool | None = None

    # -- opening -----------------------------------------------------------------------
    @classmethod
    def open_url(cls, url: str | Path, *, create: bool = True, readonly: bool = False,
                 verify: bool = True) -> PostgreSQLStore:
        """Connect, check (and with ``create`` make or migrate) the schema.

        Raises:
            StoreError: a password in the URL; the server cannot be reached; the login
                fails; the database does not exist; its ``tactorbelt`` schema is not a
                tactorbelt store; (for writing) its schema is newer than this
                tactorbelt's. Raised before anything is written.
        """
        import psycopg

        text = str(url)
        check_url(text)
        try:  # autocommit: transactions are explicit
            conn = psycopg.connect("postgresql://" + text.split("://", 1)[1], autocommit=True,
                                   connect_timeout=CONNECT_TIMEOUT_S,
                                   application_name="tactorbelt")
        except psycopg.Error as exc:
            raise _connect_error(text, exc, create, readonly) from None
        try:
            cls._check_schema(text, conn, create=create, readonly=readonly)
        except BaseException:
            with contextlib.suppress(Exception):
                conn.close()
            raise
        return cls(text, conn, readonly)

    @classmethod
    def _check_schema(cls, url: str, conn: Any, *, create: bool, readonly: bool) -> None:
        import psycopg

        try:
            tables = {r[0] for r in conn.execute(POSTGRESQL.tables_query)}
            if tables and "meta" not in tables:
                raise StoreError(
                    f"{url}: the database's schema {PG_SCHEMA!r} is not a tactorbelt store "
                    f"(tables: {', '.join(sorted(tables))}); give another database")
            meta: dict[str, str] = {}
            if tables:
                meta = dict(conn.execute("SELECT key, value FROM tactorbelt.meta").fetchall())
                if meta.get("application") != "tactorbelt":
                    raise StoreError(f"{url}: the database's schema {PG_SCHEMA!r} is not a "
                                     "tactorbelt store (no application mark); give another "
                                     "database")
            if readonly:
                if not tables:
                    raise StoreError(f"{url}: no such store (the database holds no "
                                     f"{PG_SCHEMA!r} schema; a run or sync creates it)")
                return
            version = int(meta.get("schema_version", "0"))
            if version > PG_SCHEMA_VERSION:
                raise StoreError(
                    f"{url} was written by a newer tactorbelt (schema {version}, this one "
                    f"writes {PG_SCHEMA_VERSION}); upgrade tactorbelt to write to it")
            if version == PG_SCHEMA_VERSION and cls._complete(conn):
                return
            if not tables and not create:
                raise StoreError(f"{url}: no such store (no {PG_SCHEMA!r} schema)")
            with conn.transaction():
                conn.execute("SELECT pg_advisory_xact_lock(hashtext('tactorbelt schema'))")
                migrate(conn, POSTGRESQL)
                _site_rules(conn)
                conn.execute("INSERT INTO tactorbelt.meta(key, value) VALUES "
                             "('application', 'tactorbelt') ON CONFLICT (key) DO NOTHING")
                conn.execute(
                    "INSERT INTO tactorbelt.meta(key, value) VALUES ('schema_version', %s) "
                    "ON CONFLICT (key) DO UPDATE SET value = EXCLUDED.value "
                    "WHERE tactorbelt.meta.value::int < EXCLUDED.value::int",
                    (str(PG_SCHEMA_VERSION),))
        except psycopg.errors.InsufficientPrivilege as exc:
            raise StoreError(f"{url}: the store's schema must be created or upgraded by its "
                             f"owner (this role may not: {str(exc).strip()})") from None
        except psycopg.Error as exc:
            raise StoreError(f"cannot open the store {url}: {str(exc).strip()}") from None

    @staticmethod
    def _complete(conn: Any) -> bool:
        """Whether the store has every declared table and column (read from the catalog,
        which shows a writer role the tables it may not read too)."""
        have = {(str(r[0]), str(r[1])) for r in conn.execute(
            "SELECT c.relname, a.attname FROM pg_catalog.pg_attribute a"
            " JOIN pg_catalog.pg_class c ON c.oid = a.attrelid"
            " JOIN pg_catalog.pg_namespace n ON n.oid = c.relnamespace"
            " WHERE n.nspname = %s AND c.relkind = 'r' AND a.attnum > 0"
            " AND NOT a.attisdropped", (PG_SCHEMA,))}
        return not missing_columns(POSTGRESQL, have)

    # -- helpers -----------------------------------------------------------------------
    @contextlib.contextmanager
    def _transaction(self, what: str = "write to") -> Iterator[Any]:
        import psycopg

        if self.readonly:
            raise StoreError(f"{self.url} was opened read-only")
        try:
            with self.conn.transaction(), self.conn.cursor() as cur:
                yield cur
        except psycopg.Error as exc:
            raise StoreError(f"cannot {what} {self.url}: {str(exc).strip()}") from None

    def _read_error(self) -> type[Exception]:
        import psycopg

        return psycopg.Error

    def _stream(self, sql: str, args: Sequence[Any]) -> Iterator[Sequence[Any]]:
        """Rows through a server-side cursor, 10,000 at a time."""
        with self._reading(), self.conn.transaction(), \
                self.conn.cursor(name=f"tb_samples_{uuid.uuid4().hex}") as cur:
            cur.itersize = 10_000
            cur.execute(sql, tuple(args))
            yield from cur

    def _claim(self, cur: Any, participant: str, site: str) -> None:
        if not cur.execute("SELECT tactorbelt.claim_participant(%s, %s)",
                           (participant, site)).fetchone()[0]:
            where = "another site"
            if cur.execute("SELECT has_table_privilege('tactorbelt.participants', 'SELECT')"
                           " AND NOT row_security_active('tactorbelt.participants')"
                           ).fetchone()[0]:  # the owner may know which
                row = cur.execute("SELECT site FROM tactorbelt.participants"
                                  " WHERE participant=%s", (participant,)).fetchone()
                where = f"site {row[0]!r}" if row else where
            raise StoreError(
                f"participant id {participant!r} is already taken at {where}; "
                f"give this participant another id at site {site!r}")

    def claim_participant(self, participant: str, site: str) -> None:
        """Register the participant id at ``site`` (first come); StoreError when another
        site already has it, or when this login may not write ``site``."""
        with self._transaction() as c:
            self._claim(c, participant, site)

    def check_site(self, site: str) -> None:
        """Refuse (StoreError) unless this login may write sessions of ``site``: a writer
        role (``site_writers``) writes its own site only; a role that reads only (an
        analyst) or that row-level security gives no site writes none; the owner, or
        anyone in a store without row-level security, writes any. Writes nothing."""
        role, may_insert, rls, listed = self._query(
            "SELECT current_user::text, has_table_privilege('tactorbelt.sessions', 'INSERT'),"
            " row_security_active('tactorbelt.sessions'),"
            " has_table_privilege('tactorbelt.site_writers', 'SELECT')")[0]
        mine = None
        if listed:
            rows = self._query("SELECT site FROM tactorbelt.site_writers WHERE role_name ="
                               " current_user")
            mine = str(rows[0][0]) if rows else None
        if mine is not None and mine != site:
            raise StoreError(
                f"{self.url}: the role {role!r} writes the sessions of site {mine!r}, not "
                f"{site!r}; if this is the {mine} lab, give --site {mine} (or set "
                f"TACTORBELT_SITE={mine}), else log in as the writer role of site {site!r}")
        if mine is None and (rls or not may_insert):
            why = ("it may only read (an analyst role)" if not may_insert
                   else "it is no site's writer (not in site_writers)")
            raise StoreError(
                f"{self.url}: the role {role!r} may not write sessions of site {site!r}: "
                f"{why}; log in as the writer role of site {site!r} (the store's owner "
                "makes one with setup_access, docs/multisite.md)")

    # -- samples: COPY, or INSERTs under row-level security -----------------------------
    def _write_samples(self, c: Any, trial_id: int, result: TrialResult) -> None:
        self._copy_samples(c, trial_id, result.sample_rows())

    def _copy_samples(self, c: Any, trial_id: int, samples: Iterable[Sequence[Any]]) -> None:
        rows = [(trial_id, k, *s) for k, s in enumerate(samples)]
        if self._row_security is None:  # COPY is refused under row-level security
            self._row_security = bool(c.execute(
                "SELECT row_security_active('tactorbelt.samples')").fetchone()[0])
        if self._row_security:
            c.executemany("INSERT INTO tactorbelt.samples(trial_id, sample_index, t_s, x, y,"
                          " buttons) VALUES (%s,%s,%s,%s,%s,%s)", rows)
        else:
            with c.copy("COPY tactorbelt.samples(trial_id, sample_index, t_s, x, y, buttons)"
                        " FROM STDIN") as copy:
                for r in rows:
                    copy.write_row(r)

    # -- copying sessions from another store (sync) ------------------------------------
    def sync_state(self, session_uuid: str
                   ) -> tuple[int, dict[str, Any], dict[int, tuple[str, int]]] | None:
        """``(session_id, {ended_at, status, resumed}, {trial_index: (status, attempts)})``
        of the session with this uuid, or None when the store does not hold it."""
        rows = self._query("SELECT session_id, ended_at, status, resumed FROM"
                           " tactorbelt.sessions WHERE session_uuid=%s", (session_uuid,))
        if not rows:
            return None
        sid = int(rows[0][0])
        trials = self._query("SELECT trial_index, status, attempts FROM tactorbelt.trials"
                             " WHERE session_id=%s", (sid,))
        return (sid, dict(zip(_SESSION_MUTABLE, rows[0][1:], strict=True)),
                {int(r[0]): (str(r[1]), int(r[2])) for r in trials})

    def import_session(self, row: Mapping[str, Any]) -> int:
        """Insert a session copied from another store (by its ``session_uuid``), or bring
        the copy's status, ended_at and resumed up to date; return its id here.

        Raises:
            StoreError: the row has no session_uuid, its participant id is taken at
                another site, or the write failed.
        """
        if not row.get("session_uuid"):
            raise StoreError("a session copied between stores needs its session_uuid")
        site = row.get("site") or default_site()
        with self._transaction() as c:
            got = c.execute("SELECT session_id FROM tactorbelt.sessions WHERE"
                            " session_uuid=%s FOR UPDATE", (row["session_uuid"],)).fetchone()
            if got is not None:
                c.execute("UPDATE tactorbelt.sessions SET ended_at=%s, status=%s, resumed=%s"
                          " WHERE session_id=%s AND (ended_at IS DISTINCT FROM %s OR"
                          " status<>%s OR resumed<>%s)",
                          (row["ended_at"], row["status"], row["resumed"], got[0],
                           row["ended_at"], row["status"], row["resumed"]))
                return int(got[0])
            self._claim(c, str(row["participant"]), site)
            values = {k: row.get(k) for k in _SESSION_COPY} | {"site": site}
            return self._insert(c, "sessions", {k: v for k, v in values.items()
                                                if v is not None}, "session_id")

    def import_trial(self, session_id: int, row: Mapping[str, Any],
                     samples: Sequence[Sequence[Any]]) -> bool:
        """Copy one trial (a row of another store and its ``(t_s, x, y, buttons)``
        samples) into session ``session_id``, in one transaction. A trial already here
        with the same status and attempts is left alone (False); an older attempt is
        replaced. Returns whether anything was written."""
        skip = {"trial_id", "session_id"}
        if self._trial_columns is None:
            self._trial_columns = set(self.table_columns("trials"))
        have = self._trial_columns
        values = {k: v for k, v in row.items() if k not in skip and k in have}
        if values.get("load") is None:  # a trial stored before factorial designs
            values.pop("load", None)      # takes the column's default, 'none'
        values["session_id"] = session_id
        with self._transaction() as c:
            old = c.execute("SELECT trial_id, status, attempts FROM tactorbelt.trials"
                            " WHERE session_id=%s AND trial_index=%s FOR UPDATE",
                            (session_id, row["trial_index"])).fetchone()
            if old is not None:
                if (old[1], int(old[2])) == (row["status"], int(row["attempts"])) \
                        or old[1] != "aborted":
                    return False
                c.execute("DELETE FROM tactorbelt.trials WHERE trial_id=%s", (old[0],))
            self._copy_samples(c, self._insert(c, "trials", values, "trial_id"), samples)
        return True

    def import_task_events(self, session_id: int, rows: Sequence[Mapping[str, Any]]) -> int:
        """Replace the session's task events by ``rows`` unless as many are here."""
        cols = TASK_EVENT_COLUMNS[1:]
        with self._transaction() as c:
            c.execute("SELECT session_id FROM tactorbelt.sessions WHERE session_id=%s"
                      " FOR UPDATE", (session_id,))
            n = c.execute("SELECT count(*) FROM tactorbelt.task_events WHERE session_id=%s",
                          (session_id,)).fetchone()[0]
            if n == len(rows):
                return 0
            c.execute("DELETE FROM tactorbelt.task_events WHERE session_id=%s", (session_id,))
            b = {"target", "correct"}  # bound as booleans
            c.executemany(self.dialect.insert("task_events", TASK_EVENT_COLUMNS),
                          [(session_id, *(bool(r[k]) if k in b else r[k] for k in cols))
                           for r in rows])
        return len(rows)

    def import_ratings(self, session_id: int, rows: Sequence[Mapping[str, Any]]) -> int:
        """Replace the session's ratings by ``rows`` unless the same are here."""
        want = [(int(r["block_index"]), str(r["scale"]), str(r["item"]), float(r["value"]))
                for r in rows]
        with self._transaction() as c:
            c.execute("SELECT session_id FROM tactorbelt.sessions WHERE session_id=%s"
                      " FOR UPDATE", (session_id,))
            have = c.execute("SELECT block_index, scale, item, value FROM tactorbelt.ratings"
                             " WHERE session_id=%s", (session_id,)).fetchall()
            if sorted(tuple(h) for h in have) == sorted(want):
                return 0
            c.execute("DELETE FROM tactorbelt.ratings WHERE session_id=%s", (session_id,))
            c.executemany(self.dialect.insert("ratings", (*RATING_COLUMNS, "rating_order")),
                          [(session_id, *w, i) for i, w in enumerate(want)])
        return len(want)


def _site_rules(conn: Any) -> None:
    """The site rules of :data:`PG_SCHEMA_VERSION`, made or brought up to date inside the
    migration's transaction (idempotent).

    The claim function (an older one returned the site that holds an id: replaced, and
    granted again to the writers); ``participants(participant, site)`` unique, so that
    sessions can refer to it; the participant ids of old sessions registered to their site
    where they have one site; the foreign key :data:`_SESSION_SITE_FK`, validated when
    the old rows allow it (else it stays NOT VALID: it holds for every new row and
    change, and the analysis refuses to merge the old rows, docs/multisite.md); the
    writers' INSERT and UPDATE by column (:func:`_grant_writer`).
    """
    old = conn.execute("SELECT format_type(prorettype, NULL) FROM pg_catalog.pg_proc WHERE"
                       " oid = to_regprocedure('tactorbelt.claim_participant(text, text)')"
                       ).fetchone()
    if old is not None and old[0] != "boolean":
        conn.execute("DROP FUNCTION tactorbelt.claim_participant(TEXT, TEXT)")
    conn.execute(_CLAIM)
    conn.execute("REVOKE EXECUTE ON FUNCTION tactorbelt.claim_participant(TEXT, TEXT)"
                 " FROM PUBLIC")
    have = {str(r[0]) for r in conn.execute(
        "SELECT conname FROM pg_catalog.pg_constraint WHERE connamespace ="
        " 'tactorbelt'::regnamespace").fetchall()}
    if "participants_participant_site" not in have:
        conn.execute("ALTER TABLE tactorbelt.participants ADD CONSTRAINT"
                     " participants_participant_site UNIQUE (participant, site)")
    conn.execute("INSERT INTO tactorbelt.participants(participant, site)"
                 " SELECT participant, MIN(site) FROM tactorbelt.sessions"
                 " WHERE site IS NOT NULL GROUP BY participant"
                 " HAVING COUNT(DISTINCT site) = 1 ON CONFLICT (participant) DO NOTHING")
    if _SESSION_SITE_FK not in have:
        conn.execute(f"ALTER TABLE tactorbelt.sessions ADD CONSTRAINT {_SESSION_SITE_FK}"
                     " FOREIGN KEY (participant, site) REFERENCES"
                     " tactorbelt.participants(participant, site) MATCH FULL NOT VALID")
    valid = conn.execute("SELECT convalidated FROM pg_catalog.pg_constraint WHERE conname=%s"
                         " AND connamespace = 'tactorbelt'::regnamespace",
                         (_SESSION_SITE_FK,)).fetchone()[0]
    if not valid:
        import psycopg

        with contextlib.suppress(psycopg.errors.ForeignKeyViolation), conn.transaction():
            conn.execute(f"ALTER TABLE tactorbelt.sessions VALIDATE CONSTRAINT"
                         f" {_SESSION_SITE_FK}")
    for (role,) in conn.execute(
            "SELECT w.role_name FROM tactorbelt.site_writers w"
            " JOIN pg_catalog.pg_roles r ON r.rolname = w.role_name").fetchall():
        _grant_writer(conn, str(role))


def _grant_writer(c: Any, role: str) -> None:
    """A site writer's privileges: read what row-level security shows it, write its own
    site's rows, claim participant ids; INSERT without the identity columns and UPDATE of
    the columns a run changes (:data:`_WRITER_NO_INSERT`, :data:`_WRITER_UPDATE`; a
    trial's columns but its ids), given by column (from the catalog: run
    :func:`setup_access` again after an upgrade that adds columns)."""
    from psycopg import sql

    r = sql.Identifier(role)
    c.execute(sql.SQL("GRANT USAGE ON SCHEMA tactorbelt TO {}").format(r))
    c.execute(sql.SQL("GRANT SELECT ON tactorbelt.meta, tactorbelt.site_writers TO {}")
              .format(r))
    c.execute(sql.SQL("GRANT SELECT, INSERT, UPDATE, DELETE ON tactorbelt.samples,"
                      " tactorbelt.run_options, tactorbelt.ratings TO {}").format(r))
    for table, no_insert in _WRITER_NO_INSERT.items():
        t = sql.Identifier("tactorbelt", table)
        cols = [str(x[0]) for x in c.execute(
            "SELECT attname FROM pg_catalog.pg_attribute WHERE attrelid = %s::regclass"
            " AND attnum > 0 AND NOT attisdropped ORDER BY attnum",
            (f"tactorbelt.{table}",)).fetchall()]
        update = _WRITER_UPDATE.get(table, ())
        if table == "trials":  # (a row lock needs UPDATE on a column)
            update = tuple(x for x in cols if x not in (*no_insert, "session_id"))
        c.execute(sql.SQL("REVOKE INSERT, UPDATE ON {} FROM {}").format(t, r))
        c.execute(sql.SQL("GRANT SELECT, DELETE ON {} TO {}").format(t, r))
        c.execute(sql.SQL("GRANT INSERT ({}) ON {} TO {}").format(
            sql.SQL(", ").join(sql.Identifier(x) for x in cols if x not in no_insert), t, r))
        if update:
            c.execute(sql.SQL("GRANT UPDATE ({}) ON {} TO {}").format(
                sql.SQL(", ").join(sql.Identifier(x) for x in update), t, r))
    c.execute(sql.SQL("GRANT EXECUTE ON FUNCTION tactorbelt.claim_participant(TEXT, TEXT)"
                      " TO {}").format(r))


def setup_access(store: PostgreSQLStore, *, writers: Mapping[str, str] | None = None,
                 analysts: Sequence[str] = ()) -> None:
    """Row-level security: each role of ``writers`` (role -> site) may insert and read
    its own site's sessions, trials and samples and nothing else; ``analysts`` read
    everything and write nothing. Run by the store's owner; the roles must exist
    (``CREATE ROLE name LOGIN``). Idempotent; see docs/multisite.md."""
    from psycopg import sql

    own_session = ("site IN (SELECT site FROM tactorbelt.site_writers"
                   " WHERE role_name = current_user)")
    own_trial = "session_id IN (SELECT session_id FROM tactorbelt.sessions)"
    own_sample = "trial_id IN (SELECT trial_id FROM tactorbelt.trials)"
    writers = dict(writers or {})
    with store._transaction("set up access in") as c:
        for role, site in writers.items():
            c.execute("INSERT INTO tactorbelt.site_writers(role_name, site) VALUES (%s, %s)"
                      " ON CONFLICT (role_name) DO UPDATE SET site=EXCLUDED.site", (role, site))
        for table, cond in (("sessions", own_session), ("trials", own_trial),
                            ("samples", own_sample), ("run_options", own_trial),
                            ("task_events", own_trial), ("ratings", own_trial)):
            c.execute(f"ALTER TABLE tactorbelt.{table} ENABLE ROW LEVEL SECURITY")
            c.execute(f"DROP POLICY IF EXISTS site_writer ON tactorbelt.{table}")
            c.execute(f"CREATE POLICY site_writer ON tactorbelt.{table} FOR ALL"
                      f" USING ({cond}) WITH CHECK ({cond})")
            c.execute(f"DROP POLICY IF EXISTS analyst_read ON tactorbelt.{table}")
            c.execute(f"CREATE POLICY analyst_read ON tactorbelt.{table} FOR SELECT"
                      " USING (pg_has_role(current_user, 'tactorbelt_analyst', 'MEMBER'))")
        c.execute("ALTER TABLE tactorbelt.participants ENABLE ROW LEVEL SECURITY")
        c.execute("SELECT 1 FROM pg_roles WHERE rolname='tactorbelt_analyst'")
        if c.fetchone() is None:
            c.execute("CREATE ROLE tactorbelt_analyst NOLOGIN")
        for role in writers:
            _grant_writer(c, role)
        for role in analysts:
            r = sql.Identifier(role)
            c.execute(sql.SQL("GRANT tactorbelt_analyst TO {}").format(r))
            c.execute(sql.SQL("GRANT USAGE ON SCHEMA tactorbelt TO {}").format(r))
            c.execute(sql.SQL("GRANT SELECT ON ALL TABLES IN SCHEMA tactorbelt TO {}")
                      .format(r))
