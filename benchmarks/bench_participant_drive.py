"""What drive shaping changes for the model participant: accuracy and response time on the
paper study, plain against shaped (docs/participant-model.md, "What drive shaping changes").

Runs the paper study's model sessions (seeds 1..N, the same schedules and observers) on the
sim belt with the study's ``[stimulus] drive`` plain, shaped within the motor's maximum
voltage (3.6 V, k = 1.2) and shaped with a 5 V kick (``sim?supply_v=5&kick_ms=40``,
k = 1.67), and prints one markdown row each over the test trials: accuracy and median
response time by condition, between-tactor accuracy, and the CPU seconds of the sessions.
Its last line is one JSON object (``make bench``): ``participant_<drive>_<condition>_accuracy``
and ``participant_<drive>_cpu_s`` for the drives ``plain``, ``shaped`` (3.6 V) and ``kick``.

    python benchmarks/bench_participant_drive.py [--participants 12]
"""

from __future__ import annotations

import argparse
import json
import statistics
import tempfile
import time
from pathlib import Path

#: (name, belt URL, drive, key in the JSON)
DRIVES = (("plain", "sim", "plain", "plain"), ("shaped 3.6 V", "sim", "shaped", "shaped"),
          ("shaped 5 V kick", "sim?supply_v=5&kick_ms=40", "shaped", "kick"))


def run(url: str, drive: str, seeds: list[int]) -> tuple[list[object], float]:
    from tactorbelt import open_belt
    from tactorbelt.clock import SimClock
    from tactorbelt.experiment.runner import run_session
    from tactorbelt.experiment.store import Store
    from tactorbelt.experiment.study import paper_study
    from tactorbelt.inputs.model import make_model_cursor

    st = paper_study()
    st = st.model_copy(update={"stimulus": st.stimulus.model_copy(update={"drive": drive})})
    results: list[object] = []
    cpu = time.process_time()
    with tempfile.TemporaryDirectory() as d, Store.open(Path(d) / "s.sqlite") as store:
        for n in seeds:
            clock = SimClock()
            with open_belt(url, clock=clock, layout=st.layout_obj()) as belt:
                res = run_session(st, f"model-{n:04d}", belt, make_model_cursor(
                    belt, clock, seed=n), store, clock, seed=n)
            assert res.status == "complete", res.status
            results += [r for r in res.results if r.trial.block != "training"]
    return results, time.process_time() - cpu


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--participants", type=int, default=12)
    a = ap.parse_args()
    seeds = list(range(1, a.participants + 1))
    print("| drive | static accuracy | static between-tactor | dynamic accuracy | dynamic "
          "between-tactor | static median RT (s) | dynamic median RT (s) | CPU s |")
    print("|---|---|---|---|---|---|---|---|")
    figures: dict[str, float] = {}
    for name, url, drive, key in DRIVES:
        rs, cpu = run(url, drive, seeds)
        row = [name]
        for cond in ("static", "dynamic"):
            c = [r for r in rs if r.trial.condition == cond and r.status == "done"]  # type: ignore[attr-defined]
            b = [r for r in c if not r.trial.on_tactor]  # type: ignore[attr-defined]
            acc = statistics.mean(r.correct for r in c)  # type: ignore[attr-defined]
            figures[f"participant_{key}_{cond}_accuracy"] = round(acc, 4)
            row += [f"{acc:.3f}",
                    f"{statistics.mean(r.correct for r in b):.3f}"]  # type: ignore[attr-defined]
        for cond in ("static", "dynamic"):
            rt = [r.rt_s for r in rs if r.trial.condition == cond and r.rt_s is not None]  # type: ignore[attr-defined]
            row.append(f"{statistics.median(rt):.2f}")
        row.append(f"{cpu:.1f}")
        figures[f"participant_{key}_cpu_s"] = round(cpu, 2)
        print("| " + " | ".join(row) + " |", flush=True)
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
