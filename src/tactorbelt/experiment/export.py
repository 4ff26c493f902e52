"""Export a store to tidy CSV files or to a BIDS-style behavioural dataset.

CSV (:func:`export_csv`): ``sessions.csv``, ``trials.csv`` (one row per trial, with
the participant and session number) and ``samples.csv`` (one row per cursor sample,
with participant, session and trial index).

BIDS-style (:func:`export_bids`)::

    dataset_description.json  participants.tsv  participants.json
    sub-<id>/ses-<n>/beh/sub-<id>_ses-<n>_task-betweentactor_beh.tsv   (+ .json sidecar)
    sub-<id>/ses-<n>/motion/sub-<id>_ses-<n>_task-betweentactor_tracksys-cursor_motion.tsv
                                           ..._channels.tsv, ..._motion.json

``<id>`` is the participant id with everything but letters and digits removed (BIDS
labels are alphanumeric); two ids that collapse to the same label are an error.
Missing values are ``n/a``. The motion file has no header; its columns are the rows
of ``_channels.tsv`` (trial, t_s, x, y, buttons).

I/O: reads a store (:func:`~tactorbelt.experiment.store.open_store`, read-only) through
its interface and writes files; standard library only.
"""

from __future__ import annotations

import csv
import functools
import json
import re
from pathlib import Path
from typing import Any

from .._errors import ConfigError, TactorbeltError
from .store import Store, open_store
from .study import Study

__all__ = ["BEH_COLUMNS", "TASK", "bids_label", "export_bids", "export_csv"]

TASK = "betweentactor"

TRIAL_COLUMNS = [
    "participant", "session_id", "session_number", "trial_id", "trial_index", "block",
    "block_index", "block_name", "condition", "repetition", "target_deg", "on_tactor",
    "response_deg", "response_target_deg", "correct", "rt_s", "onset_ns", "acquired_ns",
    "crossed_ns", "stimulus_off_ns", "n_samples", "status", "abort_reason", "attempts",
    "n_targets", "load",
]
SAMPLE_COLUMNS = ["participant", "session_id", "trial_index", "t_s", "x", "y", "buttons"]
SESSION_COLUMNS = [
    "session_id", "participant", "session_number", "study_name", "study_sha256", "seed",
    "condition_order", "n_trials", "belt", "firmware_version", "package_version",
    "git_commit", "host", "input", "clock", "started_at", "ended_at", "status", "resumed",
]

#: Every column of the BIDS ``_beh.tsv`` and its description (the JSON sidecar).
BEH_COLUMNS: dict[str, dict[str, Any]] = {
    "trial_index": {"Description": "Position of the trial in the session's schedule (0-based)."},
    "block": {"Description": "Block type.", "Levels": {
        "training": "target shown on screen while felt", "test": "target felt only"}},
    "block_name": {"Description": "Name of the block in the study file."},
    "condition": {"Description": "Rendering of between-tactor targets.", "Levels": {
        "static": "constant amplitudes",
        "dynamic": "trapezoidal perturbation between the two nearest tactors"}},
    "repetition": {"Description": "Repetition (test) or pass (training) of this target, 1-based."},
    "target_deg": {"Description": "Target direction; 0 = navel, clockwise seen from above.",
                   "Units": "deg"},
    "on_tactor": {"Description": "1 when the target coincides with a tactor, else 0."},
    "n_targets": {"Description": "Target count of the trial's block (targets at "
                  "k*360/n_targets); the response snaps to these."},
    "load": {"Description": "Secondary task during the block ('none' without one)."},
    "response_deg": {"Description": "Direction of the cursor at acquisition "
                     "(atan2(x, y), 0 = up/front, clockwise).", "Units": "deg"},
    "response_target_deg": {"Description": "Target nearest in angle to response_deg.",
                            "Units": "deg"},
    "correct": {"Description": "1 when response_target_deg equals target_deg, else 0."},
    "rt_s": {"Description": "Time from stimulus onset to target acquisition.", "Units": "s"},
    "onset_s": {"Description": "Stimulus onset on the session clock (monotonic).", "Units": "s"},
    "status": {"Description": "Outcome of the trial.", "Levels": {
        "done": "a response was acquired", "timeout": "no response before the timeout",
        "aborted": "interrupted (pause, device error, Ctrl-C)"}},
}

