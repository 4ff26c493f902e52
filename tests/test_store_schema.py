"""The store's schema is declared once (experiment/store/schema.py) and both SQL stores
make the same tables and columns from it; the queries are written once and compiled per
dialect."""

from __future__ import annotations

import sqlite3
from pathlib import Path
from typing import Any

import pytest

from tactorbelt.experiment.store import open_store
from tactorbelt.experiment.store.schema import (
    POSTGRESQL,
    SQLITE,
    TABLES,
    Dialect,
    columns,
    create_table,
    tables,
)

#: Columns only a dialect without rowid has: they keep the order rows were written in.
ORDER_COLUMNS = {("samples", "sample_index"), ("ratings", "rating_order")}
#: Tables only a store that several sites write has (row-level security, claimed ids).
MULTISITE_TABLES = {"run_options", "participants", "site_writers"}


def _declared(d: Dialect) -> dict[str, list[str]]:
    return {t.name: [c.name for c in columns(d, t.name)] for t in TABLES if d.has(t.only)}


def _sqlite_columns(path: Path) -> dict[str, list[tuple[str, str, bool]]]:
    conn = sqlite3.connect(path)
    try:
        names = [r[0] for r in conn.execute(
            "SELECT name FROM sqlite_master WHERE type='table' AND name NOT LIKE 'sqlite_%'")]
        return {t: [(str(r[1]), str(r[2]), bool(r[3]) or bool(r[5]))
                    for r in conn.execute(f"PRAGMA table_info({t})")] for t in names}
    finally:
        conn.close()


def _pg_columns(url: str) -> dict[str, list[tuple[str, str, bool]]]:
    import psycopg

    out: dict[str, list[tuple[str, str, bool]]] = {}
    with psycopg.connect(url) as conn:
        for t, c, typ, nullable in conn.execute(
                "SELECT table_name, column_name, data_type, is_nullable"
                " FROM information_schema.columns WHERE table_schema='tactorbelt'"
                " ORDER BY table_name, ordinal_position"):
            out.setdefault(t, []).append((c, typ.upper(), nullable == "NO"))
    return out


def test_both_dialects_render_the_one_declaration() -> None:
    """Every CREATE TABLE of either dialect comes from TABLES; the tables and columns of
    the two differ only by what a dialect's features add (order columns, multi-site
    tables)."""
    sqlite, pg = _declared(SQLITE), _declared(POSTGRESQL)
    assert set(pg) - set(sqlite) == MULTISITE_TABLES and set(sqlite) <= set(pg)
    for name, cols in sqlite.items():
        assert [c for c in pg[name] if (name, c) not in ORDER_COLUMNS] == cols, name
    for d, made in ((SQLITE, sqlite), (POSTGRESQL, pg)):
        creates = [create_table(d, t) for t in tables(d)]
        assert len(creates) == len(made)
        for stmt, name in zip(creates, made, strict=True):
            assert stmt.startswith(f"CREATE TABLE IF NOT EXISTS {d.table(name)}(")


def test_queries_are_written_once_and_compiled_per_dialect() -> None:
    text = ("SELECT t.session_id, p.t_s FROM samples p JOIN trials t USING (trial_id)"
            " WHERE t.session_id=? AND p.trial_id IN (?, ?)")
    assert SQLITE.sql(text) is text  # SQLite's spelling: unchanged, nothing to look up
    assert POSTGRESQL.sql(text) == (
        "SELECT t.session_id, p.t_s FROM tactorbelt.samples p JOIN tactorbelt.trials t"
        " USING (trial_id) WHERE t.session_id=%s AND p.trial_id IN (%s, %s)")
    # names that merely contain a table's name, or are qualified already, stay as they are
    assert POSTGRESQL.sql("SELECT n_samples, sessions_uuid FROM tactorbelt.meta") == \
        "SELECT n_samples, sessions_uuid FROM tactorbelt.meta"
    assert SQLITE.upsert("meta", ("key", "value"), ("key",)) == \
        "INSERT OR REPLACE INTO meta(key, value) VALUES (?, ?)"
    assert POSTGRESQL.upsert("meta", ("key", "value"), ("key",)) == (
        "INSERT INTO tactorbelt.meta(key, value) VALUES (%s, %s)"
        " ON CONFLICT (key) DO UPDATE SET value=EXCLUDED.value")


