"""Load one or more session stores into tidy pandas tables.

Reads the store schema (docs/study.md) by column name, through the store interface
(:func:`~tactorbelt.experiment.store.open_store`), and tolerates extra columns. Stores
are opened read-only; nothing is ever written to them. Cursor samples are not loaded in
bulk: :func:`load_samples` fetches the few trials a figure needs.

Every problem with a file (missing, not SQLite, not a tactorbelt store, no sessions)
raises :class:`~tactorbelt.StoreError` naming the file and what is wrong.

I/O layer of the analysis: imports pandas, tactorbelt._errors and the store
interface; never devices, inputs, the window or the experiment runner.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

import numpy as np
import pandas as pd

from ..._errors import StoreError
from ...factors import added_factors
from .dataset import StoreData
from .design import parse_design

if TYPE_CHECKING:
    from ...experiment.store import Store

__all__ = ["REQUIRED_COLUMNS", "StoreData", "analysis_seed", "load_samples", "load_stores",
           "store_labels"]

#: Columns each table must have (docs/study.md, "The store"). More are welcome.
REQUIRED_COLUMNS: Final[dict[str, tuple[str, ...]]] = {
    "sessions": (
        "session_id", "participant", "study_name", "study_sha256", "study_toml", "seed",
        "condition_order", "belt", "firmware_version", "package_version", "started_at",
        "ended_at", "status",
    ),
    "trials": (
        "trial_id", "session_id", "block", "condition", "repetition", "trial_index",
        "target_deg", "on_tactor", "response_deg", "response_target_deg", "correct", "rt_s",
        "onset_ns", "status",
    ),
    "samples": ("trial_id", "t_s", "x", "y", "buttons"),
}
#: Optional session columns read when present.
OPTIONAL_SESSION_COLUMNS: Final = ("input", "site")
#: Optional trial columns (schema 2, factorial designs) read when present, then the
#: column of each factor declared beyond the built-in ones (:mod:`tactorbelt.factors`; a
#: store from before it lacks it); trials of older stores get their session's study's
#: target count and load ``none``.
OPTIONAL_TRIAL_COLUMNS: Final = ("n_targets", "load", "block_index")
#: The trial's onset at the skin (the stored onset plus the measured latency of the
#: tactors that start the stimulus) and its spread, read when present; loaded as
#: ``skin_offset_s`` (``(skin_onset_ns - onset_ns) / 1e9``, from the exact integer
#: difference) and ``skin_onset_sd_s``, NaN where not known.
SKIN_ONSET_COLUMNS: Final = ("skin_onset_ns", "skin_onset_sd_ns")

def _store_ref(p: str | Path) -> Path | str:
    """A store file's path, or a server store's URL kept as text (``postgresql://...``)."""
    text = str(p)
    if not isinstance(p, Path) and text.lower().startswith(("postgresql://", "postgres://")):
        return text
    return Path(p)


def _open(path: Path | str) -> Store:
    """Open read-only through the store interface (no integrity scan: stores can be
    large, and a damaged page still fails the read that reaches it)."""
    from ...experiment.store import open_store

    return open_store(path, create=False, readonly=True, verify=False)


def _check_schema(path: Path | str, store: Store) -> dict[str, list[str]]:
    cols: dict[str, list[str]] = {t: store.table_columns(t) for t in REQUIRED_COLUMNS}
    missing = [t for t in REQUIRED_COLUMNS if not cols[t]]
    if missing:
        raise StoreError(
            f"{path} is not a tactorbelt store: table(s) {', '.join(missing)} missing "
            f"(a store has tables {', '.join(REQUIRED_COLUMNS)})"
        )
    for table, required in REQUIRED_COLUMNS.items():
        lacking = [c for c in required if c not in cols[table]]
        if lacking:
            raise StoreError(
                f"{path} is not a tactorbelt store: table {table} lacks column(s) "
                f"{', '.join(lacking)} (required: {', '.join(required)})"
            )
    return cols


def _read_store(path: Path | str, store_index: int, include_running: bool = False,
                notes: list[str] | None = None,
                extra: dict[str, list[dict[str, Any]]] | None = None
                ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Sessions and trials of one store; its ``task_events`` and ``ratings`` rows go to
    ``extra`` (tagged with ``store``)."""
    with _open(path) as store:
        if extra is not None:
            for name, rows in (("task_events", store.task_events()),
                               ("ratings", store.ratings())):
                extra.setdefault(name, []).extend({**r, "store": store_index} for r in rows)
        shared = not store.capabilities.exclusive_writer
        cols = _check_schema(path, store)
        sess_cols = list(REQUIRED_COLUMNS["sessions"]) + [
            c for c in OPTIONAL_SESSION_COLUMNS if c in cols["sessions"]]
        trial_cols = list(REQUIRED_COLUMNS["trials"]) + [
            c for c in (*OPTIONAL_TRIAL_COLUMNS, *(f.column for f in added_factors()))
            if c in cols["trials"]]
        skin = all(c in cols["trials"] for c in SKIN_ONSET_COLUMNS)
        read_cols = trial_cols + (list(SKIN_ONSET_COLUMNS) if skin else [])
        sessions = pd.DataFrame.from_records(store.read_table("sessions", sess_cols),
                                             columns=sess_cols, coerce_float=True)
        trial_rows = store.read_table("trials", read_cols)
        trials = pd.DataFrame.from_records([r[:len(trial_cols)] for r in trial_rows],
                                           columns=trial_cols, coerce_float=True)
        trials["skin_offset_s"], trials["skin_onset_sd_s"] = _skin_offsets(
            trial_rows, read_cols) if skin else ([float("nan")] * len(trial_rows),) * 2
    if shared and not include_running:  # sites may be writing: complete sessions only
        keep = sessions["status"] == "complete"
        if not keep.all() and notes is not None:
            notes.append(f"{int((~keep).sum())} session(s) of {path} that are not complete "
                         "(running or interrupted) were left out (--include-running)")
        sessions = sessions.loc[keep]
        trials = trials.loc[trials["session_id"].isin(sessions["session_id"])]
    # Each session's trials in schedule order (an aborted attempt before its rerun).
    trials = trials.sort_values(["session_id", "trial_index", "trial_id"], kind="stable",
                                na_position="first", ignore_index=True)
    sessions.insert(0, "store", store_index)
    trials.insert(0, "store", store_index)
    return sessions, trials


def _skin_offsets(rows: Sequence[Sequence[Any]], cols: Sequence[str]
                  ) -> tuple[list[float], list[float]]:
    """Per trial row: ``(skin_onset_ns - onset_ns) / 1e9`` (the integer difference, exact)
    and ``skin_onset_sd_ns / 1e9``; NaN where either onset is NULL."""
    i_on, i_skin, i_sd = (cols.index(c) for c in ("onset_ns", *SKIN_ONSET_COLUMNS))
    nan = float("nan")
    offsets: list[float] = []
    sds: list[float] = []
    for r in rows:
        on, skin, sd = r[i_on], r[i_skin], r[i_sd]
        ok = on is not None and skin is not None
        offsets.append((int(skin) - int(on)) / 1e9 if ok else nan)
        sds.append(int(sd) / 1e9 if ok and sd is not None else nan)
    return offsets, sds


def store_labels(paths: Sequence[Path | str]) -> list[str]:
    """Short, unique names for the stores: the file name, or more of the path if needed
    (a server store: its URL)."""
    if any(isinstance(p, str) for p in paths):
        return [str(p) for p in paths]
    files = [Path(p) for p in paths]
    for names in ([p.name for p in files], [f"{p.parent.name}/{p.name}" for p in files]):
        if len(set(names)) == len(names):
            return names
    return [f"{i}:{p.name}" for i, p in enumerate(files)]


def _tidy(sessions: pd.DataFrame, trials: pd.DataFrame, labels: list[str],
          notes: list[str]) -> tuple[pd.DataFrame, pd.DataFrame]:
    label = pd.Series(labels, dtype="string")

    def session_key(df: pd.DataFrame) -> pd.Series:
        return label.iloc[df["store"].to_numpy()].to_numpy() + "#" + df["session_id"].astype(str)

    sessions = sessions.copy()
    sessions["session_key"] = session_key(sessions)
    sessions["participant"] = sessions["participant"].astype(str)
    for c in ("status", "belt", "study_name", "study_sha256", "firmware_version",
              "package_version", "condition_order", "started_at", "ended_at",
              *OPTIONAL_SESSION_COLUMNS):  # the optional ones: <NA> where not stored
        sessions[c] = sessions.get(c, pd.Series(pd.NA, index=sessions.index)).astype("string")

    # The same session copied into two stores: keep the first copy.
    ident = ["participant", "study_sha256", "started_at"]
    dup = sessions.duplicated(ident, keep="first") & sessions["started_at"].notna()
    if dup.any():
        dropped = sessions.loc[dup, "session_key"].tolist()
        notes.append(
            f"{len(dropped)} session(s) appear in more than one store (same participant, "
            f"study and start time) and were counted once: {', '.join(dropped[:10])}"
            + (" ..." if len(dropped) > 10 else "")
        )
        sessions = sessions.loc[~dup].reset_index(drop=True)

    trials = trials.copy()
    trials["session_key"] = session_key(trials)
    orphan = ~trials["session_key"].isin(sessions["session_key"])
    if orphan.any():
        n_dup = int(orphan.sum())
        notes.append(f"{n_dup} trial row(s) belong to no loaded session and were ignored")
        trials = trials.loc[~orphan]
    trials = trials.merge(sessions[["session_key", "participant"]], on="session_key",
                          how="left", validate="many_to_one")
    for c in ("block", "condition", "status"):
        trials[c] = trials[c].astype("string").str.strip().str.lower()
    trials["target_deg"] = pd.to_numeric(trials["target_deg"], errors="coerce")
    trials["on_tactor"] = pd.to_numeric(trials["on_tactor"], errors="coerce").fillna(0) != 0
    for c in ("response_deg", "response_target_deg", "correct", "rt_s"):
        trials[c] = pd.to_numeric(trials[c], errors="coerce").astype(float)
    bad_target = trials["target_deg"].isna()
    if bad_target.any():
        notes.append(f"{int(bad_target.sum())} trial(s) without a target angle were ignored")
        trials = trials.loc[~bad_target]
    trials["target_deg"] = np.round(np.mod(trials["target_deg"].to_numpy(), 360.0), 6) % 360.0
    trials = _cell_columns(sessions, trials)
    unknown = ~trials["status"].isin(["done", "timeout", "aborted"])
    if unknown.any():
        vals = sorted(trials.loc[unknown, "status"].fillna("<null>").unique().tolist())
        notes.append(
            f"{int(unknown.sum())} trial(s) with unknown status ({', '.join(vals)}) were "
            "treated as aborted (allowed: done, timeout, aborted)"
        )
        trials.loc[unknown, "status"] = "aborted"
    return sessions, trials.reset_index(drop=True)


def _cell_columns(sessions: pd.DataFrame, trials: pd.DataFrame) -> pd.DataFrame:
    """``n_targets`` and ``load`` of every trial: as stored, else (stores written before
    factorial designs, schema 1) the session's study's ``[targets] count`` and ``none``."""
    if "n_targets" not in trials.columns:
        trials["n_targets"] = float("nan")
    n = pd.to_numeric(trials["n_targets"], errors="coerce")
    missing = n.isna() | (n <= 0)
    if missing.any():
        texts = sessions.set_index("session_key")["study_toml"]
        counts = {key: parse_design(None if pd.isna(text) else str(text)).targets.m
                  for key, text in texts.items()}
        n = n.where(~missing, trials["session_key"].map(counts))
    trials["n_targets"] = n.fillna(0).astype(int)
    load = trials["load"] if "load" in trials.columns else pd.Series("none", index=trials.index)
    load = load.astype("string").fillna("none").str.strip()
    trials["load"] = load.where(load != "", "none").astype(str)
    return trials


def _task_rows(sessions: pd.DataFrame, trials: pd.DataFrame, labels: list[str],
               extra: dict[str, list[dict[str, Any]]]
               ) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """The task-event and rating rows of the loaded sessions, each with its session's
    ``session_key`` and ``participant``; ratings also with the rated block's ``load``,
    ``condition`` and ``n_targets`` (from the block's trials; None when no trial of the
    block is stored)."""
    who = dict(zip(sessions["session_key"], sessions["participant"], strict=True))

    def tagged(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
        out = []
        for r in rows:
            key = f"{labels[int(r['store'])]}#{r['session_id']}"
            if key in who:
                out.append({**r, "session_key": key, "participant": who[key]})
        return out

    events = tagged(extra.get("task_events", []))
    ratings = tagged(extra.get("ratings", []))
    if ratings and "block_index" in trials.columns:
        first = trials.drop_duplicates(["session_key", "block_index"])
        block = {(k, int(b)): (str(lv), str(c), int(n)) for k, b, lv, c, n in zip(
            first["session_key"], first["block_index"], first["load"], first["condition"],
            first["n_targets"], strict=True)}
        for r in ratings:
            lv, c, n = block.get((r["session_key"], int(r["block_index"])), (None, None, None))
            r.update(load=lv, condition=c, n_targets=n)
    return events, ratings


def load_stores(paths: Sequence[str | Path], *, sites: Sequence[str] | None = None,
                include_running: bool = False) -> StoreData:
    """Load every store in ``paths`` into one :class:`StoreData`.

    ``sites``: only the sessions of these sites. A shared store (several writers, e.g.
    PostgreSQL) gives only its complete sessions unless ``include_running``.

    Raises:
        StoreError: no path given; a file missing, not SQLite, or lacking the tactorbelt
            tables or columns; or no session in any of the stores.
    """
    if not paths:
        raise StoreError("no store given; pass one or more .sqlite files")
    notes: list[str] = []
    unique: list[Path | str] = []
    seen: set[Path | str] = set()
    for p in paths:
        path = _store_ref(p)
        key = path.resolve() if isinstance(path, Path) else path
        if key in seen:
            notes.append(f"{path} was given twice and read once")
            continue
        seen.add(key)
        unique.append(path)
    all_sessions = []
    all_trials = []
    extra: dict[str, list[dict[str, Any]]] = {}
    for i, path in enumerate(unique):
        sessions, trials = _read_store(path, i, include_running, notes, extra)
        if sites is not None:
            sessions = sessions.loc[sessions.get("site", pd.Series(pd.NA, index=sessions.index)
                                                 ).isin(list(sites))]
            trials = trials.loc[trials["session_id"].isin(sessions["session_id"])]
        if sessions.empty:
            if len(unique) == 1:
                raise StoreError(
                    f"{path} is an empty store: it holds no session; run a study into it "
                    "first ('tactorbelt run' or 'tactorbelt demo')"
                )
            notes.append(f"{path} holds no session")
        all_sessions.append(sessions)
        all_trials.append(trials)
    sessions = pd.concat(all_sessions, ignore_index=True)
    trials = pd.concat(all_trials, ignore_index=True)
    if sessions.empty:
        raise StoreError(
            f"the stores hold no session ({', '.join(str(p) for p in unique)}); nothing "
            "to analyse"
        )
    labels = store_labels(unique)
    sessions, trials = _tidy(sessions, trials, labels, notes)
    _check_sites(unique, sessions)
    events, ratings = _task_rows(sessions, trials, labels, extra)
    return StoreData(paths=unique, sessions=sessions, trials=trials, notes=notes,
                     task_events=events, ratings=ratings)


def _check_sites(paths: Sequence[Path | str], sessions: pd.DataFrame) -> None:
    """With a shared store (several sites write it) among ``paths``: refuse (StoreError)
    participant ids that span sites among the loaded sessions instead of merging them.
    Local stores alone are not checked: their site is the machine's name unless set, and
    one person's sessions on two machines of a lab are one person's."""
    from ...experiment.store import backend_for
    from ...experiment.store.sites import check_one_site_per_participant

    if all(backend_for(p).capabilities.exclusive_writer for p in paths):
        return
    check_one_site_per_participant(
        [{str(k): v for k, v in r.items()} for r in sessions.to_dict("records")],
        ", ".join(str(p) for p in paths), "analysed",
        "analyse one site at a time (--site NAME), or have the store's owner give one "
        "site's sessions other ids", name=lambda r: str(r["session_key"]))


def analysis_seed(data: StoreData) -> int:
    """The analysis' default seed, derived from the data: the smallest seed of the loaded
    sessions (0 when none is stored).

    The demo stores its seed with every session, so ``tactorbelt analyze`` on the
    demo's store draws the same bootstrap resamples and sample trajectories as the
    demo did; any store gives the same report however often it is analysed.
    """
    seeds = []
    for value in data.sessions["seed"].tolist():
        try:
            seeds.append(int(value))  # exact for 64-bit seeds (no float round trip)
        except (TypeError, ValueError, OverflowError):
            continue
    seeds = [s for s in seeds if s >= 0]
    return min(seeds) if seeds else 0


def load_samples(data: StoreData, trials: pd.DataFrame) -> pd.DataFrame:
    """Cursor samples of a few trials, fetched by trial id (never the whole table).

    Args:
        data: what :func:`load_stores` returned (for the store paths).
        trials: rows with ``store`` and ``trial_id`` columns (other columns ignored).

    Returns:
        Columns ``store, trial_id, t_s, x, y, buttons``, ordered by trial and time.
    """
    frames = []
    stores = sorted({int(v) for v in trials["store"].tolist()})
    for store in stores:
        group = trials.loc[trials["store"] == store]
        ids = sorted({int(t) for t in group["trial_id"].tolist()})
        if not ids:
            continue
        with _open(data.paths[store]) as st:
            frame = pd.DataFrame.from_records(
                st.samples_of(ids), columns=["trial_id", "t_s", "x", "y", "buttons"],
                coerce_float=True)
        frame.insert(0, "store", store)
        frames.append(frame)
    if not frames:
        return pd.DataFrame(columns=["store", "trial_id", "t_s", "x", "y", "buttons"])
    return pd.concat(frames, ignore_index=True)
