"""Power of the report's headline test for effect sizes the user names.

``tactorbelt power --odds-ratio OR`` answers "how many participants does my study need
for the report's accuracy model to find an odds ratio of OR?". Each simulated study
draws its trials from that model, the binomial GLMM of
:func:`tactorbelt.analysis.stats.mixed_model`::

    logit P(correct) = b0 + b_cond [dynamic, between-tactor] + b_on [on a tactor]
                       + u_participant + v_participant [dynamic] + w_target

with the effect sizes the user names: the static between-tactor accuracy
(``accuracy``), the dynamic-over-static odds ratio at between-tactor targets
(``odds_ratio``; on-tactor targets are static in both conditions, so the condition has
no effect there), the on-tactor accuracy, and the SDs of the participant intercept,
the participant's condition slope and the target intercept (log-odds). The trials are
the study's test trials (its blocks, target counts and repetitions). Each simulated
study is then analysed by the very functions the report uses
(:func:`tactorbelt.analysis.stats.fit_model`: the same formula, the same singular-fit
simplification rule, the same Laplace fit; and the same model without the condition
terms) with the report's headline test (:func:`tactorbelt.analysis.stats.headline_method`):
the likelihood ratio of every condition term against none, referred to
``F(k, participants - 1)`` (:func:`tactorbelt.analysis.lrt.f_reference`), the test of
those the report computes that holds its level with 4 to 16 participants
(docs/analysis.md, "Tests of the condition").

A study finds the effect when that p is below alpha and the report's effect (static
minus dynamic log-odds at between-tactor targets) has the named sign. This is
simulation-based power for a GLMM (Green & MacLeod 2016, simr).

Each simulated study draws from its own generator, seeded by ``(seed, N, index)``, so
results do not depend on how the work is split across processes.

Pure apart from NumPy, pandas and the analysis (no I/O).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from .._errors import ConfigError

if TYPE_CHECKING:
    import pandas as pd

    from ..participant.power import StudyOutcome

__all__ = ["HeadlineResult", "NamedEffect", "TrialDesign", "headline_coefficient",
           "headline_statistics", "named_power", "simulate_frame", "simulate_glmm_studies"]

#: the coefficient the report's headline test is about (static minus dynamic, log-odds,
#: at between-tactor targets).
HEADLINE = "conditionstatic"


def _logit(p: float) -> float:
    return math.log(p / (1.0 - p))


@dataclass(frozen=True)
class NamedEffect:
    """The effect sizes a model-based power analysis simulates.

    Attributes:
        odds_ratio: odds of a correct answer, dynamic over static, at between-tactor
            targets (above 1: dynamic better).
        accuracy: static between-tactor accuracy (the typical participant and target).
        on_tactor_accuracy: accuracy at on-tactor targets (both conditions).
        participant_sd: SD of the per-participant intercept (log-odds).
        slope_sd: SD of the per-participant condition slope (log-odds).
        target_sd: SD of the per-target intercept (log-odds).
    """

    odds_ratio: float
    accuracy: float = 0.5
    on_tactor_accuracy: float = 0.9
    participant_sd: float = 0.5
    slope_sd: float = 0.3
    target_sd: float = 0.3

    def __post_init__(self) -> None:
        if not (math.isfinite(self.odds_ratio) and 0 < self.odds_ratio <= 1000):
            raise ConfigError(f"the odds ratio must be a number above 0 (at most 1000), got "
                              f"{self.odds_ratio!r}")
        if self.odds_ratio == 1:
            raise ConfigError("an odds ratio of 1 is no effect: name the smallest effect "
                              "worth finding, e.g. --odds-ratio 1.5")
        for name in ("accuracy", "on_tactor_accuracy"):
            v = getattr(self, name)
            if not (math.isfinite(v) and 0 < v < 1):
                raise ConfigError(f"{name.replace('_', ' ')} must be a proportion between 0 "
                                  f"and 1 (exclusive), got {v!r}")
        for name in ("participant_sd", "slope_sd", "target_sd"):
            v = getattr(self, name)
            if not (math.isfinite(v) and 0 <= v <= 5):
                raise ConfigError(f"{name.replace('_', ' ')} must be between 0 and 5 "
                                  f"(log-odds), got {v!r}")

    @classmethod
    def no_effect(cls, **sizes: float) -> NamedEffect:
        """The same model with no condition effect (odds ratio 1): the null, for
        false-positive rates (scripts/false_positive_rates.py)."""
        eff = cls(2.0, **sizes)
        object.__setattr__(eff, "odds_ratio", 1.0)
        return eff

    @property
    def headline(self) -> float:
        """The true ``conditionstatic`` coefficient: ``-log(odds_ratio)``."""
        return -math.log(self.odds_ratio)

    def dynamic_accuracy(self) -> float:
        """Dynamic between-tactor accuracy of the typical participant and target."""
        eta = _logit(self.accuracy) + math.log(self.odds_ratio)
        return 1.0 / (1.0 + math.exp(-eta))

    def to_dict(self) -> dict[str, float]:
        return {**asdict(self), "dynamic_accuracy": self.dynamic_accuracy(),
                "conditionstatic": self.headline}


@dataclass(frozen=True)
class TrialDesign:
    """One participant's counted test trials: condition, target and kind per trial."""

    condition: np.ndarray
    target_deg: np.ndarray
    on_tactor: np.ndarray
    n_targets: int
    #: the target count of each trial, when the design has several (the model then
    #: has ``factor(n_targets)``); None: one count, ``n_targets``
    counts: np.ndarray | None = None

    @classmethod
    def from_study(cls, study: Any, n_targets: int | None = None, *,
                   all_counts: bool = False) -> TrialDesign:
        """The test trials of a study (read by attribute), or of its ``n_targets`` blocks.

        Args:
            all_counts: every test block, whatever its target count (``n_targets`` is
                then the first count; ``counts`` holds each trial's).

        Raises:
            ConfigError: several target counts and none chosen; a count it lacks; no
                static or no dynamic block.
        """
        from ..geometry import TargetSet

        counts = list(study.target_counts())
        if all_counts and len(counts) > 1:
            parts = [cls.from_study(study, c) for c in counts]
            return cls(np.concatenate([p.condition for p in parts]),
                       np.concatenate([p.target_deg for p in parts]),
                       np.concatenate([p.on_tactor for p in parts]), int(counts[0]),
                       np.concatenate([np.full(p.n, p.n_targets) for p in parts]))
        if n_targets is None:
            if len(counts) != 1:
                raise ConfigError(
                    "the study has several target counts (" + ", ".join(map(str, counts))
                    + "): name the one to plan for with --effect 'dynamic vs static at N' "
                    "(the report's model has a condition effect per target count, "
                    "summary.json 'contrasts'; one odds ratio names one of them)")
            n_targets = counts[0]
        if n_targets not in counts:
            raise ConfigError(f"the study has no blocks of {n_targets} targets "
                              f"(it has {', '.join(map(str, counts))})")
        layout = study.layout_obj()
        targets = TargetSet.even(n_targets)
        on = targets.on_tactor(layout)
        cond: list[np.ndarray] = []
        deg: list[np.ndarray] = []
        kind: list[np.ndarray] = []
        for b in study.test:
            if study.block_n_targets(b) != n_targets:
                continue
            idx = np.tile(np.arange(targets.m), int(b.repetitions))
            cond.append(np.full(idx.size, b.condition))
            deg.append(targets.angles[idx])
            kind.append(on[idx])
        c = np.concatenate(cond)
        if not {"static", "dynamic"} <= set(c.tolist()):
            raise ConfigError("the model-based power analysis needs static and dynamic test "
                              f"blocks of {n_targets} targets")
        return cls(c, np.concatenate(deg), np.concatenate(kind), int(n_targets))

    @property
    def n(self) -> int:
        return int(self.condition.size)


