"""Motor calibration: from amplitude (what a law asks for) to drive level (what a motor gets).

Per tactor: ``start`` (the dead zone of an ERM: the smallest drive that spins it),
``gain`` and ``ceiling``. Amplitude 0 is off; above 0 the drive is
``start + (ceiling - start) * amplitude * gain``, clamped to [0, ceiling] (and [0, 1]).

Pure: NumPy only (TOML load and save live here too, through the standard library and tomli-w).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._errors import ConfigError

__all__ = ["Calibration", "TactorCalibration"]


@dataclass(frozen=True)
class TactorCalibration:
    """Calibration of one tactor: start level, gain and ceiling, each in [0, 1] (gain > 0)."""

    start: float = 0.0
    gain: float = 1.0
    ceiling: float = 1.0

    def __post_init__(self) -> None:
        for name in ("start", "ceiling"):
            v = getattr(self, name)
            if not (0.0 <= float(v) <= 1.0):
                raise ConfigError(f"calibration {name} must be in [0, 1], got {v!r}")
        if not (0.0 < float(self.gain) <= 10.0):
            raise ConfigError(f"calibration gain must be in (0, 10], got {self.gain!r}")
        if self.start > self.ceiling:
            raise ConfigError(
                f"calibration start ({self.start}) must not exceed ceiling ({self.ceiling})"
            )


@dataclass(frozen=True)
class Calibration:
    """Calibration of every tactor of a belt (index k is tactor k)."""

    tactors: tuple[TactorCalibration, ...]

    @classmethod
    def identity(cls, n: int) -> Calibration:
        """No dead zone, unit gain, full ceiling: drive level equals amplitude."""
        return cls(tuple(TactorCalibration() for _ in range(n)))

    @property
    def n(self) -> int:
        return len(self.tactors)

    @property
    def is_identity(self) -> bool:
        return all(t == TactorCalibration() for t in self.tactors)

    def apply(self, amplitudes: ArrayLike) -> NDArray[np.float64]:
        """Map amplitudes (last axis = tactors) to drive levels in [0, 1]."""
        a = np.asarray(amplitudes, dtype=float)
        if a.shape[-1] != self.n:
            raise ConfigError(f"expected {self.n} amplitudes, got {a.shape[-1]}")
        start = np.array([t.start for t in self.tactors])
        gain = np.array([t.gain for t in self.tactors])
        ceiling = np.array([t.ceiling for t in self.tactors])
        drive = np.clip(start + (ceiling - start) * a * gain, 0.0, ceiling)
        return np.asarray(np.where(a > 0.0, drive, 0.0))

    def to_list(self) -> list[dict[str, float]]:
        return [{"start": t.start, "gain": t.gain, "ceiling": t.ceiling} for t in self.tactors]

    @classmethod
    def from_list(cls, rows: Sequence[dict[str, float]]) -> Calibration:
        return cls(tuple(TactorCalibration(**r) for r in rows))
