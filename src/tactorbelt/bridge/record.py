"""The bridge's way into the store: one adapter, so the rest of the bridge never calls
the store itself.

A browser session is stored as ``tactorbelt run`` stores a lab one: the same
``create_session`` provenance, the schedule ``run`` makes for the participant (same
seed rule, same block order), one ``write_trial`` transaction per trial with its onsets
and skin onset, ``set_status`` at the end. :class:`Recording` offers the methods of the
runner's session seam (``SessionRecorder``: ``open_or_resume``, ``schedule``,
``finished``, ``result_for``, ``record``, ``set_run_options``, ``end``) on the Store
methods the runner uses, so moving to that seam changes this module only.

I/O edge: imports the experiment's pure modules and the store.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping
from typing import Any

from .._errors import ConfigError, StoreError
from ..experiment import provenance
from ..experiment.schedule import ScheduledTrial, block_order, make_schedule, schedule_from_json
from ..experiment.store import Store
from ..experiment.study import Study
from ..experiment.trial import TrialResult
from ..geometry import TargetSet, wrap

__all__ = ["Recording"]


class Recording:
    """One participant's session in a store (see the module docstring)."""

    def __init__(self, store: Store, study: Study, participant: str, session_id: int,
                 seed: int, schedule: list[ScheduledTrial], resumed: bool) -> None:
        self.store = store
        self.study = study
        self.participant = participant
        self.session_id = session_id
        self.seed = seed
        self.schedule = schedule
        self.resumed = resumed
        self._targets: dict[int, TargetSet] = {}

    @classmethod
    def open_or_resume(cls, store: Store, study: Study, participant: str, *,
                       input_kind: str, study_toml: str, belt_url: str | None,
                       firmware_version: str | None, calibration: Any,
                       clock: str = "wall") -> Recording:
        """The participant's unfinished session, resumed (``running`` again), or a new one.

        Raises:
            StoreError: the participant has a complete session (as ``run`` refuses
                without ``--new-session``), or the study changed since the unfinished
                session started.
        """
        sha = hashlib.sha256(study_toml.encode("utf-8")).hexdigest()
        row = store.find_resumable(participant)
        if row is not None:
            if row["study_sha256"] != sha:
                stored = Study.from_toml(row["study_toml"], path=f"{store.url} (session "
                                         f"{row['session_id']})")
                if stored != study:
                    raise StoreError(
                        f"the study changed since session {row['session_id']} of "
                        f"{participant!r} started ({row['study_name']}); serve the same "
                        "study file to continue it")
            rec = cls(store, study, participant, int(row["session_id"]), int(row["seed"]),
                      schedule_from_json(row["schedule_json"], study), True)
            store.mark_resumed(rec.session_id)
            return rec
        complete = [s for s in store.sessions(participant) if s["status"] == "complete"]
        if complete:
            raise StoreError(
                f"participant {participant!r} has completed session "
                f"{complete[-1]['session_number']} in {store.url}; check the participant id")
        seed = int(study.session.seed)
        schedule = make_schedule(study, participant, seed)
        order: list[str] = [study.test[i].condition for i in block_order(study, participant)]
        prov = provenance.collect()
        sid = store.create_session(
            participant=participant, study_name=study.name, study_toml=study_toml,
            study_sha256=sha, seed=seed, condition_order=order, schedule=schedule,
            belt=belt_url, firmware_version=firmware_version, calibration=calibration,
            package_version=prov.package_version, git_commit=prov.git_commit,
            host=prov.host, input=input_kind, clock=clock)
        return cls(store, study, participant, sid, seed, schedule, False)

    def finished(self) -> set[int]:
        """Trial indices with a final outcome (done or timeout)."""
        return self.store.finished_indices(self.session_id)

    def run_options(self) -> dict[str, Any]:
        """What :meth:`set_run_options` kept (empty: nothing yet)."""
        return self.store.run_options(self.session_id) or {}

    def set_run_options(self, options: Mapping[str, Any]) -> None:
        """Keep how the session is run (JSON values): the pages, their clocks."""
        json.dumps(dict(options))  # a value JSON cannot hold fails here, not in the store
        self.store.set_run_options(self.session_id, options)

    def result_for(self, index: int, *, onset_ns: int | None, response_deg: float | None,
                   rt_s: float | None, device_onset_ns: int | None = None,
                   onset_uncertainty_ns: int | None = None,
                   stimulus_off_ns: int | None = None) -> TrialResult:
        """Trial ``index``'s result from a response given on a page: ``response_deg``
        snapped to the nearest of its block's targets; None: a timeout."""
        if not 0 <= index < len(self.schedule):
            raise ConfigError(f"no trial {index} in the schedule (0..{len(self.schedule) - 1})")
        t = self.schedule[index]
        r = TrialResult(t, onset_ns=onset_ns, stimulus_off_ns=stimulus_off_ns,
                        device_onset_ns=device_onset_ns,
                        onset_uncertainty_ns=onset_uncertainty_ns)
        if response_deg is None:
            r.status = "timeout"
            return r
        n = t.n_targets or self.study.targets.count
        targets = self._targets.setdefault(n, TargetSet.even(n))
        chosen = float(targets.nearest(float(response_deg)))
        r.status = "done"
        r.response_deg = float(response_deg)
        r.response_target_deg = chosen
        r.correct = abs(float(wrap(chosen - t.target_deg))) < 1e-6
        r.rt_s = rt_s
        if onset_ns is not None and rt_s is not None:
            r.acquired_ns = r.crossed_ns = onset_ns + round(rt_s * 1e9)
        return r

    def record(self, result: TrialResult, skin_onset: tuple[int, int] | None = None) -> int:
        """Write one trial in one transaction; its trial_id."""
        if skin_onset is None:
            return self.store.write_trial(self.session_id, result)
        return self.store.write_trial(self.session_id, result, skin_onset_ns=skin_onset[0],
                                      skin_onset_sd_ns=skin_onset[1])

    def end(self, status: str) -> None:
        """``complete``, ``interrupted`` (resumable) or ``aborted``."""
        self.store.set_status(self.session_id, status)
