"""Sessions under cognitive load through the runner (simulated clock): practice and
baseline runs, the task during the test blocks on its own clock, events and NASA-TLX
ratings in the store, kept through pauses, aborts and resumes."""

from __future__ import annotations

import collections
import itertools
import sqlite3
from pathlib import Path
from typing import Any

import pytest

from support.studies import make_study
from support.tasks import TaskCursor, judge
from tactorbelt.clock import SimClock
from tactorbelt.devices import open_belt
from tactorbelt.experiment.listeners import Command, NullObserver
from tactorbelt.experiment.runner import run_session
from tactorbelt.experiment.schedule import make_schedule
from tactorbelt.experiment.store import SCHEMA_VERSION, Store, open_store
from tactorbelt.experiment.study import Study
from tactorbelt.inputs.scripted import ScriptedCursor
from tactorbelt.tasks import TLX_ITEMS, TLX_SCALE, WorkloadInfo

MS = 1_000_000
TLX = dict(zip(TLX_ITEMS, (65.0, 10.0, 55.0, 25.0, 60.0, 35.0), strict=True))


def load_study(tlx: bool = True, **task: Any) -> Study:
    """Two test blocks of 8 targets x 2: ``calm`` (no load) and ``busy`` (2-back)."""
    return make_study(
        minimal=True, name="load", tactors=4, targets=8, iti_s=0.5, break_every=0,
        training=0, timeout_s=3.0, max_presentation_s=2.0,
        blocks=[{"name": "calm", "condition": "static", "repetitions": 2},
                {"name": "busy", "condition": "dynamic", "repetitions": 2, "load": "nb2"}],
        tasks={"nb2": {"kind": "nback", "n": 2, "interval_s": 2.0, "practice": 6,
                       "baseline": 10, **task}},
        questionnaire={"tlx": tlx})


def _cursor(study: Study, **kw: Any) -> TaskCursor:
    sched = make_schedule(study, "P01")
    return TaskCursor(answers={t.trial_index: t.target_deg for t in sched}, **kw)


def _scripted(study: Study) -> ScriptedCursor:
    """A cursor that neither does the task nor rates (a person's joystick)."""
    sched = make_schedule(study, "P01")
    return ScriptedCursor(answers={t.trial_index: t.target_deg for t in sched})


def _run(study: Study, store: Store, cursor: Any, clock: SimClock | None = None,
         **kw: Any) -> Any:
    clock = clock or SimClock()
    with open_belt("sim", clock=clock, layout=study.layout_obj()) as belt:
        return run_session(study, "P01", belt, cursor, store, clock, **kw)


def _busy_index(study: Study) -> int:
    return next(t.block_index for t in make_schedule(study, "P01") if t.block_name == "busy")


def test_a_load_session_stores_practice_baseline_dual_events_and_ratings(
        tmp_path: Path) -> None:
    study = load_study()
    cursor = _cursor(study, tlx=TLX)
    with Store.open(tmp_path / "s.sqlite") as store:
        res = _run(study, store, cursor)
        events = store.task_events(res.session_id)
        ratings = store.ratings(res.session_id)
        trials = store.trials(res.session_id)
    assert res.status == "complete" and res.accuracy == 1.0
    busy = _busy_index(study)
    items = [e for e in events if e["item_index"] >= 0]
    count = collections.Counter(e["phase"] for e in items)
    assert count["practice"] == 6 and count["baseline"] == 10 and count["dual"] >= 5
    assert {e["block_index"] for e in events} == {busy}  # none in the block without load
    assert {e["task"] for e in events} == {"nb2"}
    # the cursor judged every item from the stimuli alone: all correct, hits at 0.4 s
    assert all(e["correct"] for e in events)
    hits = [e for e in items if e["target"]]
    assert hits and {e["response"] for e in hits} == {"press"}
    assert {round(e["rt_s"], 9) for e in hits} == {0.4}
    assert all(e["rt_s"] is None for e in items if not e["target"])
    # the dual run keeps its own clock: item k at start + k * 2 s, whatever the trials do
    dual = [e for e in items if e["phase"] == "dual"]
    start = dual[0]["t_ns"]
    assert [e["t_ns"] for e in dual] == [start + k * 2000 * MS for k in range(len(dual))]
    assert [e["item_index"] for e in dual] == list(range(len(dual)))
    onsets = [t["onset_ns"] for t in trials if t["block_name"] == "busy"]
    assert onsets[0] < start < onsets[0] + 200 * MS  # started with the block's first trial
    assert dual[-1]["t_ns"] <= max(t["acquired_ns"] or 0 for t in trials)
    # the practice, then the baseline, then the test block
    assert cursor.phases == [("nback", "practice"), (None, None), ("nback", "baseline"),
                             (None, None), ("nback", "dual"), (None, None)]
    practice_end = max(e["t_ns"] for e in items if e["phase"] == "baseline")
    assert practice_end < onsets[0]
    # NASA-TLX after each test block, from the model-like cursor
    by_block = collections.defaultdict(dict)
    for r in ratings:
        assert r["scale"] == TLX_SCALE
        by_block[r["block_index"]][r["item"]] = r["value"]
    assert set(by_block) == {t["block_index"] for t in trials}
    assert all(v == TLX for v in by_block.values())
    assert [(i.block_name, i.load, i.task is not None) for i in cursor.rated] == [
        ("calm", "none", False), ("busy", "nb2", True)]


