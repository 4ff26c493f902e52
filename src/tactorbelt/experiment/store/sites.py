"""Participant ids used at more than one site: found in session rows, refused by name.

A participant id names one person of one site (docs/multisite.md). A shared store holds
that rule itself since its schema 4 (a session's id must be registered to the session's
site), but a store written before, or sessions of a shared store read together with a
local store's, may still break it. Merging such sessions would count two people as one
(and a BIDS export would write one ``sub-`` folder for both, losing one), so the analysis
and the exports refuse them with :func:`check_one_site_per_participant`, naming the
sessions.

Pure: session rows in, an error out; no database driver.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Mapping
from typing import Any

from ..._errors import StoreError

__all__ = ["check_one_site_per_participant", "site_conflicts"]

#: How many participant ids the error names (then "...").
_SHOWN = 10


def site_conflicts(sessions: Iterable[Mapping[str, Any]]
                   ) -> dict[str, list[Mapping[str, Any]]]:
    """``{participant: its sessions}`` for every participant id whose sessions name two
    sites or more (a session without a site counts for none), in the order given."""
    by_id: dict[str, list[Mapping[str, Any]]] = {}
    for row in sessions:
        by_id.setdefault(str(row["participant"]), []).append(row)
    return {pid: rows for pid, rows in by_id.items()
            if len({str(r["site"]) for r in rows if _has_site(r)}) > 1}


def _has_site(row: Mapping[str, Any]) -> bool:
    site = row.get("site")
    return isinstance(site, str) and site != ""  # None, NaN, <NA>: no site


def check_one_site_per_participant(
        sessions: Iterable[Mapping[str, Any]], where: str, what: str, remedy: str,
        name: Callable[[Mapping[str, Any]], str] | None = None) -> None:
    """Raise StoreError when a participant id of ``sessions`` spans sites.

    Args:
        sessions: session rows (``participant``, ``site``, ``session_id``, and
            ``started_at`` when known).
        where: the store(s), for the message; ``what``: what is refused ("analysed",
            "exported"); ``remedy``: what the user can do (one sentence).
        name: how a session is named (default: ``session N``).
    """
    found = site_conflicts(sessions)
    if not found:
        return
    label = name or (lambda r: f"session {r['session_id']}")
    parts = []
    for pid, rows in list(found.items())[:_SHOWN]:
        named = ", ".join(
            f"{label(r)} at {r['site'] if _has_site(r) else 'no site'}"
            + (f" (started {r['started_at']})" if r.get("started_at") else "")
            for r in rows)
        parts.append(f"{pid!r}: {named}")
    more = f"; and {len(found) - _SHOWN} more" if len(found) > _SHOWN else ""
    raise StoreError(
        f"{where}: {len(found)} participant id(s) are used at more than one site, so "
        f"their sessions would be {what} as one person's: {'; '.join(parts)}{more}. A "
        "participant id names one person of one site (the sessions were written before "
        f"the store held that rule); {remedy} (docs/multisite.md, 'Participant ids "
        "that span sites')")
