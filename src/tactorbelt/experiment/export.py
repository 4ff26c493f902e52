"""Export a store to tidy CSV files or to a BIDS dataset (behaviour and cursor samples).

CSV (:func:`export_csv`): ``sessions.csv``, ``trials.csv`` (one row per trial, with
the participant and session number) and ``samples.csv`` (one row per cursor sample,
with participant, session and trial index); under cognitive load also
``task_events.csv`` (one row per secondary-task item or extra press) and
``ratings.csv`` (one row per questionnaire item and block), each with the participant
and session number, written when the store holds such rows.

BIDS (:func:`export_bids`), which ``bids-validator`` passes::

    dataset_description.json  README.md  participants.tsv  participants.json
    sub-<id>/ses-<n>/beh/sub-<id>_ses-<n>_task-betweentactor_beh.tsv   (+ .json sidecar)
    sub-<id>/ses-<n>/beh/sub-<id>_ses-<n>_task-betweentactor_events.tsv (+ .json; under
                                           a cognitive load: the secondary-task events)
    sub-<id>/ses-<n>/beh/sub-<id>_ses-<n>_task-nasatlx_beh.tsv (+ .json; with ratings:
                                           one row per rated block)
    sub-<id>/ses-<n>/beh/sub-<id>_ses-<n>_task-betweentactor_recording-cursor_physio.tsv.gz
                                           (+ _physio.json; the cursor samples)

Every column of every table is described in its sidecar (:data:`BEH_COLUMNS`,
:data:`EVENT_COLUMNS`, :data:`TLX_COLUMNS`, :data:`CURSOR_COLUMNS`). ``Authors`` in
``dataset_description.json`` are the ones given, else the study files' ``authors``.

``<id>`` is the participant id with everything but letters and digits removed (BIDS
labels are alphanumeric); two ids that collapse to the same label are an error.
Missing values are ``n/a``. The cursor samples are a BIDS continuous recording of the
behavioural data type (gzipped, no header; ``Columns`` of the ``_physio.json`` names
the columns: trial_index, t, t_trial, x, y, buttons). The cursor is sampled from the
stimulus onset to the response of each trial, so the recording pauses between trials:
each row carries its time ``t``, seconds from the onset of the session's first trial,
which is also the origin of ``onset`` in the ``_events.tsv``; ``StartTime`` is the first
row's ``t`` and ``SamplingFrequency`` the study's ``sample_rate_hz``.

The output directory must be new or empty; ``force=True`` first removes what an
earlier export of the same format wrote there, and refuses a directory holding
anything else (so nothing else is ever deleted).

I/O: reads a store (:func:`~tactorbelt.experiment.store.open_store`, read-only) through
its interface and writes files; standard library only.
"""

from __future__ import annotations

import contextlib
import csv
import functools
import gzip
import io
import json
import re
import shutil
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs

from .. import __version__
from .._errors import ConfigError
from ..factors import CONDITION, LOAD, TARGETS, Factor, added_factors, after_builtin
from ..tasks import TLX_ITEMS, TLX_SCALES
from .store import Store, open_store
from .study import Study

__all__ = [
    "BEH_COLUMNS",
    "CURSOR_COLUMNS",
    "DTYPES",
    "EVENT_COLUMNS",
    "RECORDING",
    "TASK",
    "TLX_COLUMNS",
    "TLX_TASK",
    "bids_label",
    "dtypes",
    "export_bids",
    "export_csv",
    "factor_sidecar",
    "study_authors",
]

TASK = "betweentactor"
#: The BIDS task label of the NASA-TLX ratings (a questionnaire after each test block).
TLX_TASK = "nasatlx"

_INT, _FLOAT, _STR, _BOOL = "Int64", "Float64", "string", "boolean"
#: The columns of every table of the CSV and Parquet exports, in order, with their
#: pandas types (nullable; :mod:`.export_formats` reads the tables back with them).
DTYPES: dict[str, dict[str, str]] = {
    "sessions": {
        "session_id": _INT, "participant": _STR, "session_number": _INT, "study_name": _STR,
        "study_sha256": _STR, "seed": _INT, "condition_order": _STR, "n_trials": _INT,
        "belt": _STR, "firmware_version": _STR, "package_version": _STR, "git_commit": _STR,
        "host": _STR, "input": _STR, "clock": _STR, "started_at": _STR, "ended_at": _STR,
        "status": _STR, "resumed": _INT,
    },
    "trials": {
        "participant": _STR, "session_id": _INT, "session_number": _INT, "trial_id": _INT,
        "trial_index": _INT, "block": _STR, "block_index": _INT, "block_name": _STR,
        CONDITION.column: _STR, "repetition": _INT, "target_deg": _FLOAT, "on_tactor": _BOOL,
        "response_deg": _FLOAT, "response_target_deg": _FLOAT, "correct": _BOOL,
        "rt_s": _FLOAT, "onset_ns": _INT, "acquired_ns": _INT, "crossed_ns": _INT,
        "stimulus_off_ns": _INT, "n_samples": _INT, "status": _STR, "abort_reason": _STR,
        "attempts": _INT, TARGETS.column: _INT, LOAD.column: _STR,
        "device_onset_ns": _INT, "onset_uncertainty_ns": _INT, "skin_onset_ns": _INT,
        "skin_onset_sd_ns": _INT,
    },
    "samples": {
        "participant": _STR, "session_id": _INT, "trial_index": _INT, "t_s": _FLOAT,
        "x": _FLOAT, "y": _FLOAT, "buttons": _INT,
    },
    # under cognitive load (written when the store has any)
    "task_events": {
        "participant": _STR, "session_id": _INT, "session_number": _INT,
        "block_index": _INT, "task": _STR, "phase": _STR, "item_index": _INT, "t_ns": _INT,
        "stimulus": _STR, "target": _BOOL, "response": _STR, "correct": _BOOL,
        "rt_s": _FLOAT,
    },
    "ratings": {
        "participant": _STR, "session_id": _INT, "session_number": _INT,
        "block_index": _INT, "scale": _STR, "item": _STR, "value": _FLOAT,
    },
}
_FACTOR_DTYPE = {"text": _STR, "int": _INT}


