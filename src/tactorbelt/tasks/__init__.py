"""Secondary tasks (cognitive load) and workload ratings.

A study loads its participants with a concurrent go/no-go task declared in
``[tasks.NAME]`` (:class:`~tactorbelt.tasks.spec.TaskSpec`): auditory or visual
n-back, or mental arithmetic. The pure core is here:

- :mod:`.schedule`: the items of a task (:class:`~.schedule.TaskItem`,
  :func:`~.schedule.item_sequence`, seeded and infinite) and the scoring of presses
  (:func:`~.schedule.classify` -> :class:`~.schedule.TaskEvent` rows of ``task_events``);
- :mod:`.session`: :class:`~.session.TaskSession`, one run of a task on its own clock
  (item k at start + k * interval, whatever the trials do), stepped by the runner on
  its sampling tick.

:class:`WorkloadInfo` is what a cursor source (the model participant) or the window
(a person) is told when the raw NASA-TLX is asked after a test block
(``[questionnaire] tlx = true``); the answers go to the store's ``ratings``.

Pure: imports the standard library only (the study types for annotations).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING

from .._errors import ConfigError

if TYPE_CHECKING:
    from .spec import TaskSpec

__all__ = [
    "PHASES",
    "TASK_LEAD_NS",
    "TLX_ITEMS",
    "TLX_SCALE",
    "WorkloadInfo",
    "check_tlx",
]

#: An item is announced (to the window, which schedules its sound or glyph, and to
#: the model participant) at least this long before its onset.
TASK_LEAD_NS = 100_000_000
#: The phases of a task run: alone before the first block with its load (practice,
#: then the single-task baseline) and during the test blocks (dual).
PHASES = ("practice", "baseline", "dual")
#: ``ratings.scale`` of the raw NASA-TLX (Hart & Staveland 1988).
TLX_SCALE = "nasa_tlx"
#: The six NASA-TLX items, in the standard order; each rated 0..100.
TLX_ITEMS = ("mental", "physical", "temporal", "performance", "effort", "frustration")


@dataclass(frozen=True)
class WorkloadInfo:
    """What the rater is told when the workload questionnaire is asked after a block.

    Attributes:
        block_index: position of the block in the session's schedule.
        block_name: the test block's name.
        condition: ``static`` or ``dynamic``.
        n_targets: the block's target count.
        load: the block's load (a ``[tasks.NAME]`` name, or ``none``).
        task: the load's task, None without one.
    """

    block_index: int
    block_name: str
    condition: str
    n_targets: int
    load: str
    task: TaskSpec | None = None


def check_tlx(values: Mapping[str, float]) -> dict[str, float]:
    """The six NASA-TLX ratings as floats, or ConfigError naming what is wrong.

    Every item of :data:`TLX_ITEMS` must be there, and nothing else, each a finite
    number in 0..100.
    """
    missing = [k for k in TLX_ITEMS if k not in values]
    extra = sorted(k for k in values if k not in TLX_ITEMS)
    if missing or extra:
        raise ConfigError(
            "NASA-TLX ratings need exactly the items " + ", ".join(TLX_ITEMS)
            + (f"; missing {', '.join(missing)}" if missing else "")
            + (f"; unknown {', '.join(extra)}" if extra else ""))
    out: dict[str, float] = {}
    for k in TLX_ITEMS:
        v = values[k]
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) \
                or not 0 <= v <= 100:
            raise ConfigError(f"NASA-TLX rating {k} must be a number from 0 to 100 (got {v!r})")
        out[k] = float(v)
    return out