class Window(NullObserver):
    """A window-like observer: presses on the items it is told of, answers the TLX."""

    def __init__(self, commands: dict[int, Command] | None = None,
                 tlx: dict[str, float] | None = None) -> None:
        self.phases: list[tuple[str | None, str | None]] = []
        self.items: list[tuple[str, int]] = []
        self.due: list[int] = []
        self.history: list[str] = []
        self.spec: Any = None
        self.asked: list[WorkloadInfo] = []
        self.tlx = tlx
        self.commands = commands or {}
        self.polls = 0

    def on_task_phase(self, name: str | None, spec: Any, phase: str | None) -> None:
        self.phases.append((name, phase))
        self.spec, self.history, self.due = spec, [], []

    def on_task_item(self, item: Any, onset_ns: int, spec: Any) -> None:
        self.items.append((item.stimulus, onset_ns))
        if judge(spec, self.history, item.stimulus):
            self.due.append(onset_ns + 550 * MS)
        self.history.append(item.stimulus)

    def task_presses(self, now_ns: int) -> list[int]:
        out = [p for p in self.due if p <= now_ns]
        self.due = [p for p in self.due if p > now_ns]
        return out

    def ask_workload(self, info: WorkloadInfo) -> dict[str, float] | None:
        self.asked.append(info)
        return self.tlx

    def poll(self, now_ns: int) -> Command | None:
        self.polls += 1
        return self.commands.get(self.polls)


def test_a_person_answers_through_the_window(tmp_path: Path) -> None:
    study = load_study()
    window = Window(tlx={**TLX, "effort": 90.0})
    with Store.open(tmp_path / "s.sqlite") as store:
        res = _run(study, store, _scripted(study), observer=window)  # a person's device
        events = store.task_events(res.session_id)
        ratings = store.ratings(res.session_id)
    assert res.status == "complete"
    assert [p for _, p in window.phases if p] == ["practice", "baseline", "dual"]
    # the window was told every item ahead of its onset, and its presses were scored
    stored = [(e["stimulus"], e["t_ns"]) for e in events if e["item_index"] >= 0]
    assert stored == window.items
    hits = [e for e in events if e["target"]]
    assert hits and all(e["correct"] and round(e["rt_s"], 9) == 0.55 for e in hits)
    assert len(window.asked) == 2
    assert {r["value"] for r in ratings if r["item"] == "effort"} == {90.0}
    assert len(ratings) == 12


def test_the_cursor_rates_first_and_nothing_is_stored_when_nobody_answers(
        tmp_path: Path) -> None:
    study = load_study()
    window = Window(tlx={**TLX, "effort": 90.0})
    with Store.open(tmp_path / "a.sqlite") as store:
        _run(study, store, _cursor(study, tlx=TLX), observer=window)
        assert window.asked == []
        assert {r["value"] for r in store.ratings() if r["item"] == "effort"} == {60.0}
    with Store.open(tmp_path / "b.sqlite") as store:
        _run(study, store, _scripted(study), observer=Window(tlx=None))
        assert store.ratings() == []
    with Store.open(tmp_path / "c.sqlite") as store:  # tlx = false: never asked
        window = Window(tlx=TLX)
        _run(load_study(tlx=False), store, _cursor(load_study(tlx=False)), observer=window)
        assert window.asked == [] and store.ratings() == []


