"""Simulated studies in chunks, in one process or a pool of them, summarised per size.

Every power analysis splits its ``sims`` studies per size into chunks of study indices
(:func:`chunks`) and runs a module-level worker on each (:func:`run_sizes`). Each
simulated study is seeded by ``(seed, N, index)`` (:func:`studies`), so results do not
depend on how the work is split, nor on ``jobs``: the outcomes are summarised in the order
of the work whatever order the processes finish in.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any

import numpy as np

from .outcomes import PowerRow, StudyOutcome, power_row

__all__ = ["chunks", "p_value", "run_sizes", "studies"]


def chunks(sims: int, jobs: int) -> list[list[int]]:
    """The study indices ``0 .. sims - 1`` in chunks (at most 25; about four a process)."""
    chunk = max(1, min(25, math.ceil(sims / max(jobs, 1) / 4)))
    return [list(range(s, min(s + chunk, sims))) for s in range(0, sims, chunk)]


def studies(n_participants: int, indices: Sequence[int], seed: int,
            one: Callable[[np.random.Generator], StudyOutcome]) -> list[StudyOutcome]:
    """``one(rng)`` for each simulated study in ``indices`` of size ``n_participants``,
    its generator seeded by ``(seed, n_participants, index)``."""
    return [one(np.random.default_rng([int(seed), int(n_participants), int(i)]))
            for i in indices]


def p_value(test: Callable[..., float], *args: Any) -> float:
    """``test(*args)`` as a float; NaN where the test cannot be computed."""
    try:
        return float(test(*args))
    except (ValueError, ZeroDivisionError, FloatingPointError):
        return float("nan")


def run_sizes(worker: Callable[..., list[StudyOutcome]],
              args: Callable[[int, list[int]], tuple[Any, ...]], sizes: Sequence[int],
              sims: int, jobs: int, alpha: float,
              advance: Callable[[int], None] | None) -> list[PowerRow]:
    """Run ``worker(*args(size, indices))`` on the :func:`chunks` of ``sims`` studies of
    each size (in ``jobs`` processes); one PowerRow per size.

    Args:
        worker: a module-level function (processes pickle it by name).
        advance: called with the number of simulated studies just finished.
    """
    work = [(n, args(n, idx)) for n in sizes for idx in chunks(sims, jobs)]
    results: dict[int, list[StudyOutcome]] = {n: [] for n in sizes}
    if jobs <= 1:
        for n, item in work:
            done = worker(*item)
            results[n].extend(done)
            if advance is not None:
                advance(len(done))
    else:
        finished: dict[int, list[StudyOutcome]] = {}
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = {pool.submit(worker, *item): i for i, (_, item) in enumerate(work)}
            for fut in as_completed(futures):
                done = finished[futures[fut]] = fut.result()
                if advance is not None:
                    advance(len(done))
        # in the order of the work, as one process runs it: the same sums to the last bit
        for i, (n, _) in enumerate(work):
            results[n].extend(finished[i])
    return [power_row(results[n], alpha) for n in sizes]
