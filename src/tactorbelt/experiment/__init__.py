"""The user study: study files, schedules, the trial state machine, the store, the runner.

- :mod:`.study`: :func:`load_study`, :class:`Study`, :func:`paper_study` (TOML + pydantic);
- :mod:`.schedule`: :func:`make_schedule` (pure, seeded), :class:`ScheduledTrial`;
- :mod:`.trial`: :class:`TrialMachine` (pure state machine), :class:`TrialResult`;
- :mod:`.store`: :class:`Store` (the store interface), :func:`open_store` (by URL; the
  SQLite store: WAL, one transaction per trial);
- :mod:`.runner`: :func:`run_session`; :mod:`.listeners`: :class:`SessionObserver`,
  :class:`Command`;
- :mod:`.export`: :func:`export_csv`, :func:`export_bids`.

Names are imported lazily, so ``import tactorbelt.experiment`` costs nothing.
"""

from __future__ import annotations

from .._registry import lazy_attributes

__all__ = [
    "Command",
    "NullObserver",
    "ScheduledTrial",
    "SessionObserver",
    "SessionResult",
    "Store",
    "Study",
    "TrialMachine",
    "TrialResult",
    "TrialState",
    "export_bids",
    "export_csv",
    "load_study",
    "make_schedule",
    "open_store",
    "paper_study",
    "run_session",
]

_LAZY = {
    "Study": "study", "load_study": "study", "paper_study": "study",
    "ScheduledTrial": "schedule", "make_schedule": "schedule",
    "TrialMachine": "trial", "TrialResult": "trial", "TrialState": "trial",
    "Store": "store", "open_store": "store",
    "Command": "listeners", "NullObserver": "listeners", "SessionObserver": "listeners",
    "SessionResult": "runner", "run_session": "runner",
    "export_csv": "export", "export_bids": "export",
}


__getattr__ = lazy_attributes(__name__, {k: f".{v}" for k, v in _LAZY.items()})


def __dir__() -> list[str]:
    return sorted(__all__)