CHANNELS = [
    ("trial", "MISC", "n/a", "trial_index of the sample's trial"),
    ("t_s", "LATENCY", "s", "time from stimulus onset"),
    ("x", "POS", "n/a", "cursor x, right positive, ellipse radius 1"),
    ("y", "POS", "n/a", "cursor y, up (front) positive, ellipse radius 1"),
    ("buttons", "MISC", "n/a", "button bit mask"),
]


def bids_label(participant: str) -> str:
    """A BIDS label (letters and digits only) for a participant id."""
    label = re.sub(r"[^A-Za-z0-9]", "", participant)
    if not label:
        raise ConfigError(f"participant id {participant!r} has no letter or digit for a BIDS label")
    return label


def _na(v: Any) -> Any:
    return "n/a" if v is None else v


def _open(db: str | Path) -> Store:
    return open_store(db, create=False, readonly=True)


def _prepare(out: str | Path) -> Path:
    o = Path(out)
    if o.exists() and not o.is_dir():
        raise ConfigError(f"{o} exists and is not a directory; give a directory for the export")
    try:
        o.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot create {o}: {exc.strerror}") from None
    return o


@functools.lru_cache(maxsize=64)
def _study_count(study_toml: str) -> int | None:
    """``[targets] count`` of a stored study text (None when it does not parse)."""
    try:
        return Study.from_toml(study_toml).targets.count
    except TactorbeltError:
        return None


def _with_cell(trial: dict[str, Any], session: dict[str, Any]) -> dict[str, Any]:
    """The trial row with ``n_targets`` and ``load``: as stored, else (a store written
    before factorial designs) the session's study's ``[targets] count`` and ``none``."""
    if trial.get("n_targets") is not None and trial.get("load") is not None:
        return trial
    out = dict(trial)
    if out.get("n_targets") is None:
        out["n_targets"] = _study_count(str(session.get("study_toml") or ""))
    if out.get("load") is None:
        out["load"] = "none"
    return out


