"""The n-back task: press when an item is the same as the one ``n`` before it.

With probability ``match_rate`` an item (from the n-th on) repeats the one n back;
otherwise it is drawn from the other seven, so no item is a match by accident. Auditory
items are tones ``tone0`` .. ``tone7`` (:data:`NBACK_TONES`, played by
:func:`tactorbelt.tasks.sounds.tone`), visual items letters (:data:`NBACK_LETTERS`).

Pure: the standard library only.
"""

from __future__ import annotations

import random
from collections import deque
from collections.abc import Iterator, Sequence
from typing import Any

from ..items import TaskItem
from . import TaskFields, TaskKind, TaskLike

__all__ = ["KIND", "NBACK_LETTERS", "NBACK_TONES", "NBack"]

#: The 8 tones of auditory n-back (the window plays tone k at its own pitch).
NBACK_TONES = tuple(f"tone{k}" for k in range(8))
#: The 8 consonants of visual n-back (distinct shapes, no vowels: no words form).
NBACK_LETTERS = ("B", "F", "H", "K", "M", "Q", "R", "X")

_BACK = {1: "the one just before it", 2: "the one two before it", 3: "the one three before it"}


def _nback(rng: random.Random, pool: Sequence[str], n: int, p: float) -> Iterator[TaskItem]:
    recent: deque[str] = deque(maxlen=n)  # the last n items
    k = 0
    while True:
        if len(recent) >= n and rng.random() < p:
            stim, target = recent[-n], True
        else:
            avoid = recent[-n] if len(recent) >= n else None
            choices = [s for s in pool if s != avoid]
            stim, target = choices[rng.randrange(len(choices))], False
        yield TaskItem(k, stim, target)
        recent.append(stim)
        k += 1


def _n(spec: TaskFields) -> int:
    return min(max(int(spec.n), 1), 3)


class NBack(TaskKind):
    name = "nback"
    go_words = ("a match", "matches")

    def check_fields(self, n: int) -> None:
        if not 1 <= n <= 3:
            raise ValueError(f"n must be 1, 2 or 3 (got {n!r})")

    def items(self, spec: TaskLike, rng: random.Random) -> Iterator[TaskItem]:
        pool = NBACK_TONES if spec.modality == "auditory" else NBACK_LETTERS
        return _nback(rng, pool, spec.n, spec.match_rate)

    def describe(self, spec: TaskLike) -> str:
        return f"{spec.n}-back"

    def title(self, spec: TaskLike) -> str:
        what = {"auditory": "tones", "visual": "letters"}[spec.modality]
        return f"{spec.n}-back ({what})"

    def rule(self, spec: TaskLike, button: str) -> list[str]:
        every = f"every {spec.interval_s:g} s"
        back = _BACK.get(spec.n, f"the one {spec.n} before it")
        if spec.modality == "auditory":
            return [f"You will hear a tone {every}.",
                    f"Press {button} when a tone is the same as {back};",
                    "otherwise do nothing."]
        return [f"A letter appears left and right of the ellipse {every}.",
                f"Press {button} when it is the same letter as {back};",
                "otherwise do nothing."]

    def prompt(self, spec: TaskLike, button: str) -> str:
        return f"{self.title(spec)}: press {button} on a match"

    def load_level(self, spec: TaskFields) -> float:
        return _n(spec) / 3.0

    def model_d_prime(self, spec: TaskFields, params: Any) -> float:
        return float(params.d_prime_nback[_n(spec) - 1])

    def model_rt_steps(self, spec: TaskFields) -> int:
        return _n(spec) - 1

    def model_is_go(self, spec: TaskFields, stimulus: str, memory: deque[str]) -> bool | None:
        n = int(spec.n)
        go: bool | None = None
        if len(memory) >= n:
            go = memory[-n] == stimulus
        memory.append(stimulus)
        while len(memory) > n:
            memory.popleft()
        return go

    def sound(self, stimulus: str, stimulus_s: float, rate: int) -> Any:
        from ..._errors import ConfigError
        from ..sounds import tone

        if stimulus not in NBACK_TONES:
            raise ConfigError(f"no sound for the n-back item {stimulus!r}: auditory items "
                              "are tone0..tone7")
        return tone(NBACK_TONES.index(stimulus), stimulus_s, rate)

    def stream_fields(self, spec: TaskLike) -> dict[str, Any]:
        return {"n": spec.n}


KIND = NBack()
