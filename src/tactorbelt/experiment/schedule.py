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

Pure: imports NumPy, the standard library and tactorbelt.geometry / experiment.study.
"""

from __future__ import annotations

import hashlib
import json
import re
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from .study import Study

__all__ = [
    "ScheduledTrial",
    "block_order",
    "make_schedule",
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
    """

    trial_index: int
    block: str
    block_index: int
    block_name: str
    condition: str
    repetition: int
    target_deg: float
    on_tactor: bool

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


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


def block_order(study: Study, participant: str) -> list[int]:
    """Indices into ``study.test`` in the order this participant runs them."""
    k = len(study.test)
    rule = study.session.condition_order
    p = participant_number(participant)
    if rule == "fixed" or k == 1:
        return list(range(k))
    if rule == "alternate":
        return list(range(k)) if p % 2 == 1 else list(reversed(range(k)))
    rows = williams_square(k)
    return rows[(p - 1) % len(rows)]


def _rng(seed: int, participant: str, block_position: int) -> np.random.Generator:
    pid = int.from_bytes(hashlib.sha256(participant.encode("utf-8")).digest()[:8], "little")
    return np.random.default_rng(np.random.SeedSequence([int(seed), pid, block_position]))


def _order(
    n_targets: int, passes: int, mode: str, rng: np.random.Generator
) -> list[tuple[int, int]]:
    """(repetition 1-based, target index) pairs for one block."""
    if mode == "none" or mode == "sequential":
        return [(r + 1, t) for r in range(passes) for t in range(n_targets)]
    if mode == "per_repetition" or mode == "random":
        out: list[tuple[int, int]] = []
        for r in range(passes):
            out += [(r + 1, int(t)) for t in rng.permutation(n_targets)]
        return out
    # full: one permutation of every (repetition, target) pair
    pairs = [(r + 1, t) for r in range(passes) for t in range(n_targets)]
    perm = rng.permutation(len(pairs))
    return [pairs[int(i)] for i in perm]


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
    targets = study.target_set()
    angles = targets.angles_deg
    on = targets.on_tactor(layout)
    out: list[ScheduledTrial] = []
    block_pos = 0

    def add(block: str, name: str, condition: str, pairs: list[tuple[int, int]]) -> None:
        for rep, t in pairs:
            out.append(ScheduledTrial(len(out), block, block_pos, name, condition, rep,
                                      float(angles[t]), bool(on[t])))

    tr = study.training
    if tr.passes > 0 and tr.conditions:
        rng = _rng(seed, participant, 0)
        # training follows the participant's condition order when the conditions match
        order = [study.test[i].condition for i in block_order(study, participant)]
        conds = sorted(tr.conditions, key=lambda c: order.index(c) if c in order else 99)
        for cond in conds:
            add("training", "training", cond, _order(targets.m, tr.passes, tr.order, rng))
        block_pos += 1
    for bi in block_order(study, participant):
        spec = study.test[bi]
        rng = _rng(seed, participant, 1 + bi)
        add("test", spec.label, spec.condition,
            _order(targets.m, spec.repetitions, study.session.randomise, rng))
        block_pos += 1
    return out


def schedule_to_json(schedule: list[ScheduledTrial]) -> str:
    """The schedule as compact JSON (a list of objects)."""
    return json.dumps([t.to_dict() for t in schedule], separators=(",", ":"))


def schedule_from_json(text: str) -> list[ScheduledTrial]:
    """Read back :func:`schedule_to_json`."""
    return [ScheduledTrial(**d) for d in json.loads(text)]