def _poll_in_dual(study: Study, tmp_path: Path) -> int:
    """The poll at which the busy block's 4th task item is announced (a dry run)."""
    seen: list[int] = []

    class Counting(Window):
        def on_task_item(self, item: Any, onset_ns: int, spec: Any) -> None:
            super().on_task_item(item, onset_ns, spec)
            seen.append(self.polls)

    with Store.open(tmp_path / "probe.sqlite") as store:
        _run(study, store, _cursor(study), observer=Counting())
    return seen[6 + 10 + 3]  # after the 6 practice and 10 baseline items


def test_events_are_kept_when_the_session_is_aborted_mid_block(tmp_path: Path) -> None:
    study = load_study()
    at = _poll_in_dual(study, tmp_path)
    window = Window({at: Command.ABORT})
    clock = SimClock()
    with Store.open(tmp_path / "s.sqlite") as store:
        res = _run(study, store, _cursor(study, tlx=TLX), clock=clock, observer=window)
        events = store.task_events(res.session_id)
        ratings = store.ratings(res.session_id)
    assert res.status == "aborted"
    dual = [e for e in events if e["phase"] == "dual"]
    assert len([e for e in dual if e["item_index"] >= 0]) >= 3
    assert max(e["t_ns"] for e in dual) <= clock.now_ns()
    assert window.phases[-1] == (None, None)  # the window was told the task ended
    busy = _busy_index(study)
    assert busy not in {r["block_index"] for r in ratings}  # an unfinished block: no TLX


def test_a_pause_writes_the_events_and_the_task_goes_on_after(tmp_path: Path) -> None:
    study = load_study()
    at = _poll_in_dual(study, tmp_path)
    window = Window({at: Command.PAUSE, at + 30: Command.RESUME})
    with Store.open(tmp_path / "s.sqlite") as store:
        res = _run(study, store, _cursor(study), observer=window)
        dual = [e for e in store.task_events(res.session_id)
                if e["phase"] == "dual" and e["item_index"] >= 0]
    assert res.status == "complete"
    assert [p for _, p in window.phases if p] == ["practice", "baseline", "dual", "dual"]
    idx = [e["item_index"] for e in dual]
    assert idx == sorted(idx) and len(set(idx)) == len(idx)  # numbered on, none twice
    gaps = {b["t_ns"] - a["t_ns"] for a, b in itertools.pairwise(dual)}
    assert min(gaps) == 2000 * MS and max(gaps) > 2000 * MS  # a new run after the pause


def test_resume_skips_the_practice_and_numbers_the_block_on(tmp_path: Path) -> None:
    study = load_study()
    busy = _busy_index(study)
    n_calm = 16
    db = tmp_path / "s.sqlite"
    with Store.open(db) as store:
        first = _run(study, store, _cursor(study, tlx=TLX), limit=n_calm + 6)
        assert first.status == "interrupted"
        before = store.task_events(first.session_id)
    assert {e["phase"] for e in before} == {"practice", "baseline", "dual"}
    cursor = _cursor(study, tlx=TLX)
    with Store.open(db) as store:
        res = _run(study, store, cursor, resume=True)
        events = store.task_events(res.session_id)
        ratings = store.ratings(res.session_id)
    assert res.status == "complete"
    assert cursor.phases == [("nback", "dual"), (None, None)]  # no second practice
    count = collections.Counter(e["phase"] for e in events if e["item_index"] >= 0)
    assert (count["practice"], count["baseline"]) == (6, 10)
    idx = [e["item_index"] for e in events if e["phase"] == "dual" and e["item_index"] >= 0]
    assert len(set(idx)) == len(idx) and len(idx) > len(
        [e for e in before if e["phase"] == "dual" and e["item_index"] >= 0])
    assert len(cursor.rated) == 1 and cursor.rated[0].block_index == busy  # calm: rated
    assert collections.Counter(r["block_index"] for r in ratings) == {0: 6, busy: 6}


