"""The one design object of a power analysis: a study's test blocks, read once.

:meth:`PowerDesign.from_study` reads everything a power analysis needs of a study
(:class:`~tactorbelt.experiment.study.Study`, by attribute): its name, the tactor layout,
the acquisition radius, the ``[stimulus]``, and each test block's condition, target
count, repetitions, load (name and level) and stimulus (with the block's overrides).
Nothing else in :mod:`tactorbelt.power` reads the study. Every power analysis takes the
design and asks it for the view it simulates:

- the model-participant simulation (:func:`~tactorbelt.power.simulation.run_power`) of a
  study with one target count: :meth:`PowerDesign.protocol`, the fast path's
  :class:`~tactorbelt.participant.simulate.Protocol`;
- the same of any study (target counts, loads): :meth:`PowerDesign.factorial`, one
  protocol per target count (:class:`~tactorbelt.participant.factorial.FactorialProtocol`);
- the GLMM power for named effect sizes (:func:`~tactorbelt.power.glmm.named_power`):
  :meth:`PowerDesign.trials`, one participant's counted test trials (:class:`TrialDesign`).

Pure: NumPy, geometry and participant.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .._errors import ConfigError
from ..factors import added_factors
from ..geometry import Layout, TargetSet
from ..participant.factorial import FactorialProtocol
from ..participant.load import load_level
from ..participant.simulate import Protocol

__all__ = ["DesignBlock", "PowerDesign", "StimulusParams", "TrialDesign"]


@dataclass(frozen=True)
class StimulusParams:
    """How a block's targets are rendered: the amplitude law and its timing."""

    law: str
    falloff_deg: float
    period_s: float
    transit_s: float

    @classmethod
    def of(cls, spec: Any) -> StimulusParams:
        """From a ``[stimulus]`` table (:class:`~tactorbelt.experiment.study.StimulusSpec`)."""
        return cls(spec.law, float(spec.falloff_deg), float(spec.period_s),
                   float(spec.transit_s))


