"""The SQLite store: one file holding sessions, trials and cursor samples.

The schema (docs/study.md, "The store") is declared once in :mod:`.schema` and the
queries and the methods that are the same for every SQL store are :class:`~.sql.Store`'s;
this module holds what is SQLite's own: the file, its lock and WAL files, the opening
checks and migration in one transaction, the samples' multi-row INSERTs and the batched
commits.

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

:func:`move_store_file` moves a closed store (with any WAL files) aside.

I/O edge of the experiment package: imports sqlite3, fcntl and the pure experiment
modules; never devices, inputs or the window.
"""

from __future__ import annotations

import contextlib
import functools
import os
import shutil
import sqlite3
import stat
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..._errors import StoreError
from ..trial import TrialResult
from .base import SCHEMA_VERSION, StoreCapabilities
from .schema import SQLITE, migrate
from .sql import COMMITS_KEY, Store

__all__ = ["APPLICATION_ID", "SQLiteStore", "move_store_file"]

#: PRAGMA application_id of a tactorbelt store ("TBLT").
APPLICATION_ID = 0x54424C54
#: Files SQLite may keep next to the store while it is open (or after a crash).
SIDE_SUFFIXES = ("-wal", "-shm", "-journal")
#: The tables every store has (older stores may lack the others).
_CORE_TABLES = ("sessions", "trials", "samples")


def _read_only(path: Path) -> bool:
    """True when the file cannot or must not be written (no write bit, or no access)."""
    try:
        mode = path.stat().st_mode
    except OSError:
        return False
    return not os.access(path, os.W_OK) or not (mode & (stat.S_IWUSR | stat.S_IWGRP | stat.S_IWOTH))


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


@functools.lru_cache(maxsize=32)
def _samples_sql(n_rows: int, buttons: bool) -> str:
    """An INSERT of ``n_rows`` samples of one trial: the trial_id is bound once (``?1``),
    then each row's t_s, x, y (and buttons, if any is pressed; else the literal 0)."""
    per = 4 if buttons else 3
    rows = [f"(?1,?{k},?{k + 1},?{k + 2},{f'?{k + 3}' if buttons else '0'})"
            for k in range(2, 2 + per * n_rows, per)]
    return "INSERT INTO samples(trial_id, t_s, x, y, buttons) VALUES " + ",".join(rows)


class SQLiteStore(Store):
    """A store in one SQLite file (see the module doc). Open with :func:`open_store`."""

    capabilities = StoreCapabilities(backend="sqlite", file=True, exclusive_writer=True,
                                     batch_commits=True)
    dialect = SQLITE
    path: Path
    conn: sqlite3.Connection

    def __init__(self, path: Path, conn: sqlite3.Connection, lock_fd: int | None,
                 readonly: bool) -> None:
        super().__init__(str(path), path, conn, readonly)
        self._lock_fd = lock_fd
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
            tables = {r[0] for r in conn.execute(SQLITE.tables_query)}
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
                migrate(conn, SQLITE)
                if app_id != APPLICATION_ID:
                    conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
                conn.execute(SQLITE.upsert("meta", ("key", "value"), ("key",)),
                             ("schema_version", str(SCHEMA_VERSION)))
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
        if not self.readonly:
            with contextlib.suppress(sqlite3.Error):
                self.conn.execute("PRAGMA busy_timeout = 0")  # never wait for a reader
                self.conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
                self.conn.execute("PRAGMA journal_mode = DELETE")
        super().close()
        if self._lock_fd is not None:
            with contextlib.suppress(OSError):
                _lock_path(self.path).unlink()  # while still holding it
            with contextlib.suppress(OSError):
                os.close(self._lock_fd)
            self._lock_fd = None

    # -- helpers -----------------------------------------------------------------------
    @contextlib.contextmanager
    def _transaction(self, what: str = "write to") -> Iterator[sqlite3.Connection]:
        """One write: a transaction, or inside a batch a savepoint (a failed write undoes
        itself alone; the batch commits after every ``_batch_every`` writes). A database
        error in it rolls it back and is raised as StoreError ``cannot {what} {path}``."""
        if self.readonly:
            raise StoreError(f"{self.path} was opened read-only")
        batch = self._batch_every
        try:
            if not (batch and self.conn.in_transaction):
                self.conn.execute("BEGIN IMMEDIATE")
            if batch:
                self.conn.execute("SAVEPOINT write")
        except sqlite3.Error as exc:
            raise StoreError(f"cannot write to {self.path}: {exc}") from None
        try:
            yield self.conn
        except sqlite3.Error as exc:
            self._rollback(batch)
            raise StoreError(f"cannot {what} {self.path}: {exc}") from None
        except BaseException:
            self._rollback(batch)
            raise
        if not batch:
            self._commit("COMMIT")
            return
        self._batch_pending += 1
        due = self._batch_pending >= batch
        if due:
            self._batch_pending = 0
        self._commit("RELEASE write", *(("COMMIT",) if due else ()))

    def _rollback(self, batch: int) -> None:
        with contextlib.suppress(sqlite3.Error):
            if batch:
                self.conn.execute("ROLLBACK TO write")
                self.conn.execute("RELEASE write")
            else:
                self.conn.execute("ROLLBACK")

    def _commit(self, *statements: str) -> None:
        """End the write (COMMIT, RELEASE); on failure roll the transaction back and raise
        StoreError."""
        try:
            for stmt in statements:
                self.conn.execute(stmt)
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
        self._set_meta(COMMITS_KEY.format(session_id), "batched")
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
                self._commit("COMMIT")
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

    def _read_error(self) -> type[Exception]:
        return sqlite3.DatabaseError

    # -- trials ------------------------------------------------------------------------
    def _put_trial(self, c: Any, session_id: int, trial_index: int,
                   values: list[Any]) -> int:
        """The trial row: first an INSERT (the usual case: the trial's first row), which
        the UNIQUE key refuses when an earlier row is there (one writer: no lock needed)."""
        try:
            return self._insert_trial_row(c, values, 1)
        except sqlite3.IntegrityError:  # UNIQUE(session_id, trial_index), or not
            attempts = self._replace_aborted(c, session_id, trial_index)
            if attempts is None:
                raise
            return self._insert_trial_row(c, values, attempts)

    def _write_samples(self, c: Any, trial_id: int, result: TrialResult) -> None:
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
