"""The store's schema, declared once, and the SQL dialects it is written in.

:data:`TABLES` and :data:`INDEXES` declare every table, column and index of a store;
:func:`create_table`, :func:`create_index` and :func:`migrate` write them in a
:class:`Dialect` (:data:`SQLITE`, :data:`POSTGRESQL`), as SQLAlchemy Core compiles one
table definition per dialect, without SQLAlchemy. The queries are written once too
(in :mod:`.sql`): in SQLite's spelling (``?`` placeholders, bare table names), which
:meth:`Dialect.sql` turns into the other dialect's (``%s``, ``tactorbelt.trials``).

What differs between the dialects, and only that, is a :class:`Dialect`'s fields:
placeholders, the namespace, column types and the identity column, ``INSERT ...
RETURNING`` or the cursor's lastrowid, upserts, row locks, how long an ``IN`` list may
be, how a boolean is bound, and its features:

- ``rowid``: rows keep the order they were written in (SQLite's rowid); a dialect
  without it (``order_columns``) has an order column where that order matters
  (``samples.sample_index``, ``ratings.rating_order``);
- ``multisite``: several sites write the store: row-level security by site, participant
  ids claimed by a site, run options in their own table (a writer may not write
  ``meta``);
- ``backfill``: a column added to an older store takes its default in the old rows
  (PostgreSQL's ``load``: ``'none'``); without it old rows keep NULL, which the
  readers take as the study's value (SQLite).

Pure: no database driver is imported here.
"""

from __future__ import annotations

import re
import uuid
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from ...factors import CONDITION, LOAD, TARGETS, added_factors
from .base import SESSION_STATUSES, TRIAL_STATUSES

__all__ = [
    "INDEXES", "POSTGRESQL", "SQLITE", "TABLES", "TABLE_NAMES", "Column", "Dialect", "Index",
    "Table", "columns", "create_index", "create_table", "migrate",
    "missing_columns", "table",
]


@dataclass(frozen=True)
class Column:
    """A column: its logical type (a key of :attr:`Dialect.types`) and constraints.

    ``only`` names the dialect feature it needs (``order_columns``...); ``added``: it was
    added to the table after the table's first version (see ``backfill``); ``required``:
    ``"column"`` when every store has it (a bare store too) or ``"value"`` when, moreover,
    it is never NULL there.
    """

    name: str
    type: str
    not_null: bool = False
    default: str | None = None
    check: tuple[str, ...] = ()
    references: str | None = None
    cascade: bool = False
    primary_key: bool = False
    added: bool = False
    only: str | None = None
    required: str | None = None


@dataclass(frozen=True)
class Table:
    """A table; ``order`` orders its rows as written where the dialect has no rowid."""

    name: str
    columns: tuple[Column, ...]
    unique: tuple[tuple[str, ...], ...] = ()
    primary_key: tuple[str, ...] = ()
    only: str | None = None
    order: str = ""


@dataclass(frozen=True)
class Index:
    name: str
    table: str
    columns: tuple[str, ...]
    unique: bool = False
    only: str | None = None


def _c(name: str, type_: str, *, nn: bool = False, req: str | None = None,
       **kw: Any) -> Column:
    return Column(name, type_, not_null=nn, required=req, **kw)


def _cs(type_: str, *names: str, nn: bool = False, req: str | None = None,
        **kw: Any) -> tuple[Column, ...]:
    """Several columns alike."""
    return tuple(_c(n, type_, nn=nn, req=req, **kw) for n in names)


