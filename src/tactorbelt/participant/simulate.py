"""Fast simulation of model participants' test trials, without the runner or the store.

The runner path (a :class:`~tactorbelt.inputs.model.ModelCursor` in
:func:`~tactorbelt.experiment.run_session`) plays every trial on a simulated belt,
samples a cursor at 100 Hz and writes SQLite. For power analyses that is far more
than needed: the model's answer depends only on the vibration it feels in its
observation window, which is the same for every presentation of a (target,
condition) pair, since each trial starts from rest. So this module

1. computes the cues of each (target, condition) stimulus once
   (:func:`stimulus_cues`, with the vibration from an injected ``vibrate`` function:
   :func:`tactorbelt.inputs.model.sim_vibrator` gives the ``sim`` belt's);
2. draws every test trial's percept, answer and RT directly (:func:`simulate_participant`).

Trial order does not matter to the model (it neither learns nor tires), so trials are
laid out block by block. RTs are the model's plan (observation + decision + the part
of the movement up to the acquisition radius), not quantised to the runner's 10 ms
samples. tests/test_participant_fast.py checks that the accuracy of this path agrees
with the full runner's.

Pure: imports NumPy, tactorbelt.geometry / stimuli and participant; never an I/O layer
(the vibration function is passed in).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .._errors import ConfigError
from ..geometry import Layout, TargetSet
from ..stimuli import Stimulus, make_stimulus
from .params import ModelParams
from .perception import Cues, perceive, sense_cues
from .timing import decision_s, observation_s, reach_fraction

__all__ = [
    "Protocol",
    "StimulusCues",
    "TrialTable",
    "simulate_participant",
    "stimulus_cues",
]

FloatArray = NDArray[np.float64]
Vibrate = Callable[[Stimulus, float], tuple[Any, Any]]

#: ModelParams fields that shape the cues: every simulated participant must share them.
CUE_FIELDS = ("gamma", "detect_amplitude", "dominance_margin", "observe_static_s",
              "observe_dynamic_s")


@dataclass(frozen=True)
class Protocol:
    """What the fast path needs of a study with one target count (a study's comes from
    its power design: :meth:`tactorbelt.power.design.PowerDesign.protocol`).

    Attributes:
        layout, targets: the tactors and the candidate targets.
        law, falloff_deg, period_s, transit_s: the stimulus rendering.
        blocks: the test blocks as ``(condition, repetitions)``.
        threshold: the acquisition radius (RT counts the movement up to it).
    """

    layout: Layout
    targets: TargetSet
    law: str
    falloff_deg: float
    period_s: float
    transit_s: float
    blocks: tuple[tuple[str, int], ...]
    threshold: float = 0.9

    @property
    def conditions(self) -> tuple[str, ...]:
        """The conditions of the test blocks, each once, in order."""
        return tuple(dict.fromkeys(c for c, _ in self.blocks))

    def stimulus(self, target_deg: float, condition: str) -> Stimulus:
        return make_stimulus(self.layout, target_deg, condition, self.law, self.falloff_deg,
                             self.period_s, self.transit_s)


@dataclass(frozen=True)
class StimulusCues:
    """The cues of every target in each condition, and the observer they were sensed by.

    Attributes:
        by_condition: condition -> cues with one entry per target (target order).
        params: the observer whose gamma, detection level, dominance margin and
            observation times shaped the cues.
    """

    by_condition: Mapping[str, Cues]
    params: ModelParams


def stimulus_cues(protocol: Protocol, vibrate: Vibrate,
                  params: ModelParams | None = None) -> StimulusCues:
    """Sense every (target, condition) stimulus once over its observation window.

    Args:
        protocol: the study.
        vibrate: ``vibrate(stimulus, duration_s) -> (t_s, vibration (n, N))`` from onset.
        params: the observer (default: the typical observer).
    """
    p = params if params is not None else ModelParams()
    out: dict[str, Cues] = {}
    for cond in protocol.conditions:
        duration = observation_s(cond, p)
        windows = []
        t_ref: FloatArray | None = None
        for x in protocol.targets.angles_deg:
            t_s, vib = vibrate(protocol.stimulus(x, cond), duration)
            t = np.asarray(t_s, dtype=float)
            if t_ref is None:
                t_ref = t
            elif t.shape != t_ref.shape or not np.allclose(t, t_ref):
                raise ConfigError("vibrate must sample every stimulus at the same times")
            windows.append(np.asarray(vib, dtype=float))
        assert t_ref is not None
        out[cond] = sense_cues(t_ref, np.stack(windows), protocol.layout, p)
    return StimulusCues(out, p)


@dataclass(frozen=True)
class TrialTable:
    """Simulated test trials of one participant (arrays of equal length).

    Attributes:
        condition: ``static`` or ``dynamic`` per trial.
        target_deg, on_tactor: the target.
        response_deg: the chosen target.
        correct: response == target.
        rt_s: onset to acquisition.
        load: the block's load (``[tasks.NAME]`` name or ``none``) per trial, or None
            when the protocol has no loads (every trial without one).
    """

    condition: NDArray[np.str_]
    target_deg: FloatArray
    on_tactor: NDArray[np.bool_]
    response_deg: FloatArray
    correct: NDArray[np.bool_]
    rt_s: FloatArray
    load: NDArray[np.str_] | None = None

    @property
    def n(self) -> int:
        return int(self.target_deg.shape[0])


def simulate_participant(protocol: Protocol, cues: StimulusCues, params: ModelParams,
                         rng: np.random.Generator) -> TrialTable:
    """Every test trial of one model participant, drawn directly from its perception.

    Raises:
        ConfigError: ``params`` differ from the cues' observer in a field that shapes
            the cues (gamma, detection level, dominance margin, observation times).
    """
    for f in CUE_FIELDS:
        if getattr(params, f) != getattr(cues.params, f):
            raise ConfigError(f"the cues were sensed with {f} = {getattr(cues.params, f)!r} "
                              f"but the participant has {getattr(params, f)!r}; "
                              "sense them again with this observer")
    targets = protocol.targets
    m = targets.m
    on = targets.on_tactor(protocol.layout)
    frac = reach_fraction(protocol.threshold, params.reach_radius)
    conds: list[NDArray[np.str_]] = []
    tdeg: list[FloatArray] = []
    ons: list[NDArray[np.bool_]] = []
    resp: list[FloatArray] = []
    rts: list[FloatArray] = []
    for cond, reps in protocol.blocks:
        idx = np.tile(np.arange(m), reps)
        pc = perceive(cues.by_condition[cond].take(idx), protocol.layout, targets, params, rng)
        n = idx.shape[0]
        rt = (observation_s(cond, params) + decision_s(rng, n, m, params)
              + params.movement_s * frac)
        conds.append(np.full(n, cond))
        tdeg.append(targets.angles[idx])
        ons.append(on[idx])
        resp.append(pc.response_deg)
        rts.append(np.asarray(rt))
    target_deg = np.concatenate(tdeg)
    response_deg = np.concatenate(resp)
    return TrialTable(
        condition=np.concatenate(conds), target_deg=target_deg, on_tactor=np.concatenate(ons),
        response_deg=response_deg, correct=np.abs(response_deg - target_deg) < 1e-6,
        rt_s=np.concatenate(rts),
    )
