"""The store seam: what the runner, export, analysis and the model study need of a store.

A store holds sessions (with their provenance and schedule), trials and cursor samples,
and under cognitive load the secondary tasks' events (``task_events``) and the workload
ratings (``ratings``).
:class:`Store` is the interface; :func:`open_store` picks an implementation by URL:

- a path, or ``sqlite:///path``: :class:`~.sqlite.SQLiteStore` (one file on disk);
- ``postgresql://user@host/dbname``: :class:`~.postgresql.PostgreSQLStore` (psycopg 3,
  the ``postgresql`` extra; several sites at once).

Implementations register in :data:`BACKENDS` (URL scheme -> ``"module:Class"``,
imported lazily); adding one is one line there. Every implementation must pass
tests/test_store_contract.py.

Pure: imports the experiment's schedule and trial types only.
"""

from __future__ import annotations

import abc
import datetime as _dt
from collections.abc import Iterable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING, Any

from ..._errors import StoreError
from ..._registry import resolve
from ..schedule import ScheduledTrial, schedule_from_json
from ..trial import TrialResult

if TYPE_CHECKING:
    from ...tasks.schedule import TaskEvent
    from ..study import Study

__all__ = [
    "BACKENDS",
    "RATING_COLUMNS",
    "SAMPLE_COLUMNS",
    "SCHEMA_VERSION",
    "SESSION_STATUSES",
    "TASK_EVENT_COLUMNS",
    "TRIAL_STATUSES",
    "Store",
    "StoreCapabilities",
    "backend_for",
    "open_store",
    "rating_value",
    "utc_now",
]

#: Version of the store schema this tactorbelt writes; a store with a newer one is refused.
#: (A PostgreSQL store is one more: its site rules, ``postgresql.PG_SCHEMA_VERSION``.)
SCHEMA_VERSION = 3
#: What each schema version added (a writer opening an older store migrates it).
SCHEMA_HISTORY = {
    1: "sessions, trials, samples",
    2: "trials.n_targets and trials.load (factorial designs)",
    3: "task_events and ratings (secondary tasks, NASA-TLX)",
}
SESSION_STATUSES = ("running", "complete", "aborted", "interrupted")
TRIAL_STATUSES = ("done", "timeout", "aborted")
#: Columns of a cursor sample row, in order.
SAMPLE_COLUMNS = ("trial_id", "t_s", "x", "y", "buttons")
#: Columns of a ``task_events`` row (the keys of :meth:`Store.task_events`), in order.
TASK_EVENT_COLUMNS = ("session_id", "block_index", "task", "phase", "item_index", "t_ns",
                      "stimulus", "target", "response", "correct", "rt_s")
#: Columns of a ``ratings`` row (the keys of :meth:`Store.ratings`), in order.
RATING_COLUMNS = ("session_id", "block_index", "scale", "item", "value")

#: URL scheme -> "module:Class" (relative to this package) of each store implementation.
#: ``None`` means "planned, not available yet". A path with no scheme is ``sqlite``.
BACKENDS: dict[str, str | None] = {
    "sqlite": "tactorbelt.experiment.store.sqlite:SQLiteStore",
    "postgresql": "tactorbelt.experiment.store.postgresql:PostgreSQLStore",
}


def rating_value(item: str, value: Any) -> float:
    """A rating as a float, or StoreError when it is not a finite number."""
    import math

    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise StoreError(f"rating {item!r} must be a finite number (got {value!r})")
    return float(value)


def utc_now() -> str:
    """The current UTC time, ISO 8601 with microseconds."""
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="microseconds")


@dataclass(frozen=True)
class StoreCapabilities:
    """What an implementation offers beyond the common operations.

    Attributes:
        backend: the URL scheme (``sqlite``).
        file: the store is one file on disk (:attr:`Store.path` is set); it can be
            copied or moved aside when closed.
        bulk_insert: :meth:`Store.bulk_insert` is supported.
        exclusive_writer: only one writer may hold the store at a time.
        sync_target: sessions copied from another store can be imported
            (:meth:`Store.sync_state`, :meth:`Store.import_session`,
            :meth:`Store.import_trial`; ``tactorbelt sync`` and ``run --push``).
        batch_commits: :meth:`Store.begin_batch` groups trial writes into fewer
            commits (simulated sessions only; see ``provenance.commit_mode``).
    """

    backend: str
    file: bool
    bulk_insert: bool
    exclusive_writer: bool
    sync_target: bool = False
    batch_commits: bool = False


def _scheme(url: str | Path) -> tuple[str, str]:
    """``(scheme, rest)``: a bare path (or a Windows drive letter) is ``sqlite``."""
    text = str(url)
    if isinstance(url, Path) or "://" not in text:
        return "sqlite", text
    scheme, rest = text.split("://", 1)
    return scheme.lower().split("+", 1)[0], rest


