#!/usr/bin/env python3
"""Digests of the stored results of model sessions, to compare two versions of tactorbelt.

Runs the model participant through the session runner (sim belt, simulated clock, its
own store per worker) for seeds 1..N of a study template and prints, per seed, the
sha256 of every stored trial row (without ids and wall-clock stamps) and every cursor
sample, in order, with the task events and ratings of a load study. Run it on two
checkouts and compare the files: a change that keeps simulated results the same keeps
every digest. Done for the runner's runs fast path and the sim belt's fewer steps:
identical for the paper study's seeds 1-1,000 (docs/reliability.md).

    python scripts/session_digests.py --seeds 1000 --workers 2 -o new.json
    PYTHONPATH=/path/to/other/checkout/src python scripts/session_digests.py ... -o old.json
"""

from __future__ import annotations

import argparse
import hashlib
import json
import multiprocessing as mp
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

#: Columns that differ between two runs of the same session.
VOLATILE = {"trial_id", "session_id", "recorded_at", "rated_at"}


#: Columns added after earlier digests were taken, left out while empty (a model session
#: on the sim belt has no measured tactor latency, so no skin onset): the digests of two
#: versions compare the results, not the table's width.
ADDED_WHEN_EMPTY = frozenset({"skin_onset_ns", "skin_onset_sd_ns"})


def _clean(row: Any) -> str:
    return json.dumps({k: v for k, v in dict(row).items() if k not in VOLATILE
                       and not (k in ADDED_WHEN_EMPTY and v is None)},
                      sort_keys=True, default=str)


def _work(args: tuple[str, Path, list[int]]) -> dict[int, str]:
    from tactorbelt import open_belt
    from tactorbelt.clock import SimClock
    from tactorbelt.experiment.runner import run_session
    from tactorbelt.experiment.store import Store
    from tactorbelt.experiment.study import Study, template_toml
    from tactorbelt.inputs.model import make_model_cursor

    template, db, seeds = args
    study = Study.from_toml(template_toml(template))
    out: dict[int, str] = {}
    with Store.open(db) as store:
        for n in seeds:
            clock = SimClock()
            with open_belt("sim", clock=clock, layout=study.layout_obj()) as belt:
                cursor = make_model_cursor(belt, clock, seed=n)
                res = run_session(study, f"model-{n:04d}", belt, cursor, store, clock, seed=n)
            h = hashlib.sha256()
            for r in store.trials(res.session_id):
                h.update(_clean(r).encode())
                for s in store.samples(r["trial_id"]):
                    h.update(repr(s).encode())
            for e in store.task_events(res.session_id):
                h.update(_clean(e).encode())
            for e in store.ratings(res.session_id):
                h.update(_clean(e).encode())
            out[n] = h.hexdigest()
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--template", default="paper", help="study template (default: paper)")
    ap.add_argument("--seeds", type=int, default=20, help="seeds 1..N (default 20)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("-o", "--output", type=Path, required=True, help="JSON file to write")
    args = ap.parse_args()
    from tactorbelt import ConfigError
    from tactorbelt.experiment.study import template_toml

    try:
        template_toml(args.template)
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if args.seeds < 1 or args.workers < 1:
        print("error: --seeds and --workers must be at least 1", file=sys.stderr)
        return 2
    seeds = list(range(1, args.seeds + 1))
    w = max(1, min(args.workers, len(seeds)))
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp, mp.get_context("spawn").Pool(w) as pool:
        parts = pool.map(_work, [(args.template, Path(tmp) / f"w{i}.sqlite", seeds[i::w])
                                 for i in range(w)])
    digests = {str(k): v for p in parts for k, v in sorted(p.items())}
    args.output.write_text(json.dumps(digests, indent=1, sort_keys=True) + "\n")
    print(f"{len(digests)} sessions of {args.template!r} in {time.perf_counter() - t0:.1f} s "
          f"-> {args.output}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
