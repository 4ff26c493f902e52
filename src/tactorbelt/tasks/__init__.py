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
from typing import TYPE_CHECKING, Final

from .._errors import ConfigError

if TYPE_CHECKING:
    from .spec import TaskSpec

__all__ = [
    "PHASES",
    "TASK_LEAD_NS",
    "TLX_ITEMS",
    "TLX_SCALE",
    "TLX_SCALES",
    "TlxScale",
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
@dataclass(frozen=True)
class TlxScale:
    """One NASA-TLX scale: its item key (``ratings.item``), title, question, anchors
    (0 and 100) and NASA's definition."""

    item: str
    title: str
    question: str
    low: str
    high: str
    definition: str


#: The six scales of NASA's form (NASA Ames Research Center, *NASA Task Load Index (TLX)
#: v1.0, paper and pencil package*, 1986), in the standard order; the window's sliders
#: (:mod:`tactorbelt.gui.tlx`) and the exports' descriptions.
TLX_SCALES: Final = (
    TlxScale("mental", "Mental Demand", "How mentally demanding was the task?",
             "Very low", "Very high",
             "How much mental and perceptual activity was required (e.g. thinking, "
             "deciding, calculating, remembering, looking, searching)? Was the task easy "
             "or demanding, simple or complex, exacting or forgiving?"),
    TlxScale("physical", "Physical Demand", "How physically demanding was the task?",
             "Very low", "Very high",
             "How much physical activity was required (e.g. pushing, pulling, turning, "
             "controlling, activating)? Was the task easy or demanding, slow or brisk, "
             "slack or strenuous, restful or laborious?"),
    TlxScale("temporal", "Temporal Demand", "How hurried or rushed was the pace of the task?",
             "Very low", "Very high",
             "How much time pressure did you feel due to the rate or pace at which the "
             "tasks or task elements occurred? Was the pace slow and leisurely or rapid "
             "and frantic?"),
    TlxScale("performance", "Performance",
             "How successful were you in accomplishing what you were asked to do?",
             "Perfect", "Failure",
             "How successful do you think you were in accomplishing the goals of the task? "
             "How satisfied were you with your performance in accomplishing these goals?"),
    TlxScale("effort", "Effort",
             "How hard did you have to work to accomplish your level of performance?",
             "Very low", "Very high",
             "How hard did you have to work (mentally and physically) to accomplish your "
             "level of performance?"),
    TlxScale("frustration", "Frustration",
             "How insecure, discouraged, irritated, stressed and annoyed were you?",
             "Very low", "Very high",
             "How insecure, discouraged, irritated, stressed and annoyed versus secure, "
             "gratified, content, relaxed and complacent did you feel during the task?"),
)
#: The six NASA-TLX items, in the standard order; each rated 0..100.
TLX_ITEMS = tuple(s.item for s in TLX_SCALES)


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
