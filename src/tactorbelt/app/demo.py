"""The paper's study with model participants: the whole-study run behind ``tactorbelt
demo``.

- :func:`run_model_study`: writes the paper's protocol, runs N model participants
  through the real session runner on the ``sim`` belt and a simulated clock, stores
  everything in ``DIR/study.sqlite`` and writes the analysis report.

The power analysis behind ``tactorbelt power`` is :mod:`tactorbelt.power`
(:func:`~tactorbelt.power.study.run_power_study`).

Seed policy (one for every model participant): participant ``i`` (1-based) of a study
with seed ``s`` draws its parameters and its cursor's seed from
``numpy.random.SeedSequence([s, i]).spawn(2)`` (:func:`model_participants`); its session
is scheduled with seed ``s``, and the analysis seed is derived from the stored sessions
(so it is ``s``; see docs/analysis.md).

The participants are models (docs/participant-model.md); their results follow from the
model's assumptions and are no evidence about people.

I/O: writes files and a store. Only ``tactorbelt demo`` (inside its command) and the tests
import this module, so NumPy, the runner and the analysis load at its top.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .._errors import ConfigError
from ..analysis.report.analyze import analyze
from ..analysis.summary import Summary
from ..clock import SimClock
from ..devices import open_belt
from ..experiment.runner import run_session
from ..experiment.store import open_store
from ..experiment.store.sqlite import move_store_file
from ..experiment.study import PAPER_STUDY_TOML, Study
from ..inputs import make_cursor
from ..participant.load import LoadParams
from ..participant.params import ModelParams, draw_participant
from ..power.study import MODEL_NOTE, prepare_out

__all__ = [
    "MODEL_NOTE",
    "PREVIOUS_STORE_NAME",
    "STORE_NAME",
    "ModelParticipant",
    "ModelStudyResult",
    "model_participants",
    "participant_ids",
    "prepare_out",
    "run_model_study",
]

STORE_NAME = "study.sqlite"
PREVIOUS_STORE_NAME = "study.previous.sqlite"

#: ``progress(what, done, total)``: what is being done and how far.
ProgressFn = Callable[[str, int, int], None]


def participant_ids(n: int) -> list[str]:
    """``model-01`` ... (at least two digits, wider for 100 or more)."""
    width = max(2, len(str(n)))
    return [f"model-{i:0{width}d}" for i in range(1, n + 1)]


@dataclass(frozen=True)
class ModelParticipant:
    """One model participant of a study: id, drawn parameters and its cursor's seed."""

    pid: str
    params: ModelParams
    cursor_seed: int


def model_participants(n: int, seed: int, base: ModelParams) -> list[ModelParticipant]:
    """The study's model participants under the one seed policy (see the module doc)."""
    people = []
    for i, pid in enumerate(participant_ids(n)):
        params_seq, cursor_seq = np.random.SeedSequence([seed, i + 1]).spawn(2)
        params = draw_participant(np.random.default_rng(params_seq), base)
        cursor_seed = int(cursor_seq.generate_state(1, np.uint64)[0] >> np.uint64(1))
        people.append(ModelParticipant(pid, params, cursor_seed))
    return people


@dataclass(frozen=True)
class ModelStudyResult:
    """What :func:`run_model_study` wrote."""

    summary: Summary
    store: Path
    report: Path


def run_model_study(out: Path, n_participants: int, seed: int,
                    progress: ProgressFn | None = None,
                    notify: Callable[[str], None] | None = None,
                    study_toml: str | None = None,
                    study_file: Path | None = None) -> ModelStudyResult:
    """Run a whole study with model participants into ``out`` and analyse it.

    Writes ``out/study.toml`` (the paper's protocol unless ``study_toml`` or
    ``study_file`` is given; a study file is checked first, its errors naming it),
    moves an earlier ``out/study.sqlite`` to ``out/study.previous.sqlite``, runs each
    participant's whole session on the sim belt and a simulated clock into
    ``out/study.sqlite``, writes ``participants.json`` and the analysis report.

    Args:
        progress: called with ``(what, done, total)``; ``what`` names the participant
            (``model-01 (1/2)``, counting trials of all participants) or the analysis
            step (``analysis: ...``).
        notify: called with a note for the user (an earlier store was moved aside).
        study_toml: the study's text (instead of the paper's protocol).
        study_file: a study file to run (instead of ``study_toml``).

    Raises:
        ConfigError: ``out`` is unusable, the study file unreadable, or a session did
            not complete.
        StudyFileError: the study file is not a valid study (file, line and field).
        StoreError: another run is using the store.
    """
    if study_file is not None:
        try:
            study_toml = Path(study_file).read_text(encoding="utf-8")
        except OSError as exc:
            raise ConfigError(f"cannot read study file {study_file}: {exc.strerror}") from None
        Study.from_toml(study_toml, path=study_file)
    text = PAPER_STUDY_TOML if study_toml is None else study_toml
    out = prepare_out(out)
    study_path = out / "study.toml"
    try:
        study_path.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise ConfigError(f"cannot write {study_path}: {exc.strerror}") from None
    study: Study = Study.from_toml(text, path=study_path)
    db = out / STORE_NAME
    if move_store_file(db, out / PREVIOUS_STORE_NAME) and notify is not None:
        notify(f"the previous store was moved to {out / PREVIOUS_STORE_NAME}")
    base = ModelParams().for_period(study.stimulus.period_s)
    people = model_participants(n_participants, seed, base)
    n_trials = study.n_trials()
    total = n_participants * n_trials
    with open_store(db) as store:
        for i, person in enumerate(people):
            what = f"{person.pid} ({i + 1}/{n_participants})"

            def session_progress(n_done: int, n_total: int, _base: int = i * n_trials,
                                 _what: str = what) -> None:
                if progress is not None:
                    progress(_what, _base + n_done, total)

            session_progress(0, n_trials)
            clock = SimClock()
            with open_belt("sim", clock=clock, layout=study.layout_obj()) as belt:
                cursor = make_cursor("model", study=study, belt=belt, clock=clock,
                                     participant=person.pid, cursor_seed=person.cursor_seed,
                                     params=person.params)
                result = run_session(study, person.pid, belt, cursor, store, clock, seed=seed,
                                     progress=session_progress, study_toml=text,
                                     input_name="model")
            if result.status != "complete":
                raise ConfigError(f"the session of {person.pid} ended {result.status}; "
                                  f"see {db}")
    doc: dict[str, Any] = {
        "note": MODEL_NOTE, "study": study.name, "seed": seed,
        "participants": {p.pid: {"seed": p.cursor_seed, "params": p.params.to_dict()}
                         for p in people}}
    if study.tasks or study.questionnaire.tlx:
        doc["load_model"] = LoadParams().to_dict()  # shared; docs/participant-model.md
    (out / "participants.json").write_text(json.dumps(doc, indent=2) + "\n",
                                           encoding="utf-8")

    def analysis_progress(what: str, done: int, steps: int) -> None:
        if progress is not None:
            progress(f"analysis: {what}", done, max(steps, 1))

    # No seed given: the analysis derives it from the stored sessions, exactly as
    # 'tactorbelt analyze' on this store does.
    summary = analyze([db], out, progress=analysis_progress)
    return ModelStudyResult(summary, db, out / "report.html")

