"""The model participant answering perceptual-calibration trials, from what it feels.

Two judgements, each from sampled vibration only (never from the stimulus value):

- :func:`judge_stronger`: two intervals, one tactor each; the felt magnitude of a tactor
  is its mean vibration amplitude over the interval with log-normal noise of SD
  ``weber_amplitude`` (the same Weber fraction the location cue uses); "the second was
  stronger" when its felt magnitude is larger.
- :func:`judge_side`: a point between two tactors a and b; the observer perceives it as
  in a test trial (:func:`~tactorbelt.participant.perception.perceive`, over its static
  observation window) and answers on which side of the marked point it felt it. The
  question names a and b, so the body site is not in doubt: when it felt the point in
  that pair it compares its felt position within the pair (``fraction``) with the
  mark's; otherwise (the vibration's strongest pair is another) its felt direction.

Both lapse at the observer's lapse rate (a random answer).

Pure: NumPy and participant.perception / params.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ..geometry import Layout, wrap
from .params import ModelParams
from .perception import perceive, sense_cues

__all__ = ["judge_side", "judge_stronger"]

_TINY = 1e-9


def judge_stronger(vib_first: ArrayLike, tactor_first: int, vib_second: ArrayLike,
                   tactor_second: int, params: ModelParams, rng: np.random.Generator) -> int:
    """1 when the second interval's tactor felt stronger than the first's, else 0.

    Args:
        vib_first, vib_second: vibration (samples, N) of each interval.
        tactor_first, tactor_second: the tactor that vibrated in each.
    """
    z = rng.standard_normal(2)
    u = rng.random(2)
    m1 = float(np.mean(np.asarray(vib_first, float)[:, tactor_first]))
    m2 = float(np.mean(np.asarray(vib_second, float)[:, tactor_second]))
    if u[0] < params.lapse:
        return int(u[1] < 0.5)
    f1 = math.log(m1 + _TINY) + params.weber_amplitude * float(z[0])
    f2 = math.log(m2 + _TINY) + params.weber_amplitude * float(z[1])
    return int(f2 > f1)


def judge_side(t_s: ArrayLike, vib: ArrayLike, layout: Layout, marked_deg: float,
               params: ModelParams, rng: np.random.Generator, pair: int | None = None) -> int:
    """1 when the point felt clockwise of ``marked_deg`` (tactor b's side), else 0.

    ``pair`` is tactor a of the pair the question names (None: not named)."""
    cues = sense_cues(t_s, vib, layout, params)
    pc = perceive(cues, layout, np.array([float(marked_deg)]), params, rng)
    if bool(pc.guessed[0]):
        return int(rng.random() < 0.5)
    a = int(cues.pair[0])
    if pair is not None and a == pair:
        mark = float(np.mod(marked_deg - layout.angles_deg[a], 360.0)) / float(
            layout.gaps_deg()[a])
        return int(float(pc.fraction[0]) > mark)
    return int(float(wrap(float(pc.perceived_deg[0]) - float(marked_deg))) > 0.0)
