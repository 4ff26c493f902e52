"""The sounds of the auditory secondary tasks, generated here (no sound files, no downloads).

- n-back tones: the items ``tone0`` .. ``tone7`` are 8 harmonic tones four semitones apart
  (a major third: 220 Hz to 1109 Hz, :data:`TONE_HZ`), easy to tell apart for people
  without musical training. Each tone has its fundamental and two harmonics (amplitudes
  1, 1/2, 1/4), lasts the task's ``stimulus_s`` and fades in and out over
  :data:`RAMP_S` (raised cosine), so it starts and ends without a click.
- arithmetic beeps: the item ``"a+b"`` (a, b in 1..4) is ``a`` high beeps
  (:data:`BEEP_HZ` [0]), a pause of one beep slot, and ``b`` lower beeps (:data:`BEEP_HZ`
  [1]). A slot is ``stimulus_s / 9`` clamped to [0.1, 0.2] s (so 4 + 4 beeps and the
  pause fit in 9 slots: at most 1.8 s); a beep fills 60 % of its slot.

Every sound is mono float32 at the sample rate asked for (48 kHz by default), peak
:data:`PEAK` (-6 dBFS), so two overlapping sounds do not clip. A task kind turns an
item's stimulus text into its sound (``TaskKind.sound``, :mod:`.kinds`); :class:`SoundBank`
makes each sound once.

Pure: NumPy only.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from .._errors import ConfigError

__all__ = [
    "BEEP_HZ",
    "PEAK",
    "RAMP_S",
    "RATE",
    "TONE_HZ",
    "SoundBank",
    "beep_slot_s",
    "beeps",
    "tone",
]

#: The sample rate of the task sounds by default (Hz).
RATE: Final = 48000
#: The 8 n-back tones (Hz): 220 Hz and 7 steps of 4 semitones above it.
TONE_HZ: Final = tuple(round(220.0 * 2.0 ** (4 * k / 12), 2) for k in range(8))
#: The first and the second operand's beeps (Hz).
BEEP_HZ: Final = (1320.0, 660.0)
#: The fade in and out of every sound (s).
RAMP_S: Final = 0.010
#: The peak amplitude of a sound (full scale = 1): -6 dBFS.
PEAK: Final = 0.5

FloatArray = NDArray[np.float32]


def _check(duration_s: float, rate: int) -> int:
    if not (math.isfinite(duration_s) and duration_s > 0):
        raise ConfigError(f"a sound lasts a positive number of seconds, got {duration_s!r}")
    if not 8000 <= rate <= 192000:
        raise ConfigError(f"sample rate must be 8000..192000 Hz, got {rate!r}")
    return max(1, round(duration_s * rate))


def _ramped(x: NDArray[np.float64], rate: int) -> FloatArray:
    """``x`` with raised-cosine fades at both ends, scaled to :data:`PEAK`."""
    n = x.shape[0]
    r = min(max(1, round(RAMP_S * rate)), n // 2 or 1)
    env = np.ones(n)
    fade = 0.5 - 0.5 * np.cos(np.pi * (np.arange(r) + 0.5) / r)
    env[:r] = fade
    env[n - r:] = np.minimum(env[n - r:], fade[::-1])
    y = x * env
    top = float(np.max(np.abs(y))) if n else 0.0
    if top > 0:
        y *= PEAK / top
    return y.astype(np.float32)


def tone(index: int, duration_s: float, rate: int = RATE) -> FloatArray:
    """The n-back tone ``index`` (0..7) for ``duration_s`` seconds.

    Raises:
        ConfigError: an index outside 0..7, a duration that is not positive.
    """
    if not 0 <= int(index) < len(TONE_HZ):
        raise ConfigError(f"there are {len(TONE_HZ)} n-back tones (0..7), got {index!r}")
    n = _check(duration_s, rate)
    t = np.arange(n) / rate
    f = TONE_HZ[int(index)]
    x = (np.sin(2 * np.pi * f * t) + 0.5 * np.sin(4 * np.pi * f * t)
         + 0.25 * np.sin(6 * np.pi * f * t))
    return _ramped(x, rate)


def beep_slot_s(stimulus_s: float) -> float:
    """The length of one beep slot of an arithmetic item (s): ``stimulus_s / 9`` in
    [0.1, 0.2]."""
    return min(max(stimulus_s / 9.0, 0.1), 0.2)


def beeps(a: int, b: int, stimulus_s: float, rate: int = RATE) -> FloatArray:
    """``a`` high beeps, a pause, ``b`` low beeps (the auditory item ``"a+b"``).

    Raises:
        ConfigError: an operand outside 1..9, a duration that is not positive.
    """
    for v in (a, b):
        if not 1 <= int(v) <= 9:
            raise ConfigError(f"an arithmetic operand is 1..9, got {v!r}")
    _check(stimulus_s, rate)
    slot = max(1, round(beep_slot_s(stimulus_s) * rate))
    on = max(2, round(0.6 * slot))
    out = np.zeros((a + b + 1) * slot - (slot - on), dtype=np.float32)
    t = np.arange(on) / rate
    starts = [(i * slot, BEEP_HZ[0]) for i in range(a)]
    starts += [((a + 1 + i) * slot, BEEP_HZ[1]) for i in range(b)]
    for s, f in starts:
        out[s:s + on] = _ramped(np.sin(2 * np.pi * f * t), rate)
    return out


class SoundBank:
    """Each item's sound made once (per stimulus and duration) and kept.

    Args:
        rate: the sample rate of the sounds (Hz).
    """

    def __init__(self, rate: int = RATE) -> None:
        self.rate = int(rate)
        self._cache: dict[tuple[Any, str, float], FloatArray] = {}

    def get(self, stimulus: str, stimulus_s: float,
            make: Callable[[str, float, int], Any]) -> FloatArray:
        """The sound of ``stimulus``, read-only: as ``make(stimulus, stimulus_s, rate)``
        makes it (a task kind's ``sound``: :mod:`.kinds`)."""
        key = (make, stimulus, float(stimulus_s))
        s = self._cache.get(key)
        if s is None:
            s = np.asarray(make(stimulus, stimulus_s, self.rate), dtype=float)
            s.flags.writeable = False
            self._cache[key] = s
        return s