def dtypes(table: str) -> dict[str, str]:
    """The column types of an exported table: :data:`DTYPES`, the trials with a column
    for each factor declared beyond the built-in ones (:mod:`tactorbelt.factors`)."""
    extra = added_factors() if table == "trials" else ()
    return {**DTYPES[table], **{f.column: _FACTOR_DTYPE[f.type] for f in extra}}


def factor_sidecar(f: Factor) -> dict[str, Any]:
    """A factor's column in a BIDS sidecar: its description and levels, as declared."""
    return {"Description": f.description, **({"Levels": dict(f.levels)} if f.levels else {})}


def _after_load(columns: dict[str, Any]) -> dict[str, Any]:
    """A BIDS table's ``columns`` (:data:`BEH_COLUMNS`, :data:`TLX_COLUMNS`) and their sidecar
    entries, with one for each factor declared beyond the built-in ones after ``load``."""
    every = {**columns, **{f.column: factor_sidecar(f) for f in added_factors()}}
    return {k: every[k] for k in after_builtin(list(columns), list(every)[len(columns):])}


#: Every column of the BIDS ``_beh.tsv`` and its description (the JSON sidecar); a
#: factor's from its declaration (:mod:`tactorbelt.factors`).
BEH_COLUMNS: dict[str, dict[str, Any]] = {
    "trial_index": {"Description": "Position of the trial in the session's schedule (0-based)."},
    "block": {"Description": "Block type.", "Levels": {
        "training": "target shown on screen while felt", "test": "target felt only"}},
    "block_name": {"Description": "Name of the block in the study file."},
    CONDITION.column: factor_sidecar(CONDITION),
    "repetition": {"Description": "Repetition (test) or pass (training) of this target, 1-based."},
    "target_deg": {"Description": "Target direction; 0 = navel, clockwise seen from above.",
                   "Units": "deg"},
    "on_tactor": {"Description": "1 when the target coincides with a tactor, else 0."},
    TARGETS.column: factor_sidecar(TARGETS),
    LOAD.column: factor_sidecar(LOAD),
    "response_deg": {"Description": "Direction of the cursor at acquisition "
                     "(atan2(x, y), 0 = up/front, clockwise).", "Units": "deg"},
    "response_target_deg": {"Description": "Target nearest in angle to response_deg.",
                            "Units": "deg"},
    "correct": {"Description": "1 when response_target_deg equals target_deg, else 0."},
    "rt_s": {"Description": "Time from stimulus onset to target acquisition.", "Units": "s"},
    "onset_s": {"Description": "Stimulus onset on the session clock (monotonic).", "Units": "s"},
    "skin_onset_s": {"Description": "Stimulus onset at the skin on the session clock: the "
                     "stored onset (the device-true onset where the belt reports it, else "
                     "onset_s) plus the measured latency of the tactors that start the "
                     "stimulus (StimulusSystem.SkinOnset); n/a without a measured latency.",
                     "Units": "s"},
    "skin_onset_sd_s": {"Description": "How far skin_onset_s may be off, pulse to pulse: the "
                        "tactors' latency spread combined with the device onset's "
                        "uncertainty (root of the sum of squares); n/a without a measured "
                        "latency.", "Units": "s"},
    "status": {"Description": "Outcome of the trial.", "Levels": {
        "done": "a response was acquired", "timeout": "no response before the timeout",
        "aborted": "interrupted (pause, device error, Ctrl-C)"}},
}

