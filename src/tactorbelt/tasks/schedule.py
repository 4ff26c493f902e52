"""The items of a secondary task and the scoring of the participant's presses.

:func:`item_sequence` gives a task's items, seeded and endless: the same spec and seed
give the same items on every machine. Every task is go/no-go:

each kind (:mod:`.kinds`: n-back, arithmetic) says which of its items are go items.

:func:`classify` scores presses against items with onsets: a press belongs to the
latest item whose onset <= press < onset + interval; the first press of an item is its
response, any later one (and a press that belongs to no item) is an extra press, a
false alarm of its own row.

Pure: imports the standard library and the task kinds only.
"""

from __future__ import annotations

import bisect
import hashlib
import random
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .items import TaskItem
from .kinds import NO_TASK, task_kind

if TYPE_CHECKING:
    from .spec import TaskSpec

__all__ = [
    "TaskEvent",
    "TaskItem",
    "classify",
    "derive_seed",
    "item_sequence",
]


@dataclass(frozen=True)
class TaskEvent:
    """One row of ``task_events``: an item and its response, or an extra press.

    Attributes:
        block_index: the block it belongs to (a test block's index in the schedule;
            practice and baseline runs take the index of the block they precede).
        task: the task's name (``[tasks.NAME]``).
        phase: ``practice``, ``baseline`` or ``dual``.
        item_index: the item's index in its run; -1 for an extra press.
        t_ns: the item's onset (runner clock); the press time for an extra press.
        stimulus: the item's stimulus; None for an extra press.
        target: a go item.
        response: ``press`` or ``""``.
        correct: pressed on a go item, or no press on a no-go item; False for an extra
            press.
        rt_s: press - onset in seconds, None without a press.
    """

    block_index: int
    task: str
    phase: str
    item_index: int
    t_ns: int
    stimulus: str | None
    target: bool
    response: str
    correct: bool
    rt_s: float | None


def derive_seed(*parts: object) -> int:
    """A 63-bit seed from parts (session seed, participant, block, phase ...), stable
    across machines and Python versions (SHA-256 of their text)."""
    text = "\x1f".join(str(p) for p in parts).encode()
    return int.from_bytes(hashlib.sha256(text).digest()[:8], "big") >> 1


def item_sequence(spec: TaskSpec, seed: int) -> Iterator[TaskItem]:
    """The items of a task, endless and deterministic in ``(spec, seed)``: its kind's
    (:mod:`.kinds`) items, drawn from a generator seeded by the spec and ``seed``.

    Raises:
        ValueError: a task of kind ``none`` (it has no items).
    """
    if spec.kind == NO_TASK:
        raise ValueError(f"a task of kind {spec.kind!r} has no items")
    rng = random.Random(derive_seed("items", spec.kind, spec.modality, spec.n, seed))
    return task_kind(spec.kind).items(spec, rng)


def classify(items_with_onsets: Sequence[tuple[TaskItem, int]], presses_ns: Sequence[int],
             interval_ns: int, *, block_index: int = 0, task: str = "", phase: str = "dual"
             ) -> list[TaskEvent]:
    """Score presses against items: one row per item, plus one per extra press.

    A press belongs to the latest item whose onset <= press < onset + ``interval_ns``;
    the first press of an item is its response (``rt_s`` from the onset), a later
    press of the same item or a press that belongs to no item is an extra press (its
    own row: item_index -1, ``correct`` False). Rows are in time order (an item at its
    onset, an extra press at its time).

    Args:
        items_with_onsets: ``(item, onset_ns)`` in onset order.
        presses_ns: press times (any order; the runner's clock).
        interval_ns: the task's item interval.
        block_index, task, phase: copied into every row.
    """
    onsets = [o for _, o in items_with_onsets]
    first: dict[int, int] = {}
    extra: list[int] = []
    for p in sorted(presses_ns):
        i = bisect.bisect_right(onsets, p) - 1
        if i < 0 or p >= onsets[i] + interval_ns or i in first:
            extra.append(p)
        else:
            first[i] = p
    rows: list[tuple[int, int, TaskEvent]] = []
    for i, (item, onset) in enumerate(items_with_onsets):
        press = first.get(i)
        rows.append((onset, 0, TaskEvent(
            block_index, task, phase, item.index, onset, item.stimulus, item.target,
            "press" if press is not None else "", (press is not None) == item.target,
            None if press is None else (press - onset) / 1e9)))
    for p in extra:
        rows.append((p, 1, TaskEvent(block_index, task, phase, -1, p, None, False, "press",
                                     False, None)))
    rows.sort(key=lambda r: (r[0], r[1]))
    return [r[2] for r in rows]
