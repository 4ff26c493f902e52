"""``tactorbelt power`` for a factorial study: a 4 x 2 design (12, 24, 36, 48 targets x
static, dynamic, 3 repetitions), 4 study sizes (4, 8, 12, 16) x 500 simulated studies,
the effect "dynamic vs static at 36", on 2 worker processes (goal: under 60 s).

Runs :func:`tactorbelt.power.study.run_power_study` as the command does (writing power.csv,
power.json, power.png to a temporary directory). Baseline, in the same run: the paper
protocol's power (4 x 500 studies of its 240-trial sessions) with the same sizes and
jobs, what ``tactorbelt power`` does by default.

Prints one JSON object: factorial_power_s, paper_power_s (baseline),
factorial_power_participants_per_s (simulated participants per second).
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

from tactorbelt.experiment.study import Study, paper_study, template_toml
from tactorbelt.power.study import run_power_study

SIZES = (4, 8, 12, 16)
SIMS = 500
JOBS = 2


def main() -> None:
    study = Study.from_toml(template_toml("resolution")
                            .replace("repetitions = 2  ", "repetitions = 3  "))
    out: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        res = run_power_study(study, SIZES, SIMS, 1, Path(tmp) / "f", jobs=JOBS,
                              effect="dynamic vs static at 36")
        out["factorial_power_s"] = time.perf_counter() - t0
        assert len(res.rows) == len(SIZES)
        t0 = time.perf_counter()
        run_power_study(paper_study(), SIZES, SIMS, 1, Path(tmp) / "p", jobs=JOBS)
        out["paper_power_s"] = time.perf_counter() - t0
    out["factorial_power_participants_per_s"] = SIMS * sum(SIZES) / out["factorial_power_s"]
    out["factorial_power_at_8"] = res.rows[1].power
    print(json.dumps({k: round(v, 4) for k, v in out.items()}))


if __name__ == "__main__":
    main()
