#!/usr/bin/env python3
"""How much a wearer profile helps: the model participant's between-tactor errors in the
paper study with and without its own profile (the closed loop of the perceptual
calibration; docs/calibration-perceptual.md).

For each model participant (drawn around the typical observer): calibrate it on a
simulated belt (QUEST+, the model answering from what it feels), then simulate the paper
study's between-tactor test trials twice, rendered plainly and rendered with its
profile, from the same random draws, and compare:

- ``felt_bias_deg``: the median felt position of the quarter-point targets (15 deg from
  a tactor) relative to the target, positive away from the nearer tactor: the
  systematic error the calibration corrects (the model feels them about 6 deg too near
  the tactor);
- ``answer_bias_deg``: the same for the mean answered target (answers snap to the 24
  targets, 15 deg apart);
- ``mean_abs_error_deg`` and ``accuracy`` of the between-tactor trials.

Run ``python scripts/calibration_effect.py [N]``; scripts/perceptual_loop.py prints it
too. NumPy, tactorbelt.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from tactorbelt.geometry import Layout, TargetSet, wrap
from tactorbelt.participant.params import ModelParams, draw_participant
from tactorbelt.participant.perception import perceive
from tactorbelt.participant.simulate import Protocol, StimulusCues, stimulus_cues

if TYPE_CHECKING:
    from tactorbelt.stimuli import Stimulus
    from tactorbelt.wearer import WearerProfile

__all__ = ["EffectRow", "calibration_effect", "summarise"]


@dataclass(frozen=True)
class EffectRow:
    """One model participant, one condition, with or without its profile (degrees)."""

    participant: str
    condition: str
    profile: bool
    felt_bias_deg: float
    answer_bias_deg: float
    mean_abs_error_deg: float
    accuracy: float


def _with_profile(vib: Callable[[Stimulus, float], Any], profile: WearerProfile
                  ) -> Callable[[Stimulus, float], Any]:
    def vibrate(stimulus: Stimulus, duration_s: float) -> Any:
        return vib(stimulus.with_profile(profile), duration_s)
    return vibrate


def _measure(name: str, protocol: Protocol, cues: StimulusCues, params: ModelParams,
             seed: int, repetitions: int, with_profile: bool) -> list[EffectRow]:
    layout, targets = protocol.layout, protocol.targets
    between = np.flatnonzero(~targets.on_tactor(layout))
    rows = []
    for cond in protocol.conditions:
        idx = np.tile(between, repetitions)
        pc = perceive(cues.by_condition[cond].take(idx), layout, targets, params,
                      np.random.default_rng(seed))
        tgt = targets.angles[idx]
        near = np.array([layout.angles_deg[protocol.stimulus(x, cond).near_idx] for x in tgt])
        away = np.sign(np.asarray(wrap(tgt - near), dtype=float))
        dist = np.abs(np.asarray(wrap(tgt - near), dtype=float))
        quarter = np.abs(dist - 15.0) < 1e-6
        felt = np.asarray(wrap(pc.perceived_deg - tgt), dtype=float) * away
        answer = np.asarray(wrap(pc.response_deg - tgt), dtype=float)
        rows.append(EffectRow(name, cond, with_profile,
                              float(np.median(felt[quarter])),
                              float(np.mean((answer * away)[quarter])),
                              float(np.abs(answer).mean()),
                              float(np.mean(np.abs(answer) < 1e-6))))
    return rows


def calibration_effect(n_participants: int = 6, seed: int = 1, repetitions: int = 20,
                       settings: Any = None) -> list[EffectRow]:
    """Calibrate ``n_participants`` model participants and measure the paper study's
    between-tactor trials (24 targets, static and dynamic, ``repetitions`` each) with and
    without their profiles. ``settings``: a
    :class:`~tactorbelt.calibration.perceptual.CalibrationSettings`."""
    from tactorbelt.calibration.perceptual import run_perceptual_calibration
    from tactorbelt.clock import SimClock
    from tactorbelt.devices.sim import SimBelt
    from tactorbelt.inputs.model import make_model_respondent, sim_vibrator

    layout = Layout.even(6)
    protocol = Protocol(layout, TargetSet.even(24), "paper", 15.0, 1.0, 0.1,
                        (("static", repetitions), ("dynamic", repetitions)))
    rng = np.random.default_rng(seed)
    vib = sim_vibrator(layout)
    rows: list[EffectRow] = []
    for i in range(n_participants):
        name = f"M{i + 1:02d}"
        params = draw_participant(rng, ModelParams())
        clock = SimClock()
        with SimBelt(layout=layout, clock=clock) as belt:
            res = run_perceptual_calibration(
                belt, clock, make_model_respondent(belt, seed * 1000 + i, params),
                participant=name, seed=seed * 1000 + i, settings=settings)
        plain = stimulus_cues(protocol, vib, params)
        warped = stimulus_cues(protocol, _with_profile(vib, res.profile), params)
        s = seed * 7919 + i
        rows += _measure(name, protocol, plain, params, s, repetitions, False)
        rows += _measure(name, protocol, warped, params, s, repetitions, True)
    return rows


def summarise(rows: list[EffectRow]) -> list[dict[str, Any]]:
    """Means over participants per (condition, profile)."""
    out = []
    for cond in dict.fromkeys(r.condition for r in rows):
        for prof in (False, True):
            sel = [r for r in rows if r.condition == cond and r.profile == prof]
            out.append({"condition": cond, "profile": prof, "n_participants": len(sel),
                        **{k: float(np.mean([getattr(r, k) for r in sel]))
                           for k in ("felt_bias_deg", "answer_bias_deg",
                                     "mean_abs_error_deg", "accuracy")}})
    return out


if __name__ == "__main__":
    import sys
    import time

    t0 = time.perf_counter()
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 6
    for row in summarise(calibration_effect(n)):
        print(row)
    print(f"{time.perf_counter() - t0:.1f} s")
