"""The runner's fast path: a simulated session nobody watches reads the model participant
in runs of ticks, and stores exactly what sampling tick by tick stores."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from support.studies import make_study
from tactorbelt.clock import Deadlines, SimClock
from tactorbelt.devices import open_belt
from tactorbelt.experiment.listeners import NullObserver
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.schedule import ScheduledTrial
from tactorbelt.experiment.store import Store
from tactorbelt.experiment.study import Study
from tactorbelt.experiment.trial import ResponseRule, TrialMachine, TrialState
from tactorbelt.geometry import TargetSet
from tactorbelt.inputs.model import ModelCursor, _Move, make_model_cursor

#: Columns that differ between two runs of the same session (ids, wall-clock stamps).
VOLATILE = {"trial_id", "session_id", "recorded_at"}


class CountingModel(ModelCursor):
    """The model participant, counting how it was read."""

    reads = 0
    runs = 0

    def read(self, now_ns: int):  # type: ignore[no-untyped-def]
        self.reads += 1
        return super().read(now_ns)

    def read_run(self, times_ns, take):  # type: ignore[no-untyped-def]
        self.runs += 1
        return super().read_run(times_ns, take)


def _session(path: Path, study: Study, observer: Any, seed: int = 5
             ) -> tuple[list[dict[str, Any]], list[Any], list[Any], CountingModel]:
    clock = SimClock()
    with Store.open(path) as store, open_belt("sim", clock=clock,
                                              layout=study.layout_obj()) as belt:
        cursor = make_model_cursor(belt, clock, seed=seed)
        cursor.__class__ = CountingModel
        decisions: list[Any] = []
        real_decide = cursor._decide

        def decide(now_ns: int) -> None:
            real_decide(now_ns)
            d = cursor.last_decision
            assert d is not None
            decisions.append((d.trial_index, d.decided_ns, d.answer_deg, d.move_start_ns,
                              clock.now_ns()))

        cursor._decide = decide  # type: ignore[method-assign]
        res = run_session(study, "P05", belt, cursor, store, clock, seed=seed,
                          observer=observer)
        assert res.status == "complete"
        rows = store.trials(res.session_id)
        trials = [{k: v for k, v in r.items() if k not in VOLATILE} for r in rows]
        samples = [store.samples(r["trial_id"]) for r in rows]
        assert isinstance(cursor, CountingModel)
        return trials, samples, decisions, cursor


@pytest.mark.parametrize("keys", [
    {},  # answers in time, the stimulus stops at the answer
    {"dwell_s": 0.05},  # the cursor must stay beyond the threshold
    {"timeout_s": 1.4},  # many answers come too late: timeouts
    {"max_presentation_s": 0.2},  # the stimulus stops before the model decides
], ids=["plain", "dwell", "timeouts", "short-stimulus"])
def test_runs_store_what_tick_by_tick_stores(tmp_path: Path, keys: dict[str, Any]) -> None:
    study = make_study(minimal=True, name="runs", tactors=6, targets=12, iti_s=0.3,
                       break_every=0, training=1, training_conditions=["static"],
                       conditions=["static", "dynamic"], repetitions=1, **keys)
    fast = _session(tmp_path / "fast.sqlite", study, None)
    slow = _session(tmp_path / "slow.sqlite", study, NullObserver())
    assert fast[3].runs > 0 and fast[3].reads <= len(fast[0])  # runs (reads only at home)
    assert slow[3].runs == 0 and slow[3].reads > 10 * len(slow[0])  # tick by tick
    assert fast[0] == slow[0]
    assert fast[1] == slow[1]
    # every decision at the same tick, the clock standing there (it reads the belt)
    assert fast[2] == slow[2] and all(d[1] == d[4] for d in fast[2])
    statuses = {t["status"] for t in fast[0]}
    if "timeout_s" in keys:
        assert statuses == {"done", "timeout"}
    else:
        assert statuses == {"done"}
    if "max_presentation_s" in keys:
        assert all(t["stimulus_off_ns"] - t["onset_ns"] == 200_000_000 for t in fast[0])


@given(start=st.integers(-10**9, 10**9), duration=st.integers(1, 2 * 10**9),
       x=st.tuples(*[st.floats(-1.5, 1.5)] * 4),
       times=st.lists(st.integers(-3 * 10**9, 3 * 10**9), min_size=1, max_size=40))
def test_a_movement_at_many_times_is_bit_for_bit_one_at_a_time(
        start: int, duration: int, x: tuple[float, float, float, float],
        times: list[int]) -> None:
    move = _Move(start, duration, *x)
    xs, ys = move.at_many(np.array(sorted(times), dtype=np.int64))
    assert [(a, b) for a, b in zip(xs.tolist(), ys.tolist(), strict=True)] == \
        [move.at(t) for t in sorted(times)]


def _trial() -> ScheduledTrial:
    return ScheduledTrial(trial_index=0, block="test", block_index=0, block_name="test",
                          condition="static", repetition=1, target_deg=30.0,
                          on_tactor=False)


@given(radii=st.lists(st.floats(0.0, 1.2), min_size=1, max_size=60),
       dwell_ms=st.sampled_from([0, 20, 50]), timeout_ms=st.sampled_from([200, 400, 10_000]),
       cut=st.integers(1, 60))
def test_feeding_a_run_is_feeding_sample_by_sample(radii: list[float], dwell_ms: int,
                                                   timeout_ms: int, cut: int) -> None:
    """Acquisition (with and without dwell), timeout, and the samples kept, whether the
    samples come one by one or in runs cut anywhere."""
    rule = ResponseRule(threshold=0.9, dwell_ns=dwell_ms * 10**6,
                        timeout_ns=timeout_ms * 10**6)
    onset = 10**9
    t = onset + 10_000_000 * np.arange(len(radii), dtype=np.int64)
    ang = np.radians(np.arange(len(radii)) * 37.0)
    x, y = np.array(radii) * np.sin(ang), np.array(radii) * np.cos(ang)
    one = TrialMachine(_trial(), rule, TargetSet.even(12))
    one.start(onset)
    for i in range(len(radii)):
        if one.feed(int(t[i]), float(x[i]), float(y[i])) is not TrialState.STIMULUS:
            break
    runs = TrialMachine(_trial(), rule, TargetSet.even(12))
    runs.start(onset)
    i = 0
    while i < len(radii) and runs.state is TrialState.STIMULUS:
        j = min(i + cut, len(radii))
        used = runs.feed_run(t[i:j], x[i:j], y[i:j])
        assert 1 <= used <= j - i
        i += used
    assert runs.state is one.state
    assert runs.result == one.result
    # the times from the onset (converted run by run) are those of the samples one by one
    got, expected = runs.result.sample_times_s(), one.result.sample_times_s()
    assert got == expected and all(type(v) is float for v in got)
    assert runs.result.sample_times_s() == expected  # again (converted anew once handed over)


@pytest.mark.parametrize("onset", [0, -2**62, 2**62])
def test_a_run_far_from_its_onset_keeps_the_exact_times(onset: int) -> None:
    """Times more than 2**53 ns from the onset have no exact float difference: they are
    converted from the exact integer difference, as sample by sample."""
    rule = ResponseRule(threshold=0.9, dwell_ns=0, timeout_ns=2**63 - 1 - abs(onset))
    machine = TrialMachine(_trial(), rule, TargetSet.even(12))
    machine.start(onset)
    t = np.array([onset + 1, onset + 2**53 + 3, onset + 2**60 + 7], dtype=np.int64)
    if onset > 0:
        t = np.array([onset + 1, onset + 5, onset + 2**40], dtype=np.int64)
    assert machine.feed_run(t, np.zeros(3), np.zeros(3)) == 3
    assert machine.result.sample_times_s() == [(int(v) - onset) / 1e9 for v in t]


@given(rate=st.sampled_from([100.0, 1000.0, 60.0, 144.0, 30.0]),
       onset=st.integers(-10**15, 10**15), first=st.integers(0, 10**6), n=st.integers(0, 300))
def test_deadlines_in_bulk_are_the_deadlines(rate: float, onset: int, first: int,
                                             n: int) -> None:
    ticks = Deadlines(SimClock(), rate, onset)
    assert ticks.deadlines(first, n).tolist() == [ticks.deadline(i)
                                                 for i in range(first, first + n)]


def test_a_run_never_reads_past_the_decision(tmp_path: Path) -> None:
    """The model decides (and reads the belt) only at a run's first time: a run that
    would cross the decision ends before it."""
    clock = SimClock()
    with open_belt("sim", clock=clock) as belt:
        cur = make_model_cursor(belt, clock, seed=2)
        from tactorbelt.inputs.base import TrialCue

        cur.trial_started(TrialCue(0, "test", "static", TargetSet.even(24).angles_deg,
                                   belt.layout), 0)
        times = 10_000_000 * np.arange(100, dtype=np.int64)
        seen: list[int] = []

        def take(t: Any, x: Any, y: Any) -> int:
            seen.append(len(t))
            return len(t)

        n = cur.read_run(times, take)
        decide_tick = math.ceil(ModelCursor(belt.vibration, 1).params.observe_static_s * 100)
        assert n == decide_tick and cur.last_decision is None
        clock.sleep_until_ns(int(times[n]))
        cur.read_run(times[n:], take)
        assert cur.last_decision is not None and cur.last_decision.decided_ns == times[n]
