"""The Summary of static versus dynamic between-tactor rendering: every table and test.

:func:`summarize` computes, from loaded stores, the tables (the ``tables`` room:
:mod:`.tables.tables`, :mod:`.tables.cells`),
the classical tests (docs/analysis.md), each with an effect size and a 95 % bootstrap CI
(BCa by ``scipy.stats.bootstrap``, seeded :class:`numpy.random.Generator`, vectorised):

- One participant: Fisher's exact test (two-sided) of between-tactor accuracy, effect
  size risk difference (dynamic - static; odds ratio alongside), CI of the accuracy
  difference; Mann-Whitney U (two-sided) of between-tactor RT, effect size
  rank-biserial correlation, CI of the difference of median RTs.
- Several participants: Wilcoxon signed-rank tests (two-sided) on per-participant
  between-tactor accuracy and median RT, effect size matched-pairs rank-biserial
  correlation, CI of the mean paired difference.
- From 3 participants: the accuracy GLMM and the log-RT mixed model of the ``models``
  room (:mod:`.models.fit`), timeouts counted per cell.

It also holds the counting rules, where response times count from
(:func:`rt_from_choice`) and the study design the sessions ran. A test that cannot be
computed carries ``computed=False`` and a ``reason`` in words.

The analysis layer between the ``report`` room (above) and the ``models`` and ``tables``
rooms (below); it re-exports nothing: import a name from the room that owns it.

Pure: imports NumPy, pandas, SciPy and the pure analysis modules; never an I/O layer,
except that ``engine="lme4"`` runs R through :mod:`.models.lme4` (temporary files and a
subprocess). Randomness comes from the ``seed`` argument only.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Final

import numpy as np
import pandas as pd

from .._errors import ConfigError
from .models.fit import mixed_model, rt_model
from .models.lrt import DEFAULT_PB_SIMS
from .tables._json import finite_float as _num
from .tables._json import finite_json as _finite_json
from .tables.cells import cell_summary, cells_to_json, participant_cells
from .tables.classical import (
    DEFAULT_N_BOOT,
    TestResult,
    _not_computed,
    fisher_accuracy,
    mann_whitney_rt,
    wilcoxon_paired,
)
from .tables.dataset import StoreData
from .tables.design import StudyDesign, parse_design
from .tables.tables import (
    CONDITIONS,
    KINDS,
    condition_summary,
    confusion_matrices,
    direction_summary,
    per_participant,
    per_target,
    prepare_trials,
    training_summary,
)
from .tables.tasks import secondary_tasks_json, tlx_rows, tlx_summary

__all__ = ["COUNTING_RULES", "RT_FROM", "Summary", "rt_from_choice", "summarize"]

COMPLETE_STATUSES: Final = frozenset({"complete", "completed", "done", "finished"})
#: Where a response time is counted from (``tactorbelt analyze --rt-from``).
RT_FROM: Final = ("skin", "command")


# -- the whole summary -----------------------------------------------------------------

@dataclass
class Summary:
    """Everything the report shows, as plain values and DataFrames.

    Attributes:
        counts: participants, sessions, trials, and how many were counted/left out.
        conditions: :func:`~tactorbelt.analysis.tables.tables.condition_summary`.
        per_target: the ``per_target.csv`` table.
        per_participant: per participant, condition and kind.
        directions: per condition and target, pooled (for the figures).
        confusion: per condition, target by response counts.
        training: training-block accuracy per condition.
        tests: every test, computed or not (with the reason).
        between_accuracy_test: the primary test (Fisher with one participant,
            Wilcoxon with several).
        design: layout, targets and law used for the amplitude figure.
        sessions: the sessions table (provenance).
        incomplete_sessions, timeouts, aborted: rows the report names.
        simulated_sessions: keys of sessions whose answers come from a model participant
            (or a scripted cursor), not from a person.
        simulated_belt_sessions: keys of sessions played on the simulated belt (no motor
            vibrated, whoever answered).
        notes: what was noticed, assumed or could not be computed, in words.
        trials: the prepared trials table (derived columns added).
        seed, n_boot: bootstrap settings.
    """

    counts: dict[str, int]
    conditions: pd.DataFrame
    per_target: pd.DataFrame
    per_participant: pd.DataFrame
    directions: pd.DataFrame
    confusion: dict[str, pd.DataFrame]
    training: pd.DataFrame
    tests: list[TestResult]
    between_accuracy_test: TestResult
    design: StudyDesign
    sessions: pd.DataFrame
    incomplete_sessions: pd.DataFrame
    timeouts: pd.DataFrame
    aborted: pd.DataFrame
    simulated_sessions: list[str]
    simulated_belt_sessions: list[str]
    notes: list[str]
    trials: pd.DataFrame
    paths: list[str]
    seed: int = 0
    n_boot: int = DEFAULT_N_BOOT
    #: the ``rt_mixed_model`` object of summary.json (None without counted trials).
    rt_model: dict[str, Any] | None = None
    #: per (condition, n_targets, load): :func:`~tactorbelt.analysis.tables.cells.cell_summary`
    cells: pd.DataFrame | None = None
    #: per (participant, condition, n_targets, load): ``participant_cells``
    participant_cells: pd.DataFrame | None = None
    #: ``summary.json["secondary_tasks"]`` (:func:`.tasks.secondary_tasks_json`), None
    #: without task events
    secondary_tasks: dict[str, Any] | None = None
    #: ``summary.json["tlx"]`` (:func:`.tasks.tlx_summary`), None without ratings
    tlx: dict[str, Any] | None = None
    #: where the response times count from (:func:`rt_from_choice`): ``skin`` or
    #: ``command``, and why
    rt_from: str = "command"
    rt_from_reason: str = ""

    @property
    def mixed_model(self) -> dict[str, Any] | None:
        """The ``mixed_model`` object of summary.json, when the GLMM was fitted."""
        t = self.test("mixed_model")
        return t.details.get("model") if t is not None and t.computed else None

    @property
    def contrasts(self) -> list[dict[str, Any]]:
        """``summary.json["contrasts"]``: dynamic - static per target count at
        between-tactor targets, Holm-adjusted (empty without the accuracy model)."""
        t = self.test("mixed_model")
        return list(t.details.get("contrasts", [])) if t is not None and t.computed else []

    @property
    def simulated(self) -> bool:
        """True when every session's data come from a simulated model participant."""
        return bool(self.simulated_sessions) and len(self.simulated_sessions) == len(self.sessions)

    def test(self, key: str) -> TestResult | None:
        """The test with this key, if it was run or considered."""
        return next((t for t in self.tests if t.key == key), None)

    def condition_row(self, condition: str, kind: str) -> pd.Series:
        """The row of :attr:`conditions` of this condition and kind (it has every one)."""
        c = self.conditions
        return c.loc[(c["condition"] == condition) & (c["kind"] == kind)].iloc[0]

    def condition_value(self, condition: str, kind: str, column: str) -> float | None:
        """One value of :attr:`conditions` (None when not finite)."""
        return _num(self.condition_row(condition, kind)[column])

    def provenance(self) -> dict[str, Any]:
        """Study names and hashes, package and firmware versions, belts, seeds."""
        s = self.sessions

        def uniq(col: str) -> list[Any]:
            vals = s[col].dropna().unique().tolist() if col in s else []
            return sorted((v.item() if hasattr(v, "item") else v) for v in vals)

        studies = (s[["study_name", "study_sha256"]].drop_duplicates().fillna("")
                   .astype(str).to_dict("records"))
        return {
            "stores": self.paths,
            "studies": studies,
            "package_versions": uniq("package_version"),
            "belts": uniq("belt"),
            "firmware_versions": uniq("firmware_version"),
            "inputs": uniq("input"),
            "session_seeds": [int(v) for v in
                              pd.to_numeric(s["seed"], errors="coerce").dropna().unique()],
            "analysis_seed": self.seed,
            "bootstrap_resamples": self.n_boot,
        }

    def to_json(self) -> dict[str, Any]:
        """The ``summary.json`` content (every number finite or null: a non-finite one
        becomes null here, whichever table it came from)."""
        conditions: dict[str, Any] = {}
        for cond in CONDITIONS:
            entry: dict[str, Any] = {}
            for kind in KINDS:
                r = self.condition_row(cond, kind)
                entry[kind] = {
                    **{k: int(r[k]) for k in ("n", "n_participants", "n_correct", "n_timeout")},
                    **{k: _num(r[k]) for k in ("accuracy", "median_rt_s", "circ_mean_error_deg",
                                               "circ_sd_error_deg")}}
                if int(r["n"]) == 0:
                    entry[kind]["note"] = "no counted test trials"
                elif int(r["n_rt"]) == 0:
                    entry[kind]["note"] = ("every counted trial timed out: no response time "
                                           "and no error")
            conditions[cond] = entry
        return _finite_json({
            "tactorbelt_analysis": 1,
            "rt_from": self.rt_from,
            "rt_from_reason": self.rt_from_reason,
            "simulated_model_data": self.simulated,
            "simulated_sessions": len(self.simulated_sessions),
            "simulated_belt_sessions": len(self.simulated_belt_sessions),
            "counts": dict(self.counts),
            "conditions": conditions,
            "cells": cells_to_json(self.cells),
            "between_accuracy_test": self.between_accuracy_test.to_dict(),
            "tests": [t.to_dict() for t in self.tests],
            "mixed_model": self.mixed_model,
            "contrasts": self.contrasts,
            "rt_mixed_model": self.rt_model,
            "secondary_tasks": self.secondary_tasks,
            "tlx": self.tlx,
            "counting": COUNTING_RULES,
            "study": {
                "layout_deg": self.design.layout.to_list(),
                "targets_deg": list(self.design.targets.angles_deg),
                "law": self.design.law, "falloff_deg": self.design.falloff_deg,
                "fallbacks": list(self.design.fallbacks),
            },
            "provenance": self.provenance(),
            "notes": list(self.notes),
        })


