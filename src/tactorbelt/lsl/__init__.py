"""Lab Streaming Layer (LSL) streams of a session: event markers and the cursor.

Labs record EEG, pupil size, heart rate or motion alongside a task and synchronise
everything with LSL (docs/lsl.md). :class:`LslListener` is one of a session's listeners
(:class:`~tactorbelt.experiment.listeners.SessionListener`, beside the experiment
window, wrapping none) and, when the session starts, opens two LSL outlets:

- ``tactorbelt-markers`` (type ``Markers``, irregular rate, one string channel): one
  JSON object per event (:data:`MARKER_EVENTS`, docs/lsl.md "Markers"), for example
  ``{"event":"stimulus_onset","trial_index":3,"target_deg":15.0,...}``;
- ``tactorbelt-cursor`` (type ``Position``, two float32 channels ``x``, ``y`` at the
  study's sampling rate): every cursor sample the runner takes.

Each sample is stamped with LSL's clock at the moment of its event: the runner's time of
the event (its clock's nanoseconds) mapped to :func:`pylsl.local_clock` by a bracketed
reading of both clocks at push time. Where the belt reports device-true onsets
(:attr:`tactorbelt.devices.base.Belt.reports_onsets`, firmware 1.1), the onset marker
carries the device's onset instead of the host's and is sent when the trial ends. Where
the belt's calibration has measured latencies (``tactorbelt validate onsets``), a
``skin_onset`` marker, sent when the trial ends, is stamped at the trial's onset at the
skin. The streams' XML description holds the study, the participant, the session and
the belt's tactor layout with each tactor's measured latency and rise.

``pylsl`` (``pip install 'tactorbelt[lsl]'``) is imported only here and only when a
stream opens; without it or without the liblsl library, :func:`load_pylsl` raises a
ConfigError saying how to install them.

I/O edge: imports the experiment's pure types; pylsl lazily.
"""

from __future__ import annotations

import json
import logging
import math
import time
from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import TYPE_CHECKING, Any

from .._errors import ConfigError
from ..experiment.listeners import Command, NullListener, NullOperator
from ..factors import BUILTIN, added_factors, after_builtin, factors

if TYPE_CHECKING:
    from ..clock import Clock
    from ..devices.base import Belt
    from ..experiment.listeners import Operator, SessionInfo
    from ..experiment.schedule import ScheduledTrial
    from ..experiment.study import TaskSpec
    from ..experiment.trial import TrialResult, TrialState
    from ..inputs.base import CursorSample
    from ..tasks import WorkloadInfo
    from ..tasks.schedule import TaskItem

__all__ = [
    "CURSOR_STREAM",
    "MARKER_EVENTS",
    "MARKER_STREAM",
    "LslListener",
    "load_pylsl",
    "marker",
    "marker_fields",
]

log = logging.getLogger(__name__)

#: The names of the two streams.
MARKER_STREAM = "tactorbelt-markers"
CURSOR_STREAM = "tactorbelt-cursor"
#: The version of the marker JSON shape (in each stream's description).
MARKER_FORMAT = "tactorbelt-markers/1"
#: Seconds an outlet stays open after the session, for its last samples to go out.
LINGER_S = 0.5
#: While waiting for consumers: how often the outlets are asked (s), how often the time
#: left is reported (s), and how long the other streams are given once the markers have
#: a consumer (a recorder connects to the streams it records within a moment).
WAIT_POLL_S = 0.05
WAIT_REPORT_S = 5.0
WAIT_GRACE_S = 0.5

#: The built-in factors' columns (condition, n_targets, load: :mod:`tactorbelt.factors`),
#: which the block, trial and onset markers carry; a factor declared beyond them follows.
_FACTORS = tuple(f.column for f in BUILTIN)
#: Every marker's ``event`` and the fields it carries besides ``event`` (docs/lsl.md).
MARKER_EVENTS: dict[str, tuple[str, ...]] = {
    "session_start": ("session_id", "participant", "study", "n_trials", "n_done", "resumed"),
    "block_start": ("block_index", "block", "block_name", *_FACTORS),
    "trial_start": ("trial_index", "block_index", "block", *_FACTORS),
    "stimulus_onset": ("trial_index", "target_deg", "on_tactor", *_FACTORS, "block",
                       "onset_clock"),
    "skin_onset": ("trial_index", "latency_ms", "sd_ms"),
    "response": ("trial_index", "response_deg", "response_target_deg", "correct", "rt_s"),
    "timeout": ("trial_index",),
    "trial_end": ("trial_index", "status", "abort_reason"),
    "block_end": ("block_index",),
    "break_start": ("n_done", "n_total"),
    "break_end": (),
    "pause": (),
    "resume": (),
    "abort": (),
    "task_start": ("task", "kind", "phase", "n", "modality", "block_index"),
    "task_item": ("task", "phase", "item_index", "stimulus", "go"),
    "task_press": ("task", "phase"),
    "task_end": ("task", "phase"),
    "workload": ("block_index", "scale", "ratings"),
    "session_end": ("status",),
}