TABLES: tuple[Table, ...] = (
    Table("meta", (_c("key", "text", primary_key=True), _c("value", "text", nn=True))),
    Table("sessions", (
        _c("session_id", "id", req="column"),
        _c("participant", "text", nn=True, req="value"),
        _c("session_number", "int", nn=True),
        *_cs("text", "study_name", "study_sha256", "study_toml", nn=True, req="column"),
        _c("seed", "int64", nn=True, req="column"),
        _c("condition_order", "text", nn=True, req="column"),
        _c("schedule_json", "text", nn=True),
        _c("n_trials", "int", nn=True),
        *_cs("text", "belt", "firmware_version", req="column"),
        _c("calibration_json", "text"),
        _c("package_version", "text", req="column"),
        *_cs("text", "git_commit", "host", "input", "clock"),
        _c("started_at", "text", nn=True, req="column"),
        _c("ended_at", "text", req="column"),
        _c("status", "text", nn=True, check=SESSION_STATUSES, req="column"),
        _c("resumed", "int", nn=True, default="0"),
        # multi-site identity: a uuid4 naming the session in every store, and its lab
        *_cs("text", "session_uuid", "site", added=True),
    )),
    Table("trials", (
        _c("trial_id", "id", req="column"),
        _c("session_id", "ref", nn=True, references="sessions", req="value"),
        _c("trial_index", "int", nn=True, req="column"),
        _c("block", "text", nn=True, check=("training", "test"), req="value"),
        _c("block_index", "int", nn=True),
        _c("block_name", "text", nn=True),
        _c(CONDITION.column, CONDITION.type, nn=True, req="value"),
        _c("repetition", "int", nn=True, req="column"),
        _c("target_deg", "real", nn=True, req="value"),
        _c("on_tactor", "int", nn=True, req="value"),
        *_cs("real", "response_deg", "response_target_deg", req="column"),
        _c("correct", "int", req="column"),
        _c("rt_s", "real", req="column"),
        _c("onset_ns", "int64", req="column"),
        *_cs("int64", "acquired_ns", "crossed_ns", "stimulus_off_ns"),
        _c("n_samples", "int", nn=True),
        _c("status", "text", nn=True, check=TRIAL_STATUSES, req="value"),
        _c("abort_reason", "text"),
        _c("attempts", "int", nn=True, default="1"),
        _c("recorded_at", "text", nn=True),
        # schema 2: factorial designs and device-side onsets
        _c(TARGETS.column, TARGETS.type, added=True),
        _c(LOAD.column, LOAD.type, nn=True, default=repr(LOAD.default), added=True),
        *_cs("int64", "device_onset_ns", "onset_uncertainty_ns", added=True),
        # the onset at the skin: the stored onset plus the starting tactors' measured
        # latency (``tactorbelt validate onsets``), and its spread; NULL without one
        *_cs("int64", "skin_onset_ns", "skin_onset_sd_ns", added=True),
    ), unique=(("session_id", "trial_index"),)),
    Table("samples", (
        _c("trial_id", "ref", nn=True, references="trials", cascade=True, req="value"),
        _c("sample_index", "int", nn=True, only="order_columns"),
        *_cs("real", "t_s", "x", "y", nn=True, req="value"),
        _c("buttons", "int", nn=True, req="value"),
    ), primary_key=("trial_id", "sample_index"), order="sample_index"),
    Table("run_options", (_c("session_id", "ref", primary_key=True, references="sessions"),
                          _c("options", "text", nn=True)), only="multisite"),
    Table("participants", (_c("participant", "text", primary_key=True),
                           _c("site", "text", nn=True)), only="multisite"),
    Table("site_writers", (_c("role_name", "text", primary_key=True),
                           _c("site", "text", nn=True)), only="multisite"),
    # schema 3: secondary tasks and workload ratings
    Table("task_events", (
        _c("event_id", "id"),
        _c("session_id", "ref", nn=True, references="sessions"),
        _c("block_index", "int", nn=True),
        _c("task", "text", nn=True),
        _c("phase", "text", nn=True, check=("practice", "baseline", "dual")),
        _c("item_index", "int", nn=True),
        _c("t_ns", "int64", nn=True),
        _c("stimulus", "text"),
        _c("target", "bool", nn=True),
        _c("response", "text", nn=True),
        _c("correct", "bool", nn=True),
        _c("rt_s", "real"),
    ), order="event_id"),
    Table("ratings", (
        _c("session_id", "ref", nn=True, references="sessions"),
        _c("block_index", "int", nn=True),
        *_cs("text", "scale", "item", nn=True),
        _c("value", "real", nn=True),
        _c("rating_order", "int", nn=True, default="0", only="order_columns"),
    ), primary_key=("session_id", "block_index", "scale", "item"),
        order="scale, rating_order"),
)
INDEXES: tuple[Index, ...] = (
    Index("task_events_session", "task_events", ("session_id",)),
    Index("trials_session", "trials", ("session_id",)),
    # where samples have no order column, their primary key indexes trial_id
    Index("samples_trial", "samples", ("trial_id",), only="rowid"),
    Index("sessions_participant", "sessions", ("participant",)),
    Index("sessions_uuid", "sessions", ("session_uuid",), unique=True),
    Index("sessions_site", "sessions", ("site",), only="multisite"),
)
TABLE_NAMES = tuple(t.name for t in TABLES)
_BY_NAME = {t.name: t for t in TABLES}