COUNTING_RULES: Final = (
    "Only test-block trials count. Trials with status 'done' count; 'timeout' trials count "
    "as incorrect, with no response time and no response direction; 'aborted' trials are "
    "left out. Training trials are summarised separately."
)


def _is_model(sessions: pd.DataFrame) -> pd.Series:
    """Sessions answered by the model participant or a scripted cursor, not a person:
    the stored input; a store without it (older versions) by a ``model...`` participant."""
    inp = sessions["input"].astype("string").str.lower()
    by_name = sessions["participant"].astype(str).str.lower().str.startswith("model")
    return inp.isin(["model", "scripted"]).fillna(False) | (inp.isna() & by_name)


def _on_simulated_belt(sessions: pd.DataFrame) -> pd.Series:
    """Sessions played on the simulated belt (``sim`` URLs): no motor vibrated."""
    scheme = sessions["belt"].astype("string").str.lower().fillna("").str.split(
        r"[:?]", regex=True).str[0]
    return scheme.str.strip().eq("sim")


def _design_for(sessions: pd.DataFrame, notes: list[str]) -> StudyDesign:
    """Parse the study of most sessions; say when studies differ or defaults were used."""
    texts = sessions["study_toml"].fillna("").astype(str)
    counts = texts.value_counts()
    text = str(counts.index[0]) if len(counts) else ""
    design = parse_design(text or None)
    if len(counts) > 1:
        parsed = {(d.layout.angles_deg, d.targets.angles_deg, d.law, d.falloff_deg)
                  for d in (parse_design(t or None) for t in counts.index)}
        if len(parsed) > 1:
            notes.append(
                f"the sessions ran {len(parsed)} different study designs; the amplitude figure "
                f"shows the one used by most sessions ({int(counts.iloc[0])} of {len(texts)})"
            )
    if design.fallbacks:
        notes.append(
            "study design: " + "; ".join(design.fallbacks) + " - fell back to the paper's "
            "defaults where needed (6 even tactors, 24 targets, paper law T = 15)"
        )
    return design


