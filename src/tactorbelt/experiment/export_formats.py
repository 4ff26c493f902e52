"""Exports people open directly in their own tools: Parquet, a tidy table for R (lme4)
and JASP, and PsychoPy's trial-by-trial CSV files (docs/export.md).

- :func:`export_parquet`: ``sessions.parquet``, ``trials.parquet`` and
  ``samples.parquet``, the tables of the CSV export
  (:func:`tactorbelt.experiment.export.export_csv`) with the column types of
  :data:`DTYPES` (pandas nullable types), for large stores.
  :func:`read_table` reads a table of either export into the same DataFrame.
- :func:`export_tidy`: ``trials_tidy.csv``, one row per finished trial (done or
  timeout; aborted attempts are left out) with the column names of the lme4 formulas
  (docs/conventions.md "Analysis outputs"), ``NA`` for missing values, 0/1 for yes/no;
  its column types are :data:`TIDY_COLUMNS` and ``codebook.csv`` lists them.
- :func:`export_psychopy`: one wide CSV per session, named and laid out as PsychoPy's
  ``ExperimentHandler.saveAsWideText`` saves a Builder experiment with the loops
  ``blocks`` and ``trials`` (``P01_<study>_<date>.csv``, UTF-8 with a byte-order mark,
  a delimiter after the last column): one row per trial, the block's and the target's
  conditions, the loop counters (``trials.thisN``, ``trials.thisRepN``, ...), the
  response as ``response.*`` columns, then ``participant``, ``session``, ``date``,
  ``expName``, ``psychopyVersion`` and ``frameRate`` (:data:`PSYCHOPY_COLUMNS`).

The output directory follows the CSV export's rule: new or empty, and ``force``
replaces only an earlier export of the same format.

I/O: reads a store read-only and writes files; pandas (and pyarrow for Parquet).
"""

from __future__ import annotations

import datetime as dt
import math
import re
from collections import Counter
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .. import __version__
from .._errors import ConfigError
from ..factors import CONDITION, LOAD, TARGETS, Factor, added_factors, after_builtin
from .export import DTYPES, _csv_value, _open, _prepare, _table_rows, _with_cell, _write_csv, dtypes

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["DTYPES", "PSYCHOPY_COLUMNS", "TIDY_COLUMNS", "dtypes", "export_parquet",
           "export_psychopy", "export_tidy", "psychopy_columns", "read_table", "tables",
           "tidy_columns"]

_TIDY_TYPES = {"text": ("text", "factor"), "int": ("integer", "integer")}


def _codebook(f: Factor) -> tuple[str, str, str, str, str]:
    """A factor's line of the tidy codebook, from its declaration."""
    levels = f" Levels: {', '.join(f.levels)}." if f.levels else ""
    return (f.column, *_TIDY_TYPES[f.type], f.measure, f.description + levels)


#: The tidy table's columns: (name, type, R type from ``read.csv(stringsAsFactors =
#: TRUE)``, JASP type, description).
TIDY_COLUMNS: list[tuple[str, str, str, str, str]] = [
    ("participant", "text", "factor", "nominal", "participant id (random-effects grouping)"),
    ("session", "integer", "integer", "scale", "the participant's session number, 1-based"),
    ("block", "text", "factor", "nominal", "training or test"),
    ("block_index", "integer", "integer", "scale", "position of the block in the session, 0-based"),
    ("block_name", "text", "factor", "nominal", "the block's name in the study file"),
    *(_codebook(f) for f in (CONDITION, TARGETS, LOAD)),
    ("trial", "integer", "integer", "scale", "trial_index: position in the session, 0-based"),
    ("repetition", "integer", "integer", "scale", "repetition of this target, 1-based"),
    ("target_deg", "number", "numeric", "scale", "target direction, degrees (0 = navel, "
     "clockwise)"),
    ("on_tactor", "0/1", "integer", "nominal", "1 when the target is at a tactor"),
    ("status", "text", "factor", "nominal", "done or timeout"),
    ("correct", "0/1", "integer", "nominal", "1 when the response selected the target; a "
     "timeout is 0"),
    ("rt_s", "number or NA", "numeric", "scale", "seconds from onset to acquisition; NA on a "
     "timeout"),
    ("response_deg", "number or NA", "numeric", "scale", "direction of the response, degrees"),
    ("response_target_deg", "number or NA", "numeric", "scale", "the target the response "
     "selected, degrees"),
    ("signed_error_deg", "number or NA", "numeric", "scale", "response_deg - target_deg, "
     "wrapped into (-180, 180]; positive = clockwise"),
]

#: The PsychoPy export's columns, in order (module doc).
#: In ``ExperimentHandler.saveAsWideText``'s order: the loops' conditions (outer loop
#: first), the loop counters, ``thisRow.t`` and ``notes``, the data, then ``extraInfo``.
PSYCHOPY_COLUMNS = [
    "block_name", "block", "condition", "n_targets", "load", "target_deg", "on_tactor",
    "blocks.thisRepN", "blocks.thisTrialN", "blocks.thisN", "blocks.thisIndex",
    "trials.thisRepN", "trials.thisTrialN", "trials.thisN", "trials.thisIndex",
    "thisRow.t", "notes",
    "stimulus.started", "response.deg", "response.target_deg", "response.corr",
    "response.rt", "response.status", "trial_index",
    "participant", "session", "date", "expName", "psychopyVersion", "frameRate",
    "tactorbeltVersion",
]

