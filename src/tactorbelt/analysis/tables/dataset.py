"""The loaded tables of one or more stores, as plain pandas data.

:func:`tactorbelt.analysis.tables.load.load_stores` fills a :class:`StoreData`; the pure
layers (tables, stats, figures) take it without knowing about files.

Pure: imports only the standard library (pandas for type checking).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

__all__ = ["StoreData"]


@dataclass
class StoreData:
    """The tables of one or more stores, concatenated.

    Attributes:
        paths: the store files (or server stores' URLs), in the order given (duplicates
            removed).
        sessions: one row per session. ``store`` is the index into ``paths``;
            ``session_key`` (``"<store file name>#<session_id>"``) is unique across stores.
        trials: one row per trial with its session's ``participant`` and
            ``session_key``; ``on_tactor`` is bool; ``correct``, ``rt_s``,
            ``response_deg`` and ``response_target_deg`` are floats (NaN for NULL);
            ``block``, ``condition`` and ``status`` are lower-case strings.
        notes: what the loader noticed and did (duplicates dropped, unknown values).
        task_events: the ``task_events`` rows (dicts keyed by the table's columns) with
            their session's ``participant`` and ``session_key``.
        ratings: the ``ratings`` rows, likewise, with the rated block's ``load``,
            ``condition`` and ``n_targets`` (from its trials).
    """

    paths: list[Path | str]
    sessions: pd.DataFrame
    trials: pd.DataFrame
    notes: list[str] = field(default_factory=list)
    task_events: list[dict[str, Any]] = field(default_factory=list)
    ratings: list[dict[str, Any]] = field(default_factory=list)
