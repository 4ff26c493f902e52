"""The SQLite store: one file holding sessions, trials and cursor samples.

Schema (docs/study.md, "The store", plus provenance columns)::

    meta(key, value)                                  schema_version
    sessions(session_id, participant, session_number, study_name, study_sha256,
             study_toml, seed, condition_order, schedule_json, n_trials, belt,
             firmware_version, calibration_json, package_version, git_commit, host,
             input, clock, started_at, ended_at, status, resumed)
    trials(trial_id, session_id, trial_index, block, block_index, block_name, condition,
           repetition, target_deg, on_tactor, response_deg, response_target_deg, correct,
           rt_s, onset_ns, acquired_ns, crossed_ns, stimulus_off_ns, n_samples,
           status, abort_reason, attempts, recorded_at, n_targets, load,
           device_onset_ns, onset_uncertainty_ns)             UNIQUE(session_id, trial_index)
    samples(trial_id, t_s, x, y, buttons)
    task_events(event_id, session_id, block_index, task, phase, item_index, t_ns,
                stimulus, target, response, correct, rt_s)          (schema 3)
    ratings(session_id, block_index, scale, item, value)
                                      PRIMARY KEY(session_id, block_index, scale, item)

Durability: while a writer has the store open it is in WAL mode with
``synchronous=FULL``, and each trial is one transaction holding the trial row and all
its samples, so a process killed at any moment loses at most the trial in flight.
The one exception: a session with nothing real involved (simulated clock, sim belt,
model participant, no window; ``provenance.commit_mode``) commits its writes in
batches (:meth:`SQLiteStore.begin_batch`, each write a savepoint), which a rerun with
the same seed reproduces; the meta row ``commits:<session_id>`` = ``batched`` says so. An
``aborted`` row is replaced (with its samples) when the trial is run again; a ``done``
or ``timeout`` row is never written twice.

Files: only one run may write a store at a time: opening for writing takes an
exclusive ``flock`` on ``<file>.lock`` and fails at once, before anything is written,
when another run holds it. A clean close checkpoints the WAL into the file, switches
the file back to the rollback journal (so later readers create no ``-wal``/``-shm``)
and removes the lock file: what stays on disk is the store file alone. After a crash
the ``-wal`` (with the last committed trials) and the lock file stay; the next open
recovers them.

:func:`create_bare_store` writes a bare store with only the columns the analysis
requires (synthetic data for tests and benchmarks); :func:`move_store_file` moves a
closed store (with any WAL files) aside.

I/O edge of the experiment package: imports sqlite3, fcntl and the pure experiment
modules; never devices, inputs or the window.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import shutil
import sqlite3
import stat
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..._errors import StoreError
from ..schedule import ScheduledTrial, schedule_from_json, schedule_to_json
from ..trial import TrialResult

if TYPE_CHECKING:
    from ...tasks.schedule import TaskEvent
    from ..study import Study
from .base import (
    RATING_COLUMNS,
    SCHEMA_VERSION,
    SESSION_STATUSES,
    TASK_EVENT_COLUMNS,
    TRIAL_STATUSES,
    Store,
    StoreCapabilities,
    rating_value,
    utc_now,
)

__all__ = ["APPLICATION_ID", "SQLiteStore", "create_bare_store", "move_store_file"]

#: PRAGMA application_id of a tactorbelt store ("TBLT").
APPLICATION_ID = 0x54424C54
#: Files SQLite may keep next to the store while it is open (or after a crash).
SIDE_SUFFIXES = ("-wal", "-shm", "-journal")
#: meta key of the run options kept with a session (input, belt, window options).
_RUN_OPTIONS_KEY = "run_options:{}"
#: meta key of a session whose trials were committed in batches (provenance.commit_mode)
_COMMITS_KEY = "commits:{}"
_TABLES = ("sessions", "trials", "samples", "task_events", "ratings")
#: The tables every store has (older stores may lack the others).
_CORE_TABLES = ("sessions", "trials", "samples")

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta(
    key TEXT PRIMARY KEY,
    value TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS sessions(
    session_id INTEGER PRIMARY KEY AUTOINCREMENT,
    participant TEXT NOT NULL,
    session_number INTEGER NOT NULL,
    study_name TEXT NOT NULL,
    study_sha256 TEXT NOT NULL,
    study_toml TEXT NOT NULL,
    seed INTEGER NOT NULL,
    condition_order TEXT NOT NULL,
    schedule_json TEXT NOT NULL,
    n_trials INTEGER NOT NULL,
    belt TEXT,
    firmware_version TEXT,
    calibration_json TEXT,
    package_version TEXT,
    git_commit TEXT,
    host TEXT,
    input TEXT,
    clock TEXT,
    started_at TEXT NOT NULL,
    ended_at TEXT,
    status TEXT NOT NULL CHECK (status IN ('running','complete','aborted','interrupted')),
    resumed INTEGER NOT NULL DEFAULT 0
);
CREATE TABLE IF NOT EXISTS trials(
    trial_id INTEGER PRIMARY KEY AUTOINCREMENT,
    session_id INTEGER NOT NULL REFERENCES sessions(session_id),
    trial_index INTEGER NOT NULL,
    block TEXT NOT NULL CHECK (block IN ('training','test')),
    block_index INTEGER NOT NULL,
    block_name TEXT NOT NULL,
    condition TEXT NOT NULL,
    repetition INTEGER NOT NULL,
    target_deg REAL NOT NULL,
    on_tactor INTEGER NOT NULL,
    response_deg REAL,
    response_target_deg REAL,
    correct INTEGER,
    rt_s REAL,
    onset_ns INTEGER,
    acquired_ns INTEGER,
    crossed_ns INTEGER,
    stimulus_off_ns INTEGER,
    n_samples INTEGER NOT NULL,
    status TEXT NOT NULL CHECK (status IN ('done','timeout','aborted')),
    abort_reason TEXT,
    attempts INTEGER NOT NULL DEFAULT 1,
    recorded_at TEXT NOT NULL,
    n_targets INTEGER,
    load TEXT,
    device_onset_ns INTEGER,
    onset_uncertainty_ns INTEGER,
    UNIQUE(session_id, trial_index)
);
CREATE TABLE IF NOT EXISTS samples(
    trial_id INTEGER NOT NULL REFERENCES trials(trial_id),
    t_s REAL NOT NULL,
    x REAL NOT NULL,
    y REAL NOT NULL,
    buttons INTEGER NOT NULL
);
CREATE TABLE IF NOT EXISTS task_events(
    event_id INTEGER PRIMARY KEY AUTOINCREMENT,
    session_id INTEGER NOT NULL REFERENCES sessions(session_id),
    block_index INTEGER NOT NULL,
    task TEXT NOT NULL,
    phase TEXT NOT NULL CHECK (phase IN ('practice','baseline','dual')),
    item_index INTEGER NOT NULL,
    t_ns INTEGER NOT NULL,
    stimulus TEXT,
    target INTEGER NOT NULL,
    response TEXT NOT NULL,
    correct INTEGER NOT NULL,
    rt_s REAL
);
CREATE TABLE IF NOT EXISTS ratings(
    session_id INTEGER NOT NULL REFERENCES sessions(session_id),
    block_index INTEGER NOT NULL,
    scale TEXT NOT NULL,
    item TEXT NOT NULL,
    value REAL NOT NULL,
    PRIMARY KEY (session_id, block_index, scale, item)
);
CREATE INDEX IF NOT EXISTS task_events_session ON task_events(session_id);
CREATE INDEX IF NOT EXISTS trials_session ON trials(session_id);
CREATE INDEX IF NOT EXISTS samples_trial ON samples(trial_id);
CREATE INDEX IF NOT EXISTS sessions_participant ON sessions(participant);
"""
_TRIAL_COLUMNS = (
    "session_id", "trial_index", "block", "block_index", "block_name", "condition",
    "repetition", "target_deg", "on_tactor", "response_deg", "response_target_deg",
    "correct", "rt_s", "onset_ns", "acquired_ns", "crossed_ns", "stimulus_off_ns",
    "n_samples", "status", "abort_reason", "attempts", "recorded_at", "n_targets", "load",
    "device_onset_ns", "onset_uncertainty_ns",
)
#: Schema migrations: version -> statements that bring version - 1 to it. Rows written
#: before version 2 keep NULL n_targets and load (the analysis reads them as the
#: study's single target count and ``none``) and NULL device onsets. Version 3 adds
#: the tables task_events and ratings (made by the schema's CREATE TABLE IF NOT EXISTS).
_MIGRATIONS: dict[int, tuple[str, ...]] = {
    2: ("ALTER TABLE trials ADD COLUMN n_targets INTEGER",
        "ALTER TABLE trials ADD COLUMN load TEXT",
        "ALTER TABLE trials ADD COLUMN device_onset_ns INTEGER",
        "ALTER TABLE trials ADD COLUMN onset_uncertainty_ns INTEGER"),
}