#: Every column of the BIDS ``_events.tsv`` (the secondary-task events) and its
#: description (the JSON sidecar).
EVENT_COLUMNS: dict[str, dict[str, Any]] = {
    "onset": {"Description": "Onset of the item (its sound or glyph), or the time of a "
              "press that answered no item, from the onset of the session's first trial "
              "(the origin of t in the cursor recording); negative before it.",
              "Units": "s"},
    "duration": {"Description": "How long the item was presented (the task's stimulus_s); "
                 "0 for a press that answered no item.", "Units": "s"},
    "trial_type": {"Description": "Kind of secondary-task event.", "Levels": {
        "go": "an item to press on (a match of the n-back, an odd sum)",
        "nogo": "an item not to press on",
        "extra_press": "a press that answered no item"}},
    "task": {"Description": "Name of the secondary task in the study file ([tasks.NAME])."},
    "phase": {"Description": "When the task ran.", "Levels": {
        "practice": "the task alone, before its first block, with feedback",
        "baseline": "the task alone, for the single-task baseline",
        "dual": "during a test block, with the localisation trials"}},
    "block_index": {"Description": "The test block the event belongs to (position in the "
                    "session's schedule, 0-based; practice and baseline take the index of "
                    "the block they precede)."},
    "item_index": {"Description": "Position of the item in its run of the task, 0-based; "
                   "-1 for a press that answered no item."},
    "stimulus": {"Description": "The item: a tone (tone0, tone1, ...), a letter or a sum "
                 "(3+4)."},
    "response": {"Description": "The participant's response to the item (n/a: none).",
                 "Levels": {"press": "the task's response button was pressed"}},
    "response_time": {"Description": "Time from the item's onset to the press (n/a "
                      "without one).", "Units": "s"},
    "correct": {"Description": "1 when pressed on a go item or not pressed on a no-go "
                "item, else 0 (0 for an extra press)."},
}

#: Every column of the BIDS ratings file and its description (the JSON sidecar).
TLX_COLUMNS: dict[str, dict[str, Any]] = {
    "block_index": {"Description": "The test block rated (position in the session's "
                    "schedule, 0-based); joins block_index of the _beh.tsv."},
    "block_name": {"Description": "Name of the block in the study file."},
    "condition": BEH_COLUMNS["condition"],
    "n_targets": BEH_COLUMNS["n_targets"],
    "load": BEH_COLUMNS["load"],
    # each item: the question of NASA's form and its anchors (tactorbelt.tasks.TLX_SCALES)
    **{s.item: {"Description": f"{s.title.capitalize()}: {s.question[0].lower()}"
                f"{s.question[1:]} Rated after the block on a slider from 0 ({s.low.lower()}) "
                f"to 100 ({s.high.lower()})."} for s in TLX_SCALES},
    "raw_tlx": {"Description": "Raw TLX: the mean of the six items, 0-100 (no pairwise "
                "weighting)."},
}

#: The BIDS label of the cursor recording (``_recording-cursor_physio.tsv.gz``).
RECORDING = "cursor"
#: Every column of the cursor recording (``beh/*_recording-cursor_physio.tsv.gz``, which
#: has no header: ``Columns`` of its ``_physio.json`` names them) and its description.
CURSOR_COLUMNS: dict[str, dict[str, Any]] = {
    "trial_index": {"Description": "trial_index of the sample's trial (joins trial_index "
                    "of the _beh.tsv)."},
    "t": {"Description": "Time of the sample from the onset of the session's first trial "
          "(the origin of onset in the _events.tsv; StartTime is the first row's t). The "
          "cursor is sampled only from the stimulus onset to the response of each trial, "
          "so the recording pauses between trials: a sample's time is its t, not "
          "StartTime + row / SamplingFrequency.", "Units": "s"},
    "t_trial": {"Description": "Time of the sample from the stimulus onset of its trial "
                "(onset_s in the _beh.tsv), as stored.", "Units": "s"},
    "x": {"Description": "Cursor x, right positive; the response ellipse has radius 1 "
          "(no unit)."},
    "y": {"Description": "Cursor y, up (front) positive; the response ellipse has radius 1 "
          "(no unit)."},
    "buttons": {"Description": "Buttons held at the sample, as a bit mask (bit k set: "
                "button k pressed; 0: none)."},
}


def bids_label(participant: str) -> str:
    """A BIDS label (letters and digits only) for a participant id."""
    label = re.sub(r"[^A-Za-z0-9]", "", participant)
    if not label:
        raise ConfigError(f"participant id {participant!r} has no letter or digit for a BIDS label")
    return label


def _na(v: Any) -> Any:
    return "n/a" if v is None else v


def _open(db: str | Path) -> Store:
    """The store, read-only; a shared one whose participant ids span sites is refused
    (:func:`~tactorbelt.experiment.store.sites.check_one_site_per_participant`)."""
    from .store.sites import check_one_site_per_participant

    store = open_store(db, create=False, readonly=True)
    if not store.capabilities.exclusive_writer:
        try:
            check_one_site_per_participant(
                store.sessions(), str(db), "exported",
                "export each site's own store, or have the store's owner give one site's "
                "sessions other ids")
        except BaseException:
            store.close()
            raise
    return store


