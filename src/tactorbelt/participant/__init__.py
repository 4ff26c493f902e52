"""The model participant: a simulated observer that feels a belt's vibration and answers.

It is a *model*, never evidence about people: what it does follows from the
assumptions documented in :class:`ModelParams` and docs/participant-model.md.

- :mod:`.params`: :class:`ModelParams` (each parameter with its source or marked as an
  assumption), :class:`Spread`, :func:`draw_participant`;
- :mod:`.perception`: :func:`sense_cues` (vibration -> cues), :func:`perceive` (cues ->
  felt direction and answer), :func:`perceive_vibration`;
- :mod:`.timing`: observation and decision times, the minimum-jerk profile;
- :mod:`.simulate`: the fast path (test trials without the runner);
- :mod:`.factorial`: the fast path of a study with several target counts or loads;
- :mod:`.load`: the model under a secondary task (the task, the NASA-TLX).

The cursor source that runs it in a session is :func:`tactorbelt.inputs.model.make_model_cursor`;
the power analyses that simulate it are :mod:`tactorbelt.power`.

Pure: NumPy only; never an I/O layer.
"""

from __future__ import annotations

from .params import ModelParams, Spread, draw_participant
from .perception import Cues, Percepts, perceive, perceive_vibration, sense_cues
from .simulate import Protocol, StimulusCues, TrialTable, simulate_participant, stimulus_cues

__all__ = [
    "Cues",
    "ModelParams",
    "Percepts",
    "Protocol",
    "Spread",
    "StimulusCues",
    "TrialTable",
    "draw_participant",
    "perceive",
    "perceive_vibration",
    "sense_cues",
    "simulate_participant",
    "stimulus_cues",
]