def _frame(rows: Iterable[list[Any]], table: str) -> pd.DataFrame:
    """Typed rows; an empty text is missing (NA), as a CSV file cannot tell them apart
    (``task_events.response`` is empty when nothing was pressed)."""
    import pandas as pd

    types = dtypes(table)
    df = pd.DataFrame([[None if v == "" else v for v in r] for r in rows],
                      columns=list(types), dtype=object)
    return df.astype(types)


def tables(db: str | Path) -> dict[str, pd.DataFrame]:
    """The store's ``sessions``, ``trials`` and ``samples`` (and ``task_events`` and
    ``ratings`` when it has any) as typed DataFrames: the rows and columns of the CSV
    export, the types of :data:`DTYPES`."""
    with _open(db) as store:
        return {name: _frame(rows, name) for name, rows in _table_rows(store).items()}


def read_table(path: str | Path) -> pd.DataFrame:
    """A table of the CSV or the Parquet export (``trials.csv``, ``samples.parquet``,
    ...) as a DataFrame with the types of :data:`DTYPES`: both give the same frame."""
    import pandas as pd

    p = Path(path)
    table = p.stem
    if table not in DTYPES:
        raise ConfigError(f"{p.name} is not a table of the export ({', '.join(DTYPES)})")
    types = dtypes(table)
    if p.suffix == ".parquet":
        _pyarrow()
        return pd.read_parquet(p).astype(types)
    # floats exactly as written (repr): pandas 3 parses them so by default
    exact: dict[str, Any] = ({} if int(pd.__version__.split(".")[0]) >= 3
                             else {"float_precision": "round_trip"})
    df = pd.read_csv(p, dtype={k: v for k, v in types.items() if v != "boolean"},
                     keep_default_na=False, na_values=[""], **exact)
    return df.astype(types)


def _pyarrow() -> None:
    try:
        import pyarrow  # noqa: F401
    except ImportError:
        raise ConfigError("Parquet files need the pyarrow package; install it with: pip "
                          "install 'tactorbelt[parquet]'") from None


def export_parquet(db: str | Path, out: str | Path, *, force: bool = False) -> list[Path]:
    """Write ``sessions.parquet``, ``trials.parquet`` and ``samples.parquet`` into ``out``,
    and ``task_events.parquet`` and ``ratings.parquet`` when the store has any.

    Raises:
        ConfigError: pyarrow is not installed, or ``out`` is not usable (as the CSV export).
    """
    _pyarrow()
    frames = tables(db)
    o = _prepare(out, "parquet", force, db)
    files = []
    try:
        for name, df in frames.items():
            files.append(o / f"{name}.parquet")
            df.to_parquet(files[-1], engine="pyarrow", index=False)
    except OSError as exc:
        raise ConfigError(f"cannot write to {o}: {exc.strerror}") from None
    return files


def _wrap180(d: float) -> float:
    w = (d + 180.0) % 360.0 - 180.0
    return 180.0 if w == -180.0 else w


def _na(v: Any) -> Any:
    """A cell of the tidy table: R's ``NA`` for a missing value, else as the CSV's."""
    return "NA" if v is None or (isinstance(v, float) and math.isnan(v)) else _csv_value(v)


def tidy_columns() -> list[tuple[str, str, str, str, str]]:
    """:data:`TIDY_COLUMNS` with each factor declared beyond the built-in ones after
    ``load``."""
    extra = [_codebook(f) for f in added_factors()]
    return after_builtin(TIDY_COLUMNS, extra, key=lambda c: c[0])


def export_tidy(db: str | Path, out: str | Path, *, force: bool = False) -> list[Path]:
    """Write ``trials_tidy.csv`` and ``codebook.csv`` into ``out`` (module doc).

    In R: ``d <- read.csv("trials_tidy.csv", stringsAsFactors = TRUE)`` gives the types of
    :data:`TIDY_COLUMNS`, and ``lme4::glmer(correct ~ condition * on_tactor +
    (1 | participant), data = d, family = binomial)`` runs on it as it is.
    """
    columns = tidy_columns()
    added = added_factors()
    with _open(db) as store:
        sessions = {int(s["session_id"]): s for s in store.sessions()}
        trials = sorted(store.trials(), key=lambda t: (t["session_id"], t["trial_index"]))
        o = _prepare(out, "tidy", force, db)
        rows = []
        for t in trials:
            if t["status"] not in ("done", "timeout"):
                continue
            s = sessions[int(t["session_id"])]
            t = _with_cell(t, s)
            resp = t["response_deg"]
            rows.append([
                s["participant"], s["session_number"], t["block"], t["block_index"],
                t["block_name"], t["condition"], t["n_targets"], t["load"],
                *(t[f.column] for f in added), t["trial_index"],
                t["repetition"], float(t["target_deg"]), int(bool(t["on_tactor"])),
                t["status"], int(bool(t["correct"])) if t["status"] == "done" else 0,
                t["rt_s"] if t["status"] == "done" else None, resp, t["response_target_deg"],
                None if resp is None else _wrap180(float(resp) - float(t["target_deg"]))])
    try:
        return [_write_csv(o / "trials_tidy.csv", [c[0] for c in columns],
                           [[_na(v) for v in r] for r in rows]),
                _write_csv(o / "codebook.csv",
                           ["column", "type", "r_type", "jasp_type", "description"], columns)]
    except OSError as exc:
        raise ConfigError(f"cannot write to {o}: {exc.strerror}") from None