def backend_for(url: str | Path) -> type[Store]:
    """The :class:`Store` class for a URL.

    Raises:
        StoreError: the scheme is unknown or its implementation is not available yet.
    """
    scheme, _ = _scheme(url)
    if scheme == "postgres":
        scheme = "postgresql"
    if scheme not in BACKENDS:
        raise StoreError(f"unknown store URL scheme {scheme!r} in {url}; give a file path, "
                         f"sqlite:///path or one of: {', '.join(sorted(BACKENDS))}")
    target = BACKENDS[scheme]
    if target is None:
        name = {"postgresql": "PostgreSQL"}.get(scheme, scheme)
        raise StoreError(f"{name} stores are not available yet ({url}); give a file path "
                         "such as study.sqlite")
    store_cls: type[Store] = resolve(target)
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
    cls = backend_for(url)
    return cls.open_url(url, create=create, readonly=readonly, verify=verify)


class Store(abc.ABC):
    """An open session store. Close it (or use ``with``) when done.

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

    # -- opening -----------------------------------------------------------------------
    @classmethod
    def open(cls, url: str | Path, create: bool = True, readonly: bool = False,
             verify: bool = True) -> Store:
        """Open a store; on :class:`Store` itself the URL picks the implementation."""
        if cls is Store:
            return open_store(url, create=create, readonly=readonly, verify=verify)
        return cls.open_url(url, create=create, readonly=readonly, verify=verify)

    @classmethod
    @abc.abstractmethod
    def open_url(cls, url: str | Path, *, create: bool, readonly: bool,
                 verify: bool) -> Store:
        """Open this implementation's store at ``url`` (see :func:`open_store`)."""

    @abc.abstractmethod
    def close(self) -> None:
        """Release the store (and, for a file store, leave only its file). Idempotent."""

    def __enter__(self) -> Store:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    # -- sessions ----------------------------------------------------------------------
    @abc.abstractmethod
    def create_session(
        self, *, participant: str, study_name: str, study_toml: str, study_sha256: str,
        seed: int, condition_order: list[str], schedule: list[ScheduledTrial],
        belt: str | None = None, firmware_version: str | None = None,
        calibration: Any = None, package_version: str | None = None,
        git_commit: str | None = None, host: str | None = None, input: str | None = None,
        clock: str | None = None, site: str | None = None, session_uuid: str | None = None,
    ) -> int:
        """Record a new session (status ``running``) with its provenance; return its id.

        ``site`` (default :func:`~tactorbelt.experiment.provenance.default_site`) is the
        lab that ran it; ``session_uuid`` (default a new uuid4) names the session in every
        store it is copied to.
        """

    @abc.abstractmethod
    def mark_resumed(self, session_id: int) -> None:
        """A resumed session is ``running`` again (and counts one more resume)."""

    @abc.abstractmethod
    def set_status(self, session_id: int, status: str) -> None:
        """Set a session's status; any status but ``running`` also sets ``ended_at``."""

    @abc.abstractmethod
    def sessions(self, participant: str | None = None) -> list[dict[str, Any]]:
        """Every session (of one participant) as a dict of its columns, oldest first."""

    @abc.abstractmethod
    def set_run_options(self, session_id: int, options: Mapping[str, Any]) -> None:
        """Keep how a session was run (input, belt, window options; JSON values), so a
        resume can reuse them. Replaces what was kept before."""

    @abc.abstractmethod
    def run_options(self, session_id: int) -> dict[str, Any] | None:
        """The options kept by :meth:`set_run_options`, or None (older sessions)."""

    # -- wearer profiles (the perceptual calibration, tactorbelt.profile) -------------------
    def _set_meta(self, key: str, value: str) -> None:
        """Keep one text value under ``key`` (implementations with a meta table)."""
        raise StoreError(f"{self.url}: this store keeps no wearer profiles")

    def _meta(self, key: str) -> str | None:
        return None

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

    def session(self, session_id: int) -> dict[str, Any]:
        """One session row as a dict."""
        for s in self.sessions():
            if s["session_id"] == session_id:
                return s
        raise StoreError(f"{self.url}: no session {session_id}")

    def find_resumable(self, participant: str) -> dict[str, Any] | None:
        """The participant's latest session that is not complete, or None."""
        open_ = [s for s in self.sessions(participant) if s["status"] != "complete"]
        return open_[-1] if open_ else None

    def schedule(self, session_id: int, study: Study | None = None) -> list[ScheduledTrial]:
        """The stored schedule of a session (``study`` fills in the target count and
        load of a schedule stored before factorial designs)."""
        return schedule_from_json(self.session(session_id)["schedule_json"], study)

    def finished_indices(self, session_id: int) -> set[int]:
        """trial_index of every trial with a final outcome (``done`` or ``timeout``)."""
        return {int(t["trial_index"]) for t in self.trials(session_id)
                if t["status"] in ("done", "timeout")}

    # -- trials ------------------------------------------------------------------------
    @abc.abstractmethod
    def write_trial(self, session_id: int, result: TrialResult, *,
                    skin_onset_ns: int | None = None,
                    skin_onset_sd_ns: int | None = None) -> int:
        """Write a trial and its samples in one transaction; return its trial_id.

        An earlier ``aborted`` row of the same trial is replaced (with its samples).
        ``skin_onset_ns`` and ``skin_onset_sd_ns``: the onset at the skin and its spread
        (the runner's, from the belt's measured latencies; None: not known), stored in the
        trial's ``skin_onset_ns`` and ``skin_onset_sd_ns``.

        Raises:
            StoreError: the trial already has a final row, or the write failed (then
                nothing of the trial was written).
        """

    @abc.abstractmethod
    def trials(self, session_id: int | None = None) -> list[dict[str, Any]]:
        """Trial rows (of one session), in the order they were recorded."""

    @abc.abstractmethod
    def samples(self, trial_id: int) -> list[tuple[float, float, float, int]]:
        """(t_s, x, y, buttons) of one trial, in time order."""

    # -- secondary tasks and workload ratings (schema 3) --------------------------------
    def write_task_events(self, session_id: int, events: Sequence[TaskEvent]) -> None:
        """Append a task run's events (:class:`~tactorbelt.tasks.schedule.TaskEvent`) in
        one transaction: all of them or, on failure (StoreError), none."""
        raise StoreError(f"{self.url}: this store does not keep task events")

    def task_events(self, session_id: int | None = None) -> list[dict[str, Any]]:
        """``task_events`` rows (of one session) as dicts keyed by
        :data:`TASK_EVENT_COLUMNS` (``target``, ``correct`` as bool), in the order they
        were written; [] for a store written before schema 3."""
        return []

    def write_ratings(self, session_id: int, block_index: int, scale: str,
                      values: Mapping[str, float]) -> None:
        """Store a questionnaire's answers after a block (item -> value), replacing that
        block's earlier rows of the same scale (one transaction)."""
        raise StoreError(f"{self.url}: this store does not keep ratings")

    def ratings(self, session_id: int | None = None) -> list[dict[str, Any]]:
        """``ratings`` rows (of one session) as dicts keyed by :data:`RATING_COLUMNS`,
        by session, block and the order written; [] before schema 3."""
        return []

    # -- bulk reads (export, analysis) -------------------------------------------------
    @abc.abstractmethod
    def table_columns(self, table: str) -> list[str]:
        """Column names of ``sessions``, ``trials``, ``samples``, ``task_events`` or
        ``ratings`` ([] when absent)."""

    @abc.abstractmethod
    def read_table(self, table: str, columns: Sequence[str]) -> list[tuple[Any, ...]]:
        """Rows of ``sessions`` (by session_id) or ``trials`` (by session_id, trial_id).

        Only the given columns, in that order; for the analysis, which reads stores
        that may hold only the columns the schema requires.
        """

    @abc.abstractmethod
    def samples_of(self, trial_ids: Sequence[int]) -> list[tuple[int, float, float, float, int]]:
        """``(trial_id, t_s, x, y, buttons)`` of some trials, by trial_id and time."""

    @abc.abstractmethod
    def iter_samples(self, session_id: int | None = None
                     ) -> Iterator[tuple[int, int, float, float, float, int]]:
        """``(session_id, trial_index, t_s, x, y, buttons)`` of every sample (of one
        session), by session, trial_id and time; streamed, never all in memory."""

    # -- bulk writes (synthetic stores for tests and benchmarks) -----------------------
    def bulk_insert(self, *, sessions: Iterable[Mapping[str, Any]] = (),
                    trials: Iterable[Mapping[str, Any]] = (),
                    samples: Iterable[Sequence[Any]] = ()) -> list[int]:
        """Insert ready-made rows in one transaction; return the new sessions' ids.

        ``sessions`` and ``trials`` are dicts keyed by column (missing columns get their
        defaults, explicit ids are kept); ``samples`` are :data:`SAMPLE_COLUMNS` tuples.
        Only when :attr:`StoreCapabilities.bulk_insert`.
        """
        raise StoreError(f"{self.url}: this store does not take bulk inserts")

    def claim_participant(self, participant: str, site: str) -> None:
        """Refuse (StoreError) a participant id that another site already uses. A store
        of one site (SQLite) takes any id."""
        return None

    def check_site(self, site: str) -> None:
        """Refuse (StoreError) unless this login may write sessions of ``site``; writes
        nothing. A store of one site (SQLite) takes any site."""
        return None

    # -- batched commits (only when capabilities.batch_commits) -------------------------
    def begin_batch(self, session_id: int, every: int) -> None:
        """From now on commit writes every ``every`` trials (and at :meth:`end_batch`)
        instead of each trial; record that session ``session_id`` batched its commits
        (:meth:`commit_mode`). Only for sessions with nothing real involved."""
        raise StoreError(f"the {self.capabilities.backend} store commits every trial")

    def end_batch(self) -> None:  # noqa: B027 - a store without batches has none to end
        """Commit what the batch holds and go back to a commit per write. Safe to call
        when no batch is open."""

    def commit_mode(self, session_id: int) -> str:
        """``per-trial`` or ``batched`` (see ``provenance.commit_mode``): how the
        session's trials were committed (``batched`` when any run of it batched)."""
        return "per-trial"

    # -- copying sessions from another store (only when capabilities.sync_target) -----
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