def _migrate(conn: sqlite3.Connection, version: int) -> None:
    """Bring a store of schema ``version`` to :data:`SCHEMA_VERSION` (inside the opening
    transaction; a column that is already there is left alone)."""
    have = {str(r[1]) for r in conn.execute("PRAGMA table_info(trials)")}
    for v in range(version + 1, SCHEMA_VERSION + 1):
        for stmt in _MIGRATIONS.get(v, ()):
            col = stmt.split("ADD COLUMN ")[1].split()[0]
            if col not in have:
                conn.execute(stmt)


#: Columns added to ``sessions`` for multi-site studies (site, a globally unique id),
#: added to older stores when opened for writing.
_IDENTITY_COLUMNS = ("session_uuid", "site")


def _add_session_identity(conn: sqlite3.Connection) -> None:
    """Add ``sessions.session_uuid`` and ``sessions.site`` when missing and give every
    session without a uuid one (inside the opening transaction)."""
    import uuid

    have = {str(r[1]) for r in conn.execute("PRAGMA table_info(sessions)")}
    for col in _IDENTITY_COLUMNS:
        if col not in have:
            conn.execute(f"ALTER TABLE sessions ADD COLUMN {col} TEXT")
    conn.execute("CREATE UNIQUE INDEX IF NOT EXISTS sessions_uuid ON sessions(session_uuid)")
    for (sid,) in conn.execute("SELECT session_id FROM sessions WHERE session_uuid IS NULL"
                               ).fetchall():
        conn.execute("UPDATE sessions SET session_uuid=? WHERE session_id=?",
                     (str(uuid.uuid4()), sid))


def _read_only(path: Path) -> bool:
    """True when the file cannot or must not be written (no write bit, or no access)."""
    try:
        mode = path.stat().st_mode
    except OSError:
        return False
    return not os.access(path, os.W_OK) or not (mode & (stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))

#: The bare schema of :func:`create_bare_store`: only the columns a store must have.
BARE_SCHEMA = """
CREATE TABLE sessions(
    session_id INTEGER PRIMARY KEY,
    participant TEXT NOT NULL,
    study_name TEXT,
    study_sha256 TEXT,
    study_toml TEXT,
    seed INTEGER,
    condition_order TEXT,
    belt TEXT,
    firmware_version TEXT,
    package_version TEXT,
    started_at TEXT,
    ended_at TEXT,
    status TEXT
);
CREATE TABLE trials(
    trial_id INTEGER PRIMARY KEY,
    session_id INTEGER NOT NULL,
    block TEXT NOT NULL,
    condition TEXT NOT NULL,
    repetition INTEGER,
    trial_index INTEGER,
    target_deg REAL NOT NULL,
    on_tactor INTEGER NOT NULL,
    response_deg REAL,
    response_target_deg REAL,
    correct INTEGER,
    rt_s REAL,
    onset_ns INTEGER,
    status TEXT NOT NULL
);
CREATE TABLE samples(
    trial_id INTEGER NOT NULL,
    t_s REAL NOT NULL,
    x REAL NOT NULL,
    y REAL NOT NULL,
    buttons INTEGER NOT NULL
)
"""
_SAMPLES_INDEX = "CREATE INDEX IF NOT EXISTS samples_trial ON samples(trial_id)"