def export_csv(db: str | Path, out: str | Path) -> list[Path]:
    """Write ``sessions.csv``, ``trials.csv`` and ``samples.csv`` into directory ``out``.

    Returns:
        The files written.

    Raises:
        StoreError: the store cannot be read. ConfigError: ``out`` is not usable.
    """
    with _open(db) as store:
        o = _prepare(out)
        sessions = store.sessions()
        by_id = {int(s["session_id"]): s for s in sessions}
        trials = sorted(store.trials(), key=lambda t: (t["session_id"], t["trial_id"]))
        try:
            files = [o / "sessions.csv", o / "trials.csv", o / "samples.csv"]
            with files[0].open("w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(SESSION_COLUMNS)
                for s in sessions:
                    w.writerow([s[k] for k in SESSION_COLUMNS])
            with files[1].open("w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(TRIAL_COLUMNS)
                for t in trials:
                    sess = by_id[int(t["session_id"])]
                    t = _with_cell(t, sess)
                    w.writerow([sess[k] if k in ("participant", "session_number") else t[k]
                                for k in TRIAL_COLUMNS])
            with files[2].open("w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(SAMPLE_COLUMNS)
                for sid, index, t_s, x, y, buttons in store.iter_samples():
                    w.writerow([by_id[int(sid)]["participant"], sid, index, repr(t_s),
                                repr(x), repr(y), buttons])
        except OSError as exc:
            raise ConfigError(f"cannot write to {o}: {exc.strerror}") from None
    return files


def _write_tsv(path: Path, header: list[str] | None, rows: Any) -> None:
    with path.open("w", newline="") as fh:
        w = csv.writer(fh, delimiter="\t", lineterminator="\n")
        if header is not None:
            w.writerow(header)
        for row in rows:
            w.writerow([_na(v) for v in row])


def export_bids(db: str | Path, out: str | Path) -> list[Path]:
    """Write a BIDS-style behavioural dataset into directory ``out`` (see the module doc).

    Returns:
        The files written.
    """
    from .. import __version__

    written: list[Path] = []
    with _open(db) as store:
        o = _prepare(out)
        sessions = store.sessions()
        labels: dict[str, str] = {}
        for s in sessions:
            lab = bids_label(s["participant"])
            if labels.setdefault(lab, s["participant"]) != s["participant"]:
                raise ConfigError(
                    f"participants {labels[lab]!r} and {s['participant']!r} both give the "
                    f"BIDS label {lab!r}; rename one of them"
                )
        desc = {
            "Name": "tactorbelt between-tactor localisation",
            "BIDSVersion": "1.9.0",
            "DatasetType": "raw",
            "GeneratedBy": [{"Name": "tactorbelt", "Version": __version__}],
        }
        p = o / "dataset_description.json"
        p.write_text(json.dumps(desc, indent=2) + "\n")
        written.append(p)
        p = o / "participants.tsv"
        _write_tsv(p, ["participant_id", "source_id"],
                   [(f"sub-{lab}", pid) for lab, pid in sorted(labels.items())])
        written.append(p)
        p = o / "participants.json"
        p.write_text(json.dumps({
            "participant_id": {"Description": "BIDS label of the participant"},
            "source_id": {"Description": "participant id as entered at the session"},
        }, indent=2) + "\n")
        written.append(p)
        for s in sessions:
            lab = bids_label(s["participant"])
            stem = f"sub-{lab}_ses-{s['session_number']}_task-{TASK}"
            base = o / f"sub-{lab}" / f"ses-{s['session_number']}"
            (base / "beh").mkdir(parents=True, exist_ok=True)
            (base / "motion").mkdir(parents=True, exist_ok=True)
            trials = [_with_cell(t, s) for t in store.trials(s["session_id"])]
            beh = base / "beh" / f"{stem}_beh.tsv"
            cols = list(BEH_COLUMNS)
            _write_tsv(beh, cols, [
                [(t["onset_ns"] / 1e9 if t["onset_ns"] is not None else None) if k == "onset_s"
                 else t[k] for k in cols] for t in trials])
            sidecar: dict[str, Any] = dict(BEH_COLUMNS)
            sidecar["TaskName"] = TASK
            sidecar["tactorbelt"] = {
                k: s[k] for k in ("study_name", "study_sha256", "seed", "condition_order",
                                  "belt", "firmware_version", "package_version", "git_commit",
                                  "host", "input", "clock", "started_at", "ended_at", "status")
            }
            bj = beh.with_suffix(".json")
            bj.write_text(json.dumps(sidecar, indent=2) + "\n")
            written += [beh, bj]
            mstem = f"{stem}_tracksys-cursor"
            motion = base / "motion" / f"{mstem}_motion.tsv"
            rows = store.iter_samples(s["session_id"])
            _write_tsv(motion, None, ([r[1], repr(r[2]), repr(r[3]), repr(r[4]), r[5]]
                                      for r in rows))
            ch = base / "motion" / f"{mstem}_channels.tsv"
            _write_tsv(ch, ["name", "component", "type", "tracked_point", "units", "description"],
                       [(n, {"x": "x", "y": "y"}.get(n, "n/a"), typ, "cursor", u, d)
                        for n, typ, u, d in CHANNELS])
            mj = base / "motion" / f"{mstem}_motion.json"
            rate = 100.0
            try:
                from .study import Study

                rate = Study.from_toml(s["study_toml"]).session.sample_rate_hz
            except Exception:
                pass
            mj.write_text(json.dumps({
                "TaskName": TASK,
                "TrackingSystemName": "cursor",
                "SamplingFrequency": rate,
                "SamplingFrequencyEffective": rate,
                "RecordingType": "epoched",
                "MotionChannelCount": 2,
                "MISCChannelCount": 2,
                "LATENCYChannelCount": 1,
                "TrackedPointsCount": 1,
                "Description": "Cursor position in the response ellipse during each trial, "
                               "sampled from stimulus onset to acquisition or timeout; "
                               "one epoch per trial (column 'trial').",
            }, indent=2) + "\n")
            written += [motion, ch, mj]
    return written
