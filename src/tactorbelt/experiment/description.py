"""What ``tactorbelt study check`` prints: a study's cells, trials per cell, block order and
duration (:func:`describe`), built from the study and one participant's schedule.

Pure: the study, its schedule and the task kinds.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..geometry import TargetSet
from ..tasks.kinds import task_kind
from .schedule import block_order, make_schedule, order_rows, order_rule
from .study import Study, plural

__all__ = ["Cell", "StudyDescription", "describe"]


def _minutes(seconds: float) -> str:
    m, s = divmod(round(seconds), 60)
    return f"{m} min {s:02d} s" if m else f"{s} s"


@dataclass(frozen=True)
class Cell:
    """One cell of the test design (one test block)."""

    block: str
    n_targets: int
    condition: str
    load: str
    repetitions: int
    #: the levels of the factors declared beyond condition, targets and load, by key
    levels: tuple[tuple[str, Any], ...] = ()

    @property
    def trials(self) -> int:
        return self.n_targets * self.repetitions


@dataclass(frozen=True)
class StudyDescription:
    """What ``tactorbelt study check`` reports about a study (:func:`describe`).

    Attributes:
        study: the study.
        participant: whose block order ``order`` is.
        cells: the test blocks in the file's (canonical) order.
        order: the block labels in the participant's running order.
        order_rule: ``design.order`` or ``session.condition_order``.
        balance_participants: participants per complete balance of the order.
        n_breaks: breaks in a session.
        duration_s, max_duration_s: the estimate with 2 s responses, and with every
            trial timing out.
    """

    study: Study
    participant: str
    cells: tuple[Cell, ...]
    order: tuple[str, ...]
    order_rule: str
    balance_participants: int
    n_breaks: int
    duration_s: float
    max_duration_s: float

    def to_text(self) -> str:
        """The report as lines of text (two-space indent; the CLI prints 'FILE: ok' first)."""
        s = self.study
        layout = s.layout_obj()
        counts = s.target_counts()
        out = [f"  study       {s.name}",
               f"  layout      {plural(layout.n, 'tactor')} at "
               f"{', '.join(f'{a:g}' for a in layout.angles_deg)} deg"]
        for n in counts:
            on = int(TargetSet.even(n).on_tactor(layout).sum())
            out.append(f"  targets     {n} ({on} on-tactor, {n - on} between-tactor)")
        st = s.stimulus
        out.append(f"  stimulus    law {st.law}, falloff {st.falloff_deg:g} deg, period "
                   f"{st.period_s:g} s, transit {st.transit_s:g} s, at most "
                   f"{st.max_presentation_s:g} s")
        named = [(st.pattern, "[stimulus]")] + [(b.pattern, b.label) for b in s.test]
        for name in dict.fromkeys(n for n, _ in named if n is not None):
            where = ", ".join(w for n, w in named if n == name)
            if name in s.patterns:
                pat = s.pattern(name)
                size = f"{len(pat.events)} events, {pat.duration_s:g} s"
            else:
                size = "not read: the study was not loaded from its file"
            out.append(f"  pattern     {name} ({size}; at each target) in {where}")
        r = s.response
        out.append(f"  response    home {r.home_radius:g}, threshold {r.threshold:g}, dwell "
                   f"{r.dwell_s:g} s, timeout {r.timeout_s:g} s")
        if s.design is not None:
            d = s.design
            added = "".join(f" x {plural(len(v), k + ' level')}" for k, v in d.levels.items())
            out.append(f"  design      {plural(len(d.targets), 'target count')} x "
                       f"{plural(len(d.condition), 'condition')} x "
                       f"{plural(len(d.load), 'load')}{added} = "
                       f"{plural(len(self.cells), 'cell')}, "
                       f"{plural(d.repetitions, 'repetition')} of every target")
        out.append("  blocks")
        tr = s.training
        n_tr = s.n_training_trials()
        width = max(9, *(len(c.block) for c in self.cells))
        if n_tr:
            tgt = (plural(counts[0], "target") if len(counts) == 1
                   else f"({' + '.join(str(n) for n in counts)}) targets")
            out.append(f"    {'training':<{width}s} {n_tr:4d} trials "
                       f"({plural(tr.passes, 'pass')} x "
                       f"{plural(len(tr.conditions), 'condition')} x {tgt}, {tr.order})")
        for c in self.cells:
            load = "" if c.load == "none" else f", load {c.load}"
            load += "".join(f", {k} {v}" for k, v in c.levels)
            out.append(f"    {c.block:<{width}s} {c.trials:4d} trials "
                       f"({c.condition}{load}, {plural(c.repetitions, 'repetition')} x "
                       f"{plural(c.n_targets, 'target')})")
        for name, t in s.used_tasks().items():
            what = task_kind(t.kind).describe(t)
            out.append(f"  task        {name}: {t.modality} {what}, an item every "
                       f"{t.interval_s:g} s ({t.stimulus_s:g} s long), press {t.response} "
                       f"on {t.match_rate:.0%} go items; {plural(t.practice, 'practice item')}"
                       f", {plural(t.baseline, 'baseline item')} before its first block")
        if s.questionnaire.tlx:
            out.append("  ratings     raw NASA-TLX (6 items, 0-100) after each test block")
        out.append(f"  total       {s.n_trials()} trials ({s.n_test_trials()} test)")
        out.append(f"  order       {self.order_rule} (balanced over "
                   f"{plural(self.balance_participants, 'participant')}); "
                   f"{self.participant}: {' -> '.join(self.order)}")
        out.append(f"  breaks      {self.n_breaks} (every {s.session.break_every} trials)"
                   if self.n_breaks else "  breaks      none")
        extra = (" + the tasks' practice and baseline" if s.used_tasks() else "") + (
            " + 1 min per NASA-TLX" if s.questionnaire.tlx else "")
        out.append(f"  duration    about {_minutes(self.duration_s)} "
                   f"(2 s per response + {s.session.iti_s:g} s ITI per trial + 1 min per "
                   f"break{extra}); at most {_minutes(self.max_duration_s)}")
        return "\n".join(out)


def describe(study: Study, participant: str = "P01", seed: int | None = None) -> StudyDescription:
    """The ``study check`` report: cells, trials per cell, block order, duration.

    Also builds the participant's schedule, so a study that cannot be scheduled fails
    here. ``seed`` (default ``session.seed``) matters for ``design.order = "random"``.
    """
    cells = tuple(Cell(b.label, study.block_n_targets(b), b.condition, b.load, b.repetitions,
                       tuple(b.levels.items()))
                  for b in study.test)
    idx = block_order(study, participant, seed)
    rule = order_rule(study)
    n = study.n_trials()
    every = study.session.break_every
    make_schedule(study, participant, seed)
    return StudyDescription(
        study=study, participant=participant, cells=cells,
        order=tuple(study.test[i].label for i in idx), order_rule=rule,
        balance_participants=order_rows(rule, len(cells)),
        n_breaks=(n - 1) // every if every else 0,
        duration_s=study.estimate_duration_s(),
        max_duration_s=study.estimate_duration_s(response_s=study.response.timeout_s),
    )