#: What an export of each format writes at the top of its directory (``--force``
#: replaces these, and refuses a directory holding anything else).
_OWNED = {
    "csv": tuple(f"{name}.csv" for name in DTYPES),
    "bids": ("dataset_description.json", "participants.tsv", "participants.json", "README",
             "README.md", "README.rst", "README.txt", "sub-*"),
    # experiment/export_formats.py
    "parquet": tuple(f"{name}.parquet" for name in DTYPES),
    "tidy": ("trials_tidy.csv", "codebook.csv"),
    "psychopy": ("*_[0-9][0-9][0-9][0-9]-[0-9][0-9]-[0-9][0-9]_[0-9][0-9]h[0-9][0-9].*.csv",
                 "*_session-*.csv"),
}


def _prepare(out: str | Path, fmt: str, force: bool, db: str | Path) -> Path:
    """The export directory: new or empty, or (``force``) a previous export emptied."""
    o = Path(out)
    if o.exists() and not o.is_dir():
        raise ConfigError(f"{o} exists and is not a directory; give a directory for the export")
    if o.is_dir():
        entries = sorted(o.iterdir())
        if entries and not force:
            names = ", ".join(e.name for e in entries[:4]) + (", ..." if len(entries) > 4 else "")
            raise ConfigError(
                f"{o} is not empty ({names}); export into a new or empty directory, or add "
                "--force to replace an earlier export there")
        if entries:
            ours = [e for e in entries if any(e.match(pat) for pat in _OWNED[fmt])]
            others = [e.name for e in entries if e not in ours]
            if others:
                raise ConfigError(
                    f"{o} holds files that are not from a tactorbelt {fmt} export "
                    f"({', '.join(others[:4])}{', ...' if len(others) > 4 else ''}); "
                    "--force replaces only an earlier export: choose another directory")
            db_path = Path(db).resolve()
            if any(db_path.is_relative_to(e.resolve()) for e in ours):
                raise ConfigError(f"the store {db} is inside {o}; choose another directory")
            try:
                for e in ours:
                    if e.is_dir() and not e.is_symlink():
                        shutil.rmtree(e)
                    else:
                        e.unlink()
            except OSError as exc:
                raise ConfigError(f"cannot replace the export in {o}: {exc.strerror}") from None
    try:
        o.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot create {o}: {exc.strerror}") from None
    return o


def _beh_value(trial: dict[str, Any], column: str) -> Any:
    """A ``_beh.tsv`` cell of a trial: the onsets in seconds (``onset_s``, ``skin_onset_s``,
    ``skin_onset_sd_s``, from the stored ns; None where not stored), else as stored."""
    if column in ("onset_s", "skin_onset_s", "skin_onset_sd_s"):
        ns = trial.get(column[:-2] + "_ns")
        return None if ns is None else ns / 1e9
    return trial[column]


@functools.lru_cache(maxsize=64)
def _parse_study(study_toml: str | None) -> Study | None:
    """The study of a stored study text (None when it does not parse: an older or
    hand-made store)."""
    try:
        return Study.from_toml(study_toml or "")
    except Exception:
        return None


def _with_cell(trial: dict[str, Any], session: dict[str, Any]) -> dict[str, Any]:
    """The trial row with ``n_targets``, ``load`` and the added factors: as stored, else
    (a store written before factorial designs) the session's study's ``[targets] count``
    and ``none``, and (a store written before a factor was declared) its default."""
    out = dict(trial)
    for f in (LOAD, *added_factors()):
        out[f.column] = f.stored(out.get(f.column))
    if out.get("n_targets") is None:
        study = _parse_study(session.get("study_toml"))
        out["n_targets"] = None if study is None else study.targets.count
    return out


def _csv_value(v: Any) -> Any:
    """A CSV cell: booleans as 0/1 (as trials.csv's ``correct``), floats exactly."""
    if isinstance(v, bool):
        return int(v)
    if isinstance(v, float):
        return repr(v)
    return v


def _table_rows(store: Store) -> dict[str, Iterable[list[Any]]]:
    """The rows of each table of the CSV (and Parquet) export (columns: :func:`dtypes`),
    the store's values: ``sessions``, ``trials`` (with their cells), ``samples`` (read as
    they are written), and ``task_events`` and ``ratings`` when the store has any; a
    row's ``participant`` and ``session_number`` are its session's."""
    sessions = store.sessions()
    by_id = {int(s["session_id"]): s for s in sessions}
    own = ("participant", "session_number")
    columns = list(dtypes("trials"))
    trials = []
    for t in sorted(store.trials(), key=lambda t: (t["session_id"], t["trial_id"])):
        sess = by_id[int(t["session_id"])]
        t = _with_cell(t, sess)  # the added factors' levels too
        trials.append([sess[k] if k in own else t[k] for k in columns])
    out: dict[str, Iterable[list[Any]]] = {
        "sessions": [[s[k] for k in DTYPES["sessions"]] for s in sessions],
        "trials": trials,
        "samples": ([by_id[int(sid)]["participant"], sid, index, t_s, x, y, buttons]
                    for sid, index, t_s, x, y, buttons in store.iter_samples()),
    }
    for name, rows in (("task_events", store.task_events()), ("ratings", store.ratings())):
        if rows:
            out[name] = [[by_id.get(int(r["session_id"]), {}).get(k) if k in own else r[k]
                          for k in DTYPES[name]] for r in rows]
    return out


