"""benchmarks/run.py: `make bench` flags a figure more than 20 % worse than committed."""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from types import ModuleType

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def _bench_module(script: str) -> ModuleType:
    """``benchmarks/<script>.py`` imported (the folder is not a package)."""
    name = f"bench_{script}"
    spec = importlib.util.spec_from_file_location(name, BENCHMARKS / f"{script}.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def _run_module() -> ModuleType:
    return _bench_module("run")


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


def test_an_instruction_count_is_flagged_at_a_few_percent() -> None:
    """A count the machine does not move is flagged at 3 %, not 20 %, and a count of
    sessions beside it is not a performance figure."""
    run = _run_module()
    before = {"session_instructions": 1.0e9, "session_instructions_sessions": 2.0}
    assert run.regressions({"session_instructions": 1.025e9,
                            "session_instructions_sessions": 5.0}, before) == []
    flagged = run.regressions({"session_instructions": 1.04e9,
                               "session_instructions_sessions": 2.0}, before)
    assert [(k, round(w, 3)) for k, _, _, w in flagged] == [("session_instructions", 0.04)]
    assert run.better("session_instructions") == "lower"


def test_the_reference_workloads_time_is_matched_to_each_figures_script() -> None:
    run = _run_module()
    before = {"session_s": 1.0, "render_24_targets_ms": 5.0,
              "speed_ref_bench_sessions_s": 0.040, "speed_ref_bench_render_s": 0.040,
              "speed_ref_workload": run.SPEED_WORKLOAD}
    measured = {"session_s": "bench_sessions", "render_24_targets_ms": "bench_render"}
    now = {"session_s": 1.4, "render_24_targets_ms": 5.0,
           "speed_ref_bench_sessions_s": 0.060, "speed_ref_bench_render_s": 0.030,
           "speed_ref_workload": run.SPEED_WORKLOAD}
    assert run.speed_factors(now, before, measured) == pytest.approx(
        {"session_s": 1.5, "render_24_targets_ms": 0.75})
    # no reference in the committed run, or one of another workload: none shown
    assert run.speed_factors(now, {"session_s": 1.0}, measured) == {}
    assert run.speed_factors(now, {**before, "speed_ref_workload": 1.0}, measured) == {}


def test_every_goal_figure_has_a_direction() -> None:
    run = _run_module()
    for g in run.GOALS:
        if g.op is not None:
            assert run.better(g.key) == ("lower" if g.op == "<=" else "higher"), g.key
    assert run.better("emulator_ping_p99_ms") == "lower"
    assert run.better("fast_participants_per_s") == "higher"


def _sandbox(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> tuple[ModuleType, Path]:
    """run.py pointed at a folder holding one benchmark that leaves a mark when run."""
    run = _run_module()
    marker = tmp_path / "ran"
    (tmp_path / "bench_mark.py").write_text(
        f"from pathlib import Path\nPath({str(marker)!r}).write_text('x')\n"
        "print('{\"session_s\": 9.0}')\n")
    monkeypatch.setattr(run, "HERE", tmp_path)
    return run, marker


def test_help_and_a_wrong_name_run_no_benchmark(tmp_path: Path,
                                                monkeypatch: pytest.MonkeyPatch) -> None:
    run, marker = _sandbox(tmp_path, monkeypatch)
    with pytest.raises(SystemExit) as ok:
        run.main(["--help"])
    assert ok.value.code == 0
    with pytest.raises(SystemExit) as bad:
        run.main(["bench_nope"])
    assert bad.value.code == 2
    assert not marker.exists()
    assert not (tmp_path / "results.json").exists()


def test_report_rewrites_the_table_from_stored_figures_without_measuring(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    run, marker = _sandbox(tmp_path, monkeypatch)
    (tmp_path / "results-full.json").write_text('{"session_s": 0.5, "sessions_1000_s": 130.0}')
    assert run.main(["--full", "--report"]) == 0
    assert not marker.exists()
    text = (tmp_path / "RESULTS-full.md").read_text()
    assert "Rewritten by `run.py --report`" in text
    # the goals table: figure | value | baseline | ratio | goal | met | what limits it
    table = [[c.strip() for c in line.strip("|").split("|")] for line in text.splitlines()
             if line.startswith("| session")]
    rows = {cells[0]: cells for cells in table if len(cells) == 7}
    assert rows["session_s"][1] == "0.5" and rows["session_s"][5] == "yes"
    assert rows["sessions_1000_s"][1] == "130" and rows["sessions_1000_s"][5] == "NO"
    # nothing stored yet: a clear error, not an empty report
    (tmp_path / "results-full.json").unlink()
    assert run.main(["--full", "--report"]) == 2


def test_a_run_stores_the_reference_time_and_shows_it_beside_a_flagged_figure(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    run, marker = _sandbox(tmp_path, monkeypatch)
    # the benchmark gives session_s 9.0; the committed run gave 5.0 with the reference
    # workload at 20 ms during the same script, and it takes 40 ms now
    monkeypatch.setattr(run, "speed_ref", lambda repeats=3: 0.040)
    committed = {"session_s": 5.0, "speed_ref_bench_mark_s": 0.020,
                 "speed_ref_workload": run.SPEED_WORKLOAD}
    monkeypatch.setattr(run, "committed", lambda name: committed)
    assert run.main(["bench_mark"]) == 0
    assert marker.exists()
    stored = json.loads((tmp_path / "results.json").read_text())
    assert stored["session_s"] == 9.0 and stored["speed_ref_bench_mark_s"] == 0.040
    assert stored["speed_ref_workload"] == run.SPEED_WORKLOAD
    text = (tmp_path / "RESULTS.md").read_text()
    assert "took 2.00-2.00 x as long" in text
    # flagged as measured (80 % worse), with the machine's slowdown beside it
    assert "| session_s | 5 | 9 | 80% | 2.00 |" in text
    # a committed run without reference times: flagged, nothing beside it
    committed.pop("speed_ref_bench_mark_s")
    assert run.main(["bench_mark"]) == 0
    text = (tmp_path / "RESULTS.md").read_text()
    assert "hold no reference times of this workload" in text
    assert "| session_s | 5 | 9 | 80% | not measured |" in text


def test_the_machines_speed_is_sampled_while_the_script_runs(
        monkeypatch: pytest.MonkeyPatch) -> None:
    run = _run_module()
    # the runner's thread times the workload before and after the script (fast then);
    # the sampler's thread while it runs (three times slower meanwhile)
    monkeypatch.setattr(run, "speed_ref", lambda repeats=3: (
        1.0 if threading.current_thread() is threading.main_thread() else 3.0))
    with run.SpeedSampler(every=0.005) as speed:
        deadline = time.monotonic() + 30.0
        while len(speed.samples) < 5 and time.monotonic() < deadline:
            time.sleep(0.005)
    assert speed.samples[0] == speed.samples[-1] == 1.0
    assert len(speed.samples) >= 6 and speed.seconds == 3.0


def test_a_slow_spell_mid_run_shows_in_the_tenths_and_not_only_at_the_ends() -> None:
    mod = _bench_module("bench_sessions")
    # two workers of 20 sessions; both slowed to 0.3 s in their 9th-12th sessions
    worker = [0.2] * 8 + [0.3] * 4 + [0.2] * 8
    tenths = mod._tenths([worker, list(worker)])
    assert len(tenths) == 10
    assert tenths[0] == tenths[-1] == 0.2  # the ends, all machine_drift compares, agree
    assert max(tenths) == 0.3 and tenths.index(0.3) == 4  # the 9th-10th sessions
    # as many parts as the shortest worker has sessions; the longer one's last part
    # takes its remainder
    assert mod._tenths([[0.1, 0.3], [0.1, 0.3, 0.5]]) == pytest.approx([0.1, 1.1 / 3])


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_stopping_the_runner_stops_the_benchmark_and_its_workers(
        tmp_path: Path, sig: signal.Signals) -> None:
    # run.py copied beside one benchmark that starts a worker process and waits
    shutil.copy(BENCHMARKS / "run.py", tmp_path / "run.py")
    pids = tmp_path / "pids"
    (tmp_path / "bench_hang.py").write_text(
        "import os, subprocess, sys, time\n"
        "w = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(120)'])\n"
        f"open({str(pids)!r}, 'w').write(f'{{os.getpid()}} {{w.pid}}')\n"
        "time.sleep(120)\n")
    # as from a terminal: Ctrl-C raises KeyboardInterrupt (even where the test's own
    # parent ignores SIGINT)
    start = ("import runpy, signal, sys; signal.signal(signal.SIGINT, "
             "signal.default_int_handler); sys.argv = [sys.argv[1], 'bench_hang']; "
             "runpy.run_path(sys.argv[0], run_name='__main__')")
    runner = subprocess.Popen([sys.executable, "-c", start, str(tmp_path / "run.py")],
                              stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while not (pids.exists() and len(pids.read_text().split()) == 2):
        assert time.monotonic() < deadline and runner.poll() is None
        time.sleep(0.05)
    script, worker = (int(x) for x in pids.read_text().split())
    runner.send_signal(sig)  # to the runner alone, as `kill PID` does
    _, err = runner.communicate(timeout=30)
    assert runner.returncode == (143 if sig == signal.SIGTERM else 130)
    assert "no results were written" in err

    def alive(pid: int) -> bool:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True

    gone = time.monotonic() + 10
    while (alive(script) or alive(worker)) and time.monotonic() < gone:
        time.sleep(0.05)
    assert not alive(script) and not alive(worker)
    assert not (tmp_path / "results.json").exists()  # nothing half-written