def _side_files(p: Path) -> list[Path]:
    return [p.with_name(p.name + s) for s in SIDE_SUFFIXES]


def _lock_path(p: Path) -> Path:
    return p.with_name(p.name + ".lock")


def _path_of(url: str | Path) -> Path:
    text = str(url)
    if not isinstance(url, Path) and text.lower().startswith("sqlite://"):
        text = text[len("sqlite://"):]
        if not text:
            raise StoreError(f"{url}: no file in the store URL; give sqlite:///path/study.sqlite")
    return Path(text)


#: Samples are inserted this many rows to a statement (a statement per row costs about
#: twice as much; 100 rows are at most 401 parameters, well within SQLite's limit), the
#: rest of a trial's rows in statements of 64, 32, ..., 1 rows: a handful of statements,
#: each parsed once, where one of every length would be some 100 to parse again after
#: every session (PRAGMA foreign_keys, which begin_batch and end_batch set, makes SQLite
#: prepare every statement anew: ~0.3 ms for one of 100 rows).
_SAMPLE_ROWS_PER_INSERT = 100


def _sample_chunks(n: int) -> list[int]:
    """The row counts of the INSERTs of ``n`` samples, in order: full statements of
    ``_SAMPLE_ROWS_PER_INSERT`` rows, then the rest in powers of two, largest first."""
    full, rest = divmod(n, _SAMPLE_ROWS_PER_INSERT)
    return [_SAMPLE_ROWS_PER_INSERT] * full + [1 << k for k in range(rest.bit_length() - 1,
                                                                        -1, -1) if rest >> k & 1]


_INSERT_TRIAL_SQL = (f"INSERT INTO trials({', '.join(_TRIAL_COLUMNS)}) "
                     f"VALUES ({', '.join('?' * len(_TRIAL_COLUMNS))})")


@functools.lru_cache(maxsize=32)
def _samples_sql(n_rows: int, buttons: bool) -> str:
    """An INSERT of ``n_rows`` samples of one trial: the trial_id is bound once (``?1``),
    then each row's t_s, x, y (and buttons, if any is pressed; else the literal 0)."""
    per = 4 if buttons else 3
    rows = [f"(?1,?{k},?{k + 1},?{k + 2},{f'?{k + 3}' if buttons else '0'})"
            for k in range(2, 2 + per * n_rows, per)]
    return "INSERT INTO samples(trial_id, t_s, x, y, buttons) VALUES " + ",".join(rows)


def _insert_samples(c: sqlite3.Connection, trial_id: int, result: TrialResult) -> None:
    """A trial's samples, in order, ``_SAMPLE_ROWS_PER_INSERT`` rows to a statement (the
    trial_id bound once a statement, and the buttons only when one is pressed: a model's
    samples bind 3 values a row instead of 5, a sixth of the time its samples take)."""
    t_s = result.sample_times_s()
    n = len(t_s)
    xs, ys, bs = result.sample_x, result.sample_y, result.sample_buttons
    if not (len(xs) == len(ys) == len(bs) == n):
        raise StoreError(f"trial {result.trial.trial_index}: sample columns of unequal length")
    buttons = any(bs)
    per = 4 if buttons else 3
    a = 0
    for rows in _sample_chunks(n):
        b = a + rows
        values: list[Any] = [trial_id] * (1 + per * rows)  # ?1, then the rows' values
        values[1::per] = t_s[a:b]
        values[2::per] = xs[a:b]
        values[3::per] = ys[a:b]
        if buttons:
            values[4::per] = bs[a:b]
        c.execute(_samples_sql(rows, buttons), values)
        a = b


