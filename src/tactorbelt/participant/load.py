"""The model participant under cognitive load: a documented dual-task model.

A secondary task (``[tasks.NAME]``: n-back or arithmetic) is summarised by one number,
its **load level** ``L`` in [0, 1] (:func:`load_level`): 0 without a task, 1/3, 2/3
and 1 for 1-, 2- and 3-back, 2/3 for odd/even arithmetic. Everything the model does
differently under load follows from ``L`` and :class:`LoadParams`:

- **localisation** (:func:`loaded_params`): while the task runs alongside the
  localisation trials (phase ``dual``), the Weber fractions and the body-site SD grow
  by ``(1 + gain * L)``, the lapse rate by ``lapse_per_load * L``, and the
  non-decision time by ``nondecision_s_per_load * L`` seconds;
- **the secondary task** (:class:`TaskResponder`): an equal-variance signal-detection
  observer with a sensitivity ``d'`` that falls with n (:func:`task_d_prime`) and is
  lower under dual-task (``dual_d_prime_factor``) than alone (phases ``practice`` and
  ``baseline``) and a participant's own ``ability`` factor, a somewhat conservative
  criterion (c = 0.3), and log-normal response times
  that grow with n and under dual-task (:func:`task_rt_median_s`);
- **NASA-TLX** (:func:`tlx_ratings`): a linear mapping from ``L`` to each of the six
  raw-TLX items, with per-participant offsets and item noise, rounded to the slider's
  step of 5.

The model never uses the schedule's answer (``TaskItem.target``): each task kind
(:mod:`tactorbelt.tasks.kinds`) works it out from the items, as a person would (an
n-back keeps the last n items it heard or saw, arithmetic computes the parity of
``a+b``), and says how hard it is (its load level, d' and response-time steps).

Sources are named where the literature supports an effect's direction; every number
is an assumption (docs/participant-model.md, "Under cognitive load"). What the model does
under load follows from these assumptions and is no evidence about people.

Pure: imports the standard library, NumPy, participant.params, the constants of
tactorbelt.tasks (the phases and the TLX items) and its kinds; task specs are read
by their fields (``kind``, ``n``), so any object with them works.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from .._errors import ConfigError
from ..tasks import PHASES, TLX_ITEMS
from ..tasks.kinds import NO_TASK, TaskKind, task_kind
from ..tasks.kinds import TaskFields as TaskLike
from .params import ModelParams

__all__ = [
    "PHASES",
    "TLX_ITEMS",
    "LoadParams",
    "TaskLike",
    "TaskResponder",
    "load_level",
    "loaded_params",
    "task_d_prime",
    "task_hit_fa",
    "task_rt_median_s",
    "tlx_ratings",
]


def _kind(spec: TaskLike) -> TaskKind:
    try:
        return task_kind(spec.kind)
    except ValueError as exc:
        raise ConfigError(f"unknown secondary task kind: {exc}") from None


def load_level(spec: TaskLike | None) -> float:
    """The task's load level L in [0, 1]: 0 without a task (or ``kind = "none"``),
    ``n / 3`` for an n-back (1/3, 2/3, 1), 2/3 for arithmetic (assumption: odd/even of a
    one-digit sum is about as demanding as a 2-back)."""
    if spec is None or spec.kind == NO_TASK:
        return 0.0
    return _kind(spec).load_level(spec)


@dataclass(frozen=True)
class LoadParams:
    """How load changes the model participant (every default is documented).

    Localisation while a task runs (dual phase), at load level L:

    Attributes:
        weber_gain: Weber fractions (amplitude and duration) times ``1 + gain * L``
            (0.5: 50 % noisier at 3-back). Assumption: dual-task interference on
            tactile judgements (Wickens' multiple resources, 2002: touch and hearing
            or vision share central resources) with no published number for this task.
        loc_sd_gain: body-site SDs and the midline bias times ``1 + gain * L`` (0.4).
            Assumption.
        lapse_per_load: lapse rate plus ``lapse_per_load * L`` (0.04): attention
            drawn to the secondary task now and then. Assumption.
        nondecision_s_per_load: non-decision time plus this many seconds times L
            (0.15 s). Assumption, of the order of dual-task slowing of choice RTs
            (the psychological refractory period: a few hundred ms at short SOAs,
            Pashler 1994), diluted because items come only every interval_s.

    The secondary task (signal detection, go/no-go):

    Attributes:
        d_prime_nback: single-task d' of 1-, 2- and 3-back ((3.5, 2.7, 1.8)).
            Assumption in numbers; that accuracy falls as n grows is the n-back's
            classic finding (Kirchner 1958; Jaeggi et al. 2010).
        d_prime_arithmetic: single-task d' of odd/even arithmetic (3.0). Assumption.
        dual_d_prime_factor: d' under dual-task times this (0.8). Assumption (a
            dual-task cost on the secondary task; its size depends on the pairing).
        criterion: the signal-detection criterion c (0.3: somewhat conservative, as
            go/no-go responders with rare targets are). Assumption.
        rt_s: median RT of a 1-back or arithmetic press alone (0.55 s). Assumption.
        rt_s_per_n: median RT plus this per n above 1 (0.12 s). Assumption (slower
            answers at higher n, as n-back studies commonly report).
        dual_rt_s: median RT plus this under dual-task (0.12 s). Assumption.
        rt_log_sd: SD of log RT (0.25). Assumption (a usual skew of RTs).

    NASA-TLX (raw, 0..100):

    Attributes:
        tlx_base: each item's rating without a task, in :data:`TLX_ITEMS` order
            ((30, 15, 30, 25, 35, 20)). Assumption (a localisation block alone is
            rated low to moderate).
        tlx_per_load: each item's increase from L = 0 to L = 1
            ((45, 5, 30, 20, 35, 30)). Assumption in numbers; raw TLX grows with
            n-back level in published studies (mental demand and effort most,
            physical demand least; Hart & Staveland 1988 for the scales).
        tlx_person_sd: SD of a participant's offset, shared by its six items (10).
            Assumption.
        tlx_item_sd: SD of the noise of each answer (6). Assumption.

    Individual differences in the task:

    Attributes:
        ability_sd: each model participant's d' is multiplied by ``exp(N(0, sd))``,
            drawn once from its seed (0.15). Assumption.
    """

    weber_gain: float = 0.5
    loc_sd_gain: float = 0.4
    lapse_per_load: float = 0.04
    nondecision_s_per_load: float = 0.15
    d_prime_nback: tuple[float, float, float] = (3.5, 2.7, 1.8)
    d_prime_arithmetic: float = 3.0
    dual_d_prime_factor: float = 0.8
    criterion: float = 0.3
    rt_s: float = 0.55
    rt_s_per_n: float = 0.12
    dual_rt_s: float = 0.12
    rt_log_sd: float = 0.25
    tlx_base: tuple[float, ...] = (30.0, 15.0, 30.0, 25.0, 35.0, 20.0)
    tlx_per_load: tuple[float, ...] = (45.0, 5.0, 30.0, 20.0, 35.0, 30.0)
    tlx_person_sd: float = 10.0
    tlx_item_sd: float = 6.0
    ability_sd: float = 0.15

    def __post_init__(self) -> None:
        for f in fields(self):
            v = getattr(self, f.name)
            vals = v if isinstance(v, tuple) else (v,)
            for x in vals:
                if isinstance(x, bool) or not isinstance(x, int | float) or not math.isfinite(x):
                    raise ConfigError(f"LoadParams.{f.name} must hold finite numbers, got {v!r}")
                if f.name != "criterion" and x < 0:
                    raise ConfigError(f"LoadParams.{f.name} must be >= 0, got {v!r}")
        if len(self.d_prime_nback) != 3:
            raise ConfigError("LoadParams.d_prime_nback holds the d' of 1-, 2- and 3-back")
        if len(self.tlx_base) != 6 or len(self.tlx_per_load) != 6:
            raise ConfigError("LoadParams.tlx_base and tlx_per_load hold one value per TLX "
                              f"item ({', '.join(TLX_ITEMS)})")
        if self.dual_d_prime_factor > 1:
            raise ConfigError("LoadParams.dual_d_prime_factor must be in [0, 1]")

    def to_dict(self) -> dict[str, Any]:
        """The parameters as a plain dict (for JSON)."""
        return {f.name: (list(getattr(self, f.name)) if isinstance(getattr(self, f.name), tuple)
                         else float(getattr(self, f.name))) for f in fields(self)}


def loaded_params(params: ModelParams, level: float, load: LoadParams = LoadParams()
                  ) -> ModelParams:
    """The observer ``params`` while a task of load ``level`` runs alongside localisation.

    ``level = 0`` returns ``params`` unchanged.
    """
    if not (math.isfinite(level) and 0.0 <= level <= 1.0):
        raise ConfigError(f"a load level is in [0, 1], got {level!r}")
    if level == 0.0:
        return params
    w = 1.0 + load.weber_gain * level
    s = 1.0 + load.loc_sd_gain * level
    return params.replace(
        weber_amplitude=params.weber_amplitude * w,
        weber_duration=params.weber_duration * w,
        loc_sd_min_deg=params.loc_sd_min_deg * s,
        loc_sd_max_deg=params.loc_sd_max_deg * s,
        midline_bias_deg=params.midline_bias_deg * s,
        lapse=min(1.0, params.lapse + load.lapse_per_load * level),
        nondecision_s=params.nondecision_s + load.nondecision_s_per_load * level,
    )


def _dual(phase: str | None) -> bool:
    if phase not in PHASES:
        raise ConfigError(f"a task phase is one of {', '.join(PHASES)}, got {phase!r}")
    return phase == "dual"


def task_d_prime(spec: TaskLike, phase: str, load: LoadParams = LoadParams(),
                 ability: float = 1.0) -> float:
    """The model's d' on ``spec`` in ``phase`` (lower in ``dual`` than alone), times the
    participant's ``ability`` (1: the typical participant)."""
    if spec.kind == NO_TASK:
        raise ConfigError(f"a task of kind {spec.kind!r} has no items to answer")
    d = _kind(spec).model_d_prime(spec, load)
    return d * ability * (load.dual_d_prime_factor if _dual(phase) else 1.0)