def rt_from_choice(trials: pd.DataFrame, rt_from: str | None = None
                   ) -> tuple[pd.DataFrame, str, str]:
    """Where the response times count from: ``(trials, used, reason)``.

    The analysed trials are those with a response time (done). ``skin``: each RT less
    the trial's ``skin_offset_s`` (``(skin_onset_ns - onset_ns) / 1e9``, the measured
    latency of the tactors that start the stimulus), so it counts from when the skin
    felt the stimulus; ``trials`` then keeps the stored RT as ``rt_command_s``.
    ``command``: the stored RTs, from the stored onset. ``rt_from`` None chooses
    ``skin`` when every analysed trial has a skin onset, else ``command``.

    Raises:
        ConfigError: ``skin`` asked for while some analysed trial has no skin onset, or
            an unknown ``rt_from``.
    """
    if rt_from is not None and rt_from not in RT_FROM:
        raise ConfigError(f"--rt-from must be one of {', '.join(RT_FROM)}, got {rt_from!r}")
    rt = pd.to_numeric(trials["rt_s"], errors="coerce").to_numpy(dtype=float)
    status = trials["status"].astype("string").fillna("")
    analysed = (status == "done").to_numpy(dtype=bool) & ~np.isnan(rt)
    offset = (pd.to_numeric(trials["skin_offset_s"], errors="coerce").to_numpy(dtype=float)
              if "skin_offset_s" in trials.columns else np.full(len(trials), np.nan))
    n = int(analysed.sum())
    lacking = int((analysed & np.isnan(offset)).sum())
    how = ("the skin onset is the stored onset plus the measured latency of the tactors "
           "that start the stimulus (the belt's calibration, 'tactorbelt validate onsets')")
    if rt_from == "skin" and lacking:
        raise ConfigError(
            f"--rt-from skin: {lacking} of the {n} analysed trials have no skin onset (their "
            "belt's calibration had no measured latency when they ran: measure it with "
            "'tactorbelt validate onsets --calibration FILE'); use --rt-from command")
    if rt_from == "command":
        used, reason = "command", "asked for (--rt-from command): RTs from the stored onset"
    elif rt_from == "skin":
        used, reason = "skin", f"asked for (--rt-from skin); {how}"
    elif n and not lacking:
        used, reason = "skin", f"every analysed trial ({n}) has a skin onset; {how}"
    elif not n:
        used, reason = "command", "no trial has a response time"
    elif lacking == n:
        used, reason = "command", ("no analysed trial has a skin onset (no measured "
                                   "latency in the belt's calibration): RTs from the "
                                   "stored onset")
    else:
        used, reason = "command", (f"{lacking} of the {n} analysed trials have no skin "
                                   "onset (no measured latency): RTs from the stored "
                                   "onset for all")
    if used == "skin":
        trials = trials.copy()
        trials["rt_command_s"] = rt
        trials["rt_s"] = np.where(analysed, rt - offset, rt)
    return trials, used, reason


