"""The fast path and the power analysis of a factorial study (targets x condition x load).

A factorial study's test blocks differ in their target count (and load). The model
participant's answer depends only on the vibration of a (target, condition) stimulus
and on the candidate targets, so each target count is its own
:class:`~tactorbelt.participant.simulate.Protocol` (its blocks' conditions and
repetitions) with its own cues, and one participant's trials are drawn block by block
with one set of parameters and one generator (:func:`simulate_factorial_participant`).

Under a load (a ``[tasks.NAME]`` secondary task) a block's trials are drawn with the
observer localising under that task's load (:func:`~tactorbelt.participant.load.loaded_params`:
noisier, slower, more lapses; assumptions, docs/participant-model.md); the condition
and interaction effects pool the loads.

Effects a power analysis can look for (:func:`parse_effect`):

- ``dynamic vs static``: per-participant between-tactor accuracy over every block,
  paired Wilcoxon; found when p < alpha and dynamic is higher;
- ``dynamic vs static at N``: the same in the blocks of N targets;
- ``interaction`` (also ``resolution x condition``): whether the dynamic-minus-static
  difference in between-tactor accuracy changes with the target count: Friedman test
  over the target counts on the per-participant differences (paired Wilcoxon with two
  counts); found when p < alpha, either way;
- ``load`` (``load NAME``): per-participant between-tactor accuracy (both conditions)
  without a load vs under a load (every load, or the load NAME), paired Wilcoxon;
  found when p < alpha and accuracy under load is lower.

Pure: NumPy (SciPy in the interaction test), participant; the Wilcoxon test is passed in.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._errors import ConfigError
from ..geometry import TargetSet
from .params import ModelParams, Spread, draw_participant
from .power import PairedTest, StudyOutcome
from .simulate import Protocol, StimulusCues, TrialTable, simulate_participant, stimulus_cues

__all__ = [
    "Effect",
    "FactorialProtocol",
    "factorial_cues",
    "friedman_interaction",
    "parse_effect",
    "simulate_factorial_participant",
    "simulate_factorial_studies",
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class FactorialProtocol:
    """One :class:`Protocol` per target count (ascending), with that count's blocks.

    Attributes:
        parts: the protocols.
        load_levels: per part, the load level of each of its blocks
            (:func:`~tactorbelt.participant.load.load_level`; empty: no load anywhere).
        loads: per part, the load name of each of its blocks (empty likewise).
    """

    parts: tuple[Protocol, ...]
    load_levels: tuple[tuple[float, ...], ...] = ()
    loads: tuple[tuple[str, ...], ...] = ()

    @classmethod
    def from_study(cls, study: Any) -> FactorialProtocol:
        """From a :class:`~tactorbelt.experiment.study.Study` (its test blocks' counts,
        conditions and repetitions; each block's stimulus overrides are not modelled
        when they differ within a count: the first block's stimulus is used)."""
        from .load import load_level

        parts = []
        levels = []
        names = []
        for n in study.target_counts():
            blocks = [b for b in study.test if study.block_n_targets(b) == n]
            levels.append(tuple(load_level(study.tasks.get(b.load)) for b in blocks))
            names.append(tuple(str(b.load) for b in blocks))
            s = study.block_stimulus(blocks[0])
            parts.append(Protocol(study.layout_obj(), TargetSet.even(n), s.law,
                                  float(s.falloff_deg), float(s.period_s), float(s.transit_s),
                                  tuple((b.condition, int(b.repetitions)) for b in blocks),
                                  float(study.response.threshold)))
        loaded = any(v > 0 for lv in levels for v in lv)
        return cls(tuple(parts), tuple(levels) if loaded else (),
                   tuple(names) if loaded else ())

    @property
    def counts(self) -> tuple[int, ...]:
        return tuple(p.targets.m for p in self.parts)

    @property
    def period_s(self) -> float:
        return self.parts[0].period_s

    def conditions(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(c for p in self.parts for c in p.conditions))

    def load_names(self) -> tuple[str, ...]:
        """The loads of the blocks (``("none",)`` without a load)."""
        if not self.loads:
            return ("none",)
        return tuple(dict.fromkeys(lv for names in self.loads for lv in names))


def factorial_cues(protocol: FactorialProtocol, vibrate: Callable[..., Any],
                   params: ModelParams | None = None) -> tuple[StimulusCues, ...]:
    """The cues of every part (see :func:`~tactorbelt.participant.simulate.stimulus_cues`)."""
    return tuple(stimulus_cues(p, vibrate, params) for p in protocol.parts)


def simulate_factorial_participant(protocol: FactorialProtocol, cues: Sequence[StimulusCues],
                                   params: ModelParams, rng: np.random.Generator
                                   ) -> dict[int, TrialTable]:
    """Every test trial of one model participant: target count -> its trials.

    Blocks under a load are drawn with the loaded observer, block by block; without any
    load, each target count's blocks are drawn together (as before loads existed).
    """
    if not protocol.load_levels:
        return {p.targets.m: simulate_participant(p, c, params, rng)
                for p, c in zip(protocol.parts, cues, strict=True)}
    from .load import loaded_params

    out: dict[int, TrialTable] = {}
    for p, c, levels, names in zip(protocol.parts, cues, protocol.load_levels,
                                   protocol.loads, strict=True):
        tables = [simulate_participant(replace(p, blocks=(block,)), c,
                                       loaded_params(params, level), rng)
                  for block, level in zip(p.blocks, levels, strict=True)]
        def cat(field: str, parts: list[TrialTable] = tables) -> Any:
            return np.concatenate([getattr(t, field) for t in parts])

        out[p.targets.m] = TrialTable(
            condition=cat("condition"), target_deg=cat("target_deg"),
            on_tactor=cat("on_tactor"), response_deg=cat("response_deg"),
            correct=cat("correct"), rt_s=cat("rt_s"),
            load=np.concatenate([np.full(t.n, name)
                                 for t, name in zip(tables, names, strict=True)]))
    return out


@dataclass(frozen=True)
class Effect:
    """The effect a factorial power analysis looks for (see :func:`parse_effect`).

    Attributes:
        kind: ``condition`` (dynamic vs static), ``interaction`` or ``load``.
        n_targets: the target count of a ``condition`` effect (None: every block).
        text: how the user named it.
        load: the load of a ``load`` effect (None: every load but ``none``).
    """

    kind: str
    n_targets: int | None = None
    text: str = "dynamic vs static"
    load: str | None = None

    def describe(self) -> str:
        if self.kind == "load":
            which = "any load" if self.load is None else f"load {self.load}"
            return (f"between-tactor accuracy (static and dynamic blocks) without a load vs "
                    f"under {which} (paired Wilcoxon; found = p < alpha and lower under "
                    "load)")
        if self.kind == "interaction":
            return ("resolution x condition interaction: does the dynamic-minus-static "
                    "between-tactor accuracy change with the target count? (Friedman test "
                    "over the target counts; Wilcoxon with two)")
        where = "every block" if self.n_targets is None else f"the {self.n_targets}-target blocks"
        return (f"dynamic vs static between-tactor accuracy in {where} (paired Wilcoxon; "
                "found = p < alpha and dynamic higher)")


_CONDITION = re.compile(r"^\s*(dynamic\s+vs\.?\s+static|static\s+vs\.?\s+dynamic|condition)"
                        r"(?:\s+at\s+(\d+)(?:\s+targets)?)?\s*$", re.I)
_LOAD = re.compile(r"^\s*load(?:\s+([A-Za-z][A-Za-z0-9_\-]*))?\s*$", re.I)
_INTERACTION = re.compile(r"^\s*(interaction|resolution\s*x\s*condition|condition\s*x\s*"
                          r"resolution|targets\s*x\s*condition|condition\s*x\s*targets)\s*$", re.I)


def parse_effect(text: str | None, counts: Sequence[int],
                 loads: Sequence[str] = ("none",)) -> Effect:
    """Read ``--effect``: ``dynamic vs static``, ``dynamic vs static at 36``,
    ``interaction`` (``resolution x condition``) or ``load`` (``load NAME``).

    Raises:
        ConfigError: an effect it does not know, a target count or load the study
            lacks, an interaction in a study with one target count, or a load effect in
            a study without blocks with and without a load.
    """
    if text is None or not text.strip():
        return Effect("condition")
    m = _CONDITION.match(text)
    if m:
        n = int(m.group(2)) if m.group(2) else None
        if n is not None and n not in counts:
            raise ConfigError(f"effect {text!r}: the study has no blocks of {n} targets "
                              f"(it has {', '.join(map(str, counts))})")
        return Effect("condition", n, text.strip())
    m = _LOAD.match(text)
    if m:
        name = m.group(1)
        loaded = [lv for lv in loads if lv != "none"]
        if "none" not in loads or not loaded:
            raise ConfigError(f"effect {text!r} needs test blocks without a load and blocks "
                              f"under one; the study's loads are {', '.join(loads)}")
        if name is not None and name not in loaded:
            raise ConfigError(f"effect {text!r}: the study has no load {name!r} (it has "
                              f"{', '.join(loaded)})")
        return Effect("load", None, text.strip(), name)
    if _INTERACTION.match(text):
        if len(counts) < 2:
            raise ConfigError(f"effect {text!r} needs at least two target counts; the study "
                              f"has {', '.join(map(str, counts))}")
        return Effect("interaction", None, text.strip())
    raise ConfigError(f"unknown effect {text!r}; use 'dynamic vs static', 'dynamic vs "
                      "static at N' (N a target count of the study), 'interaction' "
                      "(resolution x condition) or 'load' ('load NAME': one load)")


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


def friedman_interaction(diff: FloatArray, paired: PairedTest) -> float:
    """p-value of "the per-participant differences (rows) differ across the target
    counts (columns)": Friedman, or the paired test with two counts; NaN if not computed."""
    from scipy.stats import friedmanchisquare

    d = diff[np.isfinite(diff).all(axis=1)]
    if d.shape[0] < 2:
        return float("nan")
    if d.shape[1] == 2:
        return float(paired(d[:, 0], d[:, 1]))
    if np.all(d == d[:, :1]):
        return 1.0
    return float(friedmanchisquare(*d.T).pvalue)


def simulate_factorial_studies(protocol: FactorialProtocol, cues: Sequence[StimulusCues],
                               effect: Effect, n_participants: int, indices: Sequence[int],
                               seed: int, test: PairedTest, base: ModelParams | None = None,
                               spread: Spread | None = None,
                               progress: Callable[[int], None] | None = None
                               ) -> list[StudyOutcome]:
    """Simulate the studies ``indices`` of size ``n_participants`` and test ``effect``.

    Each study's generator is seeded by ``(seed, n_participants, index)``. The outcome's
    ``static_acc``/``dynamic_acc`` are the between-tactor accuracies the effect is about
    (every block for the interaction); for the load effect they are the accuracy under
    load and without a load (so "found" keeps meaning "p < alpha and the second higher").
    """
    if n_participants < 2:
        raise ConfigError(f"a study needs at least 2 participants, got {n_participants}")
    if effect.kind != "load" and not {"static", "dynamic"} <= set(protocol.conditions()):
        raise ConfigError("the power analysis needs static and dynamic test blocks")
    base = base if base is not None else cues[0].params
    counts = protocol.counts
    out: list[StudyOutcome] = []
    for i in indices:
        rng = np.random.default_rng([int(seed), int(n_participants), int(i)])
        st = np.empty(n_participants)
        dy = np.empty(n_participants)
        diff = np.empty((n_participants, len(counts)))
        for j in range(n_participants):
            params = draw_participant(rng, base, spread)
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
        try:
            p = (friedman_interaction(diff, test) if effect.kind == "interaction"
                 else float(test(st, dy)))
        except (ValueError, ZeroDivisionError, FloatingPointError):
            p = float("nan")
        out.append(replace(StudyOutcome(n_participants, st, dy, p),
                           directional=effect.kind != "interaction"))
        if progress is not None:
            progress(1)
    return out