def _phi(x: float) -> float:
    return 0.5 * (1.0 + math.erf(x / math.sqrt(2.0)))


def task_hit_fa(spec: TaskLike, phase: str, load: LoadParams = LoadParams(),
                ability: float = 1.0) -> tuple[float, float]:
    """The model's expected (hit rate, false-alarm rate): ``Phi(d'/2 - c)``, ``Phi(-d'/2 - c)``."""
    d = task_d_prime(spec, phase, load, ability)
    return _phi(d / 2.0 - load.criterion), _phi(-d / 2.0 - load.criterion)


def task_rt_median_s(spec: TaskLike, phase: str, load: LoadParams = LoadParams()) -> float:
    """The model's median press RT (seconds from the item's onset)."""
    steps = _kind(spec).model_rt_steps(spec)
    return load.rt_s + load.rt_s_per_n * steps + (load.dual_rt_s if _dual(phase) else 0.0)


class TaskResponder:
    """The model answering one secondary task: it hears or sees each item and presses.

    Call :meth:`start` when a task phase starts, :meth:`item` for each item (its
    stimulus text and onset), :meth:`presses` for the presses due by a time.

    Args:
        rng: the participant's random generator.
        load: the dual-task model.
        ability: the participant's d' factor (1: the typical participant).

    Presses stay inside the item's response window: at most ``interval_s - 0.05`` s
    after the onset (``interval_s`` given to :meth:`start`).
    """

    def __init__(self, rng: np.random.Generator, load: LoadParams = LoadParams(),
                 ability: float = 1.0) -> None:
        self._rng = rng
        self.load = load
        #: this participant's d' factor (:attr:`LoadParams.ability_sd`)
        self.ability = float(ability)
        self._spec: TaskLike | None = None
        self._phase: str | None = None
        self._memory: deque[str] = deque()
        self._pending: list[int] = []
        self._window_s = 2.0

    @property
    def active(self) -> bool:
        return self._spec is not None

    def start(self, spec: TaskLike | None, phase: str | None, interval_s: float = 2.5) -> None:
        """A task phase starts (``spec``, ``phase``) or ends (None, None). Presses still
        planned for the previous run's items are dropped (they belong to no run)."""
        if spec is None or spec.kind == NO_TASK:
            self._spec = None
            self._phase = None
        else:
            _dual(phase)
            self._spec = spec
            self._phase = phase
            self._window_s = max(0.05, float(interval_s) - 0.05)
        self._memory.clear()
        self._pending.clear()

    def is_go(self, stimulus: str) -> bool | None:
        """Whether ``stimulus`` is a go item by the model's own reckoning (and remembers
        it); None while an n-back's memory holds fewer than n items."""
        spec = self._spec
        assert spec is not None
        return _kind(spec).model_is_go(spec, stimulus, self._memory)

    def item(self, stimulus: str, onset_ns: int) -> int | None:
        """The model perceives an item presented at ``onset_ns``; returns the time of its
        press, or None (no press)."""
        spec = self._spec
        if spec is None:
            return None
        assert self._phase is not None
        go = self.is_go(stimulus)
        hit, fa = task_hit_fa(spec, self._phase, self.load, self.ability)
        u = float(self._rng.random())
        if not (u < (hit if go else fa)):
            return None
        median = task_rt_median_s(spec, self._phase, self.load)
        rt = median * math.exp(self.load.rt_log_sd * float(self._rng.standard_normal()))
        rt = min(max(rt, 0.15), self._window_s)
        t = int(onset_ns) + round(rt * 1e9)
        self._pending.append(t)
        return t

    def presses(self, now_ns: int) -> list[int]:
        """The presses due by ``now_ns`` (each returned once)."""
        due = [t for t in self._pending if t <= now_ns]
        if due:
            self._pending = [t for t in self._pending if t > now_ns]
        return sorted(due)


def tlx_ratings(level: float, rng: np.random.Generator, person_offset: float = 0.0,
                load: LoadParams = LoadParams()) -> dict[str, float]:
    """The model's raw NASA-TLX answers after a block of load ``level``.

    Each item is ``base + per_load * L + person_offset + N(0, item_sd)``, clipped to
    0..100 and rounded to the slider's step of 5.
    """
    noise = rng.standard_normal(len(TLX_ITEMS)) * load.tlx_item_sd
    out: dict[str, float] = {}
    for i, name in enumerate(TLX_ITEMS):
        v = load.tlx_base[i] + load.tlx_per_load[i] * level + person_offset + float(noise[i])
        out[name] = float(min(100.0, max(0.0, 5.0 * round(v / 5.0))))
    return out