INSTALL_HINT = (
    "install it with: pip install 'tactorbelt[lsl]' (the pylsl wheels bundle liblsl for "
    "Linux x86_64, macOS and Windows); elsewhere install liblsl itself (conda install -c "
    "conda-forge liblsl, or a liblsl package from github.com/sccn/liblsl/releases) and set "
    "PYLSL_LIB to the library's path"
)


def load_pylsl() -> Any:
    """The ``pylsl`` module with its liblsl loaded.

    Raises:
        ConfigError: pylsl is not installed, or it cannot load the liblsl library.
    """
    try:
        import pylsl
    except ModuleNotFoundError as exc:
        if exc.name != "pylsl":
            raise
        raise ConfigError(f"--lsl needs the pylsl package, which is not installed; "
                          f"{INSTALL_HINT}") from None
    except (RuntimeError, OSError) as exc:  # pylsl raises RuntimeError without liblsl
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ConfigError(f"--lsl: pylsl cannot load the liblsl library ({first}); "
                          f"{INSTALL_HINT}") from None
    return pylsl


def marker(event: str, **fields: Any) -> str:
    """One marker: compact JSON with ``event`` first, then the event's fields in the
    order of :data:`MARKER_EVENTS` (None as ``null``, floats as JSON numbers).

    Raises:
        ValueError: an unknown event or field (a programming error).
    """
    allowed = marker_fields(event)
    extra = set(fields) - set(allowed)
    if extra:
        raise ValueError(f"marker {event!r} has no field(s) {sorted(extra)}")
    body = {"event": event} | {k: _plain(fields[k]) for k in allowed if k in fields}
    return json.dumps(body, separators=(",", ":"), allow_nan=False)


def marker_fields(event: str) -> tuple[str, ...]:
    """The fields of a marker, in order: :data:`MARKER_EVENTS`'s, and after the built-in
    factors the columns of the factors declared beyond them.

    Raises:
        ValueError: an unknown event.
    """
    allowed = MARKER_EVENTS.get(event)
    if allowed is None:
        raise ValueError(f"unknown marker event {event!r}")
    if _FACTORS[-1] not in allowed:
        return allowed
    return tuple(after_builtin(allowed, [f.column for f in added_factors()]))


def _levels(t: ScheduledTrial) -> dict[str, Any]:
    """A trial's level of every factor, by column."""
    return {f.column: t.level(f) for f in factors()}


def _child(node: Any, tag: str, /, **values: str) -> Any:
    """Append the child ``tag`` to an LSL description node, with one text value per
    keyword in the order given; returns the child."""
    child = node.append_child(tag)
    for key, value in values.items():
        child.append_child_value(key, value)
    return child


def _plain(v: Any) -> Any:
    if isinstance(v, bool) or v is None or isinstance(v, int | str):
        return v
    if isinstance(v, dict):
        return {str(k): _plain(x) for k, x in v.items()}
    if isinstance(v, float):
        return v if math.isfinite(v) else None
    return str(v)