class SQLiteStore(Store):
    """A store in one SQLite file (see the module doc). Open with :func:`open_store`."""

    capabilities = StoreCapabilities(backend="sqlite", file=True, bulk_insert=True,
                                     exclusive_writer=True, batch_commits=True)

    def __init__(self, path: Path, conn: sqlite3.Connection, lock_fd: int | None,
                 readonly: bool) -> None:
        self.url = str(path)
        self.path: Path = path
        self.conn = conn
        self._lock_fd = lock_fd
        self.readonly = readonly
        self._closed = False
        self._batch_every = 0  # writes per commit while a batch is open (0: none open)
        self._batch_pending = 0

    # -- opening -----------------------------------------------------------------------
    @classmethod
    def open_url(cls, url: str | Path, *, create: bool = True, readonly: bool = False,
                 verify: bool = True) -> SQLiteStore:
        """Open (and with ``create`` make) a store for writing, or read-only.

        Raises:
            StoreError: the path is a directory; the file is not SQLite, not a
                tactorbelt store, corrupted or truncated; it is read-only (for
                writing); another run is using it; it was written by a newer
                tactorbelt (for writing); or (``create=False``) it does not exist.
                Raised before anything is written.
        """
        p = _path_of(url)
        if p.is_dir():
            raise StoreError(f"{p} is a directory; give a database file such as {p}/study.sqlite")
        exists = p.exists()
        # The file's header is left to SQLite to check: opening and closing another
        # descriptor on a database file would drop the POSIX locks that other
        # connections of this process hold on it.
        if not exists and (not create or readonly):
            raise StoreError(f"{p}: no such store (no such file); give a store written "
                             "by 'tactorbelt run' or 'tactorbelt demo'")
        if not readonly:
            if exists and _read_only(p):
                raise StoreError(
                    f"{p} is read-only; a run must write every trial. Make it writable "
                    "(chmod u+w) or give another --db"
                )
            parent = p.parent if str(p.parent) else Path(".")
            if not parent.exists():
                raise StoreError(f"cannot create {p}: directory {parent} does not exist")
            if not os.access(parent, os.W_OK):
                raise StoreError(f"cannot write to directory {parent} (needed for {p})")
        lock_path = _lock_path(p)
        made_lock = not readonly and not lock_path.exists()
        lock_fd = None if readonly else cls._lock(p)
        try:
            try:
                conn = cls._connect(p, readonly, verify)
            except sqlite3.DatabaseError as exc:
                raise cls._translate(p, exc) from None
        except BaseException:
            if lock_fd is not None:
                if made_lock:  # leave nothing behind that was not there
                    with contextlib.suppress(OSError):
                        lock_path.unlink()
                os.close(lock_fd)
            raise
        return cls(p, conn, lock_fd, readonly)

    @staticmethod
    def _lock(p: Path) -> int:
        import fcntl

        lock_path = _lock_path(p)
        while True:
            try:
                fd = os.open(lock_path, os.O_RDWR | os.O_CREAT, 0o644)
            except OSError as exc:
                raise StoreError(
                    f"cannot create the lock file {lock_path}: {exc.strerror}") from None
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                holder = ""
                with contextlib.suppress(OSError):
                    holder = os.pread(fd, 200, 0).decode(errors="replace").strip()
                os.close(fd)
                raise StoreError(
                    f"another run is using the store {p}"
                    + (f" ({holder})" if holder else "")
                    + "; wait for it to finish or give another --db"
                ) from None
            # The holder removes the lock file when it closes: a lock taken on a file
            # that was removed meanwhile locks nothing; take it again on the new file.
            try:
                same = os.path.samestat(os.fstat(fd), os.stat(lock_path))
            except OSError:
                same = False
            if same:
                break
            os.close(fd)
        with contextlib.suppress(OSError):
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"pid {os.getpid()}".encode(), 0)
        return fd

    @staticmethod
    def _connect(p: Path, readonly: bool, verify: bool = True) -> sqlite3.Connection:
        conn: sqlite3.Connection | None = None
        try:
            # A read-only store is still opened read-write when the file allows it (and
            # made query_only): a mode=ro connection cannot rebuild a WAL index (-shm)
            # that a writer left behind, and would report a sound file as malformed.
            uri = p.resolve().as_uri()
            if readonly and _read_only(p):
                uri += "?mode=ro"
            try:
                conn = sqlite3.connect(uri, uri=True, isolation_level=None,
                                       check_same_thread=False)
                conn.execute("SELECT count(*) FROM sqlite_master").fetchone()
            except sqlite3.OperationalError as exc:
                if not readonly or "unable to open" not in str(exc):
                    raise
                # A reader in a directory it cannot write (no -shm can be made).
                if conn is not None:
                    conn.close()
                conn = sqlite3.connect(p.resolve().as_uri() + "?immutable=1", uri=True,
                                       isolation_level=None, check_same_thread=False)
            if readonly:
                conn.execute("PRAGMA query_only = ON")
            conn.row_factory = sqlite3.Row
            conn.execute("PRAGMA busy_timeout = 5000")
            if verify:
                check = conn.execute("PRAGMA quick_check").fetchone()[0]
                if check != "ok":
                    raise sqlite3.DatabaseError(check)
            tables = {r[0] for r in conn.execute(
                "SELECT name FROM sqlite_master WHERE type='table'")}
            app_id = conn.execute("PRAGMA application_id").fetchone()[0]
            if tables and "sessions" not in tables:
                raise StoreError(
                    f"{p} is an SQLite database but not a tactorbelt store "
                    f"(tables: {', '.join(sorted(tables))}; a store has tables "
                    f"{', '.join(_CORE_TABLES)}); give another file"
                )
            if "sessions" in tables and app_id not in (0, APPLICATION_ID):
                raise StoreError(f"{p} is not a tactorbelt store (application_id {app_id:#x})")
            if readonly:
                if "sessions" not in tables:
                    raise StoreError(f"{p} is not a tactorbelt store: it holds no tables "
                                     f"(a store has tables {', '.join(_CORE_TABLES)})")
                return conn
            if "meta" in tables:
                version = conn.execute(
                    "SELECT value FROM meta WHERE key='schema_version'").fetchone()
                if version is not None and int(version[0]) > SCHEMA_VERSION:
                    raise StoreError(
                        f"{p} was written by a newer tactorbelt (schema {version[0]}, this "
                        f"one writes {SCHEMA_VERSION}); upgrade tactorbelt to write to it"
                    )
            conn.execute("PRAGMA journal_mode = WAL")
            conn.execute("PRAGMA synchronous = FULL")
            conn.execute("PRAGMA foreign_keys = ON")
            conn.execute("BEGIN IMMEDIATE")
            try:
                for stmt in _SCHEMA.split(";"):
                    if stmt.strip():
                        conn.execute(stmt)
                if app_id != APPLICATION_ID:
                    conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
                row = conn.execute(
                    "SELECT value FROM meta WHERE key='schema_version'").fetchone()
                if "trials" in tables:
                    _migrate(conn, int(row[0]) if row is not None else 1)
                conn.execute("INSERT OR REPLACE INTO meta(key, value) VALUES ('schema_version', ?)",
                             (str(SCHEMA_VERSION),))
                _add_session_identity(conn)
                conn.execute("COMMIT")
            except BaseException:
                conn.execute("ROLLBACK")
                raise
            return conn
        except BaseException:
            if conn is not None:
                with contextlib.suppress(Exception):
                    conn.close()
            raise

    @staticmethod
    def _translate(p: Path, exc: sqlite3.DatabaseError) -> StoreError:
        if "not a database" in str(exc):
            return StoreError(
                f"{p} is not an SQLite database, so not a tactorbelt store; give a store "
                "written by 'tactorbelt run' or 'tactorbelt demo' (a run may also name a new "
                "file, to start a store)"
            )
        if isinstance(exc, sqlite3.OperationalError):
            msg = str(exc)
            if "readonly" in msg or "read-only" in msg:
                return StoreError(f"{p} is read-only: {msg}")
            if "locked" in msg or "busy" in msg:
                return StoreError(f"another process is using the store {p}: {msg}")
            if "malformed" not in msg and "corrupt" not in msg:
                return StoreError(f"cannot open the store {p}: {msg}")
        return StoreError(
            f"{p} is corrupted or truncated ({exc}); restore it from a backup "
            "or give another file"
        )

    def close(self) -> None:
        """Close the database and release the lock, leaving only the store file.

        A writer checkpoints the WAL into the file and switches it back to the rollback
        journal (when no other connection has it open), then removes its lock file.
        Safe to call twice.
        """
        if self._closed:
            return
        with contextlib.suppress(StoreError):
            self.end_batch()
        self._closed = True
        if not self.readonly:
            with contextlib.suppress(sqlite3.Error):
                self.conn.execute("PRAGMA busy_timeout = 0")  # never wait for a reader
                self.conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
                self.conn.execute("PRAGMA journal_mode = DELETE")
        with contextlib.suppress(Exception):
            self.conn.close()
        if self._lock_fd is not None:
            with contextlib.suppress(OSError):
                _lock_path(self.path).unlink()  # while still holding it
            with contextlib.suppress(OSError):
                os.close(self._lock_fd)
            self._lock_fd = None

    # -- helpers -----------------------------------------------------------------------
    @contextlib.contextmanager
    def _transaction(self) -> Iterator[sqlite3.Connection]:
        if self.readonly:
            raise StoreError(f"{self.path} was opened read-only")
        if self._batch_every:
            with self._batched() as conn:
                yield conn
            return
        try:
            self.conn.execute("BEGIN IMMEDIATE")
        except sqlite3.Error as exc:
            raise StoreError(f"cannot write to {self.path}: {exc}") from None
        try:
            yield self.conn
        except BaseException:
            with contextlib.suppress(sqlite3.Error):
                self.conn.execute("ROLLBACK")
            raise
        self._commit()

    def _commit(self) -> None:
        """Commit the open transaction; on failure roll it back and raise StoreError."""
        try:
            self.conn.execute("COMMIT")
        except sqlite3.Error as exc:
            with contextlib.suppress(sqlite3.Error):
                self.conn.execute("ROLLBACK")
            raise StoreError(f"cannot write to {self.path}: {exc}") from None

    @contextlib.contextmanager
    def _batched(self) -> Iterator[sqlite3.Connection]:
        """One write inside the open batch: a savepoint (a failed write undoes itself
        alone); the batch commits after every ``_batch_every`` writes."""
        try:
            if not self.conn.in_transaction:
                self.conn.execute("BEGIN IMMEDIATE")
            self.conn.execute("SAVEPOINT write")
        except sqlite3.Error as exc:
            raise StoreError(f"cannot write to {self.path}: {exc}") from None
        try:
            yield self.conn
        except BaseException:
            with contextlib.suppress(sqlite3.Error):
                self.conn.execute("ROLLBACK TO write")
                self.conn.execute("RELEASE write")
            raise
        try:
            self.conn.execute("RELEASE write")
            self._batch_pending += 1
            if self._batch_pending >= self._batch_every:
                self._batch_pending = 0
                self.conn.execute("COMMIT")
        except sqlite3.Error as exc:
            with contextlib.suppress(sqlite3.Error):
                self.conn.execute("ROLLBACK")
            raise StoreError(f"cannot write to {self.path}: {exc}") from None

    def begin_batch(self, session_id: int, every: int) -> None:
        """Commit every ``every`` writes (trials, status, task events) until
        :meth:`end_batch`; recorded for the session first, in its own commit."""
        if every < 1:
            raise StoreError(f"a batch holds at least one write, got {every}")
        self.end_batch()
        with self._transaction() as c:
            c.execute("INSERT OR REPLACE INTO meta(key, value) VALUES (?, ?)",
                      (_COMMITS_KEY.format(session_id), "batched"))
        # a batch's commits need no fsync: WAL with synchronous=NORMAL never corrupts the
        # file, a power cut may lose the latest batches, which a rerun makes again
        self._pragma("synchronous = NORMAL")
        # each write's savepoint keeps the pages it changes in memory, not in a temporary
        # file (some 35 page writes a trial, a tenth of a batched session's time)
        self._pragma("temp_store = MEMORY")
        # no foreign-key lookup per sample row (a sixth of a batched session's store
        # time): every row a batch writes references its session or the trial row the
        # same write inserted (write_trial), which tests/test_batch_commits.py checks
        self._pragma("foreign_keys = OFF")
        self._batch_every, self._batch_pending = int(every), 0

    def end_batch(self) -> None:
        """Commit the open batch (if any); writes commit one by one again."""
        if not self._batch_every:
            return
        self._batch_every, self._batch_pending = 0, 0
        try:
            if self.conn.in_transaction:
                self._commit()
        finally:  # every later commit is durable again; big sorts go to disk again
            with contextlib.suppress(sqlite3.Error):
                self.conn.execute("PRAGMA synchronous = FULL")
                self.conn.execute("PRAGMA temp_store = DEFAULT")
                self.conn.execute("PRAGMA foreign_keys = ON")

    def _pragma(self, setting: str) -> None:
        try:
            self.conn.execute(f"PRAGMA {setting}")
        except sqlite3.Error as exc:
            raise StoreError(f"cannot set {setting} on {self.path}: {exc}") from None

    def commit_mode(self, session_id: int) -> str:
        rows = self._query("SELECT value FROM meta WHERE key=?",
                           (_COMMITS_KEY.format(session_id),))
        return str(rows[0][0]) if rows else "per-trial"

    def _query(self, sql: str, args: Sequence[Any] = ()) -> list[sqlite3.Row]:
        try:
            return self.conn.execute(sql, tuple(args)).fetchall()
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"cannot read {self.path}: {exc}") from None

    # -- sessions ----------------------------------------------------------------------
    def create_session(
        self,
        *,
        participant: str,
        study_name: str,
        study_toml: str,
        study_sha256: str,
        seed: int,
        condition_order: list[str],
        schedule: list[ScheduledTrial],
        belt: str | None = None,
        firmware_version: str | None = None,
        calibration: Any = None,
        package_version: str | None = None,
        git_commit: str | None = None,
        host: str | None = None,
        input: str | None = None,
        clock: str | None = None,
        site: str | None = None,
        session_uuid: str | None = None,
    ) -> int:
        """Record a new session (status ``running``) with its provenance; return its id."""
        import uuid

        from ..provenance import default_site

        try:
            with self._transaction() as c:
                row = c.execute(
                    "SELECT COALESCE(MAX(session_number), 0) FROM sessions WHERE participant=?",
                    (participant,),
                ).fetchone()
                cur = c.execute(
                    "INSERT INTO sessions(participant, session_number, study_name, study_sha256,"
                    " study_toml, seed, condition_order, schedule_json, n_trials, belt,"
                    " firmware_version, calibration_json, package_version, git_commit, host,"
                    " input, clock, started_at, status, site, session_uuid)"
                    " VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,'running',?,?)",
                    (
                        participant, int(row[0]) + 1, study_name, study_sha256, study_toml,
                        int(seed), json.dumps(condition_order), schedule_to_json(schedule),
                        len(schedule), belt, firmware_version,
                        None if calibration is None else json.dumps(calibration),
                        package_version, git_commit, host, input, clock, utc_now(),
                        site or default_site(), session_uuid or str(uuid.uuid4()),
                    ),
                )
                return int(cur.lastrowid or 0)
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"cannot write to {self.path}: {exc}") from None

    def mark_resumed(self, session_id: int) -> None:
        """A resumed session is ``running`` again (and counts one more resume)."""
        with self._transaction() as c:
            c.execute("UPDATE sessions SET status='running', ended_at=NULL, resumed=resumed+1"
                      " WHERE session_id=?", (session_id,))

    def set_run_options(self, session_id: int, options: Mapping[str, Any]) -> None:
        with self._transaction() as c:
            c.execute("INSERT OR REPLACE INTO meta(key, value) VALUES (?, ?)",
                      (_RUN_OPTIONS_KEY.format(session_id), json.dumps(dict(options))))

    def run_options(self, session_id: int) -> dict[str, Any] | None:
        rows = self._query("SELECT value FROM meta WHERE key=?",
                           (_RUN_OPTIONS_KEY.format(session_id),))
        if not rows:
            return None
        opts: dict[str, Any] = json.loads(rows[0][0])
        return opts

    def _set_meta(self, key: str, value: str) -> None:
        with self._transaction() as c:
            c.execute("INSERT OR REPLACE INTO meta(key, value) VALUES (?, ?)", (key, value))

    def _meta(self, key: str) -> str | None:
        if not self._query("SELECT 1 FROM sqlite_master WHERE type='table' AND name='meta'"):
            return None  # a bare store (written by other tools) keeps no meta rows
        rows = self._query("SELECT value FROM meta WHERE key=?", (key,))
        return str(rows[0][0]) if rows else None

    def set_status(self, session_id: int, status: str) -> None:
        """Set a session's status; any status but ``running`` also sets ``ended_at``."""
        if status not in SESSION_STATUSES:
            raise StoreError(f"unknown session status {status!r}; allowed: {SESSION_STATUSES}")
        with self._transaction() as c:
            c.execute("UPDATE sessions SET status=?, ended_at=? WHERE session_id=?",
                      (status, None if status == "running" else utc_now(), session_id))

    def session(self, session_id: int) -> dict[str, Any]:
        """One session row as a dict."""
        rows = self._query("SELECT * FROM sessions WHERE session_id=?", (session_id,))
        if not rows:
            raise StoreError(f"{self.path}: no session {session_id}")
        return dict(rows[0])

    def sessions(self, participant: str | None = None) -> list[dict[str, Any]]:
        """Every session (of one participant), oldest first."""
        if participant is None:
            rows = self._query("SELECT * FROM sessions ORDER BY session_id")
        else:
            rows = self._query("SELECT * FROM sessions WHERE participant=? ORDER BY session_id",
                               (participant,))
        return [dict(r) for r in rows]

    def find_resumable(self, participant: str) -> dict[str, Any] | None:
        """The participant's latest session that is not complete, or None."""
        rows = self._query(
            "SELECT * FROM sessions WHERE participant=? AND status!='complete'"
            " ORDER BY session_id DESC LIMIT 1", (participant,))
        return dict(rows[0]) if rows else None

    def schedule(self, session_id: int, study: Study | None = None) -> list[ScheduledTrial]:
        """The stored schedule of a session (``study`` fills in the target count and
        load of a schedule stored before factorial designs)."""
        return schedule_from_json(self.session(session_id)["schedule_json"], study)

    def finished_indices(self, session_id: int) -> set[int]:
        """trial_index of every trial with a final outcome (``done`` or ``timeout``)."""
        rows = self._query("SELECT trial_index FROM trials WHERE session_id=?"
                           " AND status IN ('done','timeout')", (session_id,))
        return {int(r[0]) for r in rows}

    # -- trials ------------------------------------------------------------------------
    def write_trial(self, session_id: int, result: TrialResult) -> int:
        """Write a trial and its samples in one transaction; return its trial_id.

        An earlier ``aborted`` row of the same trial is replaced (with its samples).

        Raises:
            StoreError: the trial already has a final row, or the write failed.
        """
        t = result.trial
        if result.status not in TRIAL_STATUSES:
            raise StoreError(f"unknown trial status {result.status!r}")
        if result.samples_released:
            raise StoreError(f"trial {t.trial_index}: its samples were released from memory "
                             "after it was stored; it cannot be written again")
        def values(attempts: int) -> tuple[Any, ...]:
            return (
                session_id, t.trial_index, t.block, t.block_index, t.block_name,
                t.condition, t.repetition, t.target_deg, int(t.on_tactor),
                result.response_deg, result.response_target_deg,
                None if result.correct is None else int(result.correct),
                result.rt_s, result.onset_ns, result.acquired_ns, result.crossed_ns,
                result.stimulus_off_ns, result.n_samples, result.status,
                result.abort_reason, attempts, utc_now(), t.n_targets or None, t.load,
                result.device_onset_ns, result.onset_uncertainty_ns,
            )

        try:
            with self._transaction() as c:
                try:  # the usual case: the trial's first row
                    cur = c.execute(_INSERT_TRIAL_SQL, values(1))
                except sqlite3.IntegrityError:  # UNIQUE(session_id, trial_index), or not
                    old = c.execute("SELECT trial_id, status, attempts FROM trials"
                                    " WHERE session_id=? AND trial_index=?",
                                    (session_id, t.trial_index)).fetchone()
                    if old is None:
                        raise
                    if old["status"] != "aborted":
                        raise StoreError(
                            f"trial {t.trial_index} of session {session_id} is already "
                            f"recorded ({old['status']}); a trial is never written twice"
                        ) from None
                    c.execute("DELETE FROM samples WHERE trial_id=?", (old["trial_id"],))
                    c.execute("DELETE FROM trials WHERE trial_id=?", (old["trial_id"],))
                    cur = c.execute(_INSERT_TRIAL_SQL, values(int(old["attempts"]) + 1))
                trial_id = int(cur.lastrowid or 0)
                if result.n_samples:
                    _insert_samples(c, trial_id, result)
                return trial_id
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"cannot write trial {t.trial_index} to {self.path}: {exc}") from None

    def trials(self, session_id: int | None = None) -> list[dict[str, Any]]:
        """Trial rows (of one session), in the order they were recorded."""
        if session_id is None:
            rows = self._query("SELECT * FROM trials ORDER BY trial_id")
        else:
            rows = self._query("SELECT * FROM trials WHERE session_id=? ORDER BY trial_id",
                               (session_id,))
        return [dict(r) for r in rows]

    def samples(self, trial_id: int) -> list[tuple[float, float, float, int]]:
        """(t_s, x, y, buttons) of one trial, in time order."""
        rows = self._query("SELECT t_s, x, y, buttons FROM samples WHERE trial_id=?"
                           " ORDER BY rowid", (trial_id,))
        return [(r[0], r[1], r[2], r[3]) for r in rows]

    # -- secondary tasks and workload ratings ------------------------------------------
    def _has_table(self, table: str) -> bool:
        return bool(self._query("SELECT 1 FROM sqlite_master WHERE type='table' AND name=?",
                                (table,)))

    def write_task_events(self, session_id: int, events: Sequence[TaskEvent]) -> None:
        """Append a task run's events in one transaction (all or none)."""
        rows = [(session_id, e.block_index, e.task, e.phase, e.item_index, int(e.t_ns),
                 e.stimulus, int(e.target), e.response, int(e.correct), e.rt_s)
                for e in events]
        if not rows:
            return
        try:
            with self._transaction() as c:
                c.executemany(
                    f"INSERT INTO task_events({', '.join(TASK_EVENT_COLUMNS)}) "
                    f"VALUES ({', '.join('?' * len(TASK_EVENT_COLUMNS))})", rows)
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"cannot write task events to {self.path}: {exc}") from None

    def task_events(self, session_id: int | None = None) -> list[dict[str, Any]]:
        """``task_events`` rows (of one session) in the order written; [] before schema 3."""
        if not self._has_table("task_events"):
            return []
        sql = f"SELECT {', '.join(TASK_EVENT_COLUMNS)} FROM task_events"
        args: tuple[Any, ...] = ()
        if session_id is not None:
            sql += " WHERE session_id=?"
            args = (session_id,)
        out = []
        for r in self._query(sql + " ORDER BY event_id", args):
            d = dict(r)
            d["target"], d["correct"] = bool(d["target"]), bool(d["correct"])
            out.append(d)
        return out

    def write_ratings(self, session_id: int, block_index: int, scale: str,
                      values: Mapping[str, float]) -> None:
        """Replace a block's ratings of ``scale`` with ``values`` (one transaction)."""
        rows = [(session_id, block_index, scale, str(k), rating_value(k, v))
                for k, v in values.items()]
        try:
            with self._transaction() as c:
                c.execute("DELETE FROM ratings WHERE session_id=? AND block_index=? AND scale=?",
                          (session_id, block_index, scale))
                c.executemany(
                    f"INSERT INTO ratings({', '.join(RATING_COLUMNS)}) VALUES (?,?,?,?,?)", rows)
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"cannot write ratings to {self.path}: {exc}") from None

    def ratings(self, session_id: int | None = None) -> list[dict[str, Any]]:
        """``ratings`` rows (of one session) by session, block and order written."""
        if not self._has_table("ratings"):
            return []
        sql = f"SELECT {', '.join(RATING_COLUMNS)} FROM ratings"
        args: tuple[Any, ...] = ()
        if session_id is not None:
            sql += " WHERE session_id=?"
            args = (session_id,)
        rows = self._query(sql + " ORDER BY session_id, block_index, rowid", args)
        return [dict(r) for r in rows]

    # -- bulk reads --------------------------------------------------------------------
    def table_columns(self, table: str) -> list[str]:
        if table not in _TABLES:
            raise StoreError(f"unknown table {table!r}; a store has {', '.join(_TABLES)}")
        return [str(r[1]) for r in self._query(f"PRAGMA table_info({table})")]

    def read_table(self, table: str, columns: Sequence[str]) -> list[tuple[Any, ...]]:
        order = {"sessions": "session_id", "trials": "session_id, trial_id"}.get(table)
        if order is None:
            raise StoreError(f"read_table reads sessions or trials, not {table!r}")
        have = set(self.table_columns(table))
        bad = [c for c in columns if c not in have]
        if bad:
            raise StoreError(f"{self.path}: table {table} lacks column(s) {', '.join(bad)}")
        rows = self._query(f"SELECT {', '.join(columns)} FROM {table} ORDER BY {order}")
        return [tuple(r) for r in rows]

    def samples_of(self, trial_ids: Sequence[int]) -> list[tuple[int, float, float, float, int]]:
        ids = sorted({int(t) for t in trial_ids})
        out: list[tuple[int, float, float, float, int]] = []
        for start in range(0, len(ids), 500):  # stay under SQLite's parameter limit
            part = ids[start:start + 500]
            rows = self._query(
                "SELECT trial_id, t_s, x, y, buttons FROM samples WHERE trial_id IN "
                f"({', '.join('?' * len(part))}) ORDER BY trial_id, t_s", part)
            out += [(r[0], r[1], r[2], r[3], r[4]) for r in rows]
        return out

    def iter_samples(self, session_id: int | None = None
                     ) -> Iterator[tuple[int, int, float, float, float, int]]:
        sql = ("SELECT t.session_id, t.trial_index, p.t_s, p.x, p.y, p.buttons"
               " FROM samples p JOIN trials t USING (trial_id)")
        args: tuple[Any, ...] = ()
        if session_id is not None:
            sql += " WHERE t.session_id=?"
            args = (session_id,)
        sql += " ORDER BY t.session_id, t.trial_id, p.rowid"
        try:
            for r in self.conn.execute(sql, args):
                yield (r[0], r[1], r[2], r[3], r[4], r[5])
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"cannot read {self.path}: {exc}") from None

    # -- bulk writes -------------------------------------------------------------------
    def bulk_insert(self, *, sessions: Iterable[Mapping[str, Any]] = (),
                    trials: Iterable[Mapping[str, Any]] = (),
                    samples: Iterable[Sequence[Any]] = ()) -> list[int]:
        """Insert ready-made rows in one transaction; return the new sessions' ids.

        Rows go in as given (explicit ids are kept, missing columns get the schema's
        defaults); for synthetic data, not for runs (:meth:`write_trial` checks trials).
        """
        ids: list[int] = []
        try:
            with self._transaction() as c:
                for row in sessions:
                    cols = list(row)
                    cur = c.execute(
                        f"INSERT INTO sessions({', '.join(cols)}) "
                        f"VALUES ({', '.join('?' * len(cols))})", [row[k] for k in cols])
                    ids.append(int(cur.lastrowid or 0))
                trial_rows = list(trials)
                if trial_rows:
                    cols = sorted({k for r in trial_rows for k in r})
                    c.executemany(
                        f"INSERT INTO trials({', '.join(cols)}) "
                        f"VALUES ({', '.join('?' * len(cols))})",
                        ([r.get(k) for k in cols] for r in trial_rows))
                c.executemany(
                    "INSERT INTO samples(trial_id, t_s, x, y, buttons) VALUES (?,?,?,?,?)",
                    samples)
        except sqlite3.DatabaseError as exc:
            raise StoreError(f"cannot write to {self.path}: {exc}") from None
        return ids

    def index_samples(self) -> None:
        """Create the index on ``samples(trial_id)`` (after a bulk load without it)."""
        with self._transaction() as c:
            c.execute(_SAMPLES_INDEX)