def test_a_load_without_a_task_and_no_practice(tmp_path: Path) -> None:
    study = load_study(kind="none")
    cursor = _cursor(study)
    with Store.open(tmp_path / "s.sqlite") as store:
        res = _run(study, store, cursor)
        assert res.status == "complete" and store.task_events() == []
    assert cursor.phases == []
    study = load_study(practice=0, baseline=0)
    cursor = _cursor(study)
    with Store.open(tmp_path / "t.sqlite") as store:
        _run(study, store, cursor)
        assert {e["phase"] for e in store.task_events()} == {"dual"}
    assert cursor.phases == [("nback", "dual"), (None, None)]


def test_a_store_of_schema_2_gains_the_task_tables(tmp_path: Path) -> None:
    db = tmp_path / "old.sqlite"
    study = load_study()
    with Store.open(db) as store:
        _run(study, store, _cursor(study, tlx=TLX), limit=3)
    conn = sqlite3.connect(db)  # as a tactorbelt of schema 2 left it
    conn.execute("DROP TABLE task_events")
    conn.execute("DROP TABLE ratings")
    conn.execute("UPDATE meta SET value='2' WHERE key='schema_version'")
    conn.commit()
    conn.close()
    with open_store(db, readonly=True) as reader:
        assert reader.task_events() == [] and reader.ratings() == []
        assert reader.table_columns("task_events") == []
    with open_store(db) as store:
        res = _run(study, store, _cursor(study, tlx=TLX), resume=True)
        assert res.status == "complete"
        assert store.task_events() and len(store.ratings()) == 12
    conn = sqlite3.connect(db)
    (version,) = conn.execute("SELECT value FROM meta WHERE key='schema_version'").fetchone()
    conn.close()
    assert int(version) == SCHEMA_VERSION == 3


def test_arithmetic_runs_the_same_way(tmp_path: Path) -> None:
    study = load_study(kind="arithmetic", modality="visual", baseline=0)
    with Store.open(tmp_path / "s.sqlite") as store:
        _run(study, store, _cursor(study))
        events = store.task_events()
    assert events and all(e["correct"] for e in events)
    assert all("+" in e["stimulus"] for e in events)


