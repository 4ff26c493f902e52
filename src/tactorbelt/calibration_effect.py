"""How much a wearer profile helps: the model participant's between-tactor errors in the
paper study with and without its own profile (the closed loop of the perceptual
calibration; docs/calibration-perceptual.md).

For each model participant: calibrate it on a simulated belt (QUEST+ with the model
answering from what it feels), then simulate the paper study's test trials (the fast
path, :mod:`tactorbelt.participant.simulate`) twice, rendered plainly and rendered with
its profile, and compare the between-tactor errors.

Library: NumPy, tactorbelt.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .geometry import Layout, TargetSet, wrap
from .participant.params import ModelParams, draw_participant
from .participant.simulate import Protocol, simulate_participant, stimulus_cues

__all__ = ["EffectRow", "calibration_effect"]


@dataclass(frozen=True)
class EffectRow:
    """One participant and condition: mean absolute and signed (away from the nearer
    tactor, positive) errors of between-tactor trials, in degrees, and accuracy."""

    participant: str
    condition: str
    profile: bool
    mean_abs_error_deg: float
    mean_error_from_near_deg: float
    accuracy: float


def _rows(name: str, protocol: Protocol, table: object, with_profile: bool) -> list[EffectRow]:
    from .participant.simulate import TrialTable

    assert isinstance(table, TrialTable)
    out = []
    layout = protocol.layout
    for cond in protocol.conditions:
        sel = (table.condition == cond) & ~table.on_tactor
        tgt, resp = table.target_deg[sel], table.response_deg[sel]
        err = np.asarray(wrap(resp - tgt), dtype=float)
        near = np.array([layout.angles_deg[protocol.stimulus(x, cond).near_idx] for x in tgt])
        away = np.sign(np.asarray(wrap(tgt - near), dtype=float))  # direction from near
        out.append(EffectRow(name, cond, with_profile, float(np.abs(err).mean()),
                             float((err * away).mean()), float(table.correct[sel].mean())))
    return out


def calibration_effect(n_participants: int = 6, seed: int = 1, repetitions: int = 20
                       ) -> list[EffectRow]:
    """Calibrate ``n_participants`` model participants and simulate the paper study
    (24 targets, static and dynamic, ``repetitions`` per target) with and without their
    profiles."""
    from .clock import SimClock
    from .devices.sim import SimBelt
    from .inputs.model import make_model_respondent, sim_vibrator
    from .perceptual import run_perceptual_calibration

    layout = Layout.even(6)
    protocol = Protocol(layout, TargetSet.even(24), "paper", 15.0, 1.0, 0.1,
                        (("static", repetitions), ("dynamic", repetitions)))
    rng = np.random.default_rng(seed)
    vib = sim_vibrator(layout)
    base = stimulus_cues(protocol, vib)
    rows: list[EffectRow] = []
    for i in range(n_participants):
        name = f"M{i + 1:02d}"
        params = draw_participant(rng, ModelParams())
        clock = SimClock()
        with SimBelt(layout=layout, clock=clock) as belt:
            res = run_perceptual_calibration(
                belt, clock, make_model_respondent(belt, seed * 1000 + i, params),
                participant=name, seed=seed * 1000 + i)
        prof = res.profile
        cues = stimulus_cues(protocol, lambda s, d, p=prof: vib(s.with_profile(p), d), params)
        plain = simulate_participant(protocol, base if params == base.params else
                                     stimulus_cues(protocol, vib, params), params,
                                     np.random.default_rng(seed * 7 + i))
        warped = simulate_participant(protocol, cues, params,
                                      np.random.default_rng(seed * 7 + i))
        rows += _rows(name, protocol, plain, False) + _rows(name, protocol, warped, True)
    return rows


if __name__ == "__main__":  # pragma: no cover - a measurement, not an API
    import time

    t0 = time.perf_counter()
    table = calibration_effect()
    for cond in ("static", "dynamic"):
        for prof in (False, True):
            sel = [r for r in table if r.condition == cond and r.profile == prof]
            mae = np.mean([r.mean_abs_error_deg for r in sel])
            signed = np.mean([r.mean_error_from_near_deg for r in sel])
            acc = np.mean([r.accuracy for r in sel])
            print(f"{cond:8s} profile={prof!s:5s} |error| {mae:5.2f}  signed from near "
                  f"{signed:+5.2f}  accuracy {acc:.3f}")
    print(f"{time.perf_counter() - t0:.1f} s")
