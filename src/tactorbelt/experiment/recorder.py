"""The session seam: recording one participant's session in a :class:`Store`.

:class:`SessionRecorder` is what the runner stores a session through, and what any
other front end (the browser bridge, a script) calls to store a session the same way:
it opens a new session or resumes an unfinished one (refusing a study that changed),
gives the schedule exactly as ``tactorbelt run`` makes it (:meth:`schedule_for`: same
seed rule, same block order), writes each trial result with its samples and skin onset
in one transaction (:meth:`record`), the secondary-task events and the questionnaire
answers, and marks the session's end (:meth:`end`). It holds no clock, belt or cursor.

I/O edge: imports the pure experiment modules and the store; never a device or a window.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from .._errors import ConfigError, StoreError
from .._registry import check_option
from ..geometry import TargetSet, wrap
from . import provenance
from .schedule import ScheduledTrial, block_order, make_schedule, schedule_from_json
from .store import Store
from .study import Study
from .trial import TrialResult

if TYPE_CHECKING:
    from ..tasks.schedule import TaskEvent

__all__ = ["END_STATUSES", "SessionRecorder"]

#: What :meth:`SessionRecorder.end` accepts (``completed``: the bridge's word for
#: ``complete``).
END_STATUSES = ("complete", "completed", "interrupted", "aborted")


@dataclass(eq=False)
class SessionRecorder:
    """One session in a store: open (or resume) it, record its trials, end it.

    Attributes:
        store: the open, writable store.
        study: the session's study.
        participant: the participant id.
        session_id: the store's id of the session.
        seed: the seed of its schedule.
        schedule: its trials, in running order (stored with the session).
        order: the test blocks' conditions in running order.
        resumed: True when this continues an unfinished session.
        metadata: free values kept with the session's run options (e.g. a browser's
            user agent); None: none.
    """

    store: Store
    study: Study
    participant: str
    session_id: int
    seed: int
    schedule: list[ScheduledTrial]
    order: tuple[str, ...]
    resumed: bool
    metadata: dict[str, Any] | None = None
    _targets: dict[int, TargetSet] = field(default_factory=dict, init=False, repr=False)

    # -- opening ---------------------------------------------------------------------------
    @staticmethod
    def schedule_for(study: Study, participant: str, seed: int | None = None
                     ) -> tuple[list[ScheduledTrial], tuple[str, ...]]:
        """The schedule of a new session and its test blocks' conditions in running
        order, exactly as ``tactorbelt run`` makes them (``seed`` None: the study's)."""
        used = study.session.seed if seed is None else int(seed)
        order = tuple(study.test[i].condition for i in block_order(study, participant))
        return make_schedule(study, participant, used), order

    @classmethod
    def open(cls, store: Store, study: Study, participant: str, *,
             input_kind: str | None = None, seed: int | None = None, resume: bool = False,
             study_toml: str | None = None, belt_url: str | None = None,
             firmware_version: str | None = None, calibration: Any = None,
             clock: str = "wall", site: str | None = None,
             metadata: Mapping[str, Any] | None = None) -> SessionRecorder:
        """A new session (status ``running``) with its provenance, or with ``resume``
        the participant's unfinished one (``running`` again).

        Args:
            store: an open, writable store.
            study: the study; ``study_toml`` its file's text, stored verbatim
                (default ``study.to_toml()``), with the pattern files its stimuli name
                appended as ``[patterns]`` tables.
            participant: the participant id (checked by the caller:
                :func:`~tactorbelt.experiment.runner.check_participant`).
            input_kind: the input's registry name, stored with the session.
            seed: the schedule's seed (None: the study's); ignored on resume.
            belt_url, firmware_version, calibration: the belt's provenance
                (``Belt.session_url``, ``firmware_version``, ``calibration.to_list()``).
            clock: ``sim`` or ``wall``.
            site: the lab (default :func:`~tactorbelt.experiment.provenance.default_site`).
            metadata: free JSON values kept with the session's run options at once
                (under ``metadata``; :meth:`set_run_options` keeps them).

        Raises:
            StoreError: ``resume`` with nothing to resume, or a study that changed since
                the session started.
        """
        # with the pattern files its stimuli name appended (Study.session_toml), so the
        # store holds what the session played
        toml = study.session_toml(study_toml if study_toml is not None else study.to_toml())
        meta = dict(metadata) if metadata else None
        sha = hashlib.sha256(toml.encode("utf-8")).hexdigest()
        if resume:
            row = store.find_resumable(participant)
            if row is None:
                raise StoreError(
                    f"participant {participant!r} has no unfinished session in "
                    f"{store.url}; run without --resume to start one"
                )
            if row["study_sha256"] != sha:
                stored = Study.from_toml(row["study_toml"], path=f"{store.url} (session "
                                         f"{row['session_id']})")
                if stored != study:
                    raise StoreError(
                        f"the study changed since session {row['session_id']} of "
                        f"{participant!r} started ({row['study_name']}, sha256 "
                        f"{row['study_sha256'][:12]}); resume with the same study file"
                    )
            rec = cls(store, study, participant, int(row["session_id"]), int(row["seed"]),
                      schedule_from_json(row["schedule_json"], study),
                      tuple(json.loads(row["condition_order"])), True, meta)
            store.mark_resumed(rec.session_id)
        else:
            used = study.session.seed if seed is None else int(seed)
            schedule, order = cls.schedule_for(study, participant, used)
            prov = provenance.collect()
            sid = store.create_session(
                participant=participant, study_name=study.name, study_toml=toml,
                study_sha256=sha, seed=used, condition_order=list(order),
                schedule=schedule, belt=belt_url, firmware_version=firmware_version,
                calibration=calibration, package_version=prov.package_version,
                git_commit=prov.git_commit, host=prov.host, input=input_kind, clock=clock,
                site=site,
            )
            rec = cls(store, study, participant, sid, used, schedule, order, False, meta)
        if rec.metadata:  # kept at once, with the options stored before (a resume)
            rec.set_run_options(store.run_options(rec.session_id) or {})
        return rec

    @classmethod
    def open_or_resume(cls, store: Store, study: Study, participant: str,
                       **kwargs: Any) -> SessionRecorder:
        """:meth:`open`, resuming the participant's unfinished session when there is one."""
        return cls.open(store, study, participant,
                        resume=store.find_resumable(participant) is not None, **kwargs)

    # -- reading back ----------------------------------------------------------------------
    def targets(self, t: ScheduledTrial) -> TargetSet:
        """The candidate targets of a trial's block (what the window draws, the model
        participant chooses among and a response snaps to)."""
        n = t.n_targets or self.study.targets.count
        if n not in self._targets:
            self._targets[n] = TargetSet.even(n)
        return self._targets[n]

    def finished(self) -> set[int]:
        """Trial indices with a final outcome (done or timeout)."""
        return self.store.finished_indices(self.session_id)

    def todo(self) -> list[ScheduledTrial]:
        """The scheduled trials without a final outcome, in order."""
        done = self.finished()
        return [t for t in self.schedule if t.trial_index not in done]

    def task_events(self) -> list[dict[str, Any]]:
        """The session's secondary-task events so far (``Store.task_events``)."""
        return self.store.task_events(self.session_id)

    def ratings(self) -> list[dict[str, Any]]:
        """The session's questionnaire answers so far (``Store.ratings``)."""
        return self.store.ratings(self.session_id)

    # -- writing ---------------------------------------------------------------------------
    def record(self, result: TrialResult,
               skin_onset: tuple[int, int] | None = None) -> int:
        """Write one trial (its samples, its onsets) in one transaction; return its id.

        ``skin_onset``: ``(skin_onset_ns, skin_onset_sd_ns)`` where the onset at the skin
        is known. An earlier ``aborted`` row of the trial is replaced.

        Raises:
            StoreError: the trial already has a final row, or the write failed.
        """
        if skin_onset is None:
            return self.store.write_trial(self.session_id, result)
        return self.store.write_trial(self.session_id, result, skin_onset_ns=skin_onset[0],
                                      skin_onset_sd_ns=skin_onset[1])

    def result_for(self, index: int, *, onset_ns: int | None,
                   response_deg: float | None, rt_s: float | None,
                   device_onset_ns: int | None = None,
                   onset_uncertainty_ns: int | None = None,
                   stimulus_off_ns: int | None = None) -> TrialResult:
        """A trial's result from a response given outside the runner (a page, a script):
        ``response_deg`` snapped to the nearest of the block's targets; None: a timeout
        (``rt_s`` and the response are then not kept).

        Raises:
            ConfigError: no trial ``index`` in the schedule.
        """
        if not 0 <= index < len(self.schedule):
            raise ConfigError(f"no trial {index} in the schedule (0..{len(self.schedule) - 1})")
        t = self.schedule[index]
        r = TrialResult(t, onset_ns=onset_ns, stimulus_off_ns=stimulus_off_ns,
                        device_onset_ns=device_onset_ns,
                        onset_uncertainty_ns=onset_uncertainty_ns)
        if response_deg is None:
            r.status = "timeout"
            return r
        chosen = float(self.targets(t).nearest(float(response_deg)))
        r.status = "done"
        r.response_deg = float(response_deg)
        r.response_target_deg = chosen
        r.correct = abs(float(wrap(chosen - t.target_deg))) < 1e-6
        r.rt_s = rt_s
        if onset_ns is not None and rt_s is not None:
            r.acquired_ns = r.crossed_ns = onset_ns + round(rt_s * 1e9)
        return r

    def write_task_events(self, events: Sequence[TaskEvent]) -> None:
        """Append a secondary-task run's events (one transaction)."""
        self.store.write_task_events(self.session_id, events)

    def write_ratings(self, block_index: int, scale: str,
                      values: Mapping[str, float]) -> None:
        """A questionnaire's answers after a block (one transaction)."""
        self.store.write_ratings(self.session_id, block_index, scale, values)

    def set_profile(self, toml_text: str) -> None:
        """The wearer profile the session runs with (part of its provenance)."""
        self.store.set_session_profile(self.session_id, toml_text)

    def set_run_options(self, options: Mapping[str, Any]) -> None:
        """Keep how the session is run (reused on resume), with :attr:`metadata`."""
        opts = dict(options)
        if self.metadata:
            opts["metadata"] = self.metadata
        self.store.set_run_options(self.session_id, opts)

    @contextlib.contextmanager
    def batched(self, every: int | None) -> Iterator[None]:
        """Commit the writes inside in batches of ``every`` trials where the store can
        (``None``: one commit per write, as outside)."""
        if every is None or not self.store.capabilities.batch_commits:
            yield
            return
        self.store.begin_batch(self.session_id, every)
        try:
            yield
        finally:
            self.store.end_batch()

    def end(self, status: str) -> None:
        """Mark the session ``complete`` (``completed``), ``interrupted`` (resumable) or
        ``aborted``. A break is not a row: the session stays ``running`` through it."""
        check_option("session status", status, END_STATUSES)
        self.store.set_status(self.session_id,
                              "complete" if status == "completed" else status)
