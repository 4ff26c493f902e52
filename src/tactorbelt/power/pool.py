"""Simulated studies in chunks, in one process or a pool of them, summarised per size.

Every power analysis splits its ``sims`` studies per size into chunks of study indices
(:func:`chunks`) and runs a module-level worker on each (:func:`run_sizes`). Each
simulated study is seeded by ``(seed, N, index)``, so results do not depend on how the
work is split, nor on ``jobs``: the outcomes are summarised in the order of the work
whatever order the processes finish in.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

from .outcomes import PowerRow, StudyOutcome, power_row

__all__ = ["chunks", "run_sizes"]


def chunks(sims: int, jobs: int) -> list[list[int]]:
    """The study indices ``0 .. sims - 1`` in chunks (at most 25; about four a process)."""
    chunk = max(1, min(25, math.ceil(sims / max(jobs, 1) / 4)))
    return [list(range(s, min(s + chunk, sims))) for s in range(0, sims, chunk)]


def run_sizes(worker: Callable[[Any], list[StudyOutcome]], work: list[tuple[int, Any]],
              sizes: Sequence[int], jobs: int, alpha: float,
              advance: Callable[[int], None] | None) -> list[PowerRow]:
    """Run the ``(size, args)`` work items (in ``jobs`` processes); one PowerRow per size.

    Args:
        worker: a module-level function (processes pickle it by name).
        advance: called with the number of simulated studies just finished.
    """
    results: dict[int, list[StudyOutcome]] = {n: [] for n in sizes}
    if jobs <= 1:
        for n, item in work:
            done = worker(item)
            results[n].extend(done)
            if advance is not None:
                advance(len(done))
    else:
        from concurrent.futures import ProcessPoolExecutor, as_completed

        finished: dict[int, list[StudyOutcome]] = {}
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            futures = {pool.submit(worker, item): i for i, (_, item) in enumerate(work)}
            for fut in as_completed(futures):
                done = finished[futures[fut]] = fut.result()
                if advance is not None:
                    advance(len(done))
        # in the order of the work, as one process runs it: the same sums to the last bit
        for i, (n, _) in enumerate(work):
            results[n].extend(finished[i])
    return [power_row(results[n], alpha) for n in sizes]
