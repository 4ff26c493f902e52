"""A pattern as a study's stimulus: played with its 0 degrees on the trial's target.

A study file names a pattern in ``[stimulus] pattern`` (or a test block's ``pattern``);
each trial plays it turned so the pattern's 0 degrees (where ``pattern import --angle 0``
puts AHAP and ``.haptic`` events) lies on the trial's target, and the participant
answers where they felt it, as for every stimulus (docs/study.md, "Pattern stimuli").

:class:`PatternStimulus` has what the :class:`~tactorbelt.player.Player` streams and what
the runner asks of a stimulus (``layout``, ``amplitudes``, ``is_dynamic``,
``describe``); a belt never renders it on the device, so it is streamed on the player's
deadlines, as ``pattern play`` streams a pattern.

Pure: NumPy and the pattern modules; :func:`check_on_belt` imports the player side lazily.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..geometry import Layout
from ..laws import DEFAULT_FALLOFF_DEG
from .model import Pattern
from .render import PatternPlayback

if TYPE_CHECKING:
    from ..devices.base import Belt

__all__ = ["PatternStimulus", "check_on_belt"]


class PatternStimulus:
    """``pattern`` on ``layout`` turned to ``target_deg``, for one trial.

    Attributes:
        layout: the belt's layout.
        target_deg: the trial's target (where the pattern's 0 degrees is shown).
        mode: the trial's condition, kept as a label (a pattern holds its own motion).
        law, falloff_deg: how angles and paths are rendered (the pattern's ``law``, else
            the block's ``[stimulus] law``).
        name: the pattern as the study file names it.
        pattern: the pattern.
        duration_s: the pattern's length (after it the motors are off until the trial
            stops the stimulus).
    """

    #: a pattern's location is not the dynamic perturbation (the runner's skin onset
    #: weighs the tactors driven at the onset, as for a static stimulus)
    is_dynamic = False
    profile = None

    def __init__(self, pattern: Pattern, layout: Layout, target_deg: float, mode: str = "static",
                 law: str | None = None, falloff_deg: float = DEFAULT_FALLOFF_DEG,
                 name: str | None = None) -> None:
        self.playback = PatternPlayback(pattern, layout, law, falloff_deg, source=name,
                                        rotate_deg=float(target_deg))
        self.pattern = pattern
        self.layout = layout
        self.target_deg = float(target_deg) % 360.0
        self.mode = mode
        self.law = self.playback.law
        self.falloff_deg = float(falloff_deg)
        self.name = name
        self.duration_s = pattern.duration_s
        self.on_tactor = layout.tactor_at(self.target_deg) >= 0

    def amplitudes(self, t: ArrayLike) -> NDArray[np.float64]:
        """Amplitudes at time(s) ``t`` (seconds from the onset): shape ``t.shape + (N,)``."""
        ta = np.asarray(t, dtype=float)
        out = self.playback.amplitudes(ta.reshape(-1))
        return out.reshape((*ta.shape, self.layout.n))

    def describe(self) -> dict[str, object]:
        """A plain dict of the parameters, for JSON and the store."""
        return {
            "pattern": self.name,
            "pattern_name": self.pattern.name,
            "pattern_duration_s": self.duration_s,
            "target_deg": self.target_deg,
            "mode": self.mode,
            "law": self.law,
            "falloff_deg": self.falloff_deg,
            "on_tactor": self.on_tactor,
            "tactor_angles_deg": list(self.layout.angles_deg),
        }


def check_on_belt(belt: Belt, stimulus: PatternStimulus, rate_hz: float | None = None) -> None:
    """Refuse a pattern stimulus the belt cannot show: an instant that needs more distinct
    intensities than the belt's ``vibration_channels`` (``pattern play``'s check).

    Raises:
        PatternFileError: naming the pattern, the first such instant and the belt's limit.
    """
    if belt.vibration_channels is None:
        return
    from .play import check_channels

    rate = float(belt.stream_rate_hz if rate_hz is None else rate_hz)
    check_channels(belt, stimulus.playback, rate, stimulus.name)
