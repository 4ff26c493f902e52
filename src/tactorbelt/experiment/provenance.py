"""Provenance of a session: the package version, the git commit and the host.

Stored with every new session (see :meth:`tactorbelt.experiment.store.Store.create_session`)
so a data set says which code and machine produced it.

Imports only the standard library (and tactorbelt's version).
"""

from __future__ import annotations

import os
import socket
import subprocess
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from .. import __version__

__all__ = ["BATCH_TRIALS", "COMMITS_BATCHED", "COMMITS_PER_TRIAL", "SITE_ENV",
           "Provenance", "collect", "commit_mode", "default_site", "git_commit"]

#: The environment variable naming the lab (site) a session runs at.
SITE_ENV = "TACTORBELT_SITE"


@lru_cache(maxsize=1)
def git_commit() -> str | None:
    """The commit of the source tree tactorbelt runs from, or None outside a git checkout."""
    here = Path(__file__).resolve().parent
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=here, capture_output=True,
                             text=True, timeout=2, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    commit = out.stdout.strip()
    return commit if out.returncode == 0 and len(commit) == 40 else None


@dataclass(frozen=True)
class Provenance:
    """Where a session ran: the package version, the git commit (or None) and the host."""

    package_version: str
    git_commit: str | None
    host: str


def collect() -> Provenance:
    """The provenance of this process."""
    return Provenance(__version__, git_commit(), socket.gethostname())


def default_site() -> str:
    """The site of a session when none is given: ``TACTORBELT_SITE``, else the host name."""
    return os.environ.get(SITE_ENV, "").strip() or socket.gethostname()


#: Each trial is committed (and synced to disk) on its own: a crash loses at most the
#: trial in flight. Every session with a person, a real belt or the wall clock.
COMMITS_PER_TRIAL = "per-trial"
#: Trials are committed in batches of :data:`BATCH_TRIALS` (and at the end): a session on
#: a simulated clock with the model participant on the sim belt, which a rerun with the
#: same seed reproduces exactly, so a crash loses nothing that cannot be made again (and
#: the batch's commits skip the fsync: SQLite's synchronous=NORMAL while it lasts).
COMMITS_BATCHED = "batched"
#: Trials per commit when a session batches its commits.
BATCH_TRIALS = 64


def commit_mode(*, simulated_clock: bool, hardware_belt: bool, person: bool,
                observer: bool) -> str:
    """How a session commits its trials: :data:`COMMITS_BATCHED` only when nothing real
    is involved (a simulated clock, no belt hardware, no person moving the cursor and no
    window or other observer), else :data:`COMMITS_PER_TRIAL`. Stored with the session
    (``Store.commit_mode``)."""
    if simulated_clock and not hardware_belt and not person and not observer:
        return COMMITS_BATCHED
    return COMMITS_PER_TRIAL
