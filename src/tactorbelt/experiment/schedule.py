"""The trial schedule of one session: a pure function of (study, participant, seed).

:func:`make_schedule` lists every trial of a session in the order it will run: the
training block, then the test blocks in the participant's counterbalanced order.
Randomisation uses a NumPy Generator seeded from ``(seed, sha256(participant),
block position)``, so the same inputs always give the same list, on every machine.
The list is stored with the session (JSON) and resume replays it from the store.

Counterbalancing of the test blocks (``session.condition_order``):

- ``fixed``: the order of the file for everyone;
- ``alternate``: participant number p (the last group of digits in the id, e.g.
  ``P07`` -> 7; a stable hash when there are none) gets the file's order when p is
  odd and the reverse when p is even;
- ``latin``: a balanced Latin square (Williams design; 2k rows for an odd number k
  of blocks), row ``(p - 1) mod rows``.

A ``[design]`` file orders its factorial blocks by ``design.order`` instead:
``williams`` (the balanced Latin square above), ``latin`` (the cyclic Latin square,
row r = r, r+1, ... mod k: each block once in each position over k participants, no
carry-over balance), ``fixed`` (the canonical order: targets, then condition, then
load) or ``random`` (a permutation seeded from the seed and the participant).

Training runs first and covers every target count of the test blocks, ascending.

Pure: imports NumPy, the standard library and tactorbelt.geometry / experiment.study.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np

from ..factors import Factor, added_factors
from ..geometry import TargetSet
from .study import Study

__all__ = [
    "ScheduledTrial",
    "block_order",
    "cyclic_latin_square",
    "make_schedule",
    "order_rows",
    "order_rule",
    "participant_number",
    "schedule_from_json",
    "schedule_to_json",
    "williams_square",
]


@dataclass(frozen=True)
class ScheduledTrial:
    """One trial of a session's schedule.

    Attributes:
        trial_index: position in the session (0-based).
        block: ``training`` or ``test``.
        block_index: position of the block in the session (0 = first block run).
        block_name: the block's name (``training`` or the test block's name).
        condition: ``static`` or ``dynamic``.
        repetition: 1-based pass (training) or repetition (test) of this target.
        target_deg: the target direction.
        on_tactor: True when the target coincides with a tactor.
        n_targets: the block's target count (its targets are at k*360/n_targets).
        load: the secondary task's name, ``none`` without one.
        levels: the levels of the factors declared beyond condition, targets and load
            (:mod:`tactorbelt.factors`), by column; stored as keys of their own.
    """

    trial_index: int
    block: str
    block_index: int
    block_name: str
    condition: str
    repetition: int
    target_deg: float
    on_tactor: bool
    n_targets: int = 0
    load: str = "none"
    levels: Mapping[str, Any] = field(default_factory=dict, hash=False)

    def level(self, f: Factor) -> Any:
        """This trial's level of factor ``f``."""
        if f.column in _TRIAL_FIELDS:
            return getattr(self, f.column)
        return self.levels.get(f.column, f.default)

    def target_set(self) -> TargetSet:
        """The candidate targets of this trial's block (what a response snaps to)."""
        return TargetSet.even(self.n_targets)

    def to_dict(self) -> dict[str, Any]:
        """The fields by name (every one a plain scalar; an added factor's level under
        its column)."""
        return {**{name: getattr(self, name) for name in _TRIAL_FIELDS}, **self.levels}


#: ScheduledTrial's scalar fields, in order (to_dict without dataclasses.asdict's deep
#: copies); ``levels`` is spread into them.
_TRIAL_FIELDS = tuple(f.name for f in fields(ScheduledTrial) if f.name != "levels")


def participant_number(participant: str) -> int:
    """The participant number used for counterbalancing.

    The last run of digits in the id (``P07`` -> 7, ``s12b`` -> 12); an id without
    digits gets a stable number from its SHA-256.
    """
    groups = re.findall(r"\d+", participant)
    if groups:
        return int(groups[-1])
    return int.from_bytes(hashlib.sha256(participant.encode()).digest()[:4], "little") + 1


