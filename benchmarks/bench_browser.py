"""The browser study in a real browser: timing seen from the page, and a 120-trial session.

``tactorbelt serve`` on the sim belt, the example page (bridge/static/examples/paper.html)
in Debian's headless Chromium driven by Selenium (tests/support/browser.py). A 120-trial
study (12 targets; static and dynamic blocks of 5 repetitions, no training) is answered
by clicks: trial i gets its stimulus' target, except every 4th, which gets the next one.
The same participant's session is then run through the library's runner (what
``tactorbelt run`` does; headless, the sim clock, a scripted cursor giving the page's
answers) into another store, and ``tactorbelt analyze`` reads both.

Prints one JSON object:

- ``browser_clock_uncertainty_ms``: the clock handshake's uncertainty (half the least
  round trip of 16 pings), the largest of the page loads (goal <= 1 ms on loopback);
- ``browser_clock_uncertainty_p50_ms``: its median over the page loads;
- ``browser_play_to_onset_p99_ms``: from the page sending `play` to the belt's onset,
  both on the page's performance.now() clock, p99 over the trials (goal <= 5 ms);
- ``browser_play_to_onset_p50_ms``, ``browser_play_to_reply_p99_ms`` (until the page has
  the reply);
- ``browser_trials_stored``: trials of the 120 in the store, each once (goal: 120);
- ``browser_analysis_equal``: 1 when the analysis of the browser session equals that of
  the same trials through the runner, in every figure that does not depend on response
  times (accuracy, errors, per target and condition, the models); else 0;
- ``browser_session_s``: the browser session's wall time.

Run alone: ``python benchmarks/bench_browser.py`` (about 2 minutes). Without Chromium,
ChromeDriver or selenium it prints ``{}`` and says why on stderr.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

STUDY = """\
name = "bench-browser"
[layout]
tactors = 6
[targets]
count = 12
[stimulus]
max_presentation_s = 10.0
[response]
timeout_s = 10.0
[session]
iti_s = 0.05
break_every = 0
[training]
passes = 0
[[test]]
name = "static"
condition = "static"
repetitions = 5
[[test]]
name = "dynamic"
condition = "dynamic"
repetitions = 5
"""

_CURRENT = """
const b = window.tactorbelt && window.tactorbelt.bridge;
const p = b && b.lastPlay;
if (!p || !p.stimulus) return null;
return {index: p.request.index, target: p.stimulus.target, n: p.stimulus.n_targets};
"""


def answer_for(index: int, target: int, n: int) -> int:
    return target if index % 4 else (target + 1) % n


def browser_session(driver: Any, url: str, timeout: float) -> tuple[dict[str, Any], dict[int, int]]:
    """Answer every trial of the page by clicking; returns the page's record and answers."""
    from selenium.common.exceptions import WebDriverException
    from selenium.webdriver.common.by import By

    from support.browser import page_state

    driver.get(url)
    answers: dict[int, int] = {}
    deadline = time.monotonic() + timeout
    while page_state(driver) not in ("done", "error"):
        if time.monotonic() > deadline:
            raise RuntimeError(f"the page did not finish within {timeout} s")
        if not driver.find_elements(By.CSS_SELECTOR, "[data-target]"):
            time.sleep(0.01)
            continue
        cur = driver.execute_script(_CURRENT)
        if cur is None or cur["index"] is None:
            continue
        k = answer_for(cur["index"], cur["target"], cur["n"])
        with contextlib.suppress(WebDriverException):
            driver.find_element(By.CSS_SELECTOR, f'[data-target="{k}"]').click()
            answers[cur["index"]] = k
    info = driver.execute_script("return {state: window.tactorbelt.state, error: "
                                 "window.tactorbelt.error, data: window.tactorbelt.data,"
                                 " welcome: window.tactorbelt.welcome}")
    if info["state"] != "done":
        raise RuntimeError(f"the page stopped: {info['error']}")
    return info, answers


def handshake(driver: Any, url: str) -> float:
    """A page load up to the welcome: the handshake's uncertainty (ms)."""
    driver.get(url)
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        w = driver.execute_script("return window.tactorbelt && window.tactorbelt.welcome")
        if w:
            driver.get("about:blank")
            return float(w["clock"]["uncertainty_ms"])
        time.sleep(0.02)
    raise RuntimeError("no welcome within 30 s")


def run_through_runner(study_path: Path, db: Path, participant: str,
                       page: dict[int, dict[str, Any]]) -> None:
    """The same participant's session through the runner, answered as on the page."""
    from tactorbelt.clock import SimClock
    from tactorbelt.devices import open_belt
    from tactorbelt.experiment.listeners import NullOperator
    from tactorbelt.experiment.runner import run_session
    from tactorbelt.experiment.store import Store
    from tactorbelt.experiment.study import load_study
    from tactorbelt.inputs.scripted import ScriptedCursor, ScriptedResponse

    study = load_study(study_path)
    responses = {i: ScriptedResponse(answer=r["angle"],
                                     reaction_s=max(r["rt_ms"] / 1000 - 0.3, 0.05),
                                     movement_s=0.3) for i, r in page.items()}
    clock = SimClock()
    with Store.open(str(db)) as store, open_belt("sim", clock=clock,
                                                 layout=study.layout_obj()) as belt:
        run_session(study, participant, belt, ScriptedCursor(responses), store, clock,
                    operator=NullOperator(), study_toml=study_path.read_text(),
                    input_name="scripted")


