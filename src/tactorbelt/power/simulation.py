"""Power by simulation with model participants: how often a study of N finds the effect.

For each study size N and each simulated study, N individual model observers are drawn
(:func:`~tactorbelt.participant.params.draw_participant`), their test trials are
simulated on the fast path (:mod:`tactorbelt.participant.simulate`; a factorial design
block by block, :mod:`tactorbelt.participant.factorial`, under a load with the observer
localising under that load), and the effect's test is run on their per-participant
between-tactor accuracies (:mod:`.effects`; the paired test is the analysis' Wilcoxon,
:func:`analysis_paired_test`). A study *finds the difference* when the test's p-value is
below alpha and the mean accuracies go the way the model predicts (dynamic above
static; without a load above under one); an interaction is found either way.

:func:`run_power` takes a protocol of the :class:`~.design.PowerDesign` (its
:meth:`~.design.PowerDesign.factorial`, or for the paper's test, dynamic vs static over
every block of a design with one target count and no load, its
:meth:`~.design.PowerDesign.protocol` alone) and an :class:`~.effects.Effect`. Each
simulated study draws from its own generator, seeded by ``(seed, N, index)``, so results
do not depend on how the work is split across processes.

The power is a property of the model's assumptions (docs/participant-model.md), not of
people: it says how large a study would need to be *if* people behaved like it.

Pure apart from the process pool: NumPy, SciPy's tests, the analysis' Wilcoxon and
participant (the sim belt's vibration inside :func:`run_power`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from numpy.typing import NDArray
from scipy.stats import friedmanchisquare, rankdata

from .._errors import ConfigError
from ..analysis.tables.classical import wilcoxon_paired
from ..participant.factorial import FactorialProtocol, simulate_factorial_participant
from ..participant.params import ModelParams, draw_participant
from ..participant.simulate import StimulusCues, TrialTable, stimulus_cues
from .effects import Effect
from .outcomes import PairedTest, PowerRow, StudyOutcome
from .pool import p_value, run_sizes, studies

__all__ = ["analysis_paired_test", "exact_signed_rank_p", "friedman_interaction",
           "observer", "run_power", "simulate_factorial_studies"]

FloatArray = NDArray[np.float64]


# -- the test ------------------------------------------------------------------------------

_SIGNS: dict[int, NDArray[np.float64]] = {}


def exact_signed_rank_p(diff: NDArray[np.float64]) -> float | None:
    """Two-sided p of ``scipy.stats.wilcoxon`` on paired differences ``diff`` where SciPy
    runs its exact permutation test (ties or zeros among at most 13 pairs), by
    enumerating every sign flip in one matrix product; None where SciPy does something
    else (no ties and no zeros: its exact distribution; more than 13 pairs: the normal
    approximation), so the caller asks SciPy.

    SciPy (1.11 and later) flips the signs of all n differences (2**n arrangements,
    zeros included, which change nothing) and counts arrangements whose signed-rank sum
    is at most / at least the observed one, within a relative tolerance of 100 machine
    epsilons; the same counts over the 2**m arrangements of the m non-zero differences
    give the same proportions. ``tests/test_participant_fast.py`` checks the equality
    on random paired accuracies.
    """
    d = np.asarray(diff, dtype=float)
    n = d.size
    nz = d[d != 0]
    m = nz.size
    if n > 13 or m == 0:
        return None
    ranks = rankdata(np.abs(nz), method="average")
    if m == n and np.unique(ranks).size == m:
        return None  # no ties, no zeros: SciPy's exact null distribution
    signs = _SIGNS.get(m)
    if signs is None:
        signs = ((np.arange(2**m)[:, None] >> np.arange(m)[None, :]) & 1).astype(float)
        _SIGNS[m] = signs
    null = signs @ ranks
    observed = float(ranks[nz > 0].sum())
    gamma = abs(np.finfo(float).eps * 100 * observed)
    less = np.count_nonzero(null <= observed + gamma) / null.size
    greater = np.count_nonzero(null >= observed - gamma) / null.size
    return float(min(max(min(less, greater) * 2, 0.0), 1.0))


def analysis_paired_test(static: FloatArray, dynamic: FloatArray) -> float:
    """The analysis' static-vs-dynamic test (paired Wilcoxon) p-value; NaN if not computed.

    Where SciPy would run its exact permutation test (ties or zeros, at most 13 pairs;
    about 0.2 s a call) the same p-value comes from :func:`exact_signed_rank_p` (a
    matrix product).
    """
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


def friedman_interaction(diff: FloatArray, paired: PairedTest) -> float:
    """p-value of "the per-participant differences (rows) differ across the target
    counts (columns)": Friedman, or the paired test with two counts; NaN if not computed."""
    d = diff[np.isfinite(diff).all(axis=1)]
    if d.shape[0] < 2:
        return float("nan")
    if d.shape[1] == 2:
        return float(paired(d[:, 0], d[:, 1]))
    if np.all(d == d[:, :1]):
        return 1.0
    return float(friedmanchisquare(*d.T).pvalue)


