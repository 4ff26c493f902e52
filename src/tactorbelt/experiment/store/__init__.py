"""Session stores: :class:`Store` and :func:`open_store` (:mod:`.sql`; constants: :mod:`.base`).

``from tactorbelt.experiment.store import Store, open_store``. The implementations,
:class:`~.sqlite.SQLiteStore` and :class:`~.postgresql.PostgreSQLStore`, share one SQL
core: the schema declared once with a dialect per database (:mod:`.schema`) and the
queries and methods, :class:`~.sql.Store`.
"""

from __future__ import annotations

from .base import (
    BACKENDS,
    RATING_COLUMNS,
    SAMPLE_COLUMNS,
    SCHEMA_VERSION,
    SESSION_STATUSES,
    TASK_EVENT_COLUMNS,
    TRIAL_STATUSES,
    StoreCapabilities,
    utc_now,
)
from .sql import Store, backend_for, open_store

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
    "utc_now",
]