def simulate_frame(design: TrialDesign, effect: NamedEffect, n_participants: int,
                   rng: np.random.Generator) -> pd.DataFrame:
    """One simulated study's counted trials in :func:`~tactorbelt.analysis.stats.model_frame`'s
    columns (every trial answered; ``rt_s`` is not simulated)."""
    import pandas as pd

    t_levels, t_index = np.unique(design.target_deg, return_inverse=True)
    w = rng.normal(0.0, effect.target_sd, t_levels.size)
    u = rng.normal(0.0, effect.participant_sd, n_participants)
    v = rng.normal(0.0, effect.slope_sd, n_participants)
    dyn = (design.condition == "dynamic").astype(float)
    on = design.on_tactor.astype(bool)
    fixed = np.where(on, _logit(effect.on_tactor_accuracy),
                     _logit(effect.accuracy) + dyn * math.log(effect.odds_ratio))
    eta = (fixed[None, :] + u[:, None] + v[:, None] * dyn[None, :]
           + w[t_index][None, :])
    correct = rng.random(eta.shape) < 1.0 / (1.0 + np.exp(-eta))
    n = design.n
    frame = pd.DataFrame({
        "correct": correct.ravel().astype(int),
        "condition": np.tile(design.condition, n_participants),
        "on_tactor": np.tile(on.astype(int), n_participants),
        "participant": np.repeat([f"p{j:03d}" for j in range(n_participants)], n),
        "target": np.tile([f"{d:g}" for d in design.target_deg], n_participants),
        "rt_s": np.nan,
        "status": "done",
    })
    if design.counts is not None:
        frame["n_targets"] = np.tile(design.counts, n_participants)
    return frame


