"""Secondary tasks and workload ratings: signal detection, dual-task cost, raw NASA-TLX.

Works on plain rows (dicts) with the columns of the store's ``task_events`` and
``ratings`` tables (docs/conventions.md, "Data store"), each with the session's
``participant`` added (and, for ratings, the block's ``load`` and ``condition``):

- :func:`d_prime`: sensitivity with the log-linear correction (Hautus 1995):
  ``H = (hits + 0.5) / (go + 1)``, ``F = (fa + 0.5) / (nogo + 1)``,
  ``d' = z(H) - z(F)``;
- :func:`secondary_task_rows`: per (participant, task, phase) the hits, misses, false
  alarms, correct rejections, rates, d', median RT of the hits and extra presses;
- :func:`dual_task_cost`: per participant and task, baseline (task alone) minus dual
  (task with localisation) accuracy and d', with a paired signed-rank test across
  participants;
- :func:`tlx_rows`, :func:`tlx_summary`: raw TLX (the mean of the six items) per
  rated block, per participant x load, and the within-participant test across load
  levels (Wilcoxon signed-rank with two levels, Friedman with more).

Pure: the standard library, NumPy and SciPy (statistics), analysis.tables.classical and the
constants of tactorbelt.tasks.
"""

from __future__ import annotations

import math
import statistics
from collections import Counter, defaultdict
from collections.abc import Iterable, Mapping, Sequence
from typing import Any

import numpy as np
from scipy.stats import friedmanchisquare, norm

from ...tasks import PHASES, TLX_ITEMS
from ._json import finite_float as _num
from .classical import signed_rank_test

__all__ = [
    "TLX_ITEMS",
    "d_prime",
    "dual_task_cost",
    "secondary_task_rows",
    "secondary_task_summary",
    "secondary_tasks_json",
    "tlx_rows",
    "tlx_summary",
]

def d_prime(hits: int, misses: int, false_alarms: int, correct_rejections: int) -> float:
    """d' with the log-linear correction (Hautus 1995), finite for any counts.

    ``H = (hits + 0.5) / (hits + misses + 1)``, ``F = (fa + 0.5) / (fa + cr + 1)``,
    ``d' = Phi^-1(H) - Phi^-1(F)``.
    """
    h = (hits + 0.5) / (hits + misses + 1.0)
    f = (false_alarms + 0.5) / (false_alarms + correct_rejections + 1.0)
    return float(norm.ppf(h)) - float(norm.ppf(f))


def _truthy(v: Any) -> bool:
    if isinstance(v, str):
        return v.strip().lower() in ("1", "true", "t", "yes")
    return bool(v) and not (isinstance(v, float) and math.isnan(v))