class _ToLsl:
    """Maps the runner's clock (ns) to LSL's clock (s).

    On the wall clock both are read at each call, LSL's on both sides of the runner's
    (the narrowest of three brackets), so the offset is current and the drift between
    the two clocks does not accumulate. A simulated clock is mapped with the offset
    read once, when the streams open.
    """

    def __init__(self, clock: Clock, local_clock: Callable[[], float]) -> None:
        self.clock = clock
        self.local_clock = local_clock
        self.fixed = self._offset() if clock.simulated else None
        self._last: dict[str, tuple[int, float]] = {}

    def _offset(self) -> float:
        best: tuple[float, float] | None = None
        for _ in range(3):
            a = self.local_clock()
            c = self.clock.now_ns()
            b = self.local_clock()
            if best is None or b - a < best[0]:
                best = (b - a, (a + b) / 2 - c / 1e9)
        assert best is not None
        return best[1]

    def __call__(self, t_ns: int, stream: str = "") -> float:
        """``t_ns`` on LSL's clock; events of a ``stream`` in the order of their times
        keep that order (the reading's jitter, tens of nanoseconds, cannot swap them)."""
        offset = self.fixed if self.fixed is not None else self._offset()
        ts = t_ns / 1e9 + offset
        last = self._last.get(stream)
        if last is not None and t_ns >= last[0] and ts < last[1]:
            ts = last[1]
        self._last[stream] = (t_ns, ts)
        return ts