def test_fresh_stores_of_both_dialects_have_the_same_tables_and_columns(
        tmp_path: Path, pg_url: str) -> None:
    """A fresh SQLite store (PRAGMA table_info) and a fresh PostgreSQL store
    (information_schema) hold the declared tables and columns, in the declared order;
    each logical type is one SQL type per dialect, and NOT NULL is the same but where
    an added column keeps NULL in old SQLite rows (``load``)."""
    open_store(tmp_path / "s.sqlite").close()
    open_store(pg_url).close()
    lite, pg = _sqlite_columns(tmp_path / "s.sqlite"), _pg_columns(pg_url)
    assert {t: [c[0] for c in cols] for t, cols in lite.items()} == _declared(SQLITE)
    assert {t: [c[0] for c in cols] for t, cols in pg.items()} == _declared(POSTGRESQL)
    types: dict[tuple[str, str], set[str]] = {}
    for name, cols in lite.items():
        pg_cols = {c[0]: c for c in pg[name]}
        declared = {c.name: c for c in columns(SQLITE, name)}
        for col, lite_type, lite_nn in cols:
            _, pg_type, pg_nn = pg_cols[col]
            kind = declared[col].type
            types.setdefault((kind, "sqlite"), set()).add(lite_type)
            types.setdefault((kind, "postgresql"), set()).add(pg_type)
            assert lite_nn == pg_nn or (name, col) == ("trials", "load"), (name, col)
    for (kind, dialect), seen in types.items():
        d = SQLITE if dialect == "sqlite" else POSTGRESQL
        want = d.types[kind].split(" GENERATED")[0].split(" PRIMARY")[0]
        assert seen == {want}, (kind, dialect, seen)


@pytest.mark.parametrize("scheme", ["sqlite", "postgresql"])
def test_a_store_missing_the_newer_columns_and_tables_is_migrated_to_the_declaration(
        tmp_path: Path, scheme: str, request: pytest.FixtureRequest) -> None:
    """An old store (no identity columns, no schema-2 columns, no schema-3 tables) gets
    exactly the declared columns, in order, when a writer opens it, and its sessions get
    uuids."""
    from support import pgserver
    from support.stores import make_session

    dialect = SQLITE if scheme == "sqlite" else POSTGRESQL
    url: Any = tmp_path / "old.sqlite" if scheme == "sqlite" else request.getfixturevalue(
        "pg_url")
    with open_store(url) as store:
        make_session(store)
    # every column added to a table after its first version (declared ``added``)
    drop = [(t, c.name) for t in ("sessions", "trials") for c in columns(dialect, t)
            if c.added]
    assert ("sessions", "session_uuid") in drop and ("trials", "load") in drop
    p = dialect.table("")  # the namespace's prefix
    stmts = [f"DROP INDEX {p}sessions_uuid",
             *(f"ALTER TABLE {p}{t} DROP COLUMN {c}" for t, c in drop),
             f"DROP TABLE {p}task_events", f"DROP TABLE {p}ratings",
             f"UPDATE {p}meta SET value='1' WHERE key='schema_version'"]
    if scheme == "sqlite":
        conn = sqlite3.connect(url)
        for stmt in stmts:
            conn.execute(stmt)
        conn.commit()
        conn.close()
    else:
        pgserver.run_sql(url, *stmts)

    def have() -> dict[str, list[str]]:
        cols = _sqlite_columns(url) if scheme == "sqlite" else _pg_columns(url)
        return {t: [c[0] for c in cs] for t, cs in cols.items()}

    assert "task_events" not in have() and "load" not in have()["trials"]
    with open_store(url) as store:
        (row,) = store.sessions()
        assert row["session_uuid"] and row["site"] is None
    assert have() == _declared(dialect)