@dataclass(frozen=True)
class HeadlineResult:
    """The report's headline test of the condition on one simulated study.

    Attributes:
        estimate: static minus dynamic log-odds at between-tactor targets (averaged
            over target counts), the report's effect; its sign is the direction.
        lrt: the likelihood ratio (every condition term against none); lrt_p its
            chi-square p.
        p: the headline p: ``lrt / df`` referred to ``F(df, participants - 1)``.
        wald_p: the Wald z p of ``conditionstatic`` (the old headline).
    """

    estimate: float
    lrt: float
    lrt_p: float
    p: float
    wald_p: float


_NAN_RESULT = HeadlineResult(math.nan, math.nan, math.nan, math.nan, math.nan)


def headline_statistics(frame: pd.DataFrame) -> HeadlineResult:
    """Fit the report's accuracy model (:func:`~tactorbelt.analysis.stats.fit_model`)
    and its null model on ``frame``: the effect and the likelihood ratio (NaN when it
    cannot be fitted)."""
    from .glmm import fit_glmm
    from .lrt import likelihood_ratio, null_spec
    from .stats import _average_contrast, fit_model

    y = frame["correct"].to_numpy()
    if y.min() == y.max():
        return _NAN_RESULT
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fit, _ = fit_model(frame)
            fit0 = fit_glmm(frame, null_spec(fit.spec), se=False)
            est, _ = _average_contrast(fit, frame)
    except (ValueError, np.linalg.LinAlgError, FloatingPointError):
        return _NAN_RESULT
    lr = likelihood_ratio(fit, fit0)
    fe = fit.fixed_effects.get(HEADLINE)
    f_p = float(lr.get("f_reference", {}).get("p", math.nan))
    return HeadlineResult(est, float(lr["statistic"]), float(lr["p"]), f_p,
                          fe.p if fe is not None else math.nan)


def headline_coefficient(frame: pd.DataFrame) -> tuple[float, float]:
    """``(estimate, p)`` of the report's ``conditionstatic`` coefficient on ``frame``, by
    :func:`~tactorbelt.analysis.stats.fit_model` (NaN, NaN when it cannot be fitted):
    the Wald z the report used to head with."""
    from .stats import fit_model

    y = frame["correct"].to_numpy()
    if y.min() == y.max():
        return math.nan, math.nan
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            fit, _ = fit_model(frame)
    except (ValueError, np.linalg.LinAlgError, FloatingPointError):
        return math.nan, math.nan
    fe = fit.fixed_effects.get(HEADLINE)
    if fe is None:
        return math.nan, math.nan
    return fe.estimate, fe.p


