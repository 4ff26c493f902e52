"""The registry of secondary-task kinds: one module per kind, one line here.

A study's ``[tasks.NAME] kind = "..."`` names a kind. Everything that differs between
kinds lives in the kind's module, as a :class:`TaskKind`: the rules its fields must
follow, its items (:func:`~tactorbelt.tasks.schedule.item_sequence`), how it is
described and explained to a participant and what the window says during it, the sound
of an auditory item, how hard the model participant finds it, and what an LSL stream
says of it. Nothing outside ``tasks/kinds/`` branches on a kind's name.

``kind = "none"`` is a load with no task: it is not a registered kind
(:data:`NO_TASK`).

Adding a kind (docs/architecture.md, "Adding things"): a module beside these with a
``KIND`` object, and one line in :data:`TASK_KINDS`.

Pure: the standard library and the registry helper; a kind's module is imported when
first asked for.
"""

from __future__ import annotations

import functools
import random
from abc import ABC, abstractmethod
from collections import deque
from collections.abc import Iterator
from typing import Any, Final, Protocol

from ..._errors import ConfigError
from ..._registry import resolve
from ..items import TaskItem

__all__ = ["NO_TASK", "TASK_KINDS", "TaskFields", "TaskKind", "TaskLike", "task_kind"]

#: ``kind`` of a load without a task.
NO_TASK: Final = "none"

#: kind name -> ``"module:attribute"`` of its :class:`TaskKind` (imported when used).
TASK_KINDS: dict[str, str] = {
    "nback": "tactorbelt.tasks.kinds.nback:KIND",
    "arithmetic": "tactorbelt.tasks.kinds.arithmetic:KIND",
}


class TaskFields(Protocol):
    """The fields of a task the model participant's side of a kind reads."""

    @property
    def kind(self) -> str: ...
    @property
    def n(self) -> int: ...


class TaskLike(TaskFields, Protocol):
    """The fields of a task (``TaskSpec``) a kind reads."""

    @property
    def modality(self) -> str: ...
    @property
    def interval_s(self) -> float: ...
    @property
    def stimulus_s(self) -> float: ...
    @property
    def match_rate(self) -> float: ...


class TaskKind(ABC):
    """One kind of go/no-go secondary task.

    Attributes:
        name: its ``kind`` in a study file.
        go_words: how the practice coach names a go item, one and many
            (``("a match", "matches")``).
    """

    name: str
    go_words: tuple[str, str]

    def check_fields(self, n: int) -> None:  # noqa: B027 - most kinds have no rule
        """Raise ValueError (with the field's words) when ``n`` does not fit the kind."""

    def check_timing(self, task: str, spec: TaskLike) -> str | None:
        """What is wrong with a task's timing for this kind (None: nothing)."""
        return None

    @abstractmethod
    def items(self, spec: TaskLike, rng: random.Random) -> Iterator[TaskItem]:
        """The task's items, endless, drawn from ``rng`` only."""

    @abstractmethod
    def describe(self, spec: TaskLike) -> str:
        """What ``study check`` says the task is (``2-back``)."""

    @abstractmethod
    def title(self, spec: TaskLike) -> str:
        """The task's name in the participant's words (``2-back (tones)``)."""

    @abstractmethod
    def rule(self, spec: TaskLike, button: str) -> list[str]:
        """The lines that explain to a participant when to press ``button``."""

    @abstractmethod
    def prompt(self, spec: TaskLike, button: str) -> str:
        """The window's one-line reminder while the task runs alone."""

    # -- the model participant (tactorbelt.participant.load) ---------------------------------
    @abstractmethod
    def load_level(self, spec: TaskFields) -> float:
        """The model participant's load level L in [0, 1] (docs/participant-model.md)."""

    @abstractmethod
    def model_d_prime(self, spec: TaskFields, params: Any) -> float:
        """The model's single-task d' from its ``LoadParams``."""

    @abstractmethod
    def model_rt_steps(self, spec: TaskFields) -> int:
        """Steps of difficulty above the easiest (0..2) that slow the model's presses."""

    @abstractmethod
    def model_is_go(self, spec: TaskFields, stimulus: str, memory: deque[str]) -> bool | None:
        """Whether ``stimulus`` is a go item by the model's own reckoning; ``memory`` is the
        model's memory of this run's items (the kind keeps what it needs in it). None:
        it cannot tell yet."""

    def sound(self, stimulus: str, stimulus_s: float, rate: int) -> Any:
        """The sound of an auditory item (float samples in [-1, 1] at ``rate`` Hz).

        Raises:
            ConfigError: the kind has no auditory items, or ``stimulus`` is not one.
        """
        raise ConfigError(f"a {self.name} task has no auditory items (got {stimulus!r})")

    def stream_fields(self, spec: TaskLike) -> dict[str, Any]:
        """Extra fields an LSL stream's description gives of the task."""
        return {}


@functools.cache
def task_kind(name: str) -> TaskKind:
    """The registered kind ``name`` (imported once).

    Raises:
        ValueError: not a registered kind (the message lists them; ``none`` is no task).
    """
    spec = TASK_KINDS.get(name)
    if spec is None:
        names = (*TASK_KINDS, NO_TASK)
        raise ValueError("should be " + ", ".join(repr(k) for k in names[:-1])
                         + f" or {names[-1]!r} (got {name!r})")
    kind = resolve(spec)
    assert isinstance(kind, TaskKind) and kind.name == name, spec
    return kind
