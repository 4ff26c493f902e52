"""The trial state machine: from a cursor at home to a response (or a timeout).

::

    WAIT_HOME --cursor in the home zone--> STIMULUS --acquisition--> RESPONSE --> ITI
                                              |--no acquisition by timeout--> TIMEOUT --> ITI
    any state --abort(reason)--> ABORTED

- WAIT_HOME: the cursor must be within ``home_radius`` of the centre.
- STIMULUS: the runner starts the stimulus and calls :meth:`TrialMachine.start` with
  the onset time, then feeds cursor samples (100 Hz, on absolute deadlines). A
  response is *acquired* at the first sample whose distance from the centre is
  beyond ``threshold`` and, with ``dwell_s > 0``, has stayed beyond it for ``dwell_s``
  (every sample since the crossing beyond the threshold).
- RESPONSE: the response angle is the cursor's angle at acquisition,
  ``degrees(atan2(x, y))`` normalised to [0, 360) (y up = front, clockwise); the
  chosen target is the nearest target in angle; RT = acquisition time - onset.
- TIMEOUT: no acquisition ``timeout_s`` after onset.

The machine is pure: it never reads a clock or a device; times come in with the
samples (integer nanoseconds on the runner's clock).

Imports numpy, the standard library and tactorbelt.geometry / experiment.schedule.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import StrEnum
from typing import TYPE_CHECKING

import numpy as np

from .._errors import TactorbeltError
from ..geometry import TargetSet, normalize, wrap
from ..inputs.base import CursorSample
from .schedule import ScheduledTrial

if TYPE_CHECKING:
    from numpy.typing import NDArray

__all__ = [
    "ResponseRule",
    "TrialMachine",
    "TrialResult",
    "TrialState",
    "cursor_angle_deg",
]


class TrialState(StrEnum):
    """States of one trial."""

    WAIT_HOME = "wait_home"
    STIMULUS = "stimulus"
    RESPONSE = "response"
    TIMEOUT = "timeout"
    ABORTED = "aborted"
    ITI = "iti"


def cursor_angle_deg(x: float, y: float) -> float:
    """The direction of a cursor position: 0 = up (front), clockwise, in [0, 360)."""
    return float(normalize(math.degrees(math.atan2(x, y))))


@dataclass(frozen=True)
class ResponseRule:
    """The timing and geometry of a response, in cursor units and nanoseconds.

    Attributes:
        home_radius: the cursor must be this close to the centre before onset.
        threshold: acquisition radius, in (0, 1].
        dwell_ns: how long the cursor must stay beyond the threshold (0 = at once).
        timeout_ns: no acquisition this long after onset is a timeout.
        max_presentation_ns: the stimulus stops this long after onset at the latest.
    """

    home_radius: float = 0.15
    threshold: float = 0.9
    dwell_ns: int = 0
    timeout_ns: int = 10_000_000_000
    max_presentation_ns: int = 10_000_000_000

    @classmethod
    def from_study(cls, study: object) -> ResponseRule:
        """The rule of a :class:`~tactorbelt.experiment.study.Study`."""
        r = study.response  # type: ignore[attr-defined]
        s = study.stimulus  # type: ignore[attr-defined]
        return cls(
            home_radius=r.home_radius,
            threshold=r.threshold,
            dwell_ns=round(r.dwell_s * 1e9),
            timeout_ns=round(r.timeout_s * 1e9),
            max_presentation_ns=round(s.max_presentation_s * 1e9),
        )


#: Times from the onset below this many ns convert to float exactly (the sample times
#: in seconds are computed from the exact integer difference up to it).
_EXACT_NS = 2**53


@dataclass(slots=True)
class TrialResult:
    """What a trial produced; the store writes it in one transaction.

    Attributes:
        trial: the scheduled trial.
        status: ``done``, ``timeout`` or ``aborted``.
        onset_ns: stimulus onset (None when aborted before onset).
        acquired_ns: time of acquisition (None unless done).
        crossed_ns: when the cursor passed the threshold (equals acquired_ns without dwell).
        stimulus_off_ns: when the stimulus was stopped.
        response_deg: the cursor's angle at acquisition.
        response_target_deg: the target nearest in angle to response_deg.
        correct: response_target_deg == target_deg.
        rt_s: (acquired_ns - onset_ns) / 1e9.
        abort_reason: why the trial was aborted.
        sample_t_ns, sample_x, sample_y, sample_buttons: the cursor samples.
        samples_released: how many samples :meth:`release_samples` dropped.
        device_onset_ns: the onset as the device saw it (its ONSET time mapped to host
            time, :meth:`tactorbelt.devices.base.Belt.last_onset`); None when the belt
            cannot tell.
        onset_uncertainty_ns: how far off device_onset_ns may be.
    """

    trial: ScheduledTrial
    status: str = "aborted"
    onset_ns: int | None = None
    acquired_ns: int | None = None
    crossed_ns: int | None = None
    stimulus_off_ns: int | None = None
    response_deg: float | None = None
    response_target_deg: float | None = None
    correct: bool | None = None
    rt_s: float | None = None
    abort_reason: str | None = None
    sample_t_ns: list[int] = field(default_factory=list)
    sample_x: list[float] = field(default_factory=list)
    sample_y: list[float] = field(default_factory=list)
    sample_buttons: list[int] = field(default_factory=list)
    #: samples dropped from memory by :meth:`release_samples` (still counted by n_samples)
    samples_released: int = field(default=0, repr=False)
    device_onset_ns: int | None = None
    onset_uncertainty_ns: int | None = None
    #: :meth:`sample_times_s` of the samples recorded in runs so far (each run's
    #: converted at once; handed over by the first call, the store's), and the onset
    #: they count from
    _times_s: list[float] = field(default_factory=list, init=False, repr=False,
                                  compare=False)
    _times_onset: int | None = field(default=None, init=False, repr=False, compare=False)

    @property
    def n_samples(self) -> int:
        return len(self.sample_t_ns) + self.samples_released

    def release_samples(self) -> None:
        """Drop the cursor samples from memory once they are stored (long sessions).

        ``n_samples`` still counts them; the store refuses to write such a result again.
        """
        self.samples_released += len(self.sample_t_ns)
        for samples in (self.sample_t_ns, self.sample_x, self.sample_y, self.sample_buttons,
                        self._times_s):
            samples.clear()

    def sample_times_s(self) -> list[float]:
        """Each sample's time in seconds from the onset (``(t - onset) / 1e9``: an exact
        integer difference, converted exactly while below 2**53 ns, then divided)."""
        onset = self.onset_ns or 0
        if (self._times_onset == onset and len(self._times_s) == len(self.sample_t_ns)
                and self._times_s):
            # converted run by run as they were recorded: handed over, not kept twice
            times, self._times_s, self._times_onset = self._times_s, [], None
            return times
        t = np.array(self.sample_t_ns, dtype=np.int64) - onset
        if t.size and max(-int(t.min()), int(t.max())) >= _EXACT_NS:
            return [(v - onset) / 1e9 for v in self.sample_t_ns]  # beyond exact floats
        return (t / 1e9).tolist()

    def sample_rows(self) -> list[tuple[float, float, float, int]]:
        """(t_s from onset, x, y, buttons) per sample."""
        return list(zip(self.sample_times_s(), self.sample_x, self.sample_y,
                        self.sample_buttons, strict=True))


class TrialMachine:
    """One trial's states. The runner drives it; it reads no clock.

    Args:
        trial: the scheduled trial.
        rule: the response rule.
        targets: the candidate targets (the response selects the nearest).
    """

    def __init__(self, trial: ScheduledTrial, rule: ResponseRule, targets: TargetSet) -> None:
        self.trial = trial
        self.rule = rule
        self._targets = targets.angles_deg
        self._target_arr = np.asarray(self._targets, dtype=float)
        self.state = TrialState.WAIT_HOME
        self.result = TrialResult(trial)
        self._thr2 = rule.threshold * rule.threshold
        self._home2 = rule.home_radius * rule.home_radius

    # -- WAIT_HOME -------------------------------------------------------------------
    def at_home(self, sample: CursorSample) -> bool:
        """True when the cursor is inside the home zone."""
        return sample.x * sample.x + sample.y * sample.y <= self._home2

    def start(self, onset_ns: int) -> None:
        """The stimulus started at ``onset_ns``: WAIT_HOME -> STIMULUS."""
        self._expect(TrialState.WAIT_HOME)
        self.result.onset_ns = int(onset_ns)
        self.state = TrialState.STIMULUS

    # -- STIMULUS --------------------------------------------------------------------
    def stimulus_due_off(self, now_ns: int) -> bool:
        """True once the longest presentation time has passed."""
        onset = self.result.onset_ns
        return onset is not None and now_ns - onset >= self.rule.max_presentation_ns

    def feed(self, t_ns: int, x: float, y: float, buttons: int = 0) -> TrialState:
        """Record one cursor sample taken at ``t_ns``; detect acquisition and timeout."""
        self._expect(TrialState.STIMULUS)
        r = self.result
        r.sample_t_ns.append(int(t_ns))
        r.sample_x.append(float(x))
        r.sample_y.append(float(y))
        r.sample_buttons.append(int(buttons))
        assert r.onset_ns is not None
        if x * x + y * y > self._thr2:
            if r.crossed_ns is None:
                r.crossed_ns = int(t_ns)
            if t_ns - r.crossed_ns >= self.rule.dwell_ns:
                self._respond(int(t_ns), float(x), float(y))
                return self.state
        else:
            r.crossed_ns = None
        if t_ns - r.onset_ns >= self.rule.timeout_ns:
            r.status = "timeout"
            r.crossed_ns = None
            self.state = TrialState.TIMEOUT
        return self.state

    def feed_run(self, t_ns: NDArray[np.int64], x: NDArray[np.float64],
                 y: NDArray[np.float64]) -> int:
        """:meth:`feed` for a run of samples (no buttons) in time order, up to the one
        that ends the trial; returns how many were recorded. The outcome is the one
        :meth:`feed` gives sample by sample."""
        self._expect(TrialState.STIMULUS)
        n = len(t_ns)
        if self.rule.dwell_ns > 0:  # the crossing time carries over from sample to sample
            for i in range(n):
                if self.feed(int(t_ns[i]), float(x[i]), float(y[i])) is not TrialState.STIMULUS:
                    return i + 1
            return n
        r = self.result
        assert r.onset_ns is not None
        above = x * x + y * y > self._thr2
        # the first sample past the response radius, and the first at or past the timeout
        # (the times increase)
        out = int(above.argmax()) if n else 0
        end = min(out if n and above[out] else n,
                  int(t_ns.searchsorted(r.onset_ns + self.rule.timeout_ns)))
        m = end + 1 if end < n else n
        if r._times_onset is None and not r.sample_t_ns:
            r._times_onset = r.onset_ns
        if r._times_onset == r.onset_ns and len(r._times_s) == len(r.sample_t_ns):
            # their times from the onset, as sample_times_s gives them
            since = t_ns[:m] - r.onset_ns
            if m and max(-int(since[0]), int(since[-1])) < _EXACT_NS:
                r._times_s.extend((since / 1e9).tolist())
        r.sample_t_ns.extend(t_ns[:m].tolist())
        r.sample_x.extend(x[:m].tolist())
        r.sample_y.extend(y[:m].tolist())
        r.sample_buttons.extend([0] * m)
        r.crossed_ns = None
        if end < n:
            i = m - 1
            if above[i]:
                r.crossed_ns = int(t_ns[i])
                self._respond(int(t_ns[i]), float(x[i]), float(y[i]))
            else:
                r.status = "timeout"
                self.state = TrialState.TIMEOUT
        return m

    def _respond(self, t_ns: int, x: float, y: float) -> None:
        r = self.result
        assert r.onset_ns is not None
        angle = cursor_angle_deg(x, y)
        chosen = self._targets[int(np.argmin(np.abs(wrap(angle - self._target_arr))))]
        r.acquired_ns = t_ns
        r.response_deg = angle
        r.response_target_deg = float(chosen)
        r.correct = abs(wrap(chosen - self.trial.target_deg)) < 1e-6
        r.rt_s = (t_ns - r.onset_ns) / 1e9
        r.status = "done"
        self.state = TrialState.RESPONSE

    def stimulus_stopped(self, now_ns: int) -> None:
        """Note when the stimulus was turned off."""
        if self.result.stimulus_off_ns is None:
            self.result.stimulus_off_ns = int(now_ns)

    # -- end states --------------------------------------------------------------------
    @property
    def finished(self) -> bool:
        """True in RESPONSE, TIMEOUT or ABORTED: the trial's outcome is known."""
        return self.state in (TrialState.RESPONSE, TrialState.TIMEOUT, TrialState.ABORTED)

    def abort(self, reason: str) -> TrialResult:
        """Abort the trial (pause, device failure, Ctrl-C): its outcome is ``aborted``."""
        r = self.result
        r.status = "aborted"
        r.abort_reason = reason
        r.acquired_ns = r.response_deg = r.response_target_deg = None
        r.correct = r.rt_s = None
        self.state = TrialState.ABORTED
        return r

    def _expect(self, state: TrialState) -> None:
        if self.state is not state:
            raise TactorbeltError(
                f"trial {self.trial.trial_index}: expected state {state.value}, "
                f"is {self.state.value}"
            )
