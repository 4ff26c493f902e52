"""The store: what the runner, export, analysis and the model study use, written once.

Every store is an SQL store: :class:`Store` is the interface and its one implementation
over a :class:`~.schema.Dialect` (its class attribute ``dialect``); the queries are
written in SQLite's spelling and :meth:`~.schema.Dialect.sql` gives the dialect's. A
subclass (:class:`~.sqlite.SQLiteStore`, :class:`~.postgresql.PostgreSQLStore`) brings
the connection and what only its database does:

- ``_transaction(what)``: a context manager giving an object with ``execute`` and
  ``executemany`` (the connection, a cursor), committing at its end, rolling back and
  raising StoreError (``cannot {what} {url}: ...``) on a database error;
- ``_read_error()``: the driver's error class (a failed read is StoreError);
- ``_write_samples(c, trial_id, result)``: the sample rows of a trial (SQLite's
  multi-row INSERTs, PostgreSQL's COPY);
- hooks with a default here: ``_put_trial`` (how an earlier row of the trial is found:
  a row lock first, or an INSERT that fails on the UNIQUE key), ``_claim`` (participant
  ids owned by a site), ``_stream`` (rows without holding them all: a server-side
  cursor in PostgreSQL);
- what only some stores can (multi-site claims, batched commits, copied sessions: see
  :class:`~.base.StoreCapabilities`), the rest refusing with StoreError.

:func:`open_store` picks the implementation by URL (:data:`~.base.BACKENDS`).
"""

from __future__ import annotations

import abc
import contextlib
import json
import uuid
from collections.abc import Iterator, Mapping, Sequence
from contextlib import AbstractContextManager
from pathlib import Path
from typing import TYPE_CHECKING, Any, ClassVar

from ..._errors import StoreError
from ..._registry import check_option, resolve
from ...factors import added_factors
from ..provenance import default_site
from ..schedule import ScheduledTrial, schedule_from_json, schedule_to_json
from ..trial import TrialResult
from .base import (
    BACKENDS,
    RATING_COLUMNS,
    SESSION_STATUSES,
    TASK_EVENT_COLUMNS,
    TRIAL_STATUSES,
    StoreCapabilities,
    rating_value,
    utc_now,
)
from .schema import Dialect
from .schema import table as schema_table

if TYPE_CHECKING:
    from ...tasks.schedule import TaskEvent
    from ..study import Study

__all__ = ["TRIAL_COLUMNS", "Store", "backend_for", "open_store"]

#: The columns a run writes of a trial row, in the order of :meth:`Store.write_trial`.
#: The added factors' columns follow them (:meth:`Store.write_trial`).
TRIAL_COLUMNS = tuple(c.name for c in schema_table("trials", added=False).columns
                      if c.name != "trial_id")
_ATTEMPTS = TRIAL_COLUMNS.index("attempts")
#: The tables :meth:`Store.table_columns` reads.
_TABLES = ("sessions", "trials", "samples", "task_events", "ratings")
#: meta key of the run options kept with a session, where they have no table of their own
_RUN_OPTIONS_KEY = "run_options:{}"
#: meta key of a session whose trials were committed in batches (provenance.commit_mode)
COMMITS_KEY = "commits:{}"