# -- simulated studies ---------------------------------------------------------------------

def _between(tables: dict[int, TrialTable], condition: str | None, n: int | None,
             load: str | None = None, loaded: bool | None = None) -> float:
    """Between-tactor accuracy in ``condition`` (None: both), the blocks of ``n``
    targets (None: all), of the load ``load`` or, with ``loaded``, under any load
    (True) or none (False)."""
    sel = [tables[n]] if n is not None else list(tables.values())
    hits = tot = 0
    for t in sel:
        m = ~t.on_tactor
        if condition is not None:
            m &= t.condition == condition
        if load is not None or loaded is not None:
            names = t.load if t.load is not None else np.full(t.n, "none")
            if load is not None:
                m &= names == load
            else:
                m &= (names != "none") if loaded else (names == "none")
        hits += int(t.correct[m].sum())
        tot += int(m.sum())
    return hits / tot if tot else float("nan")


def simulate_factorial_studies(protocol: FactorialProtocol, cues: Sequence[StimulusCues],
                               effect: Effect, n_participants: int, indices: Sequence[int],
                               seed: int, test: PairedTest) -> list[StudyOutcome]:
    """Simulate the studies ``indices`` of size ``n_participants`` and test ``effect``.

    Each study's generator is seeded by ``(seed, n_participants, index)``; the participants
    are drawn around the observer the cues were sensed by. The outcome's
    ``static_acc``/``dynamic_acc`` are the between-tactor accuracies the effect is about
    (every block for the interaction); for the load effect they are the accuracy under
    load and without a load (so "found" keeps meaning "p < alpha and the second higher").
    """
    if n_participants < 2:
        raise ConfigError(f"a study needs at least 2 participants, got {n_participants}")
    if effect.kind != "load" and not {"static", "dynamic"} <= set(protocol.conditions()):
        raise ConfigError("the power analysis needs static and dynamic test blocks")
    counts = protocol.counts

    def one(rng: np.random.Generator) -> StudyOutcome:
        st = np.empty(n_participants)
        dy = np.empty(n_participants)
        diff = np.empty((n_participants, len(counts)))
        for j in range(n_participants):
            params = draw_participant(rng, cues[0].params)
            tables = simulate_factorial_participant(protocol, cues, params, rng)
            if effect.kind == "load":
                # the outcome's pair is (under load, without): found = higher without
                st[j] = (_between(tables, None, None, loaded=True) if effect.load is None
                         else _between(tables, None, None, load=effect.load))
                dy[j] = _between(tables, None, None, loaded=False)
                continue
            st[j] = _between(tables, "static", effect.n_targets)
            dy[j] = _between(tables, "dynamic", effect.n_targets)
            if effect.kind == "interaction":
                diff[j] = [_between(tables, "dynamic", n) - _between(tables, "static", n)
                           for n in counts]
        p = (p_value(friedman_interaction, diff, test) if effect.kind == "interaction"
             else p_value(test, st, dy))
        return StudyOutcome(n_participants, st, dy, p, directional=effect.kind != "interaction")

    return studies(n_participants, indices, seed, one)


# -- power at each size --------------------------------------------------------------------

def observer(protocol: FactorialProtocol) -> ModelParams:
    """The typical observer the simulation draws around, at the protocol's stimulus
    period (a factorial protocol: its first part's)."""
    return ModelParams().for_period(protocol.period_s)


def run_power(protocol: FactorialProtocol, effect: Effect, sizes: Sequence[int], sims: int,
              seed: int, jobs: int, alpha: float,
              advance: Callable[[int], None] | None = None) -> list[PowerRow]:
    """Simulate ``sims`` studies of ``protocol`` at each size (in ``jobs`` processes), test
    ``effect`` on each, summarise each size.

    The cues are sensed once, on the sim belt, by the typical observer (:func:`observer`).
    Results do not depend on ``jobs``: each simulated study has its own seed.
    """
    from ..inputs.model import sim_vibrator

    vibrate, typical = sim_vibrator(protocol.parts[0].layout), observer(protocol)
    cues = tuple(stimulus_cues(p, vibrate, typical) for p in protocol.parts)
    return run_sizes(simulate_factorial_studies,
                     lambda n, idx: (protocol, cues, effect, n, idx, seed, analysis_paired_test),
                     sizes, sims, jobs, alpha, advance)