def summarize(data: StoreData, *, seed: int = 0, n_boot: int = DEFAULT_N_BOOT,
              engine: str = "tactorbelt", pb_sims: int | None = DEFAULT_PB_SIMS,
              progress: Any = None, rt_from: str | None = None,
              fixef_prior: Any = None) -> Summary:
    """Compute every table and test from loaded stores. Pure: no files, no clock.

    Args:
        data: what :func:`tactorbelt.analysis.tables.load.load_stores` returned.
        seed: seeds the bootstrap (a :class:`numpy.random.Generator`).
        n_boot: bootstrap resamples per interval.
        engine: who fits the mixed models: ``tactorbelt`` (:mod:`.glmm`) or ``lme4``
            (R through Rscript; raises :class:`~tactorbelt.analysis.models.lme4.Lme4Unavailable`
            without it).
        pb_sims: simulations of the accuracy model's parametric bootstrap (computed up to
            :data:`PB_MAX_PARTICIPANTS` participants; 0: never), seeded by
            ``seed``.
        progress: ``progress(done, total)`` as the bootstrap refits.
        rt_from: ``skin``, ``command`` or None (the default: skin where every analysed
            trial has a skin onset), see :func:`rt_from_choice`.
        fixef_prior: fit the accuracy model with this prior on its fixed effects
            (:class:`~tactorbelt.analysis.models.glmm.FixefPrior`, as ``blme::bglmer``).
    """
    rng = np.random.default_rng(seed)
    notes = list(data.notes)
    sessions = data.sessions.copy()
    sessions["simulated"] = _is_model(sessions).to_numpy(dtype=bool)
    sessions["simulated_belt"] = _on_simulated_belt(sessions).to_numpy(dtype=bool)
    design = _design_for(sessions, notes)
    trials, rt_used, rt_reason = rt_from_choice(data.trials, rt_from)
    tr = prepare_trials(trials)

    unknown_cond = tr["block"].eq("test") & ~tr["condition"].isin(CONDITIONS)
    if unknown_cond.any():
        vals = sorted(tr.loc[unknown_cond, "condition"].fillna("<null>").unique().tolist())
        notes.append(f"{int(unknown_cond.sum())} test trial(s) with condition "
                     f"{', '.join(vals)} were left out (allowed: static, dynamic)")
    status = tr["status"]
    test, in_training = tr["block"] == "test", tr["block"] == "training"
    counted = tr.loc[tr["counted"]]
    status_s = sessions["status"].astype("string").str.lower().fillna("")
    incomplete = sessions.loc[~status_s.isin(COMPLETE_STATUSES) | sessions["ended_at"].isna(),
                              ["session_key", "participant", "status", "started_at",
                               "ended_at"]]
    trial_cols = ["session_key", "participant", "block", "condition", "trial_index",
                  "target_deg"]
    timeouts = tr.loc[status == "timeout", trial_cols].reset_index(drop=True)
    aborted = tr.loc[status == "aborted", trial_cols].reset_index(drop=True)
    counts = {
        "stores": len(data.paths),
        "participants": int(sessions["participant"].nunique()),
        "participants_with_test_trials": int(counted["participant"].nunique()),
        "sessions": len(sessions),
        "sessions_incomplete": len(incomplete),
        "trials": len(tr),
        "test_trials": int(test.sum()),
        "counted_trials": len(counted),
        **{s: int((test & (status == s)).sum()) for s in ("done", "timeout", "aborted")},
        "training_trials": int(in_training.sum()),
        **{f"training_{s}": int((in_training & (status == s)).sum())
           for s in ("timeout", "aborted")},
    }

    cond_table = condition_summary(tr)
    pt = per_target(tr)
    pp = per_participant(tr)
    directions = direction_summary(tr)
    confusion = confusion_matrices(tr, design.targets.angles)
    training = training_summary(tr)

    tests: list[TestResult] = []
    n_part = counts["participants_with_test_trials"]
    between = counted.loc[counted["kind"] == "between_tactor"]
    if len(counted) == 0 or between.empty:
        # the tests one participant (Fisher, Mann-Whitney) or several (Wilcoxon) would get
        names = ([("Fisher's exact test", "between-tactor accuracy"),
                  ("Mann-Whitney U test", "between-tactor response time")] if n_part <= 1 else
                 [("Wilcoxon signed-rank test", "per-participant between-tactor accuracy"),
                  ("Wilcoxon signed-rank test", "per-participant between-tactor median RT")])
        reason = ("no between-tactor test trials (every target is on a tactor)" if len(counted)
                  else "no test-block trial was done or timed out" if len(tr)
                  else "the stores hold no trials")
        tests += [_not_computed(key, test_name, f"{question}, dynamic vs static", reason)
                  for key, (test_name, question) in zip(("between_accuracy", "between_rt"),
                                                        names, strict=True)]
        if len(counted) == 0:
            notes.append(f"no statistics: {reason}")
    elif n_part == 1:
        by = {c: between.loc[between["condition"] == c] for c in CONDITIONS}
        tests.append(fisher_accuracy(
            int(by["static"]["is_correct"].sum()), len(by["static"]),
            int(by["dynamic"]["is_correct"].sum()), len(by["dynamic"]), rng, n_boot))
        tests.append(mann_whitney_rt(by["static"]["rt"].to_numpy(),
                                     by["dynamic"]["rt"].to_numpy(), rng, n_boot))
    else:
        b = pp.loc[pp["kind"] == "between_tactor"].pivot(
            index="participant", columns="condition", values=["accuracy", "median_rt_s"])
        acc_s, acc_d = b[("accuracy", "static")], b[("accuracy", "dynamic")]
        lacking = b.index[acc_s.isna() | acc_d.isna()].tolist()
        if lacking:
            notes.append(
                f"{len(lacking)} participant(s) lack between-tactor trials in a condition "
                "and are left out of the paired tests: " + ", ".join(map(str, lacking[:20]))
                + (" ..." if len(lacking) > 20 else ""))
        tests.append(wilcoxon_paired(acc_s.to_numpy(), acc_d.to_numpy(), rng, n_boot,
                                     key="between_accuracy", what="accuracy"))
        tests.append(wilcoxon_paired(
            b[("median_rt_s", "static")].to_numpy(), b[("median_rt_s", "dynamic")].to_numpy(),
            rng, n_boot, key="between_rt", what="median RT", unit=", s"))
    rt_json: dict[str, Any] | None = None
    if len(counted):
        tests.append(mixed_model(tr, engine=engine, pb_sims=pb_sims, seed=seed,
                                 progress=progress, fixef_prior=fixef_prior))
        rt_json = rt_model(tr, engine=engine)
        if rt_json.get("timeout_note"):
            notes.append("RT model: " + rt_json["timeout_note"])
    primary = next(t for t in tests if t.key == "between_accuracy")
    for t in tests:
        if not t.computed:
            notes.append(f"not computed: {t.test} ({t.question}): {t.reason}")
    for cond in CONDITIONS:
        if not (counted["condition"] == cond).any() and len(counted):
            notes.append(f"no {cond} test trials: its accuracy and RT are not reported")

    secondary = secondary_tasks_json(data.task_events)
    tlx = tlx_summary(tlx_rows(data.ratings)) if data.ratings else None
    if tlx is not None and tlx["test"] is not None and not tlx["test"]["computed"]:
        notes.append(f"not computed: the NASA-TLX test across load: {tlx['test']['reason']}")
    return Summary(
        counts=counts, conditions=cond_table, per_target=pt, per_participant=pp,
        directions=directions, confusion=confusion, training=training, tests=tests,
        between_accuracy_test=primary, design=design, sessions=sessions,
        incomplete_sessions=incomplete.reset_index(drop=True), timeouts=timeouts,
        aborted=aborted,
        simulated_sessions=sessions.loc[sessions["simulated"], "session_key"].tolist(),
        simulated_belt_sessions=sessions.loc[sessions["simulated_belt"],
                                             "session_key"].tolist(),
        notes=notes, trials=tr, paths=[str(p) for p in data.paths], seed=seed, n_boot=n_boot,
        rt_model=rt_json,
        cells=cell_summary(tr, seed=seed), participant_cells=participant_cells(tr),
        secondary_tasks=secondary, tlx=tlx, rt_from=rt_used, rt_from_reason=rt_reason,
    )