def _counts(events: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    n: Counter[tuple[bool, bool]] = Counter()  # items by (a target, pressed)
    extra = 0
    rts: list[float] = []
    for e in events:
        if int(e["item_index"]) < 0:
            extra += 1
            continue
        target = _truthy(e["target"])
        pressed = isinstance(e["response"], str) and e["response"].strip().lower() == "press"
        n[target, pressed] += 1
        if target and pressed and (rt := _num(e.get("rt_s"))) is not None:
            rts.append(rt)
    hits, misses, fa, cr = n[True, True], n[True, False], n[False, True], n[False, False]
    go, nogo = hits + misses, fa + cr
    items = go + nogo
    return {
        "items": items, "hits": hits, "misses": misses, "false_alarms": fa,
        "correct_rejections": cr, "extra_presses": extra,
        "hit_rate": hits / go if go else None,
        "fa_rate": fa / nogo if nogo else None,
        "accuracy": (hits + cr) / items if items else None,
        "d_prime": d_prime(hits, misses, fa, cr) if items else None,
        "median_rt_s": statistics.median(rts) if rts else None,
    }


def _phase_key(phase: str) -> int:
    return PHASES.index(phase) if phase in PHASES else len(PHASES)


def secondary_task_rows(events: Iterable[Mapping[str, Any]], *, by_block: bool = False
                        ) -> list[dict[str, Any]]:
    """Signal-detection counts per (participant, task, phase) (and block, if ``by_block``).

    Each event row needs ``participant, task, phase, item_index, target, response,
    rt_s`` (and ``block_index`` with ``by_block``). Item rows count as hit (go item,
    press), miss (go item, no press), false alarm (no-go item, press) or correct
    rejection; rows of extra presses (``item_index`` -1) count as ``extra_presses``.
    ``median_rt_s`` is the median RT of the hits; ``d_prime`` is :func:`d_prime`.
    """
    groups: dict[tuple[Any, ...], list[Mapping[str, Any]]] = defaultdict(list)
    for e in events:
        key: tuple[Any, ...] = (str(e["participant"]), str(e["task"]), str(e["phase"]))
        if by_block:
            key += (int(e["block_index"]),)
        groups[key].append(e)
    out = []
    for key in sorted(groups, key=lambda k: (k[0], k[1], _phase_key(k[2]), *k[3:])):
        row: dict[str, Any] = {"participant": key[0], "task": key[1], "phase": key[2]}
        if by_block:
            row["block_index"] = key[3]
        row.update(_counts(groups[key]))
        out.append(row)
    return out


def _mean(xs: Iterable[float | None]) -> float | None:
    v = [x for x in xs if x is not None]
    return sum(v) / len(v) if v else None


def secondary_task_summary(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Per (task, phase): participants, items, and the mean over participants of the hit
    rate, false-alarm rate, accuracy, d' and median RT (rows of
    :func:`secondary_task_rows`)."""
    groups: dict[tuple[str, str], list[Mapping[str, Any]]] = defaultdict(list)
    for r in rows:
        groups[(str(r["task"]), str(r["phase"]))].append(r)
    out = []
    for task, phase in sorted(groups, key=lambda k: (k[0], _phase_key(k[1]))):
        g = groups[(task, phase)]
        out.append({
            "task": task, "phase": phase, "n_participants": len({r["participant"] for r in g}),
            "items": sum(int(r["items"]) for r in g),
            **{f"mean_{k}": _mean(r[k] for r in g)
               for k in ("hit_rate", "fa_rate", "accuracy", "d_prime", "median_rt_s")},
        })
    return out


def _paired(diffs: Sequence[float]) -> dict[str, Any]:
    d = np.asarray(diffs, dtype=float)
    if d.size < 2 or not np.any(d != 0):
        return {"test": "Wilcoxon signed-rank (two-sided)", "computed": False,
                "reason": "fewer than 2 participants or no non-zero difference",
                "statistic": None, "p_value": None}
    w, p, method = signed_rank_test(d)
    return {"test": "Wilcoxon signed-rank (two-sided)", "computed": True, "method": method,
            "statistic": w, "p_value": p}


def dual_task_cost(rows: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The dual-task cost per task: baseline (alone) minus dual (with localisation).

    From rows of :func:`secondary_task_rows` (per participant, task, phase). Only
    participants with both a ``baseline`` and a ``dual`` row of the task count (paired
    within participant). Returns one object per task with ``participants`` (each
    participant's accuracy and d' in both phases and their differences), the mean
    differences, and a Wilcoxon signed-rank test of the d' differences.
    """
    by: dict[tuple[str, str], dict[str, Mapping[str, Any]]] = defaultdict(dict)
    for r in rows:
        by[(str(r["task"]), str(r["participant"]))][str(r["phase"])] = r
    tasks: dict[str, list[dict[str, Any]]] = defaultdict(list)
    for (task, pid), phases in sorted(by.items()):
        b, d = phases.get("baseline"), phases.get("dual")
        if b is None or d is None or b["d_prime"] is None or d["d_prime"] is None:
            continue
        tasks[task].append({
            "participant": pid,
            "accuracy_baseline": b["accuracy"], "accuracy_dual": d["accuracy"],
            "accuracy_cost": float(b["accuracy"]) - float(d["accuracy"]),
            "d_prime_baseline": b["d_prime"], "d_prime_dual": d["d_prime"],
            "d_prime_cost": float(b["d_prime"]) - float(d["d_prime"]),
        })
    out = []
    for task, parts in sorted(tasks.items()):
        out.append({
            "task": task, "n_participants": len(parts),
            "mean_accuracy_cost": _mean(p["accuracy_cost"] for p in parts),
            "mean_d_prime_cost": _mean(p["d_prime_cost"] for p in parts),
            "d_prime_test": _paired([p["d_prime_cost"] for p in parts]),
            "participants": parts,
        })
    return out


def tlx_rows(ratings: Iterable[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """Raw TLX per rated block: the mean of the six items.

    Each rating row needs ``participant, session_id, block_index, scale, item, value``
    plus the block's ``load`` and ``condition`` (and optionally ``n_targets``). Rows of
    other scales are ignored; a block missing an item is left out (raw TLX needs all
    six), and so is a block whose ``load`` is None (no trial of it was stored, so its
    load is unknown); a row without a ``load`` key counts as ``none``.
    """
    blocks: dict[tuple[str, Any, int], dict[str, Any]] = {}
    for r in ratings:
        if str(r["scale"]) != "nasa_tlx" or ("load" in r and r["load"] is None):
            continue
        key = (str(r["participant"]), r["session_id"], int(r["block_index"]))
        b = blocks.setdefault(key, {
            "participant": key[0], "session_id": key[1], "block_index": key[2],
            "load": str(r.get("load") or "none"), "condition": r.get("condition"),
            "n_targets": r.get("n_targets"), "items": {}})
        b["items"][str(r["item"])] = float(r["value"])
    out = []
    for key in sorted(blocks, key=lambda k: (k[0], str(k[1]), k[2])):
        b = blocks[key]
        items = b.pop("items")
        if not all(i in items for i in TLX_ITEMS):
            continue
        b.update({i: items[i] for i in TLX_ITEMS})
        b["raw_tlx"] = sum(items[i] for i in TLX_ITEMS) / len(TLX_ITEMS)
        out.append(b)
    return out


def _across_load(table: Mapping[str, Mapping[str, float]], loads: Sequence[str]
                 ) -> dict[str, Any]:
    """Within-participant test of raw TLX across ``loads`` (complete participants only)."""
    complete = [pid for pid, by in table.items() if all(lv in by for lv in loads)]
    n = len(complete)
    if len(loads) < 2:
        return {"test": None, "computed": False, "reason": "one load level",
                "n_participants": n, "statistic": None, "p_value": None}
    if len(loads) == 2:
        res = _paired([table[p][loads[1]] - table[p][loads[0]] for p in complete])
        res["test"] = f"Wilcoxon signed-rank (two-sided), {loads[1]} vs {loads[0]}"
        res["n_participants"] = n
        return res
    test = "Friedman"
    if n < 2:
        return {"test": test, "computed": False, "reason": "fewer than 2 participants "
                "rated every load", "n_participants": n, "statistic": None, "p_value": None}
    m = np.array([[table[p][lv] for lv in loads] for p in complete])
    if np.all(m == m[:, :1]):
        return {"test": test, "computed": False, "reason": "no participant's ratings differ "
                "across load", "n_participants": n, "statistic": None, "p_value": None}
    r = friedmanchisquare(*m.T)
    return {"test": test, "computed": True, "n_participants": n,
            "statistic": float(r.statistic), "p_value": float(r.pvalue)}


def load_order(loads: Iterable[str]) -> list[str]:
    """The load levels, ``none`` first."""
    return sorted(set(loads), key=lambda lv: (lv != "none", lv))


def tlx_summary(rows: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """``summary.json["tlx"]`` from rows of :func:`tlx_rows`.

    ``per_participant``: raw TLX per participant x load (mean over that load's blocks);
    ``by_load`` and ``by_condition_load``: means over participants of those; ``test``:
    the within-participant test across load levels (``none`` first).
    """
    if not rows:
        return {"n_blocks": 0, "loads": [], "per_participant": [], "by_load": [],
                "by_condition_load": [], "test": None}
    loads = load_order(str(r["load"]) for r in rows)
    cell: dict[tuple[str, str], list[float]] = defaultdict(list)
    ccell: dict[tuple[str, str, str], list[float]] = defaultdict(list)
    for r in rows:
        cell[(str(r["participant"]), str(r["load"]))].append(float(r["raw_tlx"]))
        ccell[(str(r["participant"]), str(r["condition"]), str(r["load"]))].append(
            float(r["raw_tlx"]))
    table: dict[str, dict[str, float]] = defaultdict(dict)
    for (pid, lv), vs in cell.items():
        table[pid][lv] = sum(vs) / len(vs)
    per = [{"participant": pid, "load": lv, "raw_tlx": table[pid][lv]}
           for pid in sorted(table) for lv in loads if lv in table[pid]]
    by_load = []
    for lv in loads:
        vs = [table[p][lv] for p in table if lv in table[p]]
        by_load.append({"load": lv, "n_participants": len(vs), "mean_raw_tlx": _mean(vs),
                        "sd_raw_tlx": statistics.stdev(vs) if len(vs) > 1 else None})
    by_cond = []
    for cond in sorted({k[1] for k in ccell}):
        for lv in loads:
            vs = [sum(v) / len(v) for k, v in ccell.items() if k[1] == cond and k[2] == lv]
            if vs:
                by_cond.append({"condition": cond, "load": lv, "n_participants": len(vs),
                                "mean_raw_tlx": _mean(vs)})
    return {"n_blocks": len(rows), "loads": loads, "per_participant": per,
            "by_load": by_load, "by_condition_load": by_cond,
            "test": _across_load(table, loads)}


def secondary_tasks_json(events: Sequence[Mapping[str, Any]]) -> dict[str, Any] | None:
    """``summary.json["secondary_tasks"]`` from task-event rows (None without any):
    ``rows`` (per participant, task, phase), ``blocks`` (per participant, task, phase,
    block), ``by_phase`` (:func:`secondary_task_summary`) and ``dual_task_cost``."""
    if not events:
        return None
    rows = secondary_task_rows(events)
    return {
        "d_prime": "log-linear correction (Hautus 1995): H = (hits + 0.5) / (go + 1), "
                   "F = (false alarms + 0.5) / (no-go + 1), d' = z(H) - z(F)",
        "rows": rows,
        "blocks": secondary_task_rows(events, by_block=True),
        "by_phase": secondary_task_summary(rows),
        "dual_task_cost": dual_task_cost(rows),
    }