def table(name: str, *, added: bool = True) -> Table:
    """A table as declared, the trials with a column for each added factor (unless
    ``added`` is False; old rows: NULL, which the readers take as the factor's default)."""
    t = _BY_NAME[name]
    extra = added_factors() if name == "trials" and added else ()
    columns = tuple(_c(f.column, f.type, added=True) for f in extra)
    return replace(t, columns=t.columns + columns) if extra else t


@dataclass(eq=False)
class Dialect:
    """How one database spells the schema and the queries (see the module doc)."""

    name: str
    #: The placeholder of a bound value.
    param: str
    #: The database schema holding the tables ("" for none).
    namespace: str
    #: Logical type -> SQL type; ``id`` is the whole declaration of an identity key.
    types: Mapping[str, str]
    features: frozenset[str]
    #: New ids come from ``INSERT ... RETURNING`` (else the cursor's ``lastrowid``).
    returning: bool
    #: What a SELECT appends to lock the rows it reads until the transaction ends.
    lock: str
    #: How many values an ``IN (...)`` list may bind (None: one array, ``= ANY(?)``).
    max_in: int | None
    #: How a boolean is bound (int: 0/1).
    bool_value: Callable[[Any], Any]
    #: ``replace`` (INSERT OR REPLACE) or ``on_conflict`` (ON CONFLICT DO UPDATE).
    upsert_style: str
    #: A query of the names of the store's tables; of a table's columns (``?``: it).
    tables_query: str
    columns_query: str
    _compiled: dict[str, str] = field(default_factory=dict, repr=False)
    _names: re.Pattern[str] = field(
        default=re.compile(rf"(?<![\w.])({'|'.join(TABLE_NAMES)})\b(?!\.)"), repr=False)

    def has(self, feature: str | None) -> bool:
        return feature is None or feature in self.features

    def table(self, name: str) -> str:
        return f"{self.namespace}.{name}" if self.namespace else name

    def sql(self, text: str) -> str:
        """A query written in SQLite's spelling, in this dialect's (computed once)."""
        if not self.namespace and self.param == "?":
            return text
        try:
            return self._compiled[text]
        except KeyError:
            pass
        out = self._names.sub(lambda m: self.table(m.group(1)), text).replace("?", self.param)
        if len(self._compiled) > 512:  # queries with column lists of the caller's choice
            self._compiled.clear()
        self._compiled[text] = out
        return out

    def order(self, name: str) -> str:
        """What orders a table's rows as written (rowid, or its order column)."""
        return "rowid" if "rowid" in self.features else table(name).order

    def insert(self, name: str, cols: Sequence[str]) -> str:
        return self.sql(f"INSERT INTO {name}({', '.join(cols)}) "
                        f"VALUES ({', '.join('?' * len(cols))})")

    def upsert(self, name: str, cols: Sequence[str], keys: Sequence[str]) -> str:
        """An INSERT that replaces the row with the same ``keys``."""
        text = self.insert(name, cols)
        if self.upsert_style == "replace":
            return text.replace("INSERT INTO", "INSERT OR REPLACE INTO", 1)
        sets = ", ".join(f"{c}=EXCLUDED.{c}" for c in cols if c not in keys)
        return f"{text} ON CONFLICT ({', '.join(keys)}) DO UPDATE SET {sets}"

    def any_of(self, values: Sequence[Any]) -> tuple[str, Sequence[Any]]:
        """``(condition, args)``: the column is one of ``values`` (at most ``max_in``), in
        SQLite's spelling (for :meth:`sql`)."""
        if self.max_in is None:
            return "= ANY(?)", (list(values),)
        return f"IN ({', '.join('?' * len(values))})", list(values)