@dataclass(frozen=True)
class DesignBlock:
    """One test block as a power analysis sees it.

    Attributes:
        condition: ``static`` or ``dynamic``.
        n_targets: its target count (the block's ``targets``, else ``[targets] count``).
        repetitions: how often each target is presented.
        load: its load, a ``[tasks.NAME]`` name or ``none``.
        load_level: that task's load level (:func:`~tactorbelt.participant.load.load_level`;
            0 without a task).
        stimulus: the study's stimulus with the block's overrides.
        levels: its levels of the factors declared beyond condition, targets and load
            (:mod:`tactorbelt.factors`), by column; recorded, so they change no answer,
            but the model the report fits has their terms.
    """

    condition: str
    n_targets: int
    repetitions: int
    load: str
    load_level: float
    stimulus: StimulusParams
    levels: Mapping[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class PowerDesign:
    """A study's test blocks and what renders and answers them (see the module doc).

    Attributes:
        name: the study's name.
        layout: the tactors.
        threshold: the acquisition radius (a model RT counts the movement up to it).
        stimulus: the study's ``[stimulus]`` (without block overrides).
        blocks: the test blocks, in the study's order.
    """

    name: str
    layout: Layout
    threshold: float
    stimulus: StimulusParams
    blocks: tuple[DesignBlock, ...]

    @classmethod
    def from_study(cls, study: Any) -> PowerDesign:
        """Read a :class:`~tactorbelt.experiment.study.Study` (by attribute), once."""
        added = added_factors()
        blocks = tuple(
            DesignBlock(b.condition, int(study.block_n_targets(b)), int(b.repetitions),
                        str(b.load), load_level(study.tasks.get(b.load)),
                        StimulusParams.of(study.block_stimulus(b)),
                        {f.column: study.block_level(b, f) for f in added})
            for b in study.test)
        return cls(str(study.name), study.layout_obj(), float(study.response.threshold),
                   StimulusParams.of(study.stimulus), blocks)

    # -- what the design has ------------------------------------------------------
    @property
    def counts(self) -> tuple[int, ...]:
        """Every target count of the test blocks, ascending."""
        return tuple(sorted({b.n_targets for b in self.blocks}))

    @property
    def conditions(self) -> tuple[str, ...]:
        """The conditions of the test blocks, each once, in order."""
        return tuple(dict.fromkeys(b.condition for b in self.blocks))

    @property
    def loads(self) -> tuple[str, ...]:
        """The loads of the test blocks (``none`` included), each once, in order."""
        return tuple(dict.fromkeys(b.load for b in self.blocks))

    @property
    def loaded(self) -> bool:
        """Some test block names a load."""
        return any(b.load != "none" for b in self.blocks)

    def blocks_of(self, n_targets: int) -> tuple[DesignBlock, ...]:
        """The test blocks of ``n_targets`` targets, in order."""
        return tuple(b for b in self.blocks if b.n_targets == n_targets)

    # -- the views the power analyses simulate ------------------------------------
    def protocol(self) -> Protocol:
        """The fast path's protocol of a design with one target count: every test block,
        rendered with the study's ``[stimulus]``.

        Raises:
            ConfigError: the blocks have several target counts (use :meth:`factorial`).
        """
        counts = self.counts
        if len(counts) != 1:
            raise ConfigError(f"the study's test blocks have {len(counts)} target counts "
                              f"({', '.join(map(str, counts))}); simulate it with "
                              "PowerDesign.factorial()")
        return self._protocol(counts[0], self.blocks, self.stimulus)

    def _protocol(self, n: int, blocks: tuple[DesignBlock, ...], s: StimulusParams
                  ) -> Protocol:
        """The fast path's protocol of ``blocks`` (of ``n`` targets), rendered with ``s``."""
        return Protocol(self.layout, TargetSet.even(n), s.law, s.falloff_deg, s.period_s,
                        s.transit_s, tuple((b.condition, b.repetitions) for b in blocks),
                        self.threshold)

    def factorial(self) -> FactorialProtocol:
        """One protocol per target count (ascending) with that count's blocks, and their
        loads. Each block's stimulus overrides are not modelled when they differ within
        a count: the count's first block's stimulus is used."""
        parts = []
        levels = []
        names = []
        for n in self.counts:
            blocks = self.blocks_of(n)
            levels.append(tuple(b.load_level for b in blocks))
            names.append(tuple(b.load for b in blocks))
            parts.append(self._protocol(n, blocks, blocks[0].stimulus))
        loaded = any(v > 0 for lv in levels for v in lv)
        return FactorialProtocol(tuple(parts), tuple(levels) if loaded else (),
                                 tuple(names) if loaded else ())

    def trials(self, n_targets: int | None = None) -> TrialDesign:
        """One participant's counted test trials, of the blocks of ``n_targets`` targets
        (None: the design's one count).

        Raises:
            ConfigError: several target counts and none chosen; a count it lacks; no
                static or no dynamic block.
        """
        counts = list(self.counts)
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
        targets = TargetSet.even(n_targets)
        on = targets.on_tactor(self.layout)
        cond: list[np.ndarray] = []
        deg: list[np.ndarray] = []
        kind: list[np.ndarray] = []
        blocks = self.blocks_of(n_targets)
        levels: dict[str, list[np.ndarray]] = {k: [] for k in blocks[0].levels}
        for b in blocks:
            idx = np.tile(np.arange(targets.m), b.repetitions)
            cond.append(np.full(idx.size, b.condition))
            deg.append(targets.angles[idx])
            kind.append(on[idx])
            for k, column in levels.items():
                column.append(np.full(idx.size, b.levels[k], dtype=object))
        c = np.concatenate(cond)
        if not {"static", "dynamic"} <= set(c.tolist()):
            raise ConfigError("the model-based power analysis needs static and dynamic test "
                              f"blocks of {n_targets} targets")
        return TrialDesign(c, np.concatenate(deg), np.concatenate(kind), int(n_targets),
                           levels={k: np.concatenate(v) for k, v in levels.items()})


@dataclass(frozen=True)
class TrialDesign:
    """One participant's counted test trials: condition, target and kind per trial
    (:meth:`PowerDesign.trials`; what the GLMM power draws trials for)."""

    condition: np.ndarray
    target_deg: np.ndarray
    on_tactor: np.ndarray
    n_targets: int
    #: the target count of each trial, when the design has several (the model then
    #: has ``factor(n_targets)``); None: one count, ``n_targets``
    counts: np.ndarray | None = None
    #: each trial's level of every factor declared beyond condition, targets and load,
    #: by column (the model has their terms where they vary)
    levels: Mapping[str, np.ndarray] = field(default_factory=dict)

    @property
    def n(self) -> int:
        return int(self.condition.size)
