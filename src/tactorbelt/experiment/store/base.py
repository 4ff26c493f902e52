"""The store seam: what the runner, export, analysis and the model study need of a store.

A store holds sessions (with their provenance and schedule), trials and cursor samples,
and under cognitive load the secondary tasks' events (``task_events``) and the workload
ratings (``ratings``). This module holds what every store shares but its code: the
columns, statuses, schema versions, capabilities and the registry of implementations;
:class:`~.sql.Store` is the store (one SQL core) and :func:`~.sql.open_store` picks an
implementation by URL:

- a path, or ``sqlite:///path``: :class:`~.sqlite.SQLiteStore` (one file on disk);
- ``postgresql://user@host/dbname``: :class:`~.postgresql.PostgreSQLStore` (psycopg 3,
  the ``postgresql`` extra; several sites at once).

Implementations register in :data:`BACKENDS` (URL scheme -> ``"module:Class"``,
imported lazily); adding one is one line there. Every implementation must pass
tests/test_store_contract.py.

Pure: the standard library only.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass
from typing import Any

from ..._errors import StoreError

__all__ = [
    "BACKENDS",
    "RATING_COLUMNS",
    "SAMPLE_COLUMNS",
    "SCHEMA_VERSION",
    "SESSION_STATUSES",
    "TASK_EVENT_COLUMNS",
    "TRIAL_STATUSES",
    "StoreCapabilities",
    "rating_value",
    "utc_now",
]

#: Version of the store schema this tactorbelt writes; a store with a newer one is refused,
#: an older one migrated by a writer (what each version added is marked in
#: :data:`.schema.TABLES`). (A PostgreSQL store is one more: its site rules,
#: ``postgresql.PG_SCHEMA_VERSION``.)
SCHEMA_VERSION = 3
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
#: A path with no scheme is ``sqlite``.
BACKENDS: dict[str, str] = {
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
        exclusive_writer: only one writer may hold the store at a time.
        sync_target: sessions copied from another store can be imported
            (:meth:`Store.sync_state`, :meth:`Store.import_session`,
            :meth:`Store.import_trial`; ``tactorbelt sync`` and ``run --push``).
        batch_commits: :meth:`Store.begin_batch` groups trial writes into fewer
            commits (simulated sessions only; see ``provenance.commit_mode``).
    """

    backend: str
    file: bool
    exclusive_writer: bool
    sync_target: bool = False
    batch_commits: bool = False
