"""Secondary-task and NASA-TLX analysis (analysis/tables/tasks.py) on hand-made rows."""

from __future__ import annotations

from typing import Any

import pytest

from tactorbelt.analysis.tables.tasks import (
    TLX_ITEMS,
    d_prime,
    dual_task_cost,
    secondary_task_rows,
    secondary_task_summary,
    tlx_rows,
    tlx_summary,
)


def test_d_prime_matches_a_hand_computation() -> None:
    # 8 hits, 2 misses, 3 false alarms, 17 correct rejections:
    # H = 8.5/11 = 0.77273 -> z = 0.74807; F = 3.5/21 = 0.16667 -> z = -0.96742
    assert d_prime(8, 2, 3, 17) == pytest.approx(1.71528, abs=1e-5)
    # perfect performance stays finite (log-linear correction): H = 10.5/11, F = 0.5/21
    assert d_prime(10, 0, 0, 20) == pytest.approx(3.67137, abs=1e-5)
    assert d_prime(5, 5, 10, 10) == pytest.approx(0.0, abs=1e-12)


def _event(pid: str, phase: str, k: int, target: bool, press: bool, rt: float | None = None,
           task: str = "nback2", block: int = 0) -> dict[str, Any]:
    return {"participant": pid, "session_id": 1, "block_index": block, "task": task,
            "phase": phase, "item_index": k, "t_ns": k * 2_500_000_000, "stimulus": "B",
            "target": int(target), "response": "press" if press else "",
            "correct": int(target == press), "rt_s": rt if press else None}


def _stream(pid: str, phase: str, hits: int, misses: int, fa: int, cr: int,
            rts: list[float], extra: int = 0, block: int = 0) -> list[dict[str, Any]]:
    ev = []
    k = 0
    for i in range(hits):
        ev.append(_event(pid, phase, k, True, True, rts[i], block=block))
        k += 1
    for _ in range(misses):
        ev.append(_event(pid, phase, k, True, False, block=block))
        k += 1
    for _ in range(fa):
        ev.append(_event(pid, phase, k, False, True, 0.9, block=block))
        k += 1
    for _ in range(cr):
        ev.append(_event(pid, phase, k, False, False, block=block))
        k += 1
    for _ in range(extra):  # a second press on an item: its own row, item_index -1
        e = _event(pid, phase, -1, False, True, block=block)
        e.update(stimulus=None, rt_s=None, correct=0)
        ev.append(e)
    return ev


def test_rows_count_hits_misses_false_alarms_and_extra_presses() -> None:
    ev = _stream("p1", "dual", 8, 2, 3, 17, [0.5, 0.6, 0.7, 0.8, 0.4, 0.9, 1.0, 0.55], extra=2)
    (row,) = secondary_task_rows(ev)
    assert (row["participant"], row["task"], row["phase"]) == ("p1", "nback2", "dual")
    assert (row["hits"], row["misses"], row["false_alarms"], row["correct_rejections"]) == (
        8, 2, 3, 17)
    assert row["extra_presses"] == 2 and row["items"] == 30
    assert row["hit_rate"] == pytest.approx(0.8) and row["fa_rate"] == pytest.approx(0.15)
    assert row["accuracy"] == pytest.approx(25 / 30)
    assert row["d_prime"] == pytest.approx(1.71528, abs=1e-5)
    assert row["median_rt_s"] == pytest.approx(0.65)  # of the hits only


def test_rows_split_by_phase_and_block() -> None:
    ev = (_stream("p1", "practice", 5, 0, 0, 7, [0.5] * 5)
          + _stream("p1", "dual", 3, 2, 1, 6, [0.7] * 3, block=2)
          + _stream("p1", "dual", 4, 1, 0, 7, [0.6] * 4, block=5))
    rows = secondary_task_rows(ev)
    assert [r["phase"] for r in rows] == ["practice", "dual"]
    assert rows[1]["hits"] == 7
    blocks = secondary_task_rows(ev, by_block=True)
    assert [(r["phase"], r["block_index"], r["hits"]) for r in blocks] == [
        ("practice", 0, 5), ("dual", 2, 3), ("dual", 5, 4)]