class LslListener(NullListener, AbstractContextManager["LslListener"]):
    """A session listener that sends LSL markers and cursor samples (module doc).

    Args:
        clock: the runner's clock (event times are on it).
        belt: the session's belt (its URL, firmware, layout and whether it reports
            device-true onsets).
        wait_s: when the streams open, wait up to this long for a consumer (LabRecorder,
            an analysis script) before the first trial: the session starts as soon as
            the marker stream has one (the cursor stream is given
            :data:`WAIT_GRACE_S` more); samples sent while no consumer is connected are
            lost.
        wait_all: wait for a consumer of every stream, not only the markers.
        report: called with a line for the experimenter while waiting: which streams
            have a consumer and how long is left (default: the log, at INFO). The
            ``operator`` (the experiment window) also shows it
            (:meth:`~tactorbelt.experiment.listeners.Operator.show_wait`), and keeps
            handling its events (Esc Esc ends the wait).
        operator: the session's operator, or None.
        pylsl: the pylsl module (default: :func:`load_pylsl`).

    Use as a context manager (or call :meth:`close`) to close the outlets.
    """

    def __init__(self, clock: Clock, belt: Belt, *, wait_s: float = 0.0,
                 wait_all: bool = False, report: Callable[[str], None] | None = None,
                 operator: Operator | None = None, pylsl: Any = None) -> None:
        self.operator: Operator = operator if operator is not None else NullOperator()
        self.clock = clock
        self.belt = belt
        self.wait_s = float(wait_s)
        self.wait_all = bool(wait_all)
        self.report = report if report is not None else log.info
        self.lsl = pylsl if pylsl is not None else load_pylsl()
        self.to_lsl = _ToLsl(clock, self.lsl.local_clock)
        self.markers: Any = None
        self.cursor: Any = None
        self._block_ns: int | None = None
        self._block: int | None = None
        self._trial: ScheduledTrial | None = None
        self._onset_pending = False
        #: the skin onset of the trial ending: (trial_index, skin_onset_ns, sd_ns)
        self._skin: tuple[int, int, int] | None = None
        self._paused = False
        self._timeout_ns = 0
        # the running secondary task: (name, phase); its items wait here until their
        # onset, so the stream stays in time order
        self._task: tuple[str, str] | None = None
        self._items: list[tuple[int, dict[str, Any]]] = []
        #: every marker sent: (LSL timestamp, JSON text)
        self.sent: list[tuple[float, str]] = []

    # -- streams -----------------------------------------------------------------------
    def open(self, info: SessionInfo) -> None:
        """Open both outlets with the session's metadata and wait for consumers."""
        lsl = self.lsl
        study = info.study
        source = f"tactorbelt/{info.participant}/session-{info.session_id}"
        m = lsl.StreamInfo(MARKER_STREAM, "Markers", 1, lsl.IRREGULAR_RATE, "string",
                           f"{source}/markers")
        self._describe(m, info)
        m.desc().append_child_value("marker_format", MARKER_FORMAT)
        c = lsl.StreamInfo(CURSOR_STREAM, "Position", 2, float(study.session.sample_rate_hz),
                           "float32", f"{source}/cursor")
        self._describe(c, info)
        chans = c.desc().append_child("channels")
        for label, what in (("x", "right positive"), ("y", "up (front) positive")):
            _child(chans, "channel", label=label, type="Position", unit="ellipse radius",
                   description=f"cursor {label}, {what}; the response ellipse has radius 1")
        try:
            self.markers = lsl.StreamOutlet(m)
            self.cursor = lsl.StreamOutlet(c)
        except (RuntimeError, OSError, ValueError) as exc:  # liblsl: no usable network
            self.close()
            raise ConfigError(f"--lsl: liblsl cannot open the LSL streams ({exc}); check "
                              "the network and the LSL configuration (lsl_api.cfg, "
                              "LSLAPICFG; docs/lsl.md)") from None
        if self.wait_s > 0:
            self.wait_for_consumers()

    def wait_for_consumers(self) -> dict[str, bool]:
        """Wait up to ``wait_s`` for consumers (see the class), saying which streams have
        one and how long is left; returns whether each stream has one."""
        lsl = self.lsl
        outlets = {MARKER_STREAM: self.markers, CURSOR_STREAM: self.cursor}
        need = list(outlets) if self.wait_all else [MARKER_STREAM]
        show = self.operator.show_wait
        start = lsl.local_clock()
        end = start + self.wait_s
        have = dict.fromkeys(outlets, False)
        self.report(f"LSL: waiting up to {self.wait_s:g} s for a recorder (LabRecorder) on "
                    + " and ".join(need) + "; the session starts as soon as "
                    + ("every stream has" if self.wait_all else f"{MARKER_STREAM} has")
                    + " a consumer")
        next_report = start + WAIT_REPORT_S
        ready_at: float | None = None
        stopped = False
        try:
            while True:
                now = lsl.local_clock()
                changed = False
                for name, outlet in outlets.items():
                    got = bool(outlet.have_consumers())
                    changed |= got != have[name]
                    have[name] = got
                if all(have[n] for n in need):
                    ready_at = now if ready_at is None else ready_at
                else:
                    ready_at = None
                done = all(have.values()) or (ready_at is not None
                                              and now - ready_at >= WAIT_GRACE_S)
                if done or now >= end:
                    break
                if changed or now >= next_report:
                    self.report(f"LSL: {self._consumers(have)}; {max(end - now, 0):.0f} s "
                                "left")
                    next_report = now + WAIT_REPORT_S
                if show("Waiting for the recorder", self._wait_lines(have, end - now)):
                    stopped = True  # the experimenter stopped the session
                    break
                time.sleep(WAIT_POLL_S)
        finally:
            show(None, [])
        took = lsl.local_clock() - start
        if stopped:
            self.report(f"LSL: the wait was stopped in the window after {took:.1f} s")
            return have
        late = [n for n in need if not have[n]]
        if late:
            log.warning("no LSL consumer connected to %s within %g s; what it sends before "
                        "one connects is lost", " or ".join(late), self.wait_s)
        other = [n for n in outlets if n not in need and not have[n]]
        self.report(f"LSL: starting after {took:.1f} s; {self._consumers(have)}"
                    + (f" ({', '.join(other)}: what it sends before a consumer connects is "
                       "lost; --lsl-wait-all waits for every stream)" if other else ""))
        return have

    @staticmethod
    def _consumers(have: dict[str, bool]) -> str:
        return ", ".join(f"{n} {'has a consumer' if h else 'has none'}"
                         for n, h in have.items())

    def _wait_lines(self, have: dict[str, bool], left_s: float) -> list[str]:
        """The window's text while waiting for the recorder."""
        return ["The session starts when the lab's recorder (LabRecorder) records "
                + ("every stream." if self.wait_all else f"{MARKER_STREAM}."), "",
                *[f"{n}: {'recorded' if h else 'no recorder yet'}" for n, h in have.items()],
                "", f"{max(left_s, 0):.0f} s left",
                "", "Esc twice: stop the session (saved, can be resumed)."]

    def _describe(self, si: Any, info: SessionInfo) -> None:
        from .. import __version__

        d = si.desc()
        _child(d, "acquisition", manufacturer="tactorbelt", version=__version__,
               clock="sim" if self.clock.simulated else "wall")
        _child(d, "study", name=info.study.name, condition_order=",".join(info.condition_order))
        d.append_child_value("participant", info.participant)
        d.append_child_value("session_id", str(info.session_id))
        belt, cal = self.belt, self.belt.calibration
        b = _child(d, "belt", url=belt.url, drive=belt.drive,
                   firmware_version=str(belt.firmware_version or ""),
                   reports_onsets="true" if belt.reports_onsets else "false",
                   timing_validated=str(cal.validated or ""),
                   timing_method=str(cal.validation_method or ""))
        tactors = b.append_child("tactors")
        for k, angle in enumerate(belt.layout.angles_deg):
            t = _child(tactors, "tactor", index=str(k), angle_deg=f"{angle:g}")
            if k < cal.n:  # measured timing (ms): the skin-onset offset
                for name in ("latency_ms", "latency_sd_ms", "rise_ms", "rise_sd_ms"):
                    v = getattr(cal.tactors[k], name)
                    if v is not None:
                        t.append_child_value(name, f"{v:g}")

    def close(self) -> None:
        """Close both outlets (consumers see the streams end). With a consumer connected,
        first wait :data:`LINGER_S` (real time) so that the last samples reach it: liblsl
        drops what is still queued when an outlet closes."""
        outlets = [o for o in (self.markers, self.cursor) if o is not None]
        self.markers = self.cursor = None
        if any(o.have_consumers() for o in outlets):
            time.sleep(LINGER_S)
        outlets.clear()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def send(self, t_ns: int, event: str, **fields: Any) -> None:
        """Send one marker stamped at ``t_ns`` on the runner's clock."""
        if self.markers is None:
            return
        self._flush_items(t_ns)
        text = marker(event, **fields)
        ts = self.to_lsl(t_ns, MARKER_STREAM)
        self.markers.push_sample([text], ts)
        self.sent.append((ts, text))

    def _flush_items(self, until_ns: int) -> None:
        """Send the announced task items whose onset is at or before ``until_ns``."""
        while self._items and self._items[0][0] <= until_ns:
            onset, fields = self._items.pop(0)
            self.send(onset, "task_item", **fields)

    # -- markers from the session's events ----------------------------------------------
    def _end_block(self, now_ns: int) -> None:
        if self._block is not None:
            self.send(now_ns, "block_end", block_index=self._block)
            self._block = None

    def _end_trial(self, now_ns: int, status: str, reason: str | None) -> None:
        if self._trial is not None:
            self.send(now_ns, "trial_end", trial_index=self._trial.trial_index, status=status,
                      abort_reason=reason)
            self._trial = None

    def on_session_start(self, info: SessionInfo, schedule: list[ScheduledTrial]) -> None:
        self._timeout_ns = round(info.study.response.timeout_s * 1e9)
        self.open(info)
        self.send(self.clock.now_ns(), "session_start", session_id=info.session_id,
                  participant=info.participant, study=info.study.name,
                  n_trials=info.n_total, n_done=info.n_done, resumed=info.resumed)

    def on_block_start(self, block: str, condition: str) -> None:
        # sent with the block's first trial, which names it fully
        self._block_ns = self.clock.now_ns()

    def on_trial_state(self, trial: ScheduledTrial, state: TrialState, now_ns: int) -> None:
        from ..experiment.trial import TrialState

        if state is TrialState.WAIT_HOME:
            if self._block_ns is not None or self._block != trial.block_index:
                at = self._block_ns if self._block_ns is not None else now_ns
                self._end_block(at)
                self.send(at, "block_start", block_index=trial.block_index, block=trial.block,
                          block_name=trial.block_name, **_levels(trial))
                self._block, self._block_ns = trial.block_index, None
            self._trial = trial
            self._onset_pending = False
            self.send(now_ns, "trial_start", trial_index=trial.trial_index,
                      block_index=trial.block_index, block=trial.block, **_levels(trial))
        elif state is TrialState.STIMULUS:
            if self.belt.reports_onsets:
                self._onset_pending = True  # the device's onset comes with the result
            else:
                self._send_onset(trial, now_ns, "host")

    def _send_onset(self, t: ScheduledTrial, onset_ns: int, clock: str) -> None:
        self.send(onset_ns, "stimulus_onset", trial_index=t.trial_index,
                  target_deg=t.target_deg, on_tactor=t.on_tactor, **_levels(t), block=t.block,
                  onset_clock=clock)

    def on_sample(self, sample: CursorSample) -> None:
        self._flush_items(sample.t_ns)
        if self.cursor is not None:
            self.cursor.push_sample([sample.x, sample.y], self.to_lsl(sample.t_ns, CURSOR_STREAM))

    def on_skin_onset(self, trial: ScheduledTrial, skin_onset_ns: int,
                      skin_onset_sd_ns: int) -> None:
        """The runner's skin onset of the trial ending (its calibration has measured
        latencies): marked as ``skin_onset`` when the trial ends."""
        self._skin = (trial.trial_index, int(skin_onset_ns), int(skin_onset_sd_ns))

    def on_trial_done(self, result: TrialResult) -> None:
        t = result.trial
        skin, self._skin = self._skin, None
        if result.onset_ns is not None:  # the onset stored: the device's where it reports one
            stored, clock = ((result.onset_ns, "host") if result.device_onset_ns is None
                             else (result.device_onset_ns, "device"))
            if self._onset_pending:
                self._send_onset(t, stored, clock)
            if skin is not None and skin[0] == t.trial_index:
                self.send(skin[1], "skin_onset", trial_index=t.trial_index,
                          latency_ms=(skin[1] - stored) / 1e6, sd_ms=skin[2] / 1e6)
        self._onset_pending = False
        if result.status == "done" and result.acquired_ns is not None:
            self.send(result.acquired_ns, "response", trial_index=t.trial_index,
                      response_deg=result.response_deg,
                      response_target_deg=result.response_target_deg,
                      correct=result.correct, rt_s=result.rt_s)
        elif result.status == "timeout":
            at = (result.onset_ns + self._timeout_ns if result.onset_ns is not None
                  else self.clock.now_ns())
            self.send(at, "timeout", trial_index=t.trial_index)
        self._trial = t
        self._end_trial(self.clock.now_ns(), result.status, result.abort_reason)

    def on_break(self, n_done: int, n_total: int) -> None:
        self.send(self.clock.now_ns(), "break_start", n_done=n_done, n_total=n_total)

    def on_break_end(self) -> None:
        self.send(self.clock.now_ns(), "break_end")

    def on_task_phase(self, name: str | None, spec: TaskSpec | None, phase: str | None
                      ) -> None:
        now = self.clock.now_ns()
        self._end_task(now)
        if name is not None and spec is not None and phase is not None:
            from ..tasks.kinds import task_kind

            fields = {"n": None, **task_kind(spec.kind).stream_fields(spec)}
            self.send(now, "task_start", task=name, kind=spec.kind, phase=phase,
                      **fields, modality=spec.modality,
                      block_index=self._block if phase == "dual" else None)
            self._task = (name, phase)

    def _end_task(self, now_ns: int) -> None:
        """The running task ends: its items shown by now are sent, the rest never were."""
        self._flush_items(now_ns)
        self._items.clear()
        if self._task is not None:
            name, phase = self._task
            self._task = None
            self.send(now_ns, "task_end", task=name, phase=phase)

    def on_task_item(self, item: TaskItem, onset_ns: int, spec: TaskSpec) -> None:
        name, phase = self._task if self._task is not None else ("", "")
        self._items.append((onset_ns, {"task": name, "phase": phase,
                                       "item_index": item.index, "stimulus": item.stimulus,
                                       "go": item.target}))
        self._items.sort(key=lambda x: x[0])

    def on_task_presses(self, presses: list[int]) -> None:
        if self._task is not None:
            for p in sorted(presses):
                self.send(p, "task_press", task=self._task[0], phase=self._task[1])

    def on_workload(self, info: WorkloadInfo, values: dict[str, float]) -> None:
        from ..tasks import TLX_SCALE

        self.send(self.clock.now_ns(), "workload", block_index=info.block_index,
                  scale=TLX_SCALE, ratings=values)

    def on_session_end(self, status: str) -> None:
        now = self.clock.now_ns()
        self._end_task(now)
        self._end_trial(now, "aborted", None)
        self._end_block(now)
        self.send(now, "session_end", status=status)

    def on_tick(self, now_ns: int) -> None:
        self._flush_items(now_ns)

    def on_command(self, command: Command, now_ns: int) -> None:
        if command is Command.PAUSE and not self._paused:
            self._paused = True
            self.send(now_ns, "pause")
        elif command is Command.RESUME and self._paused:
            self._paused = False
            self.send(now_ns, "resume")
        elif command is Command.ABORT:
            self.send(now_ns, "abort")