#: The summary's parts that depend on the answers alone (not on response times, nor on
#: how many sessions the store holds or how they were made).
_COMPARED = ("conditions", "cells", "between_accuracy_test", "tests", "mixed_model",
             "contrasts", "study")
_TRIAL_COUNTS = ("trials", "test_trials", "counted_trials", "done", "timeout", "aborted",
                 "training_trials")


def _timing(key: str) -> bool:
    return bool({"rt", "time", "times"} & set(key.lower().split("_")))


def comparable(summary: dict[str, Any]) -> dict[str, Any]:
    """The analysis' figures that the answers alone decide."""
    def strip(obj: Any) -> Any:
        if isinstance(obj, dict):
            return {k: strip(v) for k, v in obj.items() if not _timing(k)}
        if isinstance(obj, list):
            return [strip(v) for v in obj]
        if isinstance(obj, float):
            return round(obj, 9)
        return obj

    out = {k: strip(summary.get(k)) for k in _COMPARED}
    out["tests"] = [t for t in out["tests"] or []
                    if "response time" not in str(t.get("question", ""))]
    out["counts"] = {k: summary["counts"].get(k) for k in _TRIAL_COUNTS}
    return out


def analyze(db: Path, out: Path) -> dict[str, Any]:
    proc = subprocess.run([sys.executable, "-m", "tactorbelt", "analyze", str(db), "-o",
                           str(out), "--bootstrap-sims", "0"],
                          capture_output=True, text=True, timeout=600)
    if proc.returncode != 0:
        raise RuntimeError(f"analyze failed: {proc.stderr[-1000:]}")
    return dict(json.loads((out / "summary.json").read_text()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--loads", type=int, default=5, help="page loads for the handshake")
    ap.add_argument("--keep", type=Path, default=None, help="keep the stores here")
    args = ap.parse_args()
    from support.browser import browser_missing, chromium, serve, store_rows

    reason = browser_missing()
    if reason is not None:
        print(f"bench_browser: skipped: {reason}", file=sys.stderr)
        print("{}")
        return
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = args.keep or Path(tmp_name)
        tmp.mkdir(parents=True, exist_ok=True)
        study = tmp / "bench-browser.toml"
        study.write_text(STUDY)
        db = tmp / "browser.sqlite"
        with serve(study, db) as bridge, chromium() as driver:
            t0 = time.perf_counter()
            info, answers = browser_session(driver, bridge.page_url("P01", message_ms=50),
                                            timeout=900)
            session_s = time.perf_counter() - t0
            uncertainties = [float(info["welcome"]["clock"]["uncertainty_ms"])]
            # more handshakes: page loads of other participants (sessions with no trial,
            # which the compared parts of the analysis do not count)
            for k in range(args.loads):
                uncertainties.append(handshake(driver, bridge.page_url(f"H{k + 1:02d}")))
        if args.keep:
            (tmp / "page.json").write_text(json.dumps(info, indent=1))
        stimuli = [d for d in info["data"] if d.get("tactorbelt") == "stimulus"]
        responses = {d["index"]: d for d in info["data"] if d.get("tactorbelt") == "response"}
        to_onset = np.array([s["onset_ms"] - s["request_ms"] for s in stimuli])
        to_reply = np.array([s["reply_ms"] - s["request_ms"] for s in stimuli])
        session, trials = store_rows(db, "P01")
        indices = [t["trial_index"] for t in trials]
        stored = len(set(indices)) if len(indices) == len(set(indices)) else 0

        n = 12
        page = {i: {"angle": responses[i]["response"] * 360.0 / n,
                    "rt_ms": responses[i]["rt_ms"]} for i in responses}
        lab = tmp / "run.sqlite"
        run_through_runner(study, lab, "P01", page)
        lab_session, lab_trials = store_rows(lab, "P01")
        same_schedule = session["schedule_json"] == lab_session["schedule_json"]
        same_answers = [(t["trial_index"], t["response_target_deg"], t["correct"])
                        for t in trials] == [(t["trial_index"], t["response_target_deg"],
                                              t["correct"]) for t in lab_trials]
        a = comparable(analyze(db, tmp / "analysis-browser"))
        b = comparable(analyze(lab, tmp / "analysis-run"))
        equal = same_schedule and same_answers and a == b
        if not equal:
            diff = sorted(k for k in a if a[k] != b[k])
            print(f"bench_browser: schedule equal {same_schedule}, answers equal "
                  f"{same_answers}, summary keys that differ: {diff}", file=sys.stderr)
        print(json.dumps({
            "browser_clock_uncertainty_ms": max(uncertainties),
            "browser_clock_uncertainty_p50_ms": float(np.median(uncertainties)),
            "browser_play_to_onset_p99_ms": float(np.percentile(to_onset, 99)),
            "browser_play_to_onset_p50_ms": float(np.percentile(to_onset, 50)),
            "browser_play_to_reply_p99_ms": float(np.percentile(to_reply, 99)),
            "browser_trials_stored": stored,
            "browser_analysis_equal": 1 if equal else 0,
            "browser_session_s": session_s,
        }))


if __name__ == "__main__":
    main()
