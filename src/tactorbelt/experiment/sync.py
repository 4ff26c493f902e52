"""Copy sessions from a lab's local store into a shared store (``tactorbelt sync``, and
the runner's background push).

Sessions are matched by their globally unique ``session_uuid``, trials by
``(session, trial_index)`` with their status and attempts, so a copy brings over exactly
what the target lacks and running it twice changes nothing. A session's secondary-task
events and workload ratings (schema 3) are copied with it: rewritten in one
transaction when the target's copy differs (events: fewer rows, as they are only
appended), left alone otherwise. A session is first copied
``running`` (so an analysis of complete sessions never sees it half copied), then its
trials, each with its samples in one transaction, then its status.

:class:`Pusher` does this in a background thread after every stored trial while a
session runs: the local store stays the one written first (durable on the machine with
the belt); a lost connection leaves the trials in the local store (they are the queue),
and a reconnect catches up.

I/O edge: only the :class:`~tactorbelt.experiment.store.Store` interface.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

from .._errors import StoreError
from .listeners import SessionInfo, SessionListener
from .provenance import default_site
from .schedule import ScheduledTrial
from .store import Store, open_store
from .trial import TrialResult

__all__ = ["Pusher", "SyncReport", "check_push", "check_sites", "sync_session", "sync_store",
           "sync_stores"]

FINAL = ("done", "timeout")


@dataclass
class SyncReport:
    """What a copy did: sessions new there, sessions updated, trials and samples copied,
    and the trials that were there already."""

    sessions_new: int = 0
    sessions_updated: int = 0
    trials: int = 0
    samples: int = 0
    already: int = 0
    errors: list[str] = field(default_factory=list)
    task_events: int = 0
    ratings: int = 0

    def add(self, other: SyncReport) -> None:
        """Count ``other``'s copies (and errors) in this report too."""
        for f in fields(self):
            setattr(self, f.name, getattr(self, f.name) + getattr(other, f.name))

    def summary(self, target: str) -> str:
        if not (self.sessions_new or self.sessions_updated or self.trials
                or self.task_events or self.ratings):
            return f"{target} is up to date ({self.already} trials there already)"
        extra = ""
        if self.task_events or self.ratings:
            extra = (f", {self.task_events} task event(s) and {self.ratings} rating(s) "
                     "rewritten")
        return (f"pushed to {target}: {self.sessions_new} new session(s), "
                f"{self.sessions_updated} updated, {self.trials} trial(s) with "
                f"{self.samples} samples{extra} ({self.already} trials there already)")


def _mutable(row: Mapping[str, Any]) -> dict[str, Any]:
    return {"ended_at": row.get("ended_at"), "status": row.get("status"),
            "resumed": int(row.get("resumed") or 0)}


def sync_session(local: Store, remote: Store, row: Mapping[str, Any],
                 site: str | None = None) -> SyncReport:
    """Copy one local session (its row from ``local.sessions()``) into ``remote``.

    Raises:
        StoreError: the remote store cannot take copies, the participant id is taken at
            another site, the connection failed (what was copied stays copied).
    """
    rep = SyncReport()
    uuid = row.get("session_uuid")
    if not uuid:
        raise StoreError(f"{local.url}: session {row['session_id']} has no session_uuid; "
                         "open the store for writing once (tactorbelt sync does) to give it one")
    full = dict(row)
    if not full.get("site"):
        full["site"] = site or default_site()
    state = remote.sync_state(uuid)
    if state is None:
        sid = remote.import_session(full | {"status": "running", "ended_at": None})
        there: dict[int, tuple[str, int]] = {}
        rep.sessions_new = 1
        have = {"status": "running", "ended_at": None, "resumed": full.get("resumed") or 0}
    else:
        sid, have, there = state
    for t in local.trials(int(row["session_id"])):
        key = (str(t["status"]), int(t["attempts"]))
        old = there.get(int(t["trial_index"]))
        if old == key or (old is not None and old[0] in FINAL):
            rep.already += 1
            continue
        samples = local.samples(int(t["trial_id"]))
        if remote.import_trial(sid, t, samples):
            rep.trials += 1
            rep.samples += len(samples)
        else:
            rep.already += 1
    local_id = int(row["session_id"])
    rep.task_events += remote.import_task_events(sid, local.task_events(local_id))
    rep.ratings += remote.import_ratings(sid, local.ratings(local_id))
    if _mutable(have) != _mutable(full):
        remote.import_session(full)
        rep.sessions_updated += 0 if rep.sessions_new else 1
    return rep


def check_push(url: str, participant: str, site: str) -> None:
    """A run's check before its first trial (``tactorbelt run --push URL``): the shared
    store is reachable, this login may write sessions of ``site``
    (:meth:`~tactorbelt.experiment.store.Store.check_site`), and the participant id is
    free for ``site`` (claimed for it: the one thing written).

    Raises:
        StoreError: the server cannot be reached or refuses the login; the role writes
            another site, or none; the id is taken at another site.
    """
    with open_store(url) as remote:
        remote.check_site(site)
        remote.claim_participant(participant, site)


def check_sites(local: Store, remote: Store, rows: list[dict[str, Any]],
                site: str | None = None) -> None:
    """Refuse (StoreError, before anything is copied) sessions of a site that
    ``remote``'s login may not write, naming them."""
    by_site: dict[str, list[str]] = {}
    for row in rows:
        name = f"session {row['session_id']} ({row['participant']})"
        by_site.setdefault(str(row.get("site") or site or default_site()), []).append(name)
    for s, names in sorted(by_site.items()):
        try:
            remote.check_site(s)
        except StoreError as exc:
            shown = ", ".join(names[:5]) + (", ..." if len(names) > 5 else "")
            raise StoreError(f"{exc}. Nothing was pushed from {local.url}: its {shown} "
                             f"{'is' if len(names) == 1 else 'are'} of site {s!r}") from None