def test_export_writes_task_events_and_ratings(tmp_path: Path) -> None:
    import csv

    from tactorbelt.experiment.export import export_csv

    study = load_study()
    db = tmp_path / "s.sqlite"
    with Store.open(db) as store:
        _run(study, store, _cursor(study, tlx=TLX))
        events, ratings = store.task_events(), store.ratings()
    files = export_csv(db, tmp_path / "out")
    assert [f.name for f in files] == ["sessions.csv", "trials.csv", "samples.csv",
                                       "task_events.csv", "ratings.csv"]
    with files[3].open(newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(events)
    assert {(r["participant"], r["session_number"]) for r in rows} == {("P01", "1")}
    hit = next(i for i, e in enumerate(events) if e["target"] and e["response"])
    assert (rows[hit]["target"], rows[hit]["correct"], rows[hit]["response"]) == (
        "1", "1", "press")
    assert float(rows[hit]["rt_s"]) == events[hit]["rt_s"]
    assert int(rows[hit]["t_ns"]) == events[hit]["t_ns"]
    assert rows[0]["stimulus"] == events[0]["stimulus"] and rows[0]["rt_s"] == ""
    with files[4].open(newline="") as fh:
        rated = list(csv.DictReader(fh))
    assert [(r["block_index"], r["item"], float(r["value"])) for r in rated] == [
        (str(r["block_index"]), r["item"], r["value"]) for r in ratings]


def test_the_run_summary_counts_the_secondary_task(tmp_path: Path) -> None:
    from tactorbelt.app.run import task_lines

    study = load_study()
    with Store.open(tmp_path / "s.sqlite") as store:
        _run(study, store, _cursor(study, miss_every=2, extra_presses_s=[0.9, 1.2]))
        events = store.task_events()
    lines = task_lines(events)
    assert [line.split()[:3] for line in lines] == [
        ["nb2", "practice", "6"], ["nb2", "baseline", "10"],
        ["nb2", "dual", lines[2].split()[2]]]
    for line, phase in zip(lines, ("practice", "baseline", "dual"), strict=True):
        items = [e for e in events if e["phase"] == phase and e["item_index"] >= 0]
        go = sum(e["target"] for e in items)
        hits = sum(1 for e in items if e["target"] and e["response"])
        assert f"{hits}/{go} go items pressed" in line
        # item 0 (never a go item in 2-back): pressed 0.9 s after its onset, and again
        assert f"1/{len(items) - go} false alarms" in line
        assert "1 extra presses" in line
        assert ("median RT 0.40 s" in line) == (hits > 0)
    assert any(e["target"] and not e["response"] for e in events)  # every 2nd go missed


def test_a_break_ends_a_part_of_the_run_and_the_task_goes_on_after(tmp_path: Path) -> None:
    study = make_study(
        minimal=True, name="load", tactors=4, targets=8, iti_s=0.5, break_every=5,
        training=0, blocks=[{"name": "busy", "condition": "static", "repetitions": 2,
                             "load": "nb2"}],
        tasks={"nb2": {"kind": "nback", "n": 2, "interval_s": 1.0, "practice": 0}})

    class Breaks(Window):
        def on_break(self, n_done: int, n_total: int) -> None:
            self.phases.append(("break", None))

    window = Breaks()  # the window's presses alone
    with Store.open(tmp_path / "s.sqlite") as store:
        _run(study, store, _scripted(study), observer=window)
        items = [e for e in store.task_events() if e["item_index"] >= 0]
    assert window.phases == [("nb2", "dual"), (None, None), ("break", None)] * 3 + [
        ("nb2", "dual"), (None, None)]
    idx = [e["item_index"] for e in items]
    assert idx == sorted(set(idx)) and len(items) > 10
    assert all(e["correct"] for e in items)  # each part's n-back starts afresh


def test_events_are_kept_when_the_session_fails_mid_block(tmp_path: Path) -> None:
    study = load_study()
    busy = _busy_index(study)

    class CtrlC(TaskCursor):
        def task_item(self, item: Any, onset_ns: int) -> None:
            super().task_item(item, onset_ns)
            if len(self.items) == 6 + 10 + 5:  # the 5th item of the block's run
                raise KeyboardInterrupt

    sched = make_schedule(study, "P01")
    with Store.open(tmp_path / "s.sqlite") as store:
        with pytest.raises(KeyboardInterrupt):
            _run(study, store, CtrlC(answers={t.trial_index: t.target_deg for t in sched}))
        (session,) = store.sessions()
        dual = [e for e in store.task_events() if e["phase"] == "dual"]
    assert session["status"] == "interrupted"
    assert {e["block_index"] for e in dual} == {busy}
    # items 0-3 were shown; item 3's window was cut short: kept only when pressed
    assert [e["item_index"] for e in dual if e["item_index"] >= 0] in ([0, 1, 2],
                                                                        [0, 1, 2, 3])


def test_a_questionnaire_cut_short_is_asked_first_on_resume(tmp_path: Path) -> None:
    study = load_study()
    busy = _busy_index(study)

    class Closes(TaskCursor):
        def rate_workload(self, info: WorkloadInfo) -> dict[str, float] | None:
            if info.block_index == busy:  # the window closed on the TLX screen
                raise KeyboardInterrupt
            return super().rate_workload(info)

    sched = make_schedule(study, "P01")
    answers = {t.trial_index: t.target_deg for t in sched}
    db = tmp_path / "s.sqlite"
    with Store.open(db) as store:
        with pytest.raises(KeyboardInterrupt):
            _run(study, store, Closes(answers=answers, tlx=TLX))
        assert {r["block_index"] for r in store.ratings()} == {1 - busy}
        assert len(store.finished_indices(1)) == len(sched)  # every trial done
    cursor = _cursor(study, tlx=TLX)
    with Store.open(db) as store:
        res = _run(study, store, cursor, resume=True)
        assert res.status == "complete" and res.n_run == 0
        assert {r["block_index"] for r in store.ratings()} == {0, 1}
    assert [i.block_index for i in cursor.rated] == [busy]
    assert cursor.phases == []  # no task ran again
