"""GLMM power for effect sizes the user names (``tactorbelt power --odds-ratio``).

It answers "how many participants does my study need for the report's accuracy model to
find an odds ratio of OR?". Each simulated study draws its trials from that model, the
binomial GLMM of :func:`tactorbelt.analysis.models.fit.mixed_model`::

    logit P(correct) = b0 + b_cond [dynamic, between-tactor] + b_on [on a tactor]
                       + u_participant + v_participant [dynamic] + w_target

with the effect sizes the user names (:class:`NamedEffect`): the static between-tactor
accuracy (``accuracy``), the dynamic-over-static odds ratio at between-tactor targets
(``odds_ratio``; on-tactor targets are static in both conditions, so the condition has
no effect there), the on-tactor accuracy, and the SDs of the participant intercept,
the participant's condition slope and the target intercept (log-odds). The trials are
the study's test trials (its blocks, target counts and repetitions:
:meth:`~tactorbelt.power.design.PowerDesign.trials`). Each simulated study is then
analysed by the very functions the report uses
(:func:`tactorbelt.analysis.models.fit.fit_model`: the same formula, the same singular-fit
simplification rule, the same Laplace fit; and the same model without the condition
terms) with the report's headline test (:data:`tactorbelt.analysis.models.fit.HEADLINE_TEST`):
the likelihood ratio of every condition term against none, referred to
``F(k, participants - 1)`` (:func:`tactorbelt.analysis.models.lrt.f_reference`), the test of
those the report computes that holds its level with 4 to 16 participants
(docs/analysis.md, "Tests of the condition").

A study finds the effect when that p is below alpha and the report's effect (static
minus dynamic log-odds at between-tactor targets) has the named sign. This is
simulation-based power for a GLMM (Green & MacLeod 2016, simr).

Each simulated study draws from its own generator, seeded by ``(seed, N, index)``, so
results do not depend on how the work is split across processes.

Pure apart from the process pool: NumPy, pandas and the analysis.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass

import numpy as np
import pandas as pd

from .._errors import ConfigError
from ..analysis.models.fit import _average_contrast, fit_model, model_spec
from ..analysis.models.glmm import fit_glmm
from ..analysis.models.lrt import likelihood_ratio, null_spec
from .design import TrialDesign
from .outcomes import PowerRow, StudyOutcome
from .pool import run_sizes, studies

__all__ = ["HeadlineResult", "NamedEffect", "TrialDesign", "headline_statistics",
           "maximal_formula", "named_power", "simulate_frame", "simulate_glmm_studies"]


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


def simulate_frame(trials: TrialDesign, effect: NamedEffect, n_participants: int,
                   rng: np.random.Generator) -> pd.DataFrame:
    """One simulated study's counted trials in :func:`~tactorbelt.analysis.models.fit.model_frame`'s
    columns (every trial answered; ``rt_s`` is not simulated)."""
    t_levels, t_index = np.unique(trials.target_deg, return_inverse=True)
    w = rng.normal(0.0, effect.target_sd, t_levels.size)
    u = rng.normal(0.0, effect.participant_sd, n_participants)
    v = rng.normal(0.0, effect.slope_sd, n_participants)
    dyn = (trials.condition == "dynamic").astype(float)
    on = trials.on_tactor.astype(bool)
    fixed = np.where(on, _logit(effect.on_tactor_accuracy),
                     _logit(effect.accuracy) + dyn * math.log(effect.odds_ratio))
    eta = (fixed[None, :] + u[:, None] + v[:, None] * dyn[None, :]
           + w[t_index][None, :])
    correct = rng.random(eta.shape) < 1.0 / (1.0 + np.exp(-eta))
    n = trials.n
    frame = pd.DataFrame({
        "correct": correct.ravel().astype(int),
        "condition": np.tile(trials.condition, n_participants),
        "on_tactor": np.tile(on.astype(int), n_participants),
        "participant": np.repeat([f"p{j:03d}" for j in range(n_participants)], n),
        "target": np.tile([f"{d:g}" for d in trials.target_deg], n_participants),
        "rt_s": np.nan,
        "status": "done",
    })
    if trials.counts is not None:
        frame["n_targets"] = np.tile(trials.counts, n_participants)
    for column, levels in trials.levels.items():  # recorded factors: no effect drawn
        frame[column] = np.tile(levels, n_participants)
    return frame


def maximal_formula(trials: TrialDesign, effect: NamedEffect) -> str:
    """The maximal model each simulated study is analysed with (its fixed part follows
    the design: every factor that varies, the declared ones included)."""
    frame = simulate_frame(trials, effect, 3, np.random.default_rng(0))
    return str(model_spec(frame)[0].formula())


@dataclass(frozen=True)
class HeadlineResult:
    """The report's headline test of the condition on one simulated study.

    Attributes:
        estimate: static minus dynamic log-odds at between-tactor targets (averaged
            over target counts), the report's effect; its sign is the direction.
        lrt: the likelihood ratio (every condition term against none); lrt_p its
            chi-square p.
        p: the headline p: ``lrt / df`` referred to ``F(df, participants - 1)``.
    """

    estimate: float
    lrt: float
    lrt_p: float
    p: float


_NAN_RESULT = HeadlineResult(math.nan, math.nan, math.nan, math.nan)


def headline_statistics(frame: pd.DataFrame) -> HeadlineResult:
    """Fit the report's accuracy model (:func:`~tactorbelt.analysis.models.fit.fit_model`)
    and its null model on ``frame``: the effect and the likelihood ratio (NaN when it
    cannot be fitted)."""
    y = frame["correct"].to_numpy()
    if y.min() == y.max():
        return _NAN_RESULT
    try:
        with warnings.catch_warnings(action="ignore"):
            fit, _ = fit_model(frame)
            fit0 = fit_glmm(frame, null_spec(fit.spec), se=False)
            est, _ = _average_contrast(fit, frame)
    except (ValueError, np.linalg.LinAlgError, FloatingPointError):
        return _NAN_RESULT
    lr = likelihood_ratio(fit, fit0)
    f_p = float(lr.get("f_reference", {}).get("p", math.nan))
    return HeadlineResult(est, float(lr["statistic"]), float(lr["p"]), f_p)


def _between(frame: pd.DataFrame, condition: str) -> np.ndarray:
    sel = frame.loc[(frame["condition"] == condition) & (frame["on_tactor"] == 0)]
    return sel.groupby("participant", sort=True)["correct"].mean().to_numpy(dtype=float)


def simulate_glmm_studies(trials: TrialDesign, effect: NamedEffect, n_participants: int,
                          indices: Sequence[int], seed: int) -> list[StudyOutcome]:
    """Simulate and analyse the studies ``indices`` of size ``n_participants``.

    The outcome's p is the report's headline test (:func:`headline_statistics`: the
    likelihood ratio referred to ``F(k, participants - 1)``); it counts as found when
    the report's effect has the named sign (``static_acc``/``dynamic_acc`` are the
    simulated participants' between-tactor accuracies, for the table).
    """
    if n_participants < 3:
        raise ConfigError("the report's mixed model needs at least 3 participants; "
                          f"got a study size of {n_participants}")
    sign = math.copysign(1.0, effect.headline)

    def one(rng: np.random.Generator) -> StudyOutcome:
        frame = simulate_frame(trials, effect, n_participants, rng)
        res = headline_statistics(frame)
        ok = math.isfinite(res.estimate) and math.copysign(1.0, res.estimate) == sign
        return StudyOutcome(n_participants, _between(frame, "static"),
                            _between(frame, "dynamic"), res.p, direction_ok=ok)

    return studies(n_participants, indices, seed, one)


def named_power(trials: TrialDesign, effect: NamedEffect, sizes: Sequence[int], sims: int,
                seed: int, jobs: int, alpha: float,
                advance: Callable[[int], None] | None = None) -> list[PowerRow]:
    """Power of the report's headline test for the named effect on one participant's
    ``trials`` (:meth:`~tactorbelt.power.design.PowerDesign.trials`), one row per size.
    Results do not depend on ``jobs``: each simulated study has its own seed.
    """
    return run_sizes(simulate_glmm_studies, lambda n, idx: (trials, effect, n, idx, seed),
                     sizes, sims, jobs, alpha, advance)
