"""Mental arithmetic: press when the sum ``a+b`` is odd.

An item ``a+b`` is a go item when the sum is odd (probability ``match_rate``). Visual
operands are 1..9, shown as a sum; auditory ones 1..4, played as high then low beeps
(:func:`tactorbelt.tasks.sounds.beeps`), whose nine beep slots must end before the next
item.

Pure: the standard library only.
"""

from __future__ import annotations

import random
from collections import deque
from collections.abc import Iterator
from typing import Any

from ..items import TaskItem
from . import TaskFields, TaskKind, TaskLike

__all__ = ["KIND", "Arithmetic"]


def _arithmetic(rng: random.Random, top: int, p: float) -> Iterator[TaskItem]:
    k = 0
    while True:
        odd = rng.random() < p
        a = rng.randint(1, top)
        bs = [b for b in range(1, top + 1) if (a + b) % 2 == int(odd)]
        b = bs[rng.randrange(len(bs))]
        yield TaskItem(k, f"{a}+{b}", odd)
        k += 1


class Arithmetic(TaskKind):
    name = "arithmetic"
    go_words = ("an odd sum", "odd sums")

    def check_timing(self, task: str, spec: TaskLike) -> str | None:
        if spec.modality != "auditory":
            return None
        from ..sounds import beep_slot_s

        slot = beep_slot_s(spec.stimulus_s)
        longest = 9 * slot  # 4 + 4 beeps and the pause between the operands
        if longest < spec.interval_s:
            return None
        return (f"tasks.{task}: an auditory sum lasts up to {longest:.2f} s (9 beep "
                f"slots of {slot:.2f} s) but interval_s is {spec.interval_s:g} s; make "
                f"interval_s longer than {longest:.2f} s")

    def items(self, spec: TaskLike, rng: random.Random) -> Iterator[TaskItem]:
        return _arithmetic(rng, 4 if spec.modality == "auditory" else 9, spec.match_rate)

    def describe(self, spec: TaskLike) -> str:
        return "odd sums (a+b)"

    def title(self, spec: TaskLike) -> str:
        what = "beeps" if spec.modality == "auditory" else "sums"
        return f"Odd sums ({what})"

    def rule(self, spec: TaskLike, button: str) -> list[str]:
        every = f"every {spec.interval_s:g} s"
        if spec.modality == "auditory":
            return [f"You will hear high beeps, then low beeps, {every}.",
                    "Count both and add them up.",
                    f"Press {button} when the sum is odd (3, 5, 7); otherwise do nothing."]
        return [f"A sum like 3+4 appears left and right of the ellipse {every}.",
                f"Press {button} when the sum is odd; otherwise do nothing."]

    def prompt(self, spec: TaskLike, button: str) -> str:
        return f"Press {button} when the sum is odd"

    def sound(self, stimulus: str, stimulus_s: float, rate: int) -> Any:
        from ..._errors import ConfigError
        from ..sounds import beeps

        a, plus, b = stimulus.partition("+")
        if not (plus and a.isdigit() and b.isdigit()):
            raise ConfigError(f"no sound for the sum {stimulus!r}: auditory items are a+b")
        return beeps(int(a), int(b), stimulus_s, rate)

    def load_level(self, spec: TaskFields) -> float:
        # assumption: odd/even of a one-digit sum is about as demanding as a 2-back
        return 2.0 / 3.0

    def model_d_prime(self, spec: TaskFields, params: Any) -> float:
        return float(params.d_prime_arithmetic)

    def model_rt_steps(self, spec: TaskFields) -> int:
        return 0

    def model_is_go(self, spec: TaskFields, stimulus: str, memory: deque[str]) -> bool | None:
        a, _, b = stimulus.partition("+")
        return (int(a) + int(b)) % 2 == 1


KIND = Arithmetic()
