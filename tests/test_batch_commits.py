"""Batched store commits: only a session with nothing real involved batches, its stored
results are those of a session committing every trial, and the store says which it was."""

from __future__ import annotations

import sqlite3
from pathlib import Path
from typing import Any

from support.studies import study_toml
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.experiment import provenance
from tactorbelt.experiment.listeners import NullObserver
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.schedule import make_schedule
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import Study
from tactorbelt.inputs.model import ModelCursor, make_model_cursor

STUDY = Study.from_toml(study_toml(
    minimal=True, name="batch", tactors=6, targets=8, max_presentation_s=2.0, timeout_s=3.0,
    iti_s=0.3, break_every=0, training=2, training_conditions=["static"], repetitions=2))

#: Columns that differ between two runs of the same session (ids, wall-clock stamps).
VOLATILE = {"trial_id", "session_id", "recorded_at"}


class PersonCursor(ModelCursor):
    """The model participant, but declared as a person (what a joystick declares)."""

    person = True


def _run(path: Path, *, person: bool = False, observer: Any = None,
         seen: list[tuple[int, int]] | None = None) -> tuple[list[dict[str, Any]], list[Any],
                                                              str, str]:
    clock = SimClock()
    with Store.open(path) as store, open_belt("sim", clock=clock,
                                              layout=STUDY.layout_obj()) as belt:
        cursor = make_model_cursor(belt, clock, seed=7)
        if person:
            cursor.__class__ = PersonCursor

        def progress(done: int, total: int) -> None:
            # what another process (or a crash) would find on disk now
            if seen is not None:
                with sqlite3.connect(path) as other:
                    seen.append((done, other.execute("SELECT count(*) FROM trials")
                                 .fetchone()[0]))

        res = run_session(STUDY, "model-07", belt, cursor, store, clock, seed=3,
                          observer=observer, progress=progress)
        assert res.status == "complete"
        trials = [{k: v for k, v in r.items() if k not in VOLATILE}
                  for r in store.trials(res.session_id)]
        samples = [store.samples(r["trial_id"]) for r in store.trials(res.session_id)]
        return trials, samples, store.commit_mode(res.session_id), \
            store.session(res.session_id)["clock"]


def test_batched_and_per_trial_commits_store_the_same_trials(tmp_path: Path) -> None:
    fast = _run(tmp_path / "fast.sqlite")
    slow = _run(tmp_path / "slow.sqlite", person=True)
    assert fast[2] == provenance.COMMITS_BATCHED
    assert slow[2] == provenance.COMMITS_PER_TRIAL
    assert len(fast[0]) == len(make_schedule(STUDY, "model-07", 3)) and fast[0] == slow[0]
    assert fast[1] == slow[1] and all(fast[1])
    assert fast[3] == slow[3] == "sim"


def test_a_person_commits_every_trial_and_the_model_batches(tmp_path: Path) -> None:
    seen: list[tuple[int, int]] = []
    _run(tmp_path / "person.sqlite", person=True, seen=seen)
    assert seen and all(done == on_disk for done, on_disk in seen)
    seen.clear()
    _run(tmp_path / "window.sqlite", observer=NullObserver(), seen=seen)  # someone watching
    assert seen and all(done == on_disk for done, on_disk in seen)
    seen.clear()
    _, _, mode, _ = _run(tmp_path / "model.sqlite", seen=seen)
    assert mode == provenance.COMMITS_BATCHED
    # fewer trials than a batch: none on disk until the session ends; all of them after
    assert len(seen) < provenance.BATCH_TRIALS and all(n == 0 for _, n in seen)
    with Store.open(tmp_path / "model.sqlite", readonly=True) as store:
        assert len(store.trials()) == len(seen)


def test_a_batch_commits_without_fsync_and_durability_returns_after_it(
        tmp_path: Path) -> None:
    """Inside a batch SQLite syncs only at checkpoints (synchronous=NORMAL, 1), keeps
    its savepoints' pages in memory (temp_store=MEMORY, 2) and looks up no foreign key
    per row (foreign_keys 0); before and after it, and in a session with a person, every
    commit is synced (FULL, 2), temporary data may go to disk (DEFAULT, 0) and every
    foreign key is checked (1)."""
    def settings(store: Store) -> tuple[int, int, int]:
        return (store.conn.execute("PRAGMA synchronous").fetchone()[0],
                store.conn.execute("PRAGMA temp_store").fetchone()[0],
                store.conn.execute("PRAGMA foreign_keys").fetchone()[0])

    for person, during in ((False, {(1, 2, 0)}), (True, {(2, 0, 1)})):
        seen: list[tuple[int, int]] = []
        clock = SimClock()
        with Store.open(tmp_path / f"s{person}.sqlite") as store, open_belt(
                "sim", clock=clock, layout=STUDY.layout_obj()) as belt:
            assert settings(store) == (2, 0, 1)
            cursor = make_model_cursor(belt, clock, seed=7)
            if person:
                cursor.__class__ = PersonCursor
            run_session(STUDY, "model-07", belt, cursor, store, clock, seed=3,
                        progress=lambda done, total, store=store, seen=seen: seen.append(
                            settings(store)))
            assert seen and set(seen) == during
            assert settings(store) == (2, 0, 1)
            # what the batch wrote unchecked references what exists
            assert store.conn.execute("PRAGMA foreign_key_check").fetchall() == []
            assert store.conn.execute("SELECT count(*) FROM samples").fetchone()[0] > 0


def test_the_rule_batches_only_when_nothing_real_is_involved() -> None:
    rule = provenance.commit_mode
    assert rule(simulated_clock=True, hardware_belt=False, person=False,
                observer=False) == provenance.COMMITS_BATCHED
    for real in ("simulated_clock", "hardware_belt", "person", "observer"):
        kw = dict(simulated_clock=True, hardware_belt=False, person=False, observer=False)
        kw[real] = not kw[real]
        assert rule(**kw) == provenance.COMMITS_PER_TRIAL, real


def test_belts_and_cursors_declare_what_is_real() -> None:
    clock = SimClock()
    with open_belt("sim", clock=clock) as belt:
        assert belt.hardware is False
        assert make_model_cursor(belt, clock, seed=1).person is False
    from tactorbelt.inputs.base import CursorSource

    assert CursorSource.person is True