def test_dual_task_cost_pairs_baseline_and_dual_within_participant() -> None:
    ev = []
    for pid, (bh, dh) in {"p1": (9, 6), "p2": (8, 5), "p3": (9, 7)}.items():
        ev += _stream(pid, "baseline", bh, 10 - bh, 1, 19, [0.5] * bh)
        ev += _stream(pid, "dual", dh, 10 - dh, 2, 18, [0.6] * dh)
    ev += _stream("p4", "dual", 5, 5, 2, 18, [0.6] * 5)  # no baseline: left out
    rows = secondary_task_rows(ev)
    (cost,) = dual_task_cost(rows)
    assert cost["task"] == "nback2" and cost["n_participants"] == 3
    p1 = cost["participants"][0]
    assert p1["participant"] == "p1"
    assert p1["d_prime_baseline"] == pytest.approx(d_prime(9, 1, 1, 19))
    assert p1["d_prime_cost"] == pytest.approx(d_prime(9, 1, 1, 19) - d_prime(6, 4, 2, 18))
    assert p1["accuracy_cost"] == pytest.approx(28 / 30 - 24 / 30)
    assert cost["mean_d_prime_cost"] > 0
    assert cost["d_prime_test"]["computed"]
    assert cost["d_prime_test"]["p_value"] == pytest.approx(0.25)  # exact: 2/2^3
    summ = secondary_task_summary(rows)
    assert [(s["phase"], s["n_participants"]) for s in summ] == [("baseline", 3), ("dual", 4)]


def _ratings(pid: str, session: int, block: int, load: str, values: list[float],
             condition: str = "static") -> list[dict[str, Any]]:
    return [{"participant": pid, "session_id": session, "block_index": block,
             "scale": "nasa_tlx", "item": item, "value": v, "load": load,
             "condition": condition} for item, v in zip(TLX_ITEMS, values, strict=True)]


def test_raw_tlx_is_the_mean_of_the_six_items_and_is_tested_across_load() -> None:
    r: list[dict[str, Any]] = []
    for i, pid in enumerate(["p1", "p2", "p3", "p4", "p5", "p6"]):
        r += _ratings(pid, i, 0, "none", [20, 10, 20, 20, 30, 10])
        r += _ratings(pid, i, 1, "nback2", [60 + i, 15, 50, 40, 60, 40], "dynamic")
        r += _ratings(pid, i, 2, "nback2", [70, 15, 50, 40, 60, 40])
    r += _ratings("p7", 9, 0, "none", [20, 10, 20, 20, 30, 10])[:5]  # incomplete: dropped
    unknown = _ratings("p8", 9, 0, "none", [20, 10, 20, 20, 30, 10])
    r += [{**x, "load": None} for x in unknown]  # its block has no stored trial: dropped
    rows = tlx_rows(r)
    assert len(rows) == 18
    assert rows[0]["raw_tlx"] == pytest.approx(110 / 6)
    s = tlx_summary(rows)
    assert s["loads"] == ["none", "nback2"]
    p1 = {x["load"]: x["raw_tlx"] for x in s["per_participant"] if x["participant"] == "p1"}
    assert p1["nback2"] == pytest.approx((265 / 6 + 275 / 6) / 2)
    assert s["by_load"][0]["mean_raw_tlx"] == pytest.approx(110 / 6)
    t = s["test"]
    assert t["computed"] and t["test"].startswith("Wilcoxon") and t["n_participants"] == 6
    assert t["p_value"] == pytest.approx(2 / 2**6)  # all six higher under load: exact
    conds = {(c["condition"], c["load"]) for c in s["by_condition_load"]}
    assert conds == {("static", "none"), ("static", "nback2"), ("dynamic", "nback2")}


def test_three_load_levels_use_friedman() -> None:
    r: list[dict[str, Any]] = []
    for i, pid in enumerate(["p1", "p2", "p3", "p4"]):
        r += _ratings(pid, i, 0, "none", [20] * 6)
        r += _ratings(pid, i, 1, "nback1", [40 + i] * 6)
        r += _ratings(pid, i, 2, "nback3", [70] * 6)
    s = tlx_summary(tlx_rows(r))
    assert s["loads"] == ["none", "nback1", "nback3"]
    assert s["test"]["test"] == "Friedman" and s["test"]["computed"]
    # every participant ranks none < nback1 < nback3: chi2 = n(k-1) = 8
    assert s["test"]["statistic"] == pytest.approx(8.0)
    assert s["test"]["p_value"] == pytest.approx(0.0183156, abs=1e-6)


def test_no_ratings_give_an_empty_summary() -> None:
    s = tlx_summary(tlx_rows([]))
    assert s["n_blocks"] == 0 and s["test"] is None
