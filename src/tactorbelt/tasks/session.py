"""One run of a secondary task on its own schedule: :class:`TaskSession`.

Item k is presented at ``start_ns + k * interval_ns``, whatever the localisation
trials do (waiting home, stimulus, ITI, breaks): the task keeps its own clock. The
runner steps a session on its sampling tick: :meth:`TaskSession.announce` hands out
the items due within a lead time (the window schedules their sound or glyph, the model
participant perceives them), :meth:`TaskSession.press` records response presses, and
:meth:`TaskSession.finish` scores everything (:func:`~.schedule.classify`). Every call
costs O(items due), so a 100 Hz tick stays cheap.

Pure: imports the standard library and :mod:`.schedule`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .schedule import TaskEvent, TaskItem, classify, item_sequence

if TYPE_CHECKING:
    from .spec import TaskSpec

__all__ = ["TaskSession"]


class TaskSession:
    """A run of one task: its items on a fixed grid from ``start_ns``.

    Args:
        name: the task's name (``[tasks.NAME]``).
        spec: the task.
        phase: ``practice``, ``baseline`` or ``dual``.
        block_index: the block the run belongs to (stored with every event).
        seed: the item sequence's seed (:func:`~.schedule.item_sequence`).
        start_ns: onset of item 0 (runner clock).
        n_items: items in the run (practice, baseline); None: until :meth:`finish`.
        first_index: index of item 0 (a block resumed after a pause or an abort
            numbers its items on from those already stored).
    """

    def __init__(self, name: str, spec: TaskSpec, phase: str, block_index: int, seed: int,
                 start_ns: int, n_items: int | None, *, first_index: int = 0) -> None:
        if n_items is not None and n_items < 0:
            raise ValueError(f"n_items must be >= 0, got {n_items}")
        self.name = name
        self.spec = spec
        self.phase = phase
        self.block_index = block_index
        self.seed = seed
        self.start_ns = int(start_ns)
        self.n_items = n_items
        self.first_index = first_index
        self.interval_ns = round(spec.interval_s * 1e9)
        self._items = item_sequence(spec, seed)
        self._announced: list[tuple[TaskItem, int]] = []
        self._presses: list[int] = []
        self._finished = False

    def onset_ns(self, k: int) -> int:
        """Onset of the run's k-th item (0-based)."""
        return self.start_ns + k * self.interval_ns

    @property
    def end_ns(self) -> int | None:
        """When the last item's response window ends (None for an open-ended run)."""
        return None if self.n_items is None else self.onset_ns(self.n_items)

    @property
    def announced(self) -> list[tuple[TaskItem, int]]:
        """The items handed out so far, with their onsets."""
        return list(self._announced)

    def announce(self, now_ns: int, lead_ns: int) -> list[tuple[TaskItem, int]]:
        """The items with onset <= ``now_ns + lead_ns`` not announced yet, with onsets."""
        out: list[tuple[TaskItem, int]] = []
        if self._finished:
            return out
        horizon = now_ns + lead_ns
        while self.n_items is None or len(self._announced) < self.n_items:
            k = len(self._announced)
            onset = self.onset_ns(k)
            if onset > horizon:
                break
            item = next(self._items)
            if self.first_index:
                item = TaskItem(item.index + self.first_index, item.stimulus, item.target)
            self._announced.append((item, onset))
            out.append((item, onset))
        return out

    def press(self, t_ns: int) -> None:
        """A response press at ``t_ns`` (runner clock)."""
        if not self._finished:
            self._presses.append(int(t_ns))

    def done(self, now_ns: int) -> bool:
        """True when the run has ``n_items`` and the last item's window has ended."""
        end = self.end_ns
        return end is not None and now_ns >= end

    def finish(self, now_ns: int) -> list[TaskEvent]:
        """End the run at ``now_ns``; its events (see :func:`~.schedule.classify`).

        Scored: the items with onset <= ``now_ns``, except an item without a press whose
        response window was cut short (by the block's end, a pause or an abort): the
        participant had no full chance to answer it. Presses after ``now_ns`` are
        dropped. A second call returns [].
        """
        if self._finished:
            return []
        self._finished = True
        presses = [p for p in self._presses if p <= now_ns]
        shown = [(it, o) for it, o in self._announced if o <= now_ns]
        events = classify(shown, presses, self.interval_ns, block_index=self.block_index,
                          task=self.name, phase=self.phase)
        cut = {it.index for it, o in shown if o + self.interval_ns > now_ns}
        return [e for e in events
                if not (e.item_index in cut and e.item_index >= 0 and e.response == "")]