SQLITE = Dialect(
    "sqlite", param="?", namespace="",
    types={"id": "INTEGER PRIMARY KEY AUTOINCREMENT", "ref": "INTEGER", "int": "INTEGER",
           "int64": "INTEGER", "real": "REAL", "text": "TEXT", "bool": "INTEGER"},
    features=frozenset({"rowid"}), returning=False, lock="",
    max_in=500,  # stay well under SQLite's parameter limit
    bool_value=int, upsert_style="replace",
    tables_query="SELECT name FROM sqlite_master WHERE type='table'",
    columns_query="SELECT name FROM pragma_table_info(?)",
)
POSTGRESQL = Dialect(
    "postgresql", param="%s", namespace="tactorbelt",
    types={"id": "BIGINT GENERATED BY DEFAULT AS IDENTITY PRIMARY KEY", "ref": "BIGINT",
           "int": "INTEGER", "int64": "BIGINT", "real": "DOUBLE PRECISION", "text": "TEXT",
           "bool": "BOOLEAN"},
    features=frozenset({"order_columns", "multisite", "backfill"}), returning=True,
    lock=" FOR UPDATE", max_in=None, bool_value=bool, upsert_style="on_conflict",
    tables_query="SELECT table_name FROM information_schema.tables"
                 " WHERE table_schema='tactorbelt'",
    columns_query="SELECT column_name FROM information_schema.columns"
                  " WHERE table_schema='tactorbelt' AND table_name=? ORDER BY ordinal_position",
)


def tables(d: Dialect) -> Iterator[Table]:
    return (table(t.name) for t in TABLES if d.has(t.only))


def columns(d: Dialect, name: str) -> tuple[Column, ...]:
    """The columns ``name`` has in dialect ``d``, in order."""
    return tuple(c for c in table(name).columns if d.has(c.only))


def _column_sql(d: Dialect, c: Column) -> str:
    parts = [c.name, d.types[c.type]]
    if c.primary_key:
        parts.append("PRIMARY KEY")
    keeps_null = c.added and not d.has("backfill")  # old rows keep NULL
    if c.not_null and not keeps_null:
        parts.append("NOT NULL")
    if c.default is not None and not keeps_null:
        parts.append(f"DEFAULT {c.default}")
    if c.check:
        parts.append(f"CHECK ({c.name} IN ({','.join(repr(v) for v in c.check)}))")
    if c.references:
        ref = table(c.references)
        parts.append(f"REFERENCES {d.table(ref.name)}({ref.columns[0].name})")
        if c.cascade:
            parts.append("ON DELETE CASCADE")
    return " ".join(parts)


def create_table(d: Dialect, t: Table) -> str:
    cols = columns(d, t.name)
    lines = [_column_sql(d, c) for c in cols]
    names = {c.name for c in cols}
    lines += [f"UNIQUE({', '.join(u)})" for u in t.unique]
    if t.primary_key and names.issuperset(t.primary_key):
        lines.append(f"PRIMARY KEY ({', '.join(t.primary_key)})")
    body = ",\n    ".join(lines)
    return f"CREATE TABLE IF NOT EXISTS {d.table(t.name)}(\n    {body}\n)"


def create_index(d: Dialect, name: str) -> str:
    i = next(i for i in INDEXES if i.name == name)
    return (f"CREATE {'UNIQUE ' if i.unique else ''}INDEX IF NOT EXISTS {i.name} ON "
            f"{d.table(i.table)}({', '.join(i.columns)})")


def missing_columns(d: Dialect, have: set[tuple[str, str]]) -> list[tuple[str, str]]:
    """The declared ``(table, column)`` pairs of dialect ``d`` that are not in ``have``."""
    return [(t.name, c.name) for t in tables(d) for c in columns(d, t.name)
            if (t.name, c.name) not in have]


def migrate(conn: Any, d: Dialect) -> None:
    """Create what a store lacks (tables, columns added since, indexes) and give every
    session a uuid, inside the caller's transaction (``conn.execute(sql, args)``)."""
    if d.namespace:
        conn.execute(f"CREATE SCHEMA IF NOT EXISTS {d.namespace}")
    for t in tables(d):
        conn.execute(create_table(d, t))
    for t in tables(d):
        have = {str(r[0]) for r in conn.execute(d.sql(d.columns_query), (t.name,)).fetchall()}
        for c in columns(d, t.name):
            if c.name not in have:
                conn.execute(f"ALTER TABLE {d.table(t.name)} ADD COLUMN {_column_sql(d, c)}")
    for i in INDEXES:
        if d.has(i.only):
            conn.execute(create_index(d, i.name))
    for (sid,) in conn.execute(
            d.sql("SELECT session_id FROM sessions WHERE session_uuid IS NULL")).fetchall():
        conn.execute(d.sql("UPDATE sessions SET session_uuid=? WHERE session_id=?"),
                     (str(uuid.uuid4()), sid))