def psychopy_date(iso: str | None) -> str:
    """A stored ``started_at`` (ISO 8601) as PsychoPy's ``data.getDateStr()`` writes it:
    ``2024-01-31_14h05.23.123`` (local time of the recording)."""
    if not iso:
        return ""
    try:
        t = dt.datetime.fromisoformat(iso)
    except ValueError:
        return ""
    if t.tzinfo is not None:
        t = t.astimezone()
    return t.strftime("%Y-%m-%d_%Hh%M.%S.%f")[:-3]


def _file_part(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "-", text).strip("-") or "tactorbelt"


def psychopy_columns() -> list[str]:
    """:data:`PSYCHOPY_COLUMNS` with each factor declared beyond the built-in ones after
    ``load`` (a condition of the ``blocks`` loop)."""
    return after_builtin(PSYCHOPY_COLUMNS, [f.column for f in added_factors()])


def export_psychopy(db: str | Path, out: str | Path, *, force: bool = False) -> list[Path]:
    """Write one PsychoPy-style wide CSV per session into ``out`` (module doc): rows are
    the session's trials in running order (aborted attempts left out, as PsychoPy
    keeps no row for a trial that did not run to its end)."""
    columns = psychopy_columns()
    added = added_factors()
    with _open(db) as store:
        sessions = store.sessions()
        o = _prepare(out, "psychopy", force, db)
        files: list[Path] = []
        for s in sessions:
            trials = sorted((t for t in store.trials(s["session_id"])
                             if t["status"] in ("done", "timeout")),
                            key=lambda t: t["trial_index"])
            date = psychopy_date(s["started_at"])
            name = (f"{_file_part(s['participant'])}_{_file_part(s['study_name'] or '')}_"
                    f"{date or 'session-' + str(s['session_number'])}.csv")
            path = o / name
            if path in files:
                path = path.with_stem(f"{path.stem}_{s['session_number']}")
            first_onset = min((t["onset_ns"] for t in trials if t["onset_ns"] is not None),
                              default=0)
            block_n: dict[int, int] = {}
            seen: Counter[Any] = Counter()  # trials so far of each block, and repetition
            rows = []
            for t in trials:
                t = _with_cell(t, s)
                b, rep = int(t["block_index"]), int(t["repetition"])
                block_n.setdefault(b, len(block_n))
                k, kr = seen[b], seen[(b, rep)]
                seen.update([b, (b, rep)])
                n = int(t["n_targets"] or 0)
                done = t["status"] == "done"
                row = {
                    "block_name": t["block_name"], "block": t["block"],
                    "condition": t["condition"], "n_targets": t["n_targets"],
                    "load": t["load"], "target_deg": t["target_deg"],
                    "on_tactor": int(bool(t["on_tactor"])),
                    "blocks.thisRepN": 0, "blocks.thisTrialN": block_n[b],
                    "blocks.thisN": block_n[b], "blocks.thisIndex": b,
                    "trials.thisRepN": rep - 1, "trials.thisTrialN": kr, "trials.thisN": k,
                    "trials.thisIndex": round(float(t["target_deg"]) * n / 360.0) % n if n
                    else None,
                    "stimulus.started": None if t["onset_ns"] is None
                    else (t["onset_ns"] - first_onset) / 1e9,
                    "response.deg": t["response_deg"],
                    "response.target_deg": t["response_target_deg"],
                    "response.corr": int(bool(t["correct"])) if done else 0,
                    "response.rt": t["rt_s"] if done else None,
                    "response.status": t["status"], "trial_index": t["trial_index"],
                    "participant": s["participant"], "session": s["session_number"],
                    "date": date, "expName": s["study_name"], "tactorbeltVersion": __version__,
                    **{f.column: t[f.column] for f in added},
                }
                rows.append([row.get(c) for c in columns])
            try:
                # as PsychoPy writes them: UTF-8 with a byte-order mark, a delimiter after
                # the last column of every line
                _write_csv(path, [*columns, ""],
                           [["" if v is None else v for v in r] + [""] for r in rows],
                           encoding="utf-8-sig", lineterminator="\n")
            except OSError as exc:
                raise ConfigError(f"cannot write to {o}: {exc.strerror}") from None
            files.append(path)
    return files