def create_bare_store(path: str | Path, *, samples_index: bool = True,
                        extra_columns: bool = False, fast: bool = False) -> SQLiteStore:
    """Create a bare store (only the required columns) for synthetic data; open for writing.

    The analysis reads any store that has the required tables and columns; this one has
    no more (no meta table, no provenance), so tests can check that. Fill it with
    :meth:`SQLiteStore.bulk_insert`.

    Args:
        path: the new file (must not exist).
        samples_index: create the index on ``samples(trial_id)`` now (else call
            :meth:`SQLiteStore.index_samples` after loading).
        extra_columns: add columns the analysis must tolerate (``sessions.input``,
            ``trials.notes``).
        fast: no journal and no fsync (a benchmark's scratch file; not crash safe).
    """
    p = _path_of(path)
    if p.exists():
        raise StoreError(f"{p} exists; a synthetic store is written into a new file")
    try:
        conn = sqlite3.connect(str(p), isolation_level=None, check_same_thread=False)
        conn.row_factory = sqlite3.Row
        if fast:
            conn.execute("PRAGMA journal_mode = OFF")
            conn.execute("PRAGMA synchronous = OFF")
        conn.execute("BEGIN")
        for stmt in BARE_SCHEMA.split(";"):
            if stmt.strip():
                conn.execute(stmt)
        if samples_index:
            conn.execute(_SAMPLES_INDEX)
        if extra_columns:
            conn.execute("ALTER TABLE sessions ADD COLUMN input TEXT")
            conn.execute("ALTER TABLE trials ADD COLUMN notes TEXT")
        conn.execute("COMMIT")
    except sqlite3.Error as exc:
        raise StoreError(f"cannot create {p}: {exc}") from None
    return SQLiteStore(p, conn, None, readonly=False)


