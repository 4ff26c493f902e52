"""A scripted cursor that also does the secondary task and answers the NASA-TLX.

    from support.tasks import TaskCursor

    cursor = TaskCursor(answers={t.trial_index: t.target_deg for t in schedule},
                        rt_s=0.4, tlx={"mental": 60, ...})

It judges each announced item from the stimuli alone (never ``item.target``), like a
participant: n-back from its own memory of the last n items, arithmetic from the parity
of the sum, and presses ``rt_s`` after the onset of each item it judges a go item
(``miss_every``: skip every k-th go item). ``extra_presses_s`` adds presses at times
relative to the first onset of each task run (a participant pressing by mistake).
It records the phases and items it was told of.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from tactorbelt.experiment.study import TaskSpec
from tactorbelt.inputs.scripted import ScriptedCursor, ScriptedResponse
from tactorbelt.tasks import WorkloadInfo
from tactorbelt.tasks.schedule import TaskItem

__all__ = ["TaskCursor", "judge"]


def judge(spec: TaskSpec, history: Sequence[str], stimulus: str) -> bool:
    """A go item, from the stimuli: equal to the one n back, or an odd sum."""
    if spec.kind == "arithmetic":
        a, b = stimulus.split("+")
        return (int(a) + int(b)) % 2 == 1
    return len(history) >= spec.n and history[-spec.n] == stimulus


class TaskCursor(ScriptedCursor):
    """See the module doc. ``tlx`` None: leaves the TLX to the window."""

    def __init__(self, responses: ScriptedResponse | None = None, *,
                 answers: Mapping[int, float] | None = None, rt_s: float = 0.4,
                 miss_every: int = 0, extra_presses_s: Sequence[float] = (),
                 tlx: Mapping[str, float] | None = None) -> None:
        super().__init__(responses, answers=answers)
        self.rt_ns = round(rt_s * 1e9)
        self.miss_every = miss_every
        self.extra_s = list(extra_presses_s)
        self.tlx = dict(tlx) if tlx is not None else None
        self.spec: TaskSpec | None = None
        self.phases: list[tuple[str | None, str | None]] = []
        self.items: list[tuple[TaskItem, int]] = []
        self.rated: list[WorkloadInfo] = []
        self._history: list[str] = []
        self._due: list[int] = []
        self._n_go = 0
        self._first_onset: int | None = None

    def task_phase(self, spec: TaskSpec | None, phase: str | None) -> None:
        self.spec = spec
        self.phases.append((None if spec is None else spec.kind, phase))
        self._history = []
        self._due = []  # a new run: what was planned for the last one is dropped
        self._first_onset = None

    def task_item(self, item: TaskItem, onset_ns: int) -> None:
        assert self.spec is not None
        self.items.append((item, onset_ns))
        if self._first_onset is None:
            self._first_onset = onset_ns
            self._due += [onset_ns + round(s * 1e9) for s in self.extra_s]
        if judge(self.spec, self._history, item.stimulus):
            self._n_go += 1
            if not (self.miss_every and self._n_go % self.miss_every == 0):
                self._due.append(onset_ns + self.rt_ns)
        self._history.append(item.stimulus)

    def task_presses(self, now_ns: int) -> list[int]:
        out = sorted(p for p in self._due if p <= now_ns)
        self._due = [p for p in self._due if p > now_ns]
        return out

    def rate_workload(self, info: WorkloadInfo) -> dict[str, float] | None:
        self.rated.append(info)
        return None if self.tlx is None else dict(self.tlx)
