"""The model participant as a cursor source: it feels the belt and moves a cursor.

:func:`make_model_cursor` returns a :class:`ModelCursor`, a
:class:`~tactorbelt.inputs.base.CursorSource` like a joystick, so the runner, the store
and the window see what they would see with a person:

- :meth:`~ModelCursor.trial_started` records the onset; nothing about the target is
  known (test trials carry no answer; in training the highlighted target is given and
  the model moves there);
- the first :meth:`~ModelCursor.read` at or after ``onset + observation time`` asks the
  belt for the vibration between onset and now (``sense(t0_ns, t1_ns)``, by default
  ``belt.vibration`` of the ``sim`` belt), perceives it
  (:mod:`tactorbelt.participant.perception`), picks a target and plans a minimum-jerk
  movement from home to it, which starts after the decision time;
- :meth:`~ModelCursor.trial_ended` springs the cursor back home.

Under cognitive load (:mod:`tactorbelt.participant.load`) the runner tells it when a
secondary task runs (:meth:`~ModelCursor.task_phase`) and which items come
(:meth:`~ModelCursor.task_item`): it localises with the loaded observer while a task
runs alongside the trials (phase ``dual``), presses the response button for the items
it judges go items (:meth:`~ModelCursor.task_presses`; it keeps its own memory of the
last n items and never reads the schedule's answer) and answers the NASA-TLX after a
block (:meth:`~ModelCursor.rate_workload`). The task and the TLX draw from generators
of their own, so a session without a load is the same as before.

The model is a simulated observer; what it does follows from its assumptions and is
no evidence about people (docs/participant-model.md).

Also :class:`ModelRespondent`, the model answering the perceptual calibration's trials
(:mod:`tactorbelt.calibration.perceptual`) from the vibration it feels, and :func:`sim_vibrator`,
the vibration of one stimulus on a fresh ``sim`` belt, for
the fast (runner-free) simulations of :mod:`tactorbelt.participant.simulate`.

I/O edge: imports tactorbelt.participant (pure) and, in :func:`sim_vibrator`, the sim
belt; never the window or a hardware backend.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from .._errors import ConfigError
from ..calibration.perceptual import Interval, Respondent
from ..clock import Clock, SimClock
from ..geometry import TargetSet
from ..participant.calibration import judge_side, judge_stronger
from ..participant.load import LoadParams, TaskResponder, load_level, loaded_params, tlx_ratings
from ..participant.params import ModelParams
from ..participant.perception import Percepts, perceive_vibration
from ..participant.timing import observation_s, one_decision_s
from . import participant_seed
from .base import CursorSample, CursorSource, RunTaker, TrialCue

if TYPE_CHECKING:
    from ..devices.base import Belt
    from ..geometry import Layout
    from ..stimuli import Stimulus
    from ..tasks import WorkloadInfo
    from ..tasks.schedule import TaskItem
    from ..tasks.spec import TaskSpec
    from .kinds import InputContext

__all__ = ["ModelCursor", "ModelDecision", "ModelRespondent", "Sense", "make_model_cursor",
           "make_model_respondent", "sim_vibrator"]

#: Sensor noise is drawn this many values at a time.
_NOISE_BLOCK = 4096

#: ``sense(t0_ns, t1_ns) -> (t_ns (n,), vibration (n, N))``: what the belt did.
Sense = Callable[[int, int], tuple[Any, Any]]


@dataclass(frozen=True)
class ModelDecision:
    """What the model decided in one trial (for inspection and tests).

    Attributes:
        trial_index: the trial.
        block: ``training`` or ``test``.
        decided_ns: when it decided (end of the observed window).
        answer_deg: the target it moves to.
        move_start_ns: when the movement starts.
        percept: the percept (None in training, where the shown target is used).
    """

    trial_index: int
    block: str
    decided_ns: int
    answer_deg: float
    move_start_ns: int
    percept: Percepts | None


@dataclass(frozen=True)
class _Move:
    start_ns: int
    duration_ns: int
    x0: float
    y0: float
    x1: float
    y1: float

    def at(self, now_ns: int) -> tuple[float, float]:
        s = (now_ns - self.start_ns) / self.duration_ns
        if s <= 0.0:
            return self.x0, self.y0
        if s >= 1.0:
            return self.x1, self.y1
        f = s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)  # minimum jerk (timing.min_jerk)
        return self.x0 + (self.x1 - self.x0) * f, self.y0 + (self.y1 - self.y0) * f

    def at_many(self, t_ns: NDArray[np.int64]) -> tuple[NDArray[np.float64],
                                                        NDArray[np.float64]]:
        """:meth:`at` for many increasing times, with the same floating-point operations
        in the same order (so each value is bit for bit what :meth:`at` gives)."""
        s = (t_ns - self.start_ns) / self.duration_ns
        # the times are increasing: before the movement (s <= 0), during it, after it
        i0 = int(s.searchsorted(0.0, side="right"))
        i1 = int(s.searchsorted(1.0, side="left"))
        x, y = np.empty(s.shape[0]), np.empty(s.shape[0])
        x.fill(self.x0)
        y.fill(self.y0)
        if i1 < s.shape[0]:
            x[i1:], y[i1:] = self.x1, self.y1
        if i1 > i0:
            m = s[i0:i1]
            f = m * m * m * (10.0 - 15.0 * m + 6.0 * m * m)
            x[i0:i1] = self.x0 + (self.x1 - self.x0) * f
            y[i0:i1] = self.y0 + (self.y1 - self.y0) * f
        return x, y


class ModelCursor(CursorSource):
    """A model participant driving the cursor (see the module docstring).

    No person moves it (:attr:`person` is False).

    Args:
        sense: ``sense(t0_ns, t1_ns) -> (t_ns, vibration)`` on the runner's clock.
        seed: seeds the observer's random generator (perception, timing, movement).
        params: the observer (default: the typical observer, :class:`ModelParams`).
        clock: the runner's clock (kept for reference; reads are timed by ``now_ns``).
        load: the dual-task model (default: :class:`LoadParams`, docs/participant-model.md).
    """

    person = False
    reads_runs = True

    def __init__(self, sense: Sense, seed: int, params: ModelParams | None = None,
                 clock: Clock | None = None, load: LoadParams | None = None) -> None:
        self.params = params if params is not None else ModelParams()
        self.load = load if load is not None else LoadParams()
        #: The observer localising now (``params`` under the running task's load).
        self.active_params = self.params
        #: The running task's load level (0 without a task alongside the trials).
        self.load_level = 0.0
        task_seq, tlx_seq = np.random.SeedSequence([int(seed), 18]).spawn(2)
        task_rng = np.random.default_rng(task_seq)
        ability = float(np.exp(task_rng.normal(0.0, self.load.ability_sd)))
        self._task = TaskResponder(task_rng, self.load, ability)
        self._tlx_rng = np.random.default_rng(tlx_seq)
        self._tlx_offset = float(self._tlx_rng.normal(0.0, self.load.tlx_person_sd))
        self.clock = clock
        self._sense = sense
        self._seed = int(seed)
        self._rng = np.random.default_rng(seed)
        self._cue: TrialCue | None = None
        self._onset_ns = 0
        self._decide_ns: int | None = None
        self._move = _Move(0, 1, 0.0, 0.0, 0.0, 0.0)  # at rest in the centre
        self._target_set = functools.cache(TargetSet)  # one per candidate set shown
        self._noise: list[float] | None = None  # the block as a list, for tick-by-tick reads
        self._noise_arr: NDArray[np.float64] = np.zeros(0)
        self._noise_i = 0
        #: The decision of the latest trial (None before the first decision).
        self.last_decision: ModelDecision | None = None

    # -- CursorSource -------------------------------------------------------------------
    def trial_started(self, cue: TrialCue, onset_ns: int) -> None:
        self._cue = cue
        self._onset_ns = int(onset_ns)
        obs = observation_s(cue.condition, self.params)
        self._decide_ns = self._onset_ns + round(obs * 1e9)
        x, y = self._move.at(self._onset_ns)
        self._move = _Move(self._onset_ns, 1, x, y, x, y)

    def trial_ended(self, now_ns: int) -> None:
        x, y = self._move.at(int(now_ns))
        self._move = _Move(int(now_ns), max(round(self.params.return_s * 1e9), 1), x, y,
                           0.0, 0.0)
        self._cue = None
        self._decide_ns = None

    def read(self, now_ns: int) -> CursorSample:
        now = int(now_ns)
        if self._cue is not None and self._decide_ns is not None and now >= self._decide_ns:
            self._decide(now)
        x, y = self._move.at(now)
        j = self.params.jitter
        if j > 0:
            if self._noise_i + 2 > self._noise_arr.shape[0]:
                self._refill_noise()
            noise = self._noise
            if noise is None:  # indexing a list is faster than an array, tick by tick
                noise = self._noise = self._noise_arr.tolist()
            i = self._noise_i
            x += j * noise[i]
            y += j * noise[i + 1]
            self._noise_i = i + 2
        return CursorSample(now, x, y, 0)

    def read_run(self, times_ns: NDArray[np.int64], take: RunTaker) -> int:
        """:meth:`read` at a run of sampling times (the runner's fast path): the same
        positions, decision and sensor noise, in the same order of random draws.

        A run decides (reads the belt) only at its first time and ends before the next
        decision is due and where the drawn noise runs out, so what ``take`` leaves
        unread has had no effect."""
        times = np.asarray(times_ns, dtype=np.int64)
        first = int(times[0])
        if self._cue is not None and self._decide_ns is not None and first >= self._decide_ns:
            self._decide(first)
        n = times.shape[0]
        if self._cue is not None and self._decide_ns is not None:
            n = min(n, int(times.searchsorted(self._decide_ns, side="left")))
        j = self.params.jitter
        if j > 0:
            if self._noise_i + 2 > self._noise_arr.shape[0]:
                self._refill_noise()
            n = min(n, (self._noise_arr.shape[0] - self._noise_i) // 2)
        t = times[:n]
        x, y = self._move.at_many(t)
        if j > 0:
            i = self._noise_i
            noise = self._noise_arr[i : i + 2 * n]
            x = x + j * noise[0::2]
            y = y + j * noise[1::2]
        m = int(take(t, x, y))
        if not 1 <= m <= n:
            raise ValueError(f"take() used {m} of a run of {n} samples")
        if j > 0:
            self._noise_i += 2 * m
        return m

    def calibration_respondent(self, seed: int) -> Respondent:
        """The same observer answering perceptual-calibration trials on the same belt
        (its answers seeded from its own seed and ``seed``; its cursor's draws untouched)."""
        state = np.random.SeedSequence([self._seed, int(seed)]).generate_state(1)[0]
        return ModelRespondent(self._sense, int(state), self.params)

    # -- secondary tasks and workload -------------------------------------------------------
    def task_phase(self, spec: TaskSpec | None, phase: str | None) -> None:
        """A task starts (practice or baseline: alone; dual: alongside the trials) or
        ends (None, None)."""
        interval = float(spec.interval_s) if spec is not None else 2.5
        self._task.start(spec, phase, interval)
        self.load_level = load_level(spec) if phase == "dual" else 0.0
        self.active_params = loaded_params(self.params, self.load_level, self.load)

    def task_item(self, item: TaskItem, onset_ns: int) -> None:
        """The model hears or sees ``item`` at ``onset_ns`` and may plan a press."""
        self._task.item(item.stimulus, int(onset_ns))

    def task_presses(self, now_ns: int) -> list[int]:
        return self._task.presses(int(now_ns))

    def rate_workload(self, info: WorkloadInfo) -> dict[str, float] | None:
        """The model's raw NASA-TLX after a block (:func:`tlx_ratings` of its load)."""
        return tlx_ratings(load_level(info.task), self._tlx_rng, self._tlx_offset, self.load)

    # -- internals -------------------------------------------------------------------------
    def _refill_noise(self) -> None:
        self._noise_arr = self._rng.standard_normal(_NOISE_BLOCK)
        self._noise = None
        self._noise_i = 0

    def _decide(self, now_ns: int) -> None:
        cue = self._cue
        assert cue is not None
        self._decide_ns = None
        p = self.active_params
        percept: Percepts | None = None
        if cue.block == "training" and cue.shown_target_deg is not None:
            answer = float(cue.shown_target_deg)
        else:
            t_ns, vib = self._sense(self._onset_ns, now_ns)
            t_s = (np.asarray(t_ns, dtype=np.int64) - self._onset_ns) / 1e9
            targets = self._target_set(tuple(cue.targets_deg))
            percept = perceive_vibration(t_s, vib, cue.layout, targets, p, self._rng)
            answer = float(percept.response_deg[0])
        wait = one_decision_s(self._rng, len(cue.targets_deg), p)
        angle = math.radians(answer + float(self._rng.normal(0.0, p.endpoint_sd_deg)))
        start = now_ns + round(wait * 1e9)
        x0, y0 = self._move.at(now_ns)
        r = p.reach_radius
        self._move = _Move(start, max(round(p.movement_s * 1e9), 1), x0, y0,
                           r * math.sin(angle), r * math.cos(angle))
        self.last_decision = ModelDecision(cue.trial_index, cue.block, now_ns, answer, start,
                                           percept)


def make_model_cursor(belt: Belt, clock: Clock, seed: int, params: ModelParams | None = None,
                      sense: Sense | None = None, load: LoadParams | None = None
                      ) -> CursorSource:
    """A model participant that feels ``belt`` and answers with a cursor.

    Args:
        belt: the belt the runner plays on; unless ``sense`` is given it must model its
            vibration (``belt.vibration(t0_ns, t1_ns)``, as the ``sim`` belt does).
        clock: the runner's clock.
        seed: seeds the observer (same seed, same session: the run is reproducible).
        params: the observer (default: the typical observer).
        sense: ``sense(t0_ns, t1_ns) -> (t_ns, vibration (n, N))`` to use instead of
            ``belt.vibration``.
        load: the dual-task model (default: :class:`LoadParams`).

    Raises:
        ConfigError: the belt models no vibration and no ``sense`` was given, the seed is
            not an integer, or ``params`` or ``load`` is not of its type.
    """
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
        raise ConfigError(f"the model participant's seed must be an integer, got {seed!r}")
    if params is not None and not isinstance(params, ModelParams):
        raise ConfigError(f"params must be a ModelParams, got {type(params).__name__}")
    if load is not None and not isinstance(load, LoadParams):
        raise ConfigError(f"load must be a LoadParams, got {type(load).__name__}")
    return ModelCursor(sense if sense is not None else _sense(belt), int(seed), params, clock,
                       load)


def _sense(belt: Belt) -> Sense:
    """The vibration ``belt`` models, felt by the model participant."""
    if not belt.models_vibration:
        raise ConfigError(f"the model participant feels the vibration a simulated belt "
                          f"models; belt {belt.url!r} models none. Use --belt sim with "
                          "--input model")
    return belt.vibration


class ModelRespondent(Respondent):
    """The model participant answering perceptual-calibration trials
    (a :class:`tactorbelt.calibration.perceptual.Respondent`) from the vibration it feels
    on the belt.

    It reads only ``sense(t0_ns, t1_ns)`` of each interval (never the stimulus value):
    intensity from the whole interval, location from its static observation window.

    Args:
        sense: ``sense(t0_ns, t1_ns) -> (t_ns, vibration)``, by default the sim belt's.
        seed: seeds its judgements.
        params: the observer.
    """

    name = "model"

    def __init__(self, sense: Sense, seed: int, params: ModelParams | None = None) -> None:
        self.params = params if params is not None else ModelParams()
        self._sense = sense
        self._rng = np.random.default_rng(seed)

    def say(self, text: str) -> None:
        """The model reads no instructions."""

    def stronger(self, first: Interval, second: Interval) -> int:
        _, v1 = self._sense(first.t0_ns, first.t1_ns)
        _, v2 = self._sense(second.t0_ns, second.t1_ns)
        return judge_stronger(v1, first.tactor, v2, second.tactor, self.params, self._rng)

    def side(self, interval: Interval, pair: tuple[int, int], marked_deg: float,
             layout: Layout) -> int:
        t1 = min(interval.t1_ns, interval.t0_ns + round(self.params.observe_static_s * 1e9))
        t_ns, vib = self._sense(interval.t0_ns, t1)
        t_s = (np.asarray(t_ns, dtype=np.int64) - interval.t0_ns) / 1e9
        return judge_side(t_s, vib, layout, marked_deg, self.params, self._rng, pair[0])


def make_model_respondent(belt: Belt, seed: int, params: ModelParams | None = None
                          ) -> ModelRespondent:
    """The model participant answering calibration trials on ``belt`` (a belt that models
    its vibration: ``--belt sim``).

    Raises:
        ConfigError: the belt models no vibration.
    """
    return ModelRespondent(_sense(belt), int(seed), params)


def sim_vibrator(layout: Layout, **sim_options: Any
                 ) -> Callable[[Stimulus, float], tuple[NDArray[np.float64],
                                                        NDArray[np.float64]]]:
    """The vibration of a stimulus played from rest on a fresh ``sim`` belt.

    Returns ``vibrate(stimulus, duration_s) -> (t_s (n,), vibration (n, N))`` sampled
    at 1 kHz from onset, exactly what a model participant senses in the runner over
    its observation window. ``sim_options`` go to the sim belt (``calibration``,
    ``params``).
    """
    from ..devices.sim import SimBelt

    def vibrate(stimulus: Stimulus, duration_s: float) -> tuple[NDArray[np.float64],
                                                                 NDArray[np.float64]]:
        clock = SimClock()
        belt = SimBelt(layout=layout, clock=clock, **sim_options)
        with belt:
            belt.play(stimulus)
            t0 = clock.now_ns() + belt.preroll_ns  # the onset, as Player.start gives it
            clock.advance(round(duration_s * 1e9))
            t_ns, vib = belt.vibration(t0, clock.now_ns())
        return (np.asarray(t_ns) - t0) / 1e9, np.asarray(vib)

    return vibrate


def cursor(ctx: InputContext) -> CursorSource:
    """The ``model`` input kind's cursor (:mod:`tactorbelt.inputs.kinds`): its own seed
    ``ctx.cursor_seed``, else :func:`~tactorbelt.inputs.participant_seed` of the
    session's seed and the participant; the typical observer timed for the study's
    dynamic period unless ``ctx.params``."""
    if ctx.belt is None or ctx.clock is None or ctx.study is None:
        raise ConfigError("the model participant (--input model) needs the belt and the "
                          "clock")
    session_seed = ctx.study.session.seed if ctx.seed is None else int(ctx.seed)
    own = participant_seed(session_seed, ctx.participant) if ctx.cursor_seed is None \
        else int(ctx.cursor_seed)
    params = ctx.params if ctx.params is not None else \
        ModelParams().for_period(ctx.study.stimulus.period_s)
    return make_model_cursor(ctx.belt, ctx.clock, own, params=params)


def respondent(ctx: InputContext) -> Respondent:
    """The ``model`` input kind's respondent for the perceptual calibration."""
    if ctx.belt is None:
        raise ConfigError("the model participant (--input model) needs the belt")
    return make_model_respondent(ctx.belt, int(ctx.seed or 0), ctx.params)