def export_csv(db: str | Path, out: str | Path, *, force: bool = False) -> list[Path]:
    """Write ``sessions.csv``, ``trials.csv`` and ``samples.csv`` into directory ``out``,
    and ``task_events.csv`` and ``ratings.csv`` when the store holds any.

    ``out`` must be new or empty; ``force`` replaces an earlier CSV export there.

    Returns:
        The files written.

    Raises:
        StoreError: the store cannot be read. ConfigError: ``out`` is not usable.
    """
    with _open(db) as store:
        o = _prepare(out, "csv", force, db)
        files = []
        try:
            for name, rows in _table_rows(store).items():
                files.append(_write_csv(o / f"{name}.csv", dtypes(name),
                                        ([_csv_value(v) for v in r] for r in rows)))
        except OSError as exc:
            raise ConfigError(f"cannot write to {o}: {exc.strerror}") from None
    return files


def _write_json(path: Path, doc: Any) -> Path:
    path.write_text(json.dumps(doc, indent=2) + "\n")
    return path


def _write_csv(path: Path, header: Iterable[str], rows: Iterable[Sequence[Any]],
               encoding: str | None = None, **fmt: Any) -> Path:
    """A CSV file: the header, then the rows (``fmt``: the csv writer's format)."""
    with path.open("w", newline="", encoding=encoding) as fh:
        w = csv.writer(fh, **fmt)
        w.writerow(header)
        w.writerows(rows)
    return path


def _write_tsv(path: Path, header: list[str], rows: Iterable[Sequence[Any]],
               sidecar: dict[str, Any]) -> list[Path]:
    """A TSV file (``n/a`` for a missing value) and its JSON sidecar; both paths."""
    _write_csv(path, header, ([_na(v) for v in row] for row in rows), delimiter="\t",
               lineterminator="\n")
    return [path, _write_json(path.with_suffix(".json"), sidecar)]


def _studies(sessions: list[dict[str, Any]]) -> list[Study | None]:
    """The distinct studies of the sessions (parsed from the stored study files)."""
    seen: dict[str, Study | None] = {}
    for s in sessions:
        seen.setdefault(s["study_sha256"] or s["study_name"], _parse_study(s["study_toml"]))
    return list(seen.values())


def study_authors(studies: Sequence[Any]) -> list[str]:
    """The authors the study files name (``authors``), each once, in order."""
    return list(dict.fromkeys(a for st in studies for a in getattr(st, "authors", None) or []))


def _readme(name: str, studies: list[Any], sessions: list[dict[str, Any]],
            labels: dict[str, str], events: bool = False, ratings: bool = False) -> str:
    """A README describing the study, the task and every file and column."""
    lines = [f"# {name}", "",
             "Exported by tactorbelt from a session store "
             f"({len(sessions)} session(s), {len(labels)} participant(s)).", ""]
    for st in studies:
        if st is None:
            continue
        if st.description.strip():
            lines += [st.description.strip(), ""]
        lay = st.layout_obj()
        lines += [
            f"## Study: {st.name}", "",
            f"- Belt: {lay.n} vibrotactile motors (tactors) round the waist at "
            f"{', '.join(f'{a:g}' for a in lay.angles_deg)} degrees "
            "(0 = navel, clockwise seen from above).",
            f"- Targets: {st.targets.count} directions, evenly spaced.",
            f"- Stimulus: {st.stimulus.law} amplitude law (falloff {st.stimulus.falloff_deg:g} "
            f"degrees); the dynamic condition adds a perturbation of period "
            f"{st.stimulus.period_s:g} s.",
            f"- Response: move the cursor from the centre of an ellipse towards the felt "
            f"direction; a response is taken when it passes {st.response.threshold:g} of the "
            f"radius (timeout {st.response.timeout_s:g} s).",
            f"- Trials per session: {st.n_trials()} ({st.n_test_trials()} test).", ""]
    lines += [
        "## Task", "",
        f"Task `{TASK}`: on each trial the participant feels a direction on the belt "
        "(one tactor, or a point between two tactors rendered by the amplitudes of the two "
        "nearest) and points to it with a joystick or mouse cursor. Training blocks show "
        "the target on screen; test blocks do not.", "",
        "## Files", "",
        "- `participants.tsv`: one row per participant (`source_id` is the id typed at the "
        "session).",
        "- `sub-<label>/ses-<n>/beh/*_beh.tsv`: one row per trial; the columns are "
        "described in the `_beh.json` sidecar and below.",
        f"- `sub-<label>/ses-<n>/beh/*_recording-{RECORDING}_physio.tsv.gz`: the cursor "
        "samples (gzipped, no header; `Columns` in the `_physio.json` sidecar names the "
        "columns). The cursor is sampled from the stimulus onset to the response of each "
        "trial, so the recording pauses between trials: each sample's time is its column "
        "`t`, seconds from the onset of the session's first trial (`StartTime` is the "
        "first sample's `t`).", "",
        "## Trial columns (`_beh.tsv`)", ""]
    lines += _column_lines(_after_load(BEH_COLUMNS))
    if events:
        lines += ["", "## Secondary-task events (`_events.tsv`)", "",
                  "Under a cognitive load, `beh/*_task-betweentactor_events.tsv` has one row "
                  "per item of the secondary task (practice, baseline and during the test "
                  "blocks) and per press that answered no item:", ""]
        lines += _column_lines(EVENT_COLUMNS)
    if ratings:
        lines += ["", f"## Workload ratings (`_task-{TLX_TASK}_beh.tsv`)", "",
                  f"`beh/*_task-{TLX_TASK}_beh.tsv` has one row per test block rated with the "
                  "raw NASA-TLX after it:", ""]
        lines += _column_lines(_after_load(TLX_COLUMNS))
    lines += ["", f"## Cursor samples (`_recording-{RECORDING}_physio.tsv.gz`)", ""]
    lines += _column_lines(CURSOR_COLUMNS)
    return "\n".join(lines) + "\n"


