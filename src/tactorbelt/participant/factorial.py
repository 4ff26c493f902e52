"""The fast path of a factorial study (targets x condition x load).

A factorial study's test blocks differ in their target count (and load). The model
participant's answer depends only on the vibration of a (target, condition) stimulus
and on the candidate targets, so each target count is its own
:class:`~tactorbelt.participant.simulate.Protocol` (its blocks' conditions and
repetitions) with its own cues, and one participant's trials are drawn block by block
with one set of parameters and one generator (:func:`simulate_factorial_participant`).

Under a load (a ``[tasks.NAME]`` secondary task) a block's trials are drawn with the
observer localising under that task's load (:func:`~tactorbelt.participant.load.loaded_params`:
noisier, slower, more lapses; assumptions, docs/participant-model.md).

A study's :class:`FactorialProtocol` comes from its power design
(:meth:`tactorbelt.power.design.PowerDesign.factorial`); the power analysis of a
factorial study (its effects and tests) is :mod:`tactorbelt.power.simulation`.

Pure: NumPy, participant.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, fields, replace

import numpy as np

from .params import ModelParams
from .simulate import Protocol, StimulusCues, TrialTable, simulate_participant

__all__ = ["FactorialProtocol", "simulate_factorial_participant"]


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

    @property
    def counts(self) -> tuple[int, ...]:
        return tuple(p.targets.m for p in self.parts)

    @property
    def period_s(self) -> float:
        return self.parts[0].period_s

    def conditions(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(c for p in self.parts for c in p.conditions))


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
        columns = {f.name: np.concatenate([getattr(t, f.name) for t in tables])
                   for f in fields(TrialTable) if f.name != "load"}
        out[p.targets.m] = TrialTable(**columns, load=np.concatenate(
            [np.full(t.n, name) for t, name in zip(tables, names, strict=True)]))
    return out