def sync_store(local: Store, remote: Store, *, site: str | None = None,
               session_ids: set[int] | None = None) -> SyncReport:
    """Copy every session of ``local`` (or those in ``session_ids``) into ``remote``.

    First, every one of them must be of a site that ``remote``'s login may write
    (:func:`check_sites`: else StoreError and nothing is copied). A session refused by
    the remote (a participant id taken at another site) is reported in
    :attr:`SyncReport.errors` and the others are copied.
    """
    if not remote.capabilities.sync_target:
        raise StoreError(f"{remote.url}: a {remote.capabilities.backend} store does not take "
                         "copied sessions; push to a postgresql:// store")
    rep = SyncReport()
    rows = [row for row in local.sessions()
            if session_ids is None or int(row["session_id"]) in session_ids]
    check_sites(local, remote, rows, site)
    for row in rows:
        try:
            rep.add(sync_session(local, remote, row, site))
        except StoreError as exc:
            if "already taken" not in str(exc):
                raise
            rep.errors.append(f"session {row['session_id']} ({row['participant']}): {exc}")
    return rep


def sync_stores(local: str | Path, url: str, *, site: str | None = None) -> SyncReport:
    """``tactorbelt sync LOCAL URL``: push whatever of the local store ``url`` lacks.

    The local store is opened for writing (older stores get their session uuids), so it
    must not be in use by a run (whose own push does the same meanwhile).
    """
    with open_store(local, create=False) as src, open_store(url) as dst:
        return sync_store(src, dst, site=site)


class Pusher(SessionListener):
    """Pushes a running session's trials from the local store to a shared one, in a
    background thread, after each stored trial: a listener of the session
    (:meth:`on_session_start` watches it, :meth:`on_trial_done` pushes).

    Args:
        local: the local store's path (read with a read-only connection of its own).
        url: the shared store's URL.
        site: the site of sessions that have none.
        retry_s: seconds between attempts while the shared store is unreachable.
        opener: opens the shared store (tests inject failures).
    """

    def __init__(self, local: str | Path, url: str, *, site: str | None = None,
                 retry_s: float = 2.0,
                 opener: Callable[[str], Store] | None = None) -> None:
        self.local, self.url, self.site, self.retry_s = local, url, site, retry_s
        self._open = opener or (lambda u: open_store(u))
        self._sessions: set[int] = set()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        self._remote: Store | None = None
        self.report = SyncReport()
        #: The last error (a lost connection), None after a successful pass.
        self.error: str | None = None
        #: Final trials of the watched sessions not yet in the shared store (None:
        #: never connected).
        self.pending: int | None = None
        self.passes = 0

    def start(self) -> Pusher:
        self._thread = threading.Thread(target=self._loop, name="tactorbelt-push", daemon=True)
        self._thread.start()
        return self

    def on_session_start(self, info: SessionInfo, schedule: list[ScheduledTrial]) -> None:
        """Push this local session (from now on, after each trial)."""
        with self._lock:
            self._sessions.add(int(info.session_id))
        self._wake.set()

    def on_trial_done(self, result: TrialResult) -> None:
        """A trial was stored locally: push it soon."""
        self._wake.set()

    def close(self, wait_s: float = 10.0) -> int | None:
        """Push what is left (waiting at most ``wait_s``), stop; the trials not pushed
        (0: all there; None: the shared store was never reached)."""
        deadline = time.monotonic() + wait_s
        failures = 0
        while self._thread is not None and self._thread.is_alive() \
                and time.monotonic() < deadline and failures < 2:
            done = self.passes
            self._wake.set()
            while self.passes == done and time.monotonic() < deadline:
                time.sleep(0.02)
            if self.error is None and self.pending == 0:
                break
            failures += self.error is not None  # unreachable: one more try, then stop
            time.sleep(min(0.5, max(0.0, deadline - time.monotonic())))
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(timeout=max(1.0, self.retry_s + 1.0))
        if self._remote is not None:
            with contextlib.suppress(Exception):
                self._remote.close()
            self._remote = None
        return self.pending

    def _loop(self) -> None:
        while not self._stop.is_set():
            self._wake.wait(timeout=self.retry_s)
            self._wake.clear()
            if self._stop.is_set():
                break
            self._pass()
            self.passes += 1

    def _pass(self) -> None:
        with self._lock:
            ids = set(self._sessions)
        if not ids:
            return
        try:
            if self._remote is None:
                self._remote = self._open(self.url)
            with open_store(self.local, create=False, readonly=True, verify=False) as src:
                rep = sync_store(src, self._remote, site=self.site, session_ids=ids)
                pending = 0
                for sid in ids:
                    uuid = src.session(sid).get("session_uuid")
                    state = self._remote.sync_state(str(uuid)) if uuid else None
                    there = state[2] if state else {}
                    pending += sum(1 for t in src.trials(sid) if t["status"] in FINAL
                                   and there.get(int(t["trial_index"]), ("",))[0] not in FINAL)
            self.report.add(rep)
            self.pending = pending
            self.error = "; ".join(rep.errors) or None
        except Exception as exc:  # a lost connection, a refused session: retry later
            self.error = str(exc) if isinstance(exc, StoreError) else f"{type(exc).__name__}: {exc}"
            if self._remote is not None:
                with contextlib.suppress(Exception):
                    self._remote.close()
                self._remote = None
