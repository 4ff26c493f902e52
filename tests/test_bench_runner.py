"""benchmarks/run.py: `make bench` flags a figure more than 20 % worse than committed."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

RUN = Path(__file__).resolve().parents[1] / "benchmarks" / "run.py"


def _run_module() -> ModuleType:
    spec = importlib.util.spec_from_file_location("bench_run", RUN)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["bench_run"] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def test_a_figure_more_than_20_percent_worse_is_flagged_either_way() -> None:
    run = _run_module()
    before = {"session_s": 1.0, "wire_encode_decode_per_s": 1000.0, "player_p99_ms": 0.1,
              "sessions_per_s": 3.0, "trials": 240.0}
    now = {"session_s": 1.3, "wire_encode_decode_per_s": 700.0, "player_p99_ms": 0.11,
           "sessions_per_s": 5.0, "trials": 10.0, "new_figure_s": 9.0}
    flagged = {k: round(w, 2) for k, _, _, w in run.regressions(now, before)}
    # slower (a time up 30 %) and a rate down 30 % are flagged; 10 % worse, better,
    # counts and figures without a committed value are not
    assert flagged == {"session_s": 0.3, "wire_encode_decode_per_s": 0.3}


def test_every_goal_figure_has_a_direction() -> None:
    run = _run_module()
    for g in run.GOALS:
        if g.op is not None:
            assert run.better(g.key) == ("lower" if g.op == "<=" else "higher"), g.key
    assert run.better("emulator_ping_p99_ms") == "lower"
    assert run.better("fast_participants_per_s") == "higher"
