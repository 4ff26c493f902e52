"""One item of a secondary task (shared by the task kinds and the scoring).

Pure: the standard library only.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["TaskItem"]


@dataclass(frozen=True)
class TaskItem:
    """One item of a task.

    Attributes:
        index: position in the task run (0-based).
        stimulus: ``tone3`` (auditory n-back), ``K`` (visual n-back) or ``3+4``
            (arithmetic).
        target: a go item (press the response button). Scoring only: a participant
            (and the model participant) must work it out from the stimuli.
    """

    index: int
    stimulus: str
    target: bool