def _column_lines(columns: dict[str, dict[str, Any]]) -> list[str]:
    """A README's list of columns: name, description (and units)."""
    return [f"- `{k}`: {v['Description']}" + (f" ({v['Units']})" if "Units" in v else "")
            for k, v in columns.items()]


def _cursor_rows(store: Store, session_id: int, trials: list[dict[str, Any]]
                 ) -> Iterator[list[Any]]:
    """Cursor-recording rows (:data:`CURSOR_COLUMNS`): trial_index, t (from the first
    trial's onset, 6 decimals), t_trial, x, y (as stored), buttons."""
    onsets = {int(t["trial_index"]): t["onset_ns"] for t in trials if t["onset_ns"] is not None}
    start = min(onsets.values(), default=0)
    for _sid, index, t_s, x, y, buttons in store.iter_samples(session_id):
        onset = onsets.get(int(index), start)
        yield [index, f"{(onset - start) / 1e9 + t_s:.6f}", repr(float(t_s)), repr(x),
               repr(y), buttons]


def _write_cursor(path: Path, rows: Iterator[list[Any]]) -> float | None:
    """Write the headerless, gzipped cursor recording (byte for byte the same on every
    export: no name or time in the gzip header); returns the first row's t (None: no
    samples)."""
    first: float | None = None
    with path.open("wb") as raw, \
            gzip.GzipFile(filename="", mode="wb", fileobj=raw, mtime=0) as gz, \
            io.TextIOWrapper(gz, encoding="utf-8", newline="") as fh:
        w = csv.writer(fh, delimiter="\t", lineterminator="\n")
        for row in rows:
            if first is None:
                first = float(row[1])
            w.writerow([_na(v) for v in row])
    return first


def _cursor_sidecar(session: dict[str, Any], start: float | None) -> dict[str, Any]:
    """The ``_physio.json`` of a session's cursor recording."""
    study = _parse_study(session.get("study_toml"))
    out: dict[str, Any] = {
        "SamplingFrequency": study.session.sample_rate_hz if study is not None else 100.0,
        "StartTime": 0.0 if start is None else start,
        "Columns": list(CURSOR_COLUMNS),
    }
    if session.get("package_version"):
        out["SoftwareVersions"] = f"tactorbelt {session['package_version']}"
    return out | CURSOR_COLUMNS


def _event_rows(events: list[dict[str, Any]], origin_ns: int, study: Any
                ) -> list[list[Any]]:
    """``_events.tsv`` rows (:data:`EVENT_COLUMNS`) of a session's task events, by onset."""
    rows = []
    for e in events:
        extra = e["item_index"] < 0
        spec = (study.tasks.get(e["task"]) if study is not None else None)
        duration = 0.0 if extra else (spec.stimulus_s if spec is not None else None)
        kind = "extra_press" if extra else ("go" if e["target"] else "nogo")
        rows.append([f"{(e['t_ns'] - origin_ns) / 1e9:.6f}", duration, kind, e["task"],
                     e["phase"], e["block_index"], e["item_index"], e["stimulus"],
                     e["response"] or None,
                     None if e["rt_s"] is None else repr(float(e["rt_s"])), int(e["correct"])])
    rows.sort(key=lambda r: float(r[0]))
    return rows