class Store(abc.ABC):
    """An open session store (see the module doc). Close it (or use ``with``) when done.

    ``Store.open(url, create=True, readonly=False)`` is :func:`open_store`.
    """

    #: What this implementation offers (a class attribute of each implementation).
    capabilities: StoreCapabilities
    #: Where the store is, as given when it was opened (a path for SQLite).
    url: str
    #: The store's file when :attr:`StoreCapabilities.file` (else None).
    path: Path | None
    #: Opened read-only: every write raises StoreError.
    readonly: bool

    #: How this store's database spells the schema and the queries.
    dialect: ClassVar[Dialect]
    conn: Any

    def __init__(self, url: str, path: Path | None, conn: Any, readonly: bool) -> None:
        self.url = url
        self.path = path
        self.conn = conn
        self.readonly = readonly
        self._closed = False
        self._tables: set[str] = set()  # tables seen (a table is never dropped)
        # the factors declared beyond the built-in ones, as the store was opened
        self._added = added_factors()
        self._insert_trial_sql = self.dialect.insert(
            "trials", TRIAL_COLUMNS + tuple(f.column for f in self._added))

    # -- opening -----------------------------------------------------------------------
    @classmethod
    def open(cls, url: str | Path, create: bool = True, readonly: bool = False,
             verify: bool = True) -> Store:
        """Open a store; on :class:`Store` itself the URL picks the implementation."""
        impl = backend_for(url) if cls is Store else cls
        return impl.open_url(url, create=create, readonly=readonly, verify=verify)

    @classmethod
    @abc.abstractmethod
    def open_url(cls, url: str | Path, *, create: bool, readonly: bool,
                 verify: bool) -> Store:
        """Open this implementation's store at ``url`` (see :func:`open_store`)."""

    def close(self) -> None:
        """Release the store (and, for a file store, leave only its file). Idempotent."""
        if self._closed:
            return
        self._closed = True
        with contextlib.suppress(Exception):
            self.conn.close()

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- what a subclass brings ------------------------------------------------------
    def _transaction(self, what: str = "write to") -> AbstractContextManager[Any]:
        raise NotImplementedError

    def _read_error(self) -> type[Exception]:
        """The driver's error class of a failed read."""
        raise NotImplementedError

    def _write_samples(self, c: Any, trial_id: int, result: TrialResult) -> None:
        raise NotImplementedError

    def _claim(self, c: Any, participant: str, site: str) -> None:  # noqa: B027
        """Claim a participant id for ``site`` (a store of one site takes any id)."""

    # -- helpers ---------------------------------------------------------------------
    @contextlib.contextmanager
    def _reading(self) -> Iterator[None]:
        """A database error in it is raised as StoreError ``cannot read {url}: ...``."""
        try:
            yield
        except self._read_error() as exc:
            raise StoreError(f"cannot read {self.url}: {str(exc).strip()}") from None

    def _query(self, sql: str, args: Sequence[Any] = ()) -> list[Any]:
        """The rows of a query (they index like tuples)."""
        with self._reading():
            return list(self.conn.execute(sql, tuple(args)).fetchall())

    def _dicts(self, sql: str, args: Sequence[Any] = ()) -> list[dict[str, Any]]:
        """The rows of a query as dicts."""
        with self._reading():
            cur = self.conn.execute(sql, tuple(args))
            names = [d[0] for d in cur.description]
            return [dict(zip(names, r, strict=True)) for r in cur]

    def _stream(self, sql: str, args: Sequence[Any]) -> Iterator[Sequence[Any]]:
        """The rows of a query, without holding them all."""
        with self._reading():
            yield from self.conn.execute(sql, tuple(args))

    def _sql(self, text: str) -> str:
        return self.dialect.sql(text)

    def _select(self, what: str, table: str, column: str, value: Any,
                order: str) -> list[dict[str, Any]]:
        """``what`` of ``table``'s rows (those whose ``column`` is ``value``, unless it is
        None) ordered by ``order``, as dicts."""
        where, args = ("", ()) if value is None else (f" WHERE {column}=?", (value,))
        return self._dicts(self._sql(f"SELECT {what} FROM {table}{where} ORDER BY {order}"),
                           args)

    def _new_id(self, c: Any, sql: str, values: Sequence[Any], key: str) -> int:
        """Run an INSERT of one row; the new row's ``key`` (its id)."""
        if self.dialect.returning:
            return int(c.execute(f"{sql} RETURNING {key}", values).fetchone()[0])
        return int(c.execute(sql, values).lastrowid or 0)

    def _insert(self, c: Any, name: str, row: Mapping[str, Any], key: str) -> int:
        """Insert ``row`` into table ``name``; the new row's ``key``."""
        return self._new_id(c, self.dialect.insert(name, list(row)), list(row.values()), key)

    def _has_table(self, name: str) -> bool:
        """Whether the store has table ``name`` (a store of an older schema, opened
        read-only, may lack the newer ones; a writer has migrated it)."""
        if name not in self._tables:
            self._tables = {str(r[0]) for r in self._query(self._sql(self.dialect.tables_query))}
        return name in self._tables

    # -- sessions ----------------------------------------------------------------------
    def create_session(
        self, *, participant: str, study_name: str, study_toml: str, study_sha256: str,
        seed: int, condition_order: list[str], schedule: list[ScheduledTrial],
        belt: str | None = None, firmware_version: str | None = None,
        calibration: Any = None, package_version: str | None = None,
        git_commit: str | None = None, host: str | None = None, input: str | None = None,
        clock: str | None = None, site: str | None = None, session_uuid: str | None = None,
    ) -> int:
        """Record a new session (status ``running``) with its provenance; return its id.

        Raises:
            StoreError: the participant id is taken at another site, or the write failed.
        """
        site = site or default_site()
        with self._transaction() as c:
            self._claim(c, participant, site)
            (n,) = c.execute(self._sql("SELECT COALESCE(MAX(session_number), 0) FROM sessions"
                                       " WHERE participant=?"), (participant,)).fetchone()
            row = {
                "participant": participant, "session_number": int(n) + 1,
                "study_name": study_name, "study_sha256": study_sha256,
                "study_toml": study_toml, "seed": int(seed),
                "condition_order": json.dumps(condition_order),
                "schedule_json": schedule_to_json(schedule), "n_trials": len(schedule),
                "belt": belt, "firmware_version": firmware_version,
                "calibration_json": None if calibration is None else json.dumps(calibration),
                "package_version": package_version, "git_commit": git_commit, "host": host,
                "input": input, "clock": clock, "started_at": utc_now(), "status": "running",
                "site": site, "session_uuid": session_uuid or str(uuid.uuid4()),
            }
            return self._insert(c, "sessions", row, "session_id")

    def mark_resumed(self, session_id: int) -> None:
        """A resumed session is ``running`` again (and counts one more resume)."""
        with self._transaction() as c:
            c.execute(self._sql("UPDATE sessions SET status='running', ended_at=NULL,"
                                " resumed=resumed+1 WHERE session_id=?"), (session_id,))

    def set_status(self, session_id: int, status: str) -> None:
        """Set a session's status; any status but ``running`` also sets ``ended_at``."""
        check_option("session status", status, SESSION_STATUSES, StoreError)
        with self._transaction() as c:
            c.execute(self._sql("UPDATE sessions SET status=?, ended_at=? WHERE session_id=?"),
                      (status, None if status == "running" else utc_now(), session_id))

    def sessions(self, participant: str | None = None) -> list[dict[str, Any]]:
        """Every session (of one participant), oldest first."""
        return self._select("*", "sessions", "participant", participant, "session_id")

    def session(self, session_id: int) -> dict[str, Any]:
        """One session row as a dict."""
        rows = self._dicts(self._sql("SELECT * FROM sessions WHERE session_id=?"),
                           (session_id,))
        if not rows:
            raise StoreError(f"{self.url}: no session {session_id}")
        return rows[0]

    def find_resumable(self, participant: str) -> dict[str, Any] | None:
        """The participant's latest session that is not complete, or None."""
        rows = self._dicts(self._sql("SELECT * FROM sessions WHERE participant=? AND"
                                     " status<>'complete' ORDER BY session_id DESC LIMIT 1"),
                           (participant,))
        return rows[0] if rows else None

    def finished_indices(self, session_id: int) -> set[int]:
        """trial_index of every trial with a final outcome (``done`` or ``timeout``)."""
        rows = self._query(self._sql("SELECT trial_index FROM trials WHERE session_id=?"
                                     " AND status IN ('done','timeout')"), (session_id,))
        return {int(r[0]) for r in rows}

    def set_run_options(self, session_id: int, options: Mapping[str, Any]) -> None:
        """Keep how a session was run (input, belt, window options; JSON values), so a
        resume can reuse them. Replaces what was kept before."""
        text = json.dumps(dict(options))
        if not self.dialect.has("multisite"):
            self._set_meta(_RUN_OPTIONS_KEY.format(session_id), text)
            return
        with self._transaction() as c:  # a site's writer may not write meta
            c.execute(self.dialect.upsert("run_options", ("session_id", "options"),
                                          ("session_id",)), (session_id, text))

    def run_options(self, session_id: int) -> dict[str, Any] | None:
        """The options kept by :meth:`set_run_options`, or None (older sessions)."""
        if self.dialect.has("multisite"):
            rows = self._query(self._sql("SELECT options FROM run_options"
                                         " WHERE session_id=?"), (session_id,))
            text = str(rows[0][0]) if rows else None
        else:
            text = self._meta(_RUN_OPTIONS_KEY.format(session_id))
        if text is None:
            return None
        opts: dict[str, Any] = json.loads(text)
        return opts

    def _set_meta(self, key: str, value: str) -> None:
        with self._transaction() as c:
            c.execute(self.dialect.upsert("meta", ("key", "value"), ("key",)), (key, value))

    def _meta(self, key: str) -> str | None:
        if not self._has_table("meta"):
            return None  # a bare store (written by other tools) keeps no meta rows
        rows = self._query(self._sql("SELECT value FROM meta WHERE key=?"), (key,))
        return str(rows[0][0]) if rows else None

    def commit_mode(self, session_id: int) -> str:
        """``per-trial`` or ``batched`` (see ``provenance.commit_mode``): how the
        session's trials were committed (``batched`` when any run of it batched)."""
        return self._meta(COMMITS_KEY.format(session_id)) or "per-trial"

    # -- wearer profiles (the perceptual calibration) ------------------------------------
    def save_wearer_profile(self, participant: str, toml_text: str) -> None:
        """Keep a participant's wearer profile (TOML text), replacing an older one."""
        self._set_meta(f"wearer_profile:{participant}", toml_text)

    def wearer_profile(self, participant: str) -> str | None:
        """The participant's wearer profile (TOML text), or None."""
        return self._meta(f"wearer_profile:{participant}")

    def set_session_profile(self, session_id: int, toml_text: str) -> None:
        """Record the wearer profile a session was run with (its provenance)."""
        self._set_meta(f"session_profile:{session_id}", toml_text)

    def session_profile(self, session_id: int) -> str | None:
        """The wearer profile a session was run with (TOML text), or None."""
        return self._meta(f"session_profile:{session_id}")

    def schedule(self, session_id: int, study: Study | None = None) -> list[ScheduledTrial]:
        """The stored schedule of a session (``study`` fills in the target count and
        load of a schedule stored before factorial designs)."""
        return schedule_from_json(self.session(session_id)["schedule_json"], study)

    # -- trials ------------------------------------------------------------------------
    def write_trial(self, session_id: int, result: TrialResult, *,
                    skin_onset_ns: int | None = None,
                    skin_onset_sd_ns: int | None = None) -> int:
        """Write a trial and its samples in one transaction; return its trial_id.

        An earlier ``aborted`` row of the same trial is replaced (with its samples).
        ``skin_onset_ns``, ``skin_onset_sd_ns``: the onset at the skin and its spread, or
        None .

        Raises:
            StoreError: the trial already has a final row, or the write failed.
        """
        t = result.trial
        if result.status not in TRIAL_STATUSES:
            raise StoreError(f"unknown trial status {result.status!r}")
        if result.samples_released:
            raise StoreError(f"trial {t.trial_index}: its samples were released from memory "
                             "after it was stored; it cannot be written again")
        values = [  # in the order of TRIAL_COLUMNS
            session_id, t.trial_index, t.block, t.block_index, t.block_name,
            t.condition, t.repetition, t.target_deg, int(t.on_tactor),
            result.response_deg, result.response_target_deg,
            None if result.correct is None else int(result.correct),
            result.rt_s, result.onset_ns, result.acquired_ns, result.crossed_ns,
            result.stimulus_off_ns, result.n_samples, result.status,
            result.abort_reason, None, utc_now(), t.n_targets or None, t.load or "none",
            result.device_onset_ns, result.onset_uncertainty_ns,
            None if skin_onset_ns is None else int(skin_onset_ns),
            None if skin_onset_sd_ns is None else int(skin_onset_sd_ns),
            *(t.level(f) for f in self._added),
        ]
        with self._transaction(f"write trial {t.trial_index} to") as c:
            trial_id = self._put_trial(c, session_id, t.trial_index, values)
            if result.n_samples:
                self._write_samples(c, trial_id, result)
            return trial_id

    def _put_trial(self, c: Any, session_id: int, trial_index: int,
                   values: list[Any]) -> int:
        """Insert a trial row (``values`` of :data:`TRIAL_COLUMNS`) in place of an aborted
        one; its trial_id. Here: the earlier row, locked, first."""
        return self._insert_trial_row(
            c, values, self._replace_aborted(c, session_id, trial_index) or 1)

    def _insert_trial_row(self, c: Any, values: list[Any], attempts: int) -> int:
        values[_ATTEMPTS] = attempts
        return self._new_id(c, self._insert_trial_sql, values, "trial_id")

    def _replace_aborted(self, c: Any, session_id: int, trial_index: int) -> int | None:
        """Delete the trial's earlier ``aborted`` row (and its samples); the attempt the new
        row is, or None when there is no earlier row. StoreError for a final one."""
        old = c.execute(self._sql("SELECT trial_id, status, attempts FROM trials"
                                  " WHERE session_id=? AND trial_index=?") + self.dialect.lock,
                        (session_id, trial_index)).fetchone()
        if old is None:
            return None
        if old[1] != "aborted":
            raise StoreError(f"trial {trial_index} of session {session_id} is already "
                             f"recorded ({old[1]}); a trial is never written twice")
        c.execute(self._sql("DELETE FROM samples WHERE trial_id=?"), (old[0],))
        c.execute(self._sql("DELETE FROM trials WHERE trial_id=?"), (old[0],))
        return int(old[2]) + 1

    def trials(self, session_id: int | None = None) -> list[dict[str, Any]]:
        """Trial rows (of one session), in the order they were recorded."""
        return self._select("*", "trials", "session_id", session_id, "trial_id")

    def samples(self, trial_id: int) -> list[tuple[float, float, float, int]]:
        """(t_s, x, y, buttons) of one trial, in time order."""
        rows = self._query(self._sql("SELECT t_s, x, y, buttons FROM samples WHERE trial_id=?"
                                     f" ORDER BY {self.dialect.order('samples')}"),
                           (trial_id,))
        return [(r[0], r[1], r[2], r[3]) for r in rows]

    # -- secondary tasks and workload ratings ------------------------------------------
    def write_task_events(self, session_id: int, events: Sequence[TaskEvent]) -> None:
        """Append a task run's events in one transaction (all or none)."""
        b = self.dialect.bool_value
        rows = [(session_id, e.block_index, e.task, e.phase, e.item_index, int(e.t_ns),
                 e.stimulus, b(e.target), e.response, b(e.correct), e.rt_s) for e in events]
        if not rows:
            return
        with self._transaction("write task events to") as c:
            c.executemany(self.dialect.insert("task_events", TASK_EVENT_COLUMNS), rows)

    def task_events(self, session_id: int | None = None) -> list[dict[str, Any]]:
        """``task_events`` rows (of one session) in the order written; [] before schema 3."""
        out = self._rows_of("task_events", TASK_EVENT_COLUMNS, session_id, "event_id")
        for d in out:
            d["target"], d["correct"] = bool(d["target"]), bool(d["correct"])
        return out

    def _rows_of(self, table: str, cols: Sequence[str], session_id: int | None,
                 order: str) -> list[dict[str, Any]]:
        """``cols`` of ``table``'s rows (of one session) as dicts; [] without the table."""
        if not self._has_table(table):
            return []
        return self._select(", ".join(cols), table, "session_id", session_id, order)

    def write_ratings(self, session_id: int, block_index: int, scale: str,
                      values: Mapping[str, float]) -> None:
        """Replace a block's ratings of ``scale`` with ``values`` (one transaction)."""
        rows: list[tuple[Any, ...]] = [(session_id, block_index, scale, str(k),
                                        rating_value(k, v)) for k, v in values.items()]
        cols: tuple[str, ...] = RATING_COLUMNS
        if self.dialect.has("order_columns"):
            cols += ("rating_order",)
            rows = [(*r, i) for i, r in enumerate(rows)]
        with self._transaction("write ratings to") as c:
            c.execute(self._sql("DELETE FROM ratings WHERE session_id=? AND block_index=?"
                                " AND scale=?"), (session_id, block_index, scale))
            c.executemany(self.dialect.insert("ratings", cols), rows)

    def ratings(self, session_id: int | None = None) -> list[dict[str, Any]]:
        """``ratings`` rows (of one session) by session, block and order written; []
        before schema 3."""
        return self._rows_of("ratings", RATING_COLUMNS, session_id,
                             f"session_id, block_index, {self.dialect.order('ratings')}")

    # -- bulk reads --------------------------------------------------------------------
    def table_columns(self, table: str) -> list[str]:
        """Column names of ``sessions``, ``trials``, ``samples``, ``task_events`` or
        ``ratings`` ([] when absent)."""
        check_option("table", table, _TABLES, StoreError)
        return [str(r[0]) for r in self._query(self._sql(self.dialect.columns_query),
                                               (table,))]

    def read_table(self, table: str, columns: Sequence[str]) -> list[tuple[Any, ...]]:
        """Rows of ``sessions`` (by session_id) or ``trials`` (by session_id, trial_id).

        Only the given columns, in that order; for the analysis, which reads stores
        that may hold only the columns the schema requires.
        """
        order = {"sessions": "session_id", "trials": "session_id, trial_id"}.get(table)
        if order is None:
            raise StoreError(f"read_table reads sessions or trials, not {table!r}")
        have = set(self.table_columns(table))
        bad = [c for c in columns if c not in have]
        if bad:
            raise StoreError(f"{self.url}: table {table} lacks column(s) {', '.join(bad)}")
        rows = self._query(self._sql(f"SELECT {', '.join(columns)} FROM {table}"
                                     f" ORDER BY {order}"))
        return [tuple(r) for r in rows]

    def samples_of(self, trial_ids: Sequence[int]) -> list[tuple[int, float, float, float, int]]:
        """``(trial_id, t_s, x, y, buttons)`` of some trials, by trial_id and time."""
        ids = sorted({int(t) for t in trial_ids})
        step = self.dialect.max_in or max(1, len(ids))
        order = f"trial_id, t_s, {self.dialect.order('samples')}"
        out: list[tuple[int, float, float, float, int]] = []
        for start in range(0, len(ids), step):
            cond, args = self.dialect.any_of(ids[start:start + step])
            rows = self._query(self._sql("SELECT trial_id, t_s, x, y, buttons FROM samples"
                                         f" WHERE trial_id {cond} ORDER BY {order}"), args)
            out += [(r[0], r[1], r[2], r[3], r[4]) for r in rows]
        return out

    def iter_samples(self, session_id: int | None = None
                     ) -> Iterator[tuple[int, int, float, float, float, int]]:
        """``(session_id, trial_index, t_s, x, y, buttons)`` of every sample (of one
        session), by session, trial_id and time; streamed, never all in memory."""
        sql = ("SELECT t.session_id, t.trial_index, p.t_s, p.x, p.y, p.buttons"
               " FROM samples p JOIN trials t USING (trial_id)")
        args: tuple[Any, ...] = ()
        if session_id is not None:
            sql += " WHERE t.session_id=?"
            args = (session_id,)
        sql += f" ORDER BY t.session_id, t.trial_id, p.{self.dialect.order('samples')}"
        for r in self._stream(self._sql(sql), args):
            yield (r[0], r[1], r[2], r[3], r[4], r[5])

    # -- multi-site stores, batched commits, copied sessions (defaults: none) ---------
    def claim_participant(self, participant: str, site: str) -> None:
        """Refuse (StoreError) a participant id that another site already uses. A store
        of one site (SQLite) takes any id."""
        return None

    def check_site(self, site: str) -> None:
        """Refuse (StoreError) unless this login may write sessions of ``site``; writes
        nothing. A store of one site (SQLite) takes any site."""
        return None

    def begin_batch(self, session_id: int, every: int) -> None:
        """From now on commit writes every ``every`` trials (and at :meth:`end_batch`)
        instead of each trial; record that session ``session_id`` batched its commits
        (:meth:`commit_mode`). Only for sessions with nothing real involved."""
        raise StoreError(f"the {self.capabilities.backend} store commits every trial")

    def end_batch(self) -> None:  # noqa: B027 - a store without batches has none to end
        """Commit what the batch holds and go back to a commit per write. Safe to call
        when no batch is open."""

    def sync_state(self, session_uuid: str
                   ) -> tuple[int, dict[str, Any], dict[int, tuple[str, int]]] | None:
        """``(session_id, {ended_at, status, resumed}, {trial_index: (status, attempts)})``
        of the session with this uuid here, or None."""
        raise StoreError(f"{self.url}: this store does not take copied sessions")

    def import_session(self, row: Mapping[str, Any]) -> int:
        """Insert a session row of another store (keyed by ``session_uuid``) or update
        its status, ended_at and resumed; return its id here."""
        raise StoreError(f"{self.url}: this store does not take copied sessions")

    def import_trial(self, session_id: int, row: Mapping[str, Any],
                     samples: Sequence[Sequence[Any]]) -> bool:
        """Copy a trial row of another store and its ``(t_s, x, y, buttons)`` samples in
        one transaction; False when it is here already (nothing written)."""
        raise StoreError(f"{self.url}: this store does not take copied sessions")

    def import_task_events(self, session_id: int, rows: Sequence[Mapping[str, Any]]) -> int:
        """Make session ``session_id``'s task events those of another store's copy of it
        (``task_events`` rows, in the order written; they are only ever appended, so a
        copy with as many is up to date). One transaction; the rows written (0: none)."""
        raise StoreError(f"{self.url}: this store does not take copied sessions")

    def import_ratings(self, session_id: int, rows: Sequence[Mapping[str, Any]]) -> int:
        """Make session ``session_id``'s ratings those of another store's copy of it
        (``ratings`` rows). One transaction; the rows written (0: the same already)."""
        raise StoreError(f"{self.url}: this store does not take copied sessions")


