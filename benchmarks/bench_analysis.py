"""Benchmark: analysis of 1,000 participants x 240 trials with their 100 Hz samples.

Writes a synthetic store (tests/support/synthetic.py, executemany; ~36 M sample
rows, ~1.7 GB; participants and targets differ as in a real study: SDs 0.5, 0.3 and
0.3 log-odds for the participant intercept, condition slope and target intercept, so
the mixed model is fitted as on real data, not refitted after singular fits of
identical participants) once into a cache directory, then times ``analyze()`` end to end
(load, tables, tests, mixed model, figures, report). The target is under 30 s on 2
cores. Prints one JSON object, e.g. ``{"analyze_1000_s": 12.3, ...}``.

Usage: python benchmarks/bench_analysis.py [--participants 1000] [--cache DIR] [--keep]
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # support.synthetic


def main() -> int:
    os.environ.setdefault("MPLBACKEND", "Agg")
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=1000)
    ap.add_argument("--cache", type=Path,
                    default=Path(tempfile.gettempdir()) / "tactorbelt-bench-analysis")
    ap.add_argument("--keep", action="store_true", help="keep the store for the next run")
    args = ap.parse_args()

    from support.synthetic import synthesize_store
    from tactorbelt.analysis.report.analyze import analyze

    args.cache.mkdir(parents=True, exist_ok=True)
    db = args.cache / f"store_{args.participants}_varied.sqlite"
    result: dict[str, float | int | str] = {}
    if not db.exists():
        t0 = time.perf_counter()
        tmp = db.with_suffix(".partial")
        tmp.unlink(missing_ok=True)
        counts = synthesize_store(tmp, args.participants, seed=0, participant_sd=0.5,
                                  slope_sd=0.3, target_sd=0.3)
        tmp.rename(db)
        result["write_store_s"] = round(time.perf_counter() - t0, 2)
        result["sample_rows"] = counts["samples"]
    result["store_mb"] = round(db.stat().st_size / 1e6, 1)
    out = Path(tempfile.mkdtemp(prefix="bench-analysis-out-"))
    try:
        t0 = time.perf_counter()
        summary = analyze([db], out, seed=0)
        result[f"analyze_{args.participants}_s"] = round(time.perf_counter() - t0, 2)
        result["trials"] = summary.counts["trials"]
        result["participants"] = summary.counts["participants"]
        result["mixed_model"] = summary.tests[-1].test
        try:
            import resource

            result["max_rss_mb"] = round(
                resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)
        except ImportError:  # pragma: no cover - not on POSIX
            pass
    finally:
        shutil.rmtree(out, ignore_errors=True)
        if not args.keep:
            db.unlink(missing_ok=True)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