def _tlx_rows(ratings: list[dict[str, Any]], trials: list[dict[str, Any]]) -> list[list[Any]]:
    """Ratings-file rows (:data:`TLX_COLUMNS`): one per rated block, with its cell."""
    blocks: dict[int, dict[str, float]] = {}
    for r in ratings:
        if r["scale"] == "nasa_tlx":
            blocks.setdefault(int(r["block_index"]), {})[r["item"]] = float(r["value"])
    cells: dict[int, dict[str, Any]] = {}
    for t in trials:
        cells.setdefault(int(t["block_index"]), t)
    rows = []
    for b, values in sorted(blocks.items()):
        t = cells.get(b, {})
        items = [values.get(k) for k in TLX_ITEMS]
        known = [v for v in items if v is not None]
        mean = sum(known) / len(known) if len(known) == len(items) else None
        rows.append([b, t.get("block_name"), t.get("condition"), t.get("n_targets"),
                     t.get("load"), *(t.get(f.column) for f in added_factors()),
                     *[None if v is None else f"{v:g}" for v in items],
                     None if mean is None else f"{mean:.6g}"])
    return rows


def export_bids(db: str | Path, out: str | Path, *, readme: str | Path | None = None,
                authors: Sequence[str] | None = None, force: bool = False) -> list[Path]:
    """Write a BIDS behavioural dataset, with the cursor samples, into directory ``out``
    (module doc).

    Args:
        readme: a README file to copy; default: one generated from the study files.
        authors: the dataset's authors (``dataset_description.json``); None: the ones the
            study files name (:func:`study_authors`).
        force: replace an earlier BIDS export in ``out`` (which must otherwise be new or
            empty).

    Returns:
        The files written.
    """
    readme_text: str | None = None
    readme_name = "README.md"
    if readme is not None:
        rp = Path(readme)
        try:
            readme_text = rp.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            why = exc.strerror if isinstance(exc, OSError) else "not UTF-8 text"
            raise ConfigError(f"cannot read the README {rp}: {why}") from None
        readme_name = "README" + (rp.suffix if rp.suffix in (".md", ".rst", ".txt") else "")
    written: list[Path] = []
    with _open(db) as store:
        sessions = store.sessions()
        labels: dict[str, str] = {}
        for s in sessions:
            lab = bids_label(s["participant"])
            if labels.setdefault(lab, s["participant"]) != s["participant"]:
                raise ConfigError(
                    f"participants {labels[lab]!r} and {s['participant']!r} both give the "
                    f"BIDS label {lab!r}; rename one of them"
                )
        o = _prepare(out, "bids", force, db)
        studies = _studies(sessions)
        names = list(dict.fromkeys(s["study_name"] for s in sessions if s["study_name"]))
        name = "; ".join(names) or "tactorbelt between-tactor localisation"
        desc: dict[str, Any] = {
            "Name": name,
            "BIDSVersion": "1.9.0",
            "DatasetType": "raw",
        }
        if authors is None:
            authors = study_authors(studies)
        if authors:
            desc["Authors"] = list(authors)
        desc["GeneratedBy"] = [{"Name": "tactorbelt", "Version": __version__}]
        written.append(_write_json(o / "dataset_description.json", desc))
        p = o / readme_name
        p.write_text(readme_text if readme_text is not None
                     else _readme(name, studies, sessions, labels,
                                  events=bool(store.task_events()),
                                  ratings=bool(store.ratings())), encoding="utf-8")
        written.append(p)
        written += _write_tsv(
            o / "participants.tsv", ["participant_id", "source_id"],
            [(f"sub-{lab}", pid) for lab, pid in sorted(labels.items())], {
                "participant_id": {"Description": "BIDS label of the participant"},
                "source_id": {"Description": "participant id as entered at the session"}})
        for s in sessions:
            lab = bids_label(s["participant"])
            stem = f"sub-{lab}_ses-{s['session_number']}_task-{TASK}"
            base = o / f"sub-{lab}" / f"ses-{s['session_number']}"
            (base / "beh").mkdir(parents=True, exist_ok=True)
            trials = [_with_cell(t, s) for t in store.trials(s["session_id"])]
            beh_cols = _after_load(BEH_COLUMNS)
            cols = list(beh_cols)
            written += _write_tsv(
                base / "beh" / f"{stem}_beh.tsv", cols,
                [[_beh_value(t, k) for k in cols] for t in trials],
                beh_cols | {"TaskName": TASK, "StimulusSystem": _stimulus_system(s),
                            "tactorbelt": {k: s[k] for k in (
                                "study_name", "study_sha256", "seed", "condition_order",
                                "belt", "firmware_version", "package_version", "git_commit",
                                "host", "input", "clock", "started_at", "ended_at",
                                "status")}})
            written += _task_files(store, s, trials, base / "beh", stem, lab)
            rec = base / "beh" / f"{stem}_recording-{RECORDING}_physio.tsv.gz"
            start = _write_cursor(rec, _cursor_rows(store, s["session_id"], trials))
            written += [rec, _write_json(rec.with_name(rec.name.removesuffix(".tsv.gz")
                                                       + ".json"), _cursor_sidecar(s, start))]
    return written


_SKIN_ONSET_RULE = (
    "skin_onset_s = the stored onset (device-true where the belt reports it, else the "
    "command time) + the measured latency (command to 10 % of the steady vibration, "
    "'tactorbelt validate onsets') of the tactors that start the stimulus: for a dynamic "
    "stimulus the nearer tactor, where its dwell starts; otherwise every tactor driven "
    "above zero at the onset, their latencies averaged with the amplitudes as weights.")