def _between(frame: pd.DataFrame, condition: str) -> np.ndarray:
    sel = frame.loc[(frame["condition"] == condition) & (frame["on_tactor"] == 0)]
    return sel.groupby("participant", sort=True)["correct"].mean().to_numpy(dtype=float)


def simulate_glmm_studies(design: TrialDesign, effect: NamedEffect, n_participants: int,
                          indices: Sequence[int], seed: int,
                          progress: Callable[[int], None] | None = None) -> list[StudyOutcome]:
    """Simulate and analyse the studies ``indices`` of size ``n_participants``.

    The outcome's p is the report's headline test (:func:`headline_statistics`: the
    likelihood ratio referred to ``F(k, participants - 1)``); it counts as found when
    the report's effect has the named sign (``static_acc``/``dynamic_acc`` are the
    simulated participants' between-tactor accuracies, for the table).
    """
    from ..participant.power import StudyOutcome

    if n_participants < 3:
        raise ConfigError("the report's mixed model needs at least 3 participants; "
                          f"got a study size of {n_participants}")
    sign = math.copysign(1.0, effect.headline)
    out: list[StudyOutcome] = []
    for i in indices:
        rng = np.random.default_rng([int(seed), int(n_participants), int(i)])
        frame = simulate_frame(design, effect, n_participants, rng)
        res = headline_statistics(frame)
        ok = math.isfinite(res.estimate) and math.copysign(1.0, res.estimate) == sign
        out.append(StudyOutcome(n_participants, _between(frame, "static"),
                                _between(frame, "dynamic"), res.p, direction_ok=ok))
        if progress is not None:
            progress(1)
    return out


def _chunk(args: tuple[TrialDesign, NamedEffect, int, list[int], int]) -> list[StudyOutcome]:
    design, effect, n, indices, seed = args
    return simulate_glmm_studies(design, effect, n, indices, seed)


def _run(worker: Callable[[Any], list[Any]], items: list[tuple[int, Any]], jobs: int,
         advance: Callable[[int], None] | None) -> dict[int, list[Any]]:
    out: dict[int, list[Any]] = {}
    if jobs <= 1:
        for n, item in items:
            done = worker(item)
            out.setdefault(n, []).extend(done)
            if advance is not None:
                advance(len(done))
        return out
    from concurrent.futures import ProcessPoolExecutor, as_completed

    with ProcessPoolExecutor(max_workers=jobs) as pool:
        futures = {pool.submit(worker, item): n for n, item in items}
        for fut in as_completed(futures):
            done = fut.result()
            out.setdefault(futures[fut], []).extend(done)
            if advance is not None:
                advance(len(done))
    return out


def _chunks(sims: int, jobs: int) -> list[list[int]]:
    chunk = max(1, min(25, math.ceil(sims / max(jobs, 1) / 4)))
    return [list(range(s, min(s + chunk, sims))) for s in range(0, sims, chunk)]


def named_power(design: TrialDesign, effect: NamedEffect, sizes: Sequence[int], sims: int,
                seed: int, jobs: int = 1, alpha: float = 0.05,
                advance: Callable[[int], None] | None = None) -> list[Any]:
    """Power of the report's headline test for the named effect, one row per size.

    Results do not depend on ``jobs``: each simulated study has its own seed.

    Returns:
        :class:`~tactorbelt.participant.power.PowerRow` per size.
    """
    from ..participant.power import power_row

    items = [(n, (design, effect, n, idx, seed)) for n in sizes for idx in _chunks(sims, jobs)]
    results = _run(_chunk, items, jobs, advance)
    return [power_row(results[n], alpha) for n in sizes]
