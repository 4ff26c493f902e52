"""Hand-built analysis datasets shared by the analysis tests."""

from __future__ import annotations

from pathlib import Path

from support.synthetic import create_store, insert_session, insert_trials

__all__ = ["HAND_TRIALS", "_rows", "hand_store"]

# One participant. (block, condition, target, on_tactor, response_target, correct, rt, status)
HAND_TRIALS = [
    ("test", "static", 0.0, 0, 0.0, 1, 1.0, "done"),
    ("test", "static", 0.0, 0, 15.0, 0, 1.2, "done"),
    ("test", "static", 15.0, 0, 0.0, 0, 1.4, "done"),
    ("test", "static", 15.0, 0, None, None, None, "timeout"),
    ("test", "static", 30.0, 1, 30.0, 1, 0.8, "done"),
    ("test", "static", 30.0, 1, 30.0, 1, 0.9, "done"),
    ("test", "static", 345.0, 0, 0.0, 0, 1.1, "done"),
    ("test", "static", 0.0, 0, None, None, None, "aborted"),
    ("training", "static", 0.0, 0, 0.0, 1, 0.5, "done"),
    ("test", "dynamic", 0.0, 0, 0.0, 1, 1.5, "done"),
    ("test", "dynamic", 0.0, 0, 0.0, 1, 1.6, "done"),
    ("test", "dynamic", 15.0, 0, 15.0, 1, 1.7, "done"),
    ("test", "dynamic", 15.0, 0, 30.0, 0, 1.8, "done"),
    ("test", "dynamic", 30.0, 1, 30.0, 1, 0.7, "done"),
    ("test", "dynamic", 345.0, 0, 345.0, 1, 1.3, "done"),
    ("test", "dynamic", 345.0, 0, 330.0, 0, 1.9, "done"),
]


def _rows(session_id: int, trials: list[tuple], start: int = 0) -> list[dict]:
    rows = []
    for i, (block, cond, target, on, resp, correct, rt, status) in enumerate(trials):
        rows.append({
            "session_id": session_id, "block": block, "condition": cond, "repetition": 0,
            "trial_index": start + i, "target_deg": target, "on_tactor": on,
            "response_deg": None if resp is None else resp + 2.0,
            "response_target_deg": resp, "correct": correct, "rt_s": rt,
            "onset_ns": 1_000_000_000 * i, "status": status,
        })
    return rows


def hand_store(path: Path, **session: object) -> Path:
    conn = create_store(path, extra_columns=True)
    sid = insert_session(conn, **session)
    insert_trials(conn, _rows(sid, HAND_TRIALS))
    conn.close()
    return path