_TIMING = ("latency_ms", "latency_sd_ms", "rise_ms", "rise_sd_ms", "fall_ms", "fall_sd_ms")


def _stimulus_system(session: dict[str, Any]) -> dict[str, Any]:
    """The ``StimulusSystem`` object of a session's ``_beh.json``: the belt, its tactor
    layout in body coordinates, its actuators (and carrier), the amplitude law, the
    calibration with each tactor's measured latency and rise, and the skin-onset rule."""
    from ..devices.registry import BACKENDS

    belt = str(session.get("belt") or "")
    query = parse_qs(belt.partition("?")[2])
    # the actuators and carrier the belt's registry entry declares
    backend = BACKENDS.get(belt.split(":", 1)[0].split("?", 1)[0].lower())
    out: dict[str, Any] = {
        "Description": "The vibrotactile belt that presented the stimuli.",
        "Belt": belt or "n/a",
        "ActuatorType": backend.actuator if backend and backend.actuator else "unknown",
        # the session's belt URL names a shaped drive (docs/belts.md, "Drive shaping")
        "Drive": query.get("drive", ["plain"])[0],
    }
    if session.get("firmware_version"):
        out["FirmwareVersion"] = str(session["firmware_version"])
    if backend is not None and backend.carrier_hz is not None:
        carrier = backend.carrier_hz
        with contextlib.suppress(ValueError):
            carrier = float(query.get("carrier_hz", [carrier])[0])
        out["CarrierFrequency"] = carrier
        out["CarrierFrequencyUnits"] = "Hz"
    study = _parse_study(session.get("study_toml"))
    angles: list[float] = []
    if study is not None:
        angles = [float(a) for a in study.layout_obj().angles_deg]
        sp = study.stimulus
        out["TactorLayout"] = {
            "Description": "Tactor k's direction on the body: 0 = navel, clockwise seen "
                           "from above (index k = tactor k).",
            "AnglesDeg": angles, "Units": "deg"}
        out["AmplitudeLaw"] = {
            "Description": "The amplitude of each tactor for a felt location (the study's "
                           "[stimulus]; blocks may override it, see the study file).",
            "Law": sp.law, "FalloffDeg": sp.falloff_deg, "PeriodS": sp.period_s,
            "TransitS": sp.transit_s}
    rows: list[dict[str, Any]] = []
    with contextlib.suppress(TypeError, ValueError):
        rows = list(json.loads(session.get("calibration_json") or "[]") or [])
    if rows:
        tactors = []
        for k, r in enumerate(rows):
            row: dict[str, Any] = {"Index": k}
            if k < len(angles):
                row["AngleDeg"] = angles[k]
            row |= {n.capitalize(): r[n] for n in ("start", "gain", "ceiling") if n in r}
            row |= {n: r[n] for n in _TIMING if r.get(n) is not None}
            tactors.append(row)
        out["Calibration"] = {
            "Description": "Drive level of tactor k for an amplitude a > 0: Start + "
                           "(Ceiling - Start) * a * Gain, clamped to [0, Ceiling] (0 for "
                           "a = 0). latency_ms: command to 10 % of the steady vibration; "
                           "rise_ms: 10 to 90 %; fall_ms: 90 to 10 % after the stop; *_sd_ms: "
                           "their spread over pulses (tactorbelt validate onsets; absent: "
                           "not measured).",
            "Tactors": tactors}
    out["SkinOnset"] = _SKIN_ONSET_RULE
    return out


def _task_files(store: Store, s: dict[str, Any], trials: list[dict[str, Any]], beh: Path,
                stem: str, lab: str) -> list[Path]:
    """A session's secondary-task events (``_events.tsv``) and NASA-TLX ratings
    (``task-nasatlx_beh.tsv``), each with its sidecar, when it has any."""
    written: list[Path] = []
    events = store.task_events(s["session_id"])
    if events:
        onsets = [t["onset_ns"] for t in trials if t["onset_ns"] is not None]
        origin = min(onsets) if onsets else min(e["t_ns"] for e in events)
        rows = _event_rows(events, origin, _parse_study(s["study_toml"]))
        written += _write_tsv(beh / f"{stem}_events.tsv", list(EVENT_COLUMNS), rows,
                              EVENT_COLUMNS)
    tlx = _tlx_rows(store.ratings(s["session_id"]), trials)
    if tlx:
        tlx_cols = _after_load(TLX_COLUMNS)
        written += _write_tsv(
            beh / f"sub-{lab}_ses-{s['session_number']}_task-{TLX_TASK}_beh.tsv",
            list(tlx_cols), tlx, {
                "TaskName": TLX_TASK,
                "TaskDescription": "Raw NASA Task Load Index (NASA-TLX): six workload items "
                                   "rated on 0-100 sliders after each test block of the "
                                   f"{TASK} task.",
                **tlx_cols})
    return written