def move_store_file(src: str | Path, dst: str | Path) -> bool:
    """Move a closed store file (and any WAL files of a crashed run) to ``dst``.

    A store at ``dst`` is replaced. Leftover WAL files of a store whose file is gone are
    removed. Returns whether there was a store to move.

    Raises:
        StoreError: another run holds the store, or the files cannot be moved.
    """
    import fcntl

    s, d = _path_of(src), _path_of(dst)
    fd = None
    try:
        if _lock_path(s).exists():
            fd = os.open(_lock_path(s), os.O_RDWR)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                raise StoreError(f"another run is using {s}; wait for it to finish") from None
        if not s.exists():
            for side in _side_files(s):  # leftovers of a run that lost its main file
                side.unlink(missing_ok=True)
            return False
        for old in (d, *_side_files(d)):
            old.unlink(missing_ok=True)
        for a, b in zip((s, *_side_files(s)), (d, *_side_files(d)), strict=True):
            if a.exists():
                shutil.move(str(a), str(b))
        if fd is not None:  # a crashed run's lock, now held by us
            _lock_path(s).unlink(missing_ok=True)
    except OSError as exc:
        raise StoreError(f"cannot move the store {s} to {d}: {exc.strerror}") from None
    finally:
        if fd is not None:
            os.close(fd)
    return True
