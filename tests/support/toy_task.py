"""A toy secondary-task kind for the registry tests (tests/test_task_kinds.py): press on an
even digit. Everything a kind is lives here, as a new kind's module would."""

from __future__ import annotations

import random
from collections import deque
from collections.abc import Iterator
from typing import Any

import numpy as np

from tactorbelt.tasks.items import TaskItem
from tactorbelt.tasks.kinds import TaskFields, TaskKind, TaskLike


class EvenDigits(TaskKind):
    name = "even"
    go_words = ("an even digit", "even digits")

    def check_fields(self, n: int) -> None:
        if n != 2:
            raise ValueError(f"n is not used by an even-digit task; leave it at 2 (got {n!r})")

    def items(self, spec: TaskLike, rng: random.Random) -> Iterator[TaskItem]:
        k = 0
        while True:
            go = rng.random() < spec.match_rate
            digit = rng.choice((0, 2, 4, 6, 8) if go else (1, 3, 5, 7, 9))
            yield TaskItem(k, str(digit), go)
            k += 1

    def describe(self, spec: TaskLike) -> str:
        return "even digits"

    def title(self, spec: TaskLike) -> str:
        return "Even digits"

    def rule(self, spec: TaskLike, button: str) -> list[str]:
        return [f"Press {button} when the digit is even."]

    def prompt(self, spec: TaskLike, button: str) -> str:
        return f"Press {button} on an even digit"

    def load_level(self, spec: TaskFields) -> float:
        return 0.25

    def model_d_prime(self, spec: TaskFields, params: Any) -> float:
        return 3.2

    def model_rt_steps(self, spec: TaskFields) -> int:
        return 0

    def model_is_go(self, spec: TaskFields, stimulus: str, memory: deque[str]) -> bool | None:
        return int(stimulus) % 2 == 0

    def sound(self, stimulus: str, stimulus_s: float, rate: int) -> Any:
        t = np.arange(round(stimulus_s * rate)) / rate
        return 0.3 * np.sin(2 * np.pi * (300 + 40 * int(stimulus)) * t)


KIND = EvenDigits()
