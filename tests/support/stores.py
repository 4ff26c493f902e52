"""Store implementations for the store contract suite, and session/trial builders.

:data:`URLS` maps every scheme of :data:`tactorbelt.experiment.store.BACKENDS` to a
function giving a fresh store URL in a temporary directory (None: no server to test
against, skipped). A new implementation registered in BACKENDS is covered once it has
an entry here (e.g. PostgreSQL: a URL from ``TACTORBELT_TEST_POSTGRESQL_URL``).
"""

from __future__ import annotations

import hashlib
import sqlite3
from collections.abc import Callable
from pathlib import Path

import pytest

from support import pgserver
from tactorbelt.experiment.schedule import ScheduledTrial, make_schedule
from tactorbelt.experiment.store import BACKENDS, Store
from tactorbelt.experiment.study import paper_study
from tactorbelt.experiment.trial import TrialResult

__all__ = ["SCHEDULE", "URLS", "make_result", "make_schema_2", "make_session",
           "set_schema_version", "store_params"]

SCHEDULE: list[ScheduledTrial] = make_schedule(paper_study(), "P01")


def _sqlite_schema(url: str, version: int) -> None:
    conn = sqlite3.connect(url.removeprefix("sqlite://"))
    conn.execute("UPDATE meta SET value=? WHERE key='schema_version'", (str(version),))
    conn.commit()
    conn.close()


#: scheme -> (fresh URL in a temporary directory, or None to skip; set schema version).
URLS: dict[str, tuple[Callable[[Path], str | None], Callable[[str, int], None]]] = {
    "sqlite": (lambda tmp: f"sqlite://{tmp / 'contract.sqlite'}", _sqlite_schema),
    # a fresh database on TACTORBELT_TEST_POSTGRESQL_URL's server, or on a throwaway
    # server (support.pgserver); None (skipped) without psycopg or the server binaries
    "postgresql": (lambda tmp: pgserver.contract_url(), pgserver.set_schema_version),
}


def store_params() -> list[object]:
    """One pytest param per registered store scheme (skipped when not available)."""
    params: list[object] = []
    for scheme in sorted(BACKENDS):
        marks = []
        if scheme not in URLS:
            marks.append(pytest.mark.skip(reason=f"no test URL for {scheme} stores"))
        params.append(pytest.param(scheme, marks=marks, id=scheme))
    return params


def set_schema_version(scheme: str, url: str, version: int) -> None:
    URLS[scheme][1](url, version)


def make_schema_2(scheme: str, url: str) -> None:
    """Make a closed store look as a tactorbelt of schema 2 left it (no task_events, no
    ratings)."""
    drop = ("DROP TABLE {}task_events", "DROP TABLE {}ratings")
    if scheme == "sqlite":
        conn = sqlite3.connect(url.removeprefix("sqlite://"))
        for stmt in drop:
            conn.execute(stmt.format(""))
        conn.commit()
        conn.close()
    else:
        pgserver.run_sql(url, *(stmt.format("tactorbelt.") for stmt in drop))
    set_schema_version(scheme, url, 2)


def make_session(store: Store, participant: str = "P01", **extra: object) -> int:
    study = paper_study()
    text = study.to_toml()
    fields: dict[str, object] = {
        "participant": participant, "study_name": study.name, "study_toml": text,
        "study_sha256": hashlib.sha256(text.encode()).hexdigest(), "seed": 1,
        "condition_order": ["static", "dynamic"], "schedule": SCHEDULE, "belt": "sim",
        "package_version": "0.1.0",
    }
    fields.update(extra)
    return store.create_session(**fields)  # type: ignore[arg-type]


def make_result(index: int = 0, status: str = "done", n: int = 3) -> TrialResult:
    t = SCHEDULE[index]
    r = TrialResult(t, status=status, onset_ns=1_000_000_000 + index)
    if status == "done":
        r.acquired_ns = 1_500_000_000 + index
        r.rt_s = 0.5
        r.response_deg = t.target_deg
        r.response_target_deg = t.target_deg
        r.correct = True
    for k in range(n):
        r.sample_t_ns.append(1_000_000_000 + index + k * 10_000_000)
        r.sample_x.append(0.1 * k + index)
        r.sample_y.append(0.2 * k)
        r.sample_buttons.append(k % 2)
    return r