def backend_for(url: str | Path) -> type[Store]:
    """The :class:`Store` class for a URL (a bare path, or a Windows drive letter, is
    ``sqlite``).

    Raises:
        StoreError: the scheme is unknown.
    """
    text = str(url)
    scheme = ("sqlite" if isinstance(url, Path) or "://" not in text
              else text.split("://", 1)[0].lower().split("+", 1)[0])
    scheme = {"postgres": "postgresql"}.get(scheme, scheme)
    if scheme not in BACKENDS:
        raise StoreError(f"unknown store URL scheme {scheme!r} in {url}; give a file path, "
                         f"sqlite:///path or one of: {', '.join(sorted(BACKENDS))}")
    store_cls: type[Store] = resolve(BACKENDS[scheme])
    return store_cls


def open_store(url: str | Path, create: bool = True, readonly: bool = False,
               verify: bool = True) -> Store:
    """Open (and with ``create`` make) the store at ``url`` for writing, or read-only.

    Args:
        url: a path (``study.sqlite``), ``sqlite:///abs/path`` or
            ``sqlite:relative/path``, or ``postgresql://user@host/dbname``.
        create: make the store (its schema) when it does not exist.
        readonly: open for reading only; nothing is written, no lock is taken.
        verify: check the store's integrity when opening (a full scan of an SQLite
            file; readers of very large stores may skip it).

    Raises:
        StoreError: unknown or unavailable scheme, or the store cannot be opened (see
            the implementation's ``open``). Raised before anything is written.
    """
    return Store.open(url, create=create, readonly=readonly, verify=verify)
