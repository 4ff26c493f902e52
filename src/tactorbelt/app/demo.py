"""The paper's study with model participants: the whole-study runs behind ``tactorbelt
demo`` and ``tactorbelt power``.

- :func:`run_model_study`: writes the paper's protocol, runs N model participants
  through the real session runner on the ``sim`` belt and a simulated clock, stores
  everything in ``DIR/study.sqlite`` and writes the analysis report.
- :func:`run_power_study`: estimates, by simulation on the fast path
  (:mod:`tactorbelt.participant.simulate`, in a process pool), how often a study of N
  model participants finds the static-versus-dynamic difference with the analysis'
  test; writes power.csv, power.json and power.png.

Seed policy (one for every model participant): participant ``i`` (1-based) of a study
with seed ``s`` draws its parameters and its cursor's seed from
``numpy.random.SeedSequence([s, i]).spawn(2)`` (:func:`model_participants`); its session
is scheduled with seed ``s``, and the analysis seed is derived from the stored sessions
(so it is ``s``; see docs/analysis.md).

The participants are models (docs/participant-model.md); their results follow from the
model's assumptions and are no evidence about people.

I/O: writes files and a store; imports NumPy, the runner, the analysis and matplotlib
only inside the functions.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .._errors import ConfigError

if TYPE_CHECKING:
    import numpy as np

    from ..analysis.power_model import NamedEffect
    from ..analysis.stats import Summary
    from ..experiment.study import Study
    from ..participant.factorial import Effect, FactorialProtocol
    from ..participant.params import ModelParams
    from ..participant.power import PowerRow, StudyOutcome
    from ..participant.simulate import Protocol, StimulusCues

__all__ = [
    "MODEL_NOTE",
    "NAMED_NOTE",
    "PREVIOUS_STORE_NAME",
    "STORE_NAME",
    "ModelParticipant",
    "ModelStudyResult",
    "PowerStudyResult",
    "analysis_paired_test",
    "model_participants",
    "participant_ids",
    "prepare_out",
    "run_model_study",
    "run_power",
    "run_power_study",
]

STORE_NAME = "study.sqlite"
PREVIOUS_STORE_NAME = "study.previous.sqlite"
MODEL_NOTE = ("The participants are simulated observers (the model participant): their "
              "results follow from the model's assumptions and are no evidence about people.")
SMALL_STUDY_NOTE = ("with 5 or fewer participants the exact two-sided Wilcoxon test cannot "
                    "reach p < 0.05 (its smallest p is 2/2^n), whatever the effect.")
NAMED_NOTE = ("The trials are simulated from the report's accuracy model with the effect "
              "sizes you named, and each simulated study is analysed with that model: the "
              "power holds if people's accuracies follow that model with those sizes.")

#: ``progress(what, done, total)``: what is being done and how far.
ProgressFn = Callable[[str, int, int], None]


def prepare_out(path: Path) -> Path:
    """Create the output directory (and parents), or explain why it cannot be."""
    if path.exists() and not path.is_dir():
        raise ConfigError(f"--out {path} exists and is not a directory")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"cannot create directory {path}: {exc.strerror}") from None
    return path


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
    import numpy as np

    from ..participant.params import draw_participant

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
    #: Where an earlier store in the directory was moved, or None.
    previous_store: Path | None


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
    from ..analysis.report import analyze
    from ..clock import SimClock
    from ..devices import open_belt
    from ..experiment.runner import run_session
    from ..experiment.store import open_store
    from ..experiment.store.sqlite import move_store_file
    from ..experiment.study import PAPER_STUDY_TOML, Study
    from ..inputs import make_cursor
    from ..participant.params import ModelParams

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
    moved = out / PREVIOUS_STORE_NAME if move_store_file(db, out / PREVIOUS_STORE_NAME) else None
    if moved is not None and notify is not None:
        notify(f"the previous store was moved to {moved}")
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
        from ..participant.load import LoadParams

        doc["load_model"] = LoadParams().to_dict()  # shared; docs/participant-model.md
    (out / "participants.json").write_text(json.dumps(doc, indent=2) + "\n",
                                           encoding="utf-8")

    def analysis_progress(what: str, done: int, steps: int) -> None:
        if progress is not None:
            progress(f"analysis: {what}", done, max(steps, 1))

    # No seed given: the analysis derives it from the stored sessions, exactly as
    # 'tactorbelt analyze' on this store does.
    summary = analyze([db], out, progress=analysis_progress)
    return ModelStudyResult(summary, db, out / "report.html", moved)


# -- power ---------------------------------------------------------------------------------

def analysis_paired_test(static: np.ndarray, dynamic: np.ndarray) -> float:
    """The analysis' static-vs-dynamic test (paired Wilcoxon) p-value; NaN if not computed.

    Where SciPy would run its exact permutation test (ties or zeros, at most 13 pairs;
    about 0.2 s a call) the same p-value comes from
    :func:`~tactorbelt.participant.power.exact_signed_rank_p` (a matrix product).
    """
    import numpy as np

    from ..analysis.stats import wilcoxon_paired
    from ..participant.power import exact_signed_rank_p

    s = np.asarray(static, dtype=float)
    d = np.asarray(dynamic, dtype=float)
    ok = ~(np.isnan(s) | np.isnan(d))
    diff = d[ok] - s[ok]
    if diff.size >= 2 and np.any(diff != 0):
        p = exact_signed_rank_p(diff)
        if p is not None:
            return p

    res = wilcoxon_paired(static, dynamic, np.random.default_rng(0), n_boot=1,
                          key="between_accuracy", what="accuracy")
    if not res.computed or res.p_value is None:
        return float("nan")
    return float(res.p_value)


def _power_chunk(args: tuple[Protocol, StimulusCues, int, list[int], int]
                 ) -> list[StudyOutcome]:
    """Worker: simulate some studies of one size (module level, so processes can run it)."""
    from ..participant.power import simulate_studies

    protocol, cues, n, indices, seed = args
    return simulate_studies(protocol, cues, n, indices, seed, analysis_paired_test)


def _factorial_chunk(args: tuple[FactorialProtocol, tuple[StimulusCues, ...], Effect, int,
                                  list[int], int]) -> list[StudyOutcome]:
    """Worker: simulate some factorial studies of one size (module level, for processes)."""
    from ..participant.factorial import simulate_factorial_studies

    protocol, cues, effect, n, indices, seed = args
    return simulate_factorial_studies(protocol, cues, effect, n, indices, seed,
                                      analysis_paired_test)


def _pool(worker: Callable[[Any], list[StudyOutcome]], work: list[tuple[int, Any]],
          sizes: Sequence[int], jobs: int, alpha: float,
          advance: Callable[[int], None] | None) -> list[PowerRow]:
    """Run ``(size, args)`` work items (in ``jobs`` processes); one PowerRow per size."""
    from ..participant.power import power_row

    results: dict[int, list[StudyOutcome]] = {n: [] for n in sizes}
    if jobs <= 1:
        for n, item in work:
            done = worker(item)
            results[n].extend(done)
            if advance is not None:
                advance(len(done))
    else:
        from concurrent.futures import ProcessPoolExecutor, as_completed

        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = {pool.submit(worker, item): n for n, item in work}
            for fut in as_completed(futures):
                done = fut.result()
                results[futures[fut]].extend(done)
                if advance is not None:
                    advance(len(done))
    return [power_row(results[n], alpha) for n in sizes]


def _chunks(sims: int, jobs: int) -> list[list[int]]:
    chunk = max(1, min(25, math.ceil(sims / max(jobs, 1) / 4)))
    return [list(range(s, min(s + chunk, sims))) for s in range(0, sims, chunk)]


def run_power(protocol: Protocol, cues: StimulusCues, sizes: Sequence[int], sims: int,
              seed: int, jobs: int, alpha: float,
              advance: Callable[[int], None] | None = None) -> list[PowerRow]:
    """Simulate ``sims`` studies at each size (in ``jobs`` processes) and summarise them.

    Results do not depend on ``jobs``: each simulated study has its own seed.
    """
    work = [(n, (protocol, cues, n, idx, seed)) for n in sizes for idx in _chunks(sims, jobs)]
    return _pool(_power_chunk, work, sizes, jobs, alpha, advance)


def run_factorial_power(protocol: FactorialProtocol, cues: tuple[StimulusCues, ...],
                        effect: Effect, sizes: Sequence[int], sims: int, seed: int,
                        jobs: int, alpha: float,
                        advance: Callable[[int], None] | None = None) -> list[PowerRow]:
    """:func:`run_power` for a factorial study and a named effect."""
    work = [(n, (protocol, cues, effect, n, idx, seed))
            for n in sizes for idx in _chunks(sims, jobs)]
    return _pool(_factorial_chunk, work, sizes, jobs, alpha, advance)


def _plot_power(rows: Sequence[PowerRow], path: Path, title: str, alpha: float) -> None:
    os.environ.setdefault("MPLBACKEND", "Agg")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    n = [r.n_participants for r in rows]
    pw = [r.power for r in rows]
    lo = [r.power - r.ci_low for r in rows]
    hi = [r.ci_high - r.power for r in rows]
    fig, ax = plt.subplots(figsize=(6.4, 4.2), dpi=120)
    ax.axhline(0.8, color="0.6", lw=1, ls="--", label="power 0.8")
    ax.errorbar(n, pw, yerr=[lo, hi], fmt="o-", color="tab:orange", capsize=4,
                label="simulated power (95 % Clopper-Pearson CI)")
    ax.set_xlabel("participants")
    ax.set_ylabel("power")
    ax.set_ylim(-0.03, 1.03)
    ax.set_xticks(n)
    ax.set_title(title, fontsize=10)
    ax.legend(loc="lower right", fontsize=8)
    ax.grid(alpha=0.3)
    fig.text(0.01, 0.01, f"Model participants (simulated); alpha = {alpha:g}, "
             f"{rows[0].sims} simulated studies per size. Follows from the model's "
             "assumptions.", fontsize=6.5, color="0.35")
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    fig.savefig(path)
    plt.close(fig)


@dataclass(frozen=True)
class PowerStudyResult:
    """What :func:`run_power_study` computed and wrote."""

    rows: list[PowerRow]
    study_name: str
    plot: Path
    notes: list[str]
    #: the effect looked for, in words
    effect: str = "dynamic vs static between-tactor accuracy"
    #: what the rows' ``static_acc`` and ``dynamic_acc`` are: ``static``, ``dynamic``,
    #: or for a load effect ``loaded`` (under load) and ``no_load``
    pair: tuple[str, str] = ("static", "dynamic")
    #: the test each simulated study ran, in words
    test: str = ("paired Wilcoxon signed-rank on per-participant between-tactor accuracy "
                 "(the model-participant simulation's test, not the report's GLMM)")


def _write_power(rows: Sequence[PowerRow], out: Path, doc: dict[str, Any],
                 pair: tuple[str, str] = ("static", "dynamic")) -> None:
    """power.csv and power.json (``pair``: what the rows' two accuracies are)."""
    header = ["participants", "sims", "found", "power", "ci_low", "ci_high",
              f"mean_{pair[0]}_between_acc", f"mean_{pair[1]}_between_acc", "median_p"]
    lines = [",".join(header)]
    for r in rows:
        lines.append(",".join([str(r.n_participants), str(r.sims), str(r.found),
                               f"{r.power:.4f}", f"{r.ci_low:.4f}", f"{r.ci_high:.4f}",
                               f"{r.static_acc:.4f}", f"{r.dynamic_acc:.4f}",
                               "" if not _finite(r.median_p) else f"{r.median_p:.6g}"]))
    (out / "power.csv").write_text("\n".join(lines) + "\n", encoding="utf-8")
    doc = {**doc, "rows": [{_row_key(k, pair): (None if isinstance(v, float)
                                                and not math.isfinite(v) else v)
                            for k, v in r.__dict__.items()} for r in rows]}
    (out / "power.json").write_text(json.dumps(doc, indent=2) + "\n", encoding="utf-8")


#: what a model-based power analysis tests, in words (power.json, the CLI and the plot).
NAMED_TEST = ("the report's headline test: the binomial GLMM of accuracy (correct ~ "
              "condition * on_tactor + (1 + condition | participant) + (1 | target), "
              "simplified while singular by the report's rule; Laplace maximum likelihood) "
              "against the same model without the condition terms: the likelihood ratio "
              "referred to F(k, participants - 1); found = p < alpha with the named sign")


def _named_power(study: Study, eff: Effect, named: NamedEffect, sizes: Sequence[int],
                 sims: int, seed: int, out: Path, jobs: int, alpha: float,
                 advance: Callable[[int], None] | None) -> PowerStudyResult:
    """Model-based power: trials drawn from the report's GLMM with the named effect sizes."""
    from ..analysis.power_model import TrialDesign

    if eff.kind != "condition":
        raise ConfigError("--odds-ratio plans for the condition effect (dynamic vs static); "
                          f"'{eff.text}' cannot be named by that odds ratio (use --effect "
                          "'dynamic vs static at N', or leave out --odds-ratio to simulate "
                          "model participants)")
    if min(sizes) < 3:
        raise ConfigError("the report's mixed model needs at least 3 participants: use "
                          "study sizes of 3 or more with --odds-ratio")
    from ..analysis.power_model import named_power

    design = TrialDesign.from_study(study, eff.n_targets)
    rows = named_power(design, named, sizes, sims, seed, jobs, alpha, advance)
    what = (f"odds ratio {named.odds_ratio:g} (dynamic over static, {design.n_targets} "
            "targets)")
    _write_power(rows, out, {
        "note": NAMED_NOTE, "study": study.name, "test": NAMED_TEST,
        "simulated_from": "the same GLMM, with the named effect sizes "
                          "(tactorbelt.analysis.power_model)",
        "effect": what, "effect_sizes": named.to_dict(), "n_targets": design.n_targets,
        "trials_per_participant": design.n, "alpha": alpha, "sims": sims, "seed": seed,
    })
    plot = out / "power.png"
    _plot_power(rows, plot, f"{study.name}: {what}", alpha)
    return PowerStudyResult(rows, study.name, plot, [NAMED_NOTE], what, test=NAMED_TEST)


def _finite(v: float) -> bool:
    return math.isfinite(v)


def run_power_study(study: Study, sizes: Sequence[int], sims: int, seed: int, out: Path,
                    *, jobs: int | None = None, alpha: float = 0.05,
                    advance: Callable[[int], None] | None = None,
                    study_label: str | None = None,
                    effect: str | None = None,
                    named: NamedEffect | None = None) -> PowerStudyResult:
    """Simulate ``sims`` studies per size, write power.csv, power.json and power.png.

    Args:
        jobs: worker processes (default: the number of CPUs, at most 8).
        advance: called with the number of simulated studies just finished.
        study_label: how to name the study in errors (its file).
        effect: the effect to detect in a factorial study (``dynamic vs static``,
            ``dynamic vs static at N``, ``interaction``, ``load``, ``load NAME``; see
            :func:`tactorbelt.participant.factorial.parse_effect`). None: dynamic vs
            static between-tactor accuracy over every test block (the paper's test).

    Raises:
        ConfigError: the study lacks a static or a dynamic test block (a load effect:
            blocks with and without a load); an unknown effect; ``out`` unusable.
    """
    from ..inputs.model import sim_vibrator
    from ..participant.factorial import (
        FactorialProtocol,
        factorial_cues,
        parse_effect,
    )
    from ..participant.params import ModelParams
    from ..participant.simulate import Protocol, stimulus_cues

    counts = study.target_counts()
    conds = tuple(dict.fromkeys(b.condition for b in study.test))
    eff = parse_effect(effect, counts, tuple(dict.fromkeys(b.load for b in study.test)))
    if eff.kind != "load" and ("static" not in conds or "dynamic" not in conds):
        raise ConfigError(f"{study_label or 'the study'} needs a static and a dynamic test "
                          f"block for the static-vs-dynamic test; it has {', '.join(conds)}")
    # the two accuracies of each row: static/dynamic, or under load/without (load effect)
    pair = ("loaded", "no_load") if eff.kind == "load" else ("static", "dynamic")
    n_jobs = jobs if jobs is not None else max(1, min(8, os.cpu_count() or 1))
    out = prepare_out(out)
    if named is not None:
        return _named_power(study, eff, named, sizes, sims, seed, out, n_jobs, alpha, advance)
    loaded = any(b.load != "none" for b in study.test)
    if effect is None and len(counts) == 1 and not loaded:  # the paper's protocol
        protocol = Protocol.from_study(study)
        base = ModelParams().for_period(protocol.period_s)
        cues = stimulus_cues(protocol, sim_vibrator(protocol.layout), base)
        rows = run_power(protocol, cues, sizes, sims, seed, n_jobs, alpha, advance=advance)
    else:
        fp = FactorialProtocol.from_study(study)
        base = ModelParams().for_period(fp.period_s)
        fcues = factorial_cues(fp, sim_vibrator(study.layout_obj()), base)
        rows = run_factorial_power(fp, fcues, eff, sizes, sims, seed, n_jobs, alpha,
                                   advance=advance)

    doc: dict[str, Any] = {
        "note": MODEL_NOTE,
        "study": study.name,
        "test": "Wilcoxon signed-rank (two-sided) on per-participant between-tactor "
                "accuracy, dynamic vs static (tactorbelt.analysis.stats.wilcoxon_paired); "
                "found = p < alpha and mean dynamic > mean static",
        **({} if effect is None and len(counts) == 1 and not loaded else
           {"effect": eff.text, "test": eff.describe(), "target_counts": counts,
            **({"loads": "blocks under a load are simulated with the model localising "
                         "under that load (tactorbelt.participant.load; assumptions)"}
               if loaded else {})}),
        "alpha": alpha, "sims": sims, "seed": seed,
        "model": base.to_dict(),
    }
    _write_power(rows, out, doc, pair)
    plot = out / "power.png"
    what = ("static vs dynamic between-tactor accuracy" if effect is None
            else f"effect: {eff.text}")
    _plot_power(rows, plot, f"{study.name}: {what}", alpha)
    notes = [MODEL_NOTE, "each simulated study ran the paired Wilcoxon test; the report's "
                         "headline test is the accuracy GLMM: plan for it with --odds-ratio"]
    if any(r.n_participants <= 5 for r in rows):
        notes.append(SMALL_STUDY_NOTE)
    if loaded:
        notes.append("blocks under a load are simulated with the model localising worse "
                     "under that load (a documented assumption, docs/participant-model.md)")
    return PowerStudyResult(rows, study.name, plot, notes,
                            what if effect is not None else eff.describe(), pair)


def _row_key(key: str, pair: tuple[str, str]) -> str:
    """power.json's name of a PowerRow field (``static_acc`` is ``loaded_acc`` for a
    load effect)."""
    return {"static_acc": f"{pair[0]}_acc", "dynamic_acc": f"{pair[1]}_acc"}.get(key, key)