def williams_square(k: int) -> list[list[int]]:
    """A balanced Latin square for k conditions (k rows when k is even, 2k when odd).

    Each condition appears once per row and once per column per k rows, and (for the
    full set of rows) each condition follows each other equally often.
    """
    if k < 1:
        return []
    # Williams first row: 0, 1, k-1, 2, k-2, ...
    first = [0] + [((i + 1) // 2 if i % 2 else k - i // 2) % k for i in range(1, k)]
    rows = [[(c + r) % k for c in first] for r in range(k)]
    if k % 2 == 1:
        rows += [list(reversed(row)) for row in rows]
    return rows


def cyclic_latin_square(k: int) -> list[list[int]]:
    """The cyclic Latin square: row r is ``r, r+1, ..., r+k-1`` (mod k)."""
    return [[(r + c) % k for c in range(k)] for r in range(k)]


def order_rows(rule: str, k: int) -> int:
    """How many participants complete one balance of ``k`` blocks under ``rule``.

    ``williams``/``latin`` (condition_order): k rows, 2k when k is odd; cyclic
    ``latin`` (design.order): k; ``alternate``: 2; ``fixed`` and ``random``: 1 (random
    balances only in expectation).
    """
    if k <= 1:
        return 1
    if rule == "alternate":
        return 2
    if rule in ("fixed", "random"):
        return 1
    return len(williams_square(k)) if rule == "williams" else k


def order_rule(study: Study) -> str:
    """The counterbalancing rule in force: ``design.order`` or ``session.condition_order``."""
    return study.design.order if study.design is not None else study.session.condition_order


def block_order(study: Study, participant: str, seed: int | None = None) -> list[int]:
    """Indices into ``study.test`` in the order this participant runs them.

    ``seed`` (default ``session.seed``) matters only for ``design.order = "random"``.
    """
    k = len(study.test)
    rule = order_rule(study)
    if rule == "fixed" or k == 1:
        return list(range(k))
    if rule == "random":
        seed = study.session.seed if seed is None else int(seed)
        return [int(i) for i in _rng(seed, participant, -1).permutation(k)]
    p = participant_number(participant)
    if rule == "alternate":
        return list(range(k)) if p % 2 == 1 else list(reversed(range(k)))
    # ``latin``: the balanced (Williams) square in session.condition_order, the cyclic one
    # in design.order
    cyclic = rule == "latin" and study.design is not None
    rows = cyclic_latin_square(k) if cyclic else williams_square(k)
    return rows[(p - 1) % len(rows)]


def _rng(seed: int, participant: str, block_position: int) -> np.random.Generator:
    pid = int.from_bytes(hashlib.sha256(participant.encode("utf-8")).digest()[:8], "little")
    # block_position -1 (the random block order) becomes 2**32, never a block's position
    pos = block_position if block_position >= 0 else 2**32
    return np.random.default_rng(np.random.SeedSequence([int(seed), pid, pos]))


def _order(
    n_targets: int, passes: int, mode: str, rng: np.random.Generator
) -> list[tuple[int, int]]:
    """(repetition 1-based, target index) pairs for one block."""
    pairs = [(r + 1, t) for r in range(passes) for t in range(n_targets)]
    if mode == "none" or mode == "sequential":
        return pairs
    if mode == "per_repetition" or mode == "random":  # a permutation per repetition
        return [(r + 1, int(t)) for r in range(passes) for t in rng.permutation(n_targets)]
    # full: one permutation of every (repetition, target) pair
    return [pairs[int(i)] for i in rng.permutation(len(pairs))]


def make_schedule(study: Study, participant: str, seed: int | None = None) -> list[ScheduledTrial]:
    """Every trial of one session, in running order.

    Args:
        study: the study.
        participant: the participant id (part of the randomisation seed and of the
            counterbalancing).
        seed: the randomisation seed (None: the study's ``session.seed``).

    Returns:
        The training trials (block ``training``), then each test block's trials in
        the participant's block order. Same inputs, same list.
    """
    seed = study.session.seed if seed is None else int(seed)
    layout = study.layout_obj()
    out: list[ScheduledTrial] = []
    block_pos = 0
    order_idx = block_order(study, participant, seed)

    def add(block: str, name: str, condition: str, n: int, load: str,
            pairs: list[tuple[int, int]], levels: Mapping[str, Any]) -> None:
        targets = TargetSet.even(n)
        angles = targets.angles_deg
        on = targets.on_tactor(layout)
        for rep, t in pairs:
            out.append(ScheduledTrial(len(out), block, block_pos, name, condition, rep,
                                      float(angles[t]), bool(on[t]), n, load, levels))

    added = added_factors()
    untrained = {f.column: f.default for f in added}

    tr = study.training
    if tr.passes > 0 and tr.conditions:
        rng = _rng(seed, participant, 0)
        # training follows the participant's condition order when the conditions match
        order = [study.test[i].condition for i in order_idx]
        conds = sorted(tr.conditions, key=lambda c: order.index(c) if c in order else 99)
        for n in study.target_counts():
            for cond in conds:
                add("training", "training", cond, n, "none", _order(n, tr.passes, tr.order, rng),
                    untrained)
        block_pos += 1
    for bi in order_idx:
        spec = study.test[bi]
        n = study.block_n_targets(spec)
        rng = _rng(seed, participant, 1 + bi)
        add("test", spec.label, spec.condition, n, spec.load,
            _order(n, spec.repetitions, study.session.randomise, rng),
            {f.column: spec.level(f) for f in added})
        block_pos += 1
    return out


def schedule_to_json(schedule: list[ScheduledTrial]) -> str:
    """The schedule as compact JSON (a list of objects)."""
    return json.dumps([t.to_dict() for t in schedule], separators=(",", ":"))


def schedule_from_json(text: str, study: Study | None = None) -> list[ScheduledTrial]:
    """Read back :func:`schedule_to_json`.

    A schedule stored before factorial designs lacks ``n_targets`` and ``load``: they
    become the study's ``[targets] count`` (or the block's, matched by name) and
    ``none``. Without ``study``, a missing ``n_targets`` stays 0.
    """
    counts: dict[str, int] = {}
    default = 0
    if study is not None:
        default = study.targets.count
        counts = {b.label: study.block_n_targets(b) for b in study.test}
    out = []
    for d in json.loads(text):
        d = dict(d)
        if "n_targets" not in d:
            d["n_targets"] = counts.get(d.get("block_name", ""), default)
        d.setdefault("load", "none")
        levels = {k: d.pop(k) for k in list(d) if k not in _TRIAL_FIELDS}
        out.append(ScheduledTrial(**d, levels=levels))
    return out
