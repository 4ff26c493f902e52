"""Angles, tactor layouts and target sets.

Conventions (docs/conventions.md): degrees, normalised to [0, 360); 0 is the navel, angles
grow clockwise seen from above (90 = right flank, 180 = spine, 270 = left flank).
The default layout puts N tactors at ``180/N + k*360/N``; targets sit at ``k*360/M``.

Pure: imports only NumPy and tactorbelt._errors.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._errors import ConfigError

__all__ = [
    "ANGLE_TOLERANCE_DEG",
    "Layout",
    "TargetSet",
    "normalize",
    "parse_angle",
    "parse_number",
    "region_name",
    "wrap",
]

#: Two angles closer than this are the same angle (on-tactor test, duplicates).
ANGLE_TOLERANCE_DEG = 1e-6

FloatArray = NDArray[np.float64]


def normalize(angle: ArrayLike) -> Any:
    """Normalise angles to [0, 360). Works on scalars and arrays."""
    if type(angle) is float:  # Python's % is NumPy's mod for floats (fmod, sign fix-up)
        r = angle % 360.0
        return 0.0 if r >= 360.0 else r
    a = np.mod(np.asarray(angle, dtype=float), 360.0)
    # np.mod(-1e-17, 360) == 360.0 in floating point: fold it back to 0.
    a = np.where(a >= 360.0, 0.0, a)
    return float(a) if a.ndim == 0 else a


def wrap(angle: ArrayLike) -> Any:
    """Wrap angle differences into (-180, 180]. Works on scalars and arrays."""
    if type(angle) is float:  # Python's % is NumPy's mod for floats (fmod, sign fix-up)
        r = 180.0 - (180.0 - angle) % 360.0
        return 180.0 if r <= -180.0 else r
    a = np.asarray(angle, dtype=float)
    if a.ndim == 0:
        return wrap(float(a))
    w = np.mod(np.subtract(180.0, a), 360.0)
    np.subtract(180.0, w, out=w)
    # np.mod(-3e-14, 360) == 360.0 (for a just above 180): fold -180 back to 180.
    if w.size and not w.min() > -180.0:  # (a NaN anywhere: look at every element)
        w[w <= -180.0] = 180.0
    return w


def parse_number(text: object, what: str) -> float:
    """A finite float from text (or a number), or ConfigError naming ``what``."""
    try:
        value = float(text)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ConfigError(f"{what} must be a number, got {text!r}") from None
    if not math.isfinite(value):
        raise ConfigError(f"{what} must be a finite number, got {text!r}")
    return value


def parse_angle(text: str | float, what: str = "angle") -> float:
    """Parse a finite angle in degrees (any real number; normalised to [0, 360)).

    Raises:
        ConfigError: for text that is not a finite number (``abc``, ``nan``, ``inf``).
    """
    try:
        value = float(text)
    except (TypeError, ValueError):
        value = math.nan
    if not math.isfinite(value):
        raise ConfigError(f"{what} must be a finite number of degrees, got {text!r}")
    return float(normalize(value))


@dataclass(frozen=True)
class Layout:
    """Where the tactors sit around the torso.

    Tactor ``k`` is index ``k`` in every array. Angles are kept in the order given
    (normalised); neighbours are found by angle, so an uneven or unsorted layout works.

    Use :meth:`even` for N evenly spaced tactors (the default layout of docs/conventions.md) or
    :meth:`from_angles` for explicit angles.
    """

    angles_deg: tuple[float, ...]
    _sorted_idx: tuple[int, ...] = field(init=False, repr=False, compare=False)
    _cache: dict[str, Any] = field(init=False, repr=False, compare=False, hash=False)

    def __post_init__(self) -> None:
        angles = tuple(float(normalize(a)) for a in self.angles_deg)
        if len(angles) < 2:
            raise ConfigError(f"a layout needs at least 2 tactors, got {len(angles)}")
        if not all(math.isfinite(a) for a in angles):
            raise ConfigError("tactor angles must be finite numbers of degrees")
        order = sorted(range(len(angles)), key=lambda k: angles[k])
        for i, k in enumerate(order):
            j = order[(i + 1) % len(order)]
            gap = (angles[j] - angles[k]) % 360.0
            if gap < ANGLE_TOLERANCE_DEG or 360.0 - gap < ANGLE_TOLERANCE_DEG:
                raise ConfigError(
                    f"duplicate tactor angles: tactors {min(k, j)} and {max(k, j)} "
                    f"are both at {angles[k]:g} deg; every tactor needs its own angle"
                )
        object.__setattr__(self, "angles_deg", angles)
        object.__setattr__(self, "_sorted_idx", tuple(order))
        # Derived arrays, computed once (read-only): the laws use them on every frame.
        arr = np.array(angles, dtype=float)
        idx = np.array(order)
        cw = np.empty(len(order), dtype=np.intp)
        ccw = np.empty(len(order), dtype=np.intp)
        cw[idx] = np.roll(idx, -1)
        ccw[idx] = np.roll(idx, 1)
        gaps = np.mod(arr[cw] - arr, 360.0)
        gaps_ccw = gaps[ccw]
        for a in (arr, cw, ccw, gaps, gaps_ccw):
            a.setflags(write=False)
        object.__setattr__(self, "_cache", {"angles": arr, "cw": cw, "ccw": ccw, "gaps": gaps,
                                            "gaps_ccw": gaps_ccw})

    @classmethod
    def even(cls, n: int = 6) -> Layout:
        """N tactors at ``180/N + k*360/N`` (two front tactors symmetric about the navel)."""
        if isinstance(n, bool) or int(n) != n:
            raise ConfigError(f"tactor count must be an integer, got {n!r}")
        n = int(n)
        if n < 2:
            raise ConfigError(f"a layout needs at least 2 tactors, got {n}")
        return cls(tuple(180.0 / n + k * 360.0 / n for k in range(n)))

    @classmethod
    def from_angles(cls, angles: Iterable[float | str]) -> Layout:
        """Explicit tactor angles (degrees, any order, possibly uneven)."""
        return cls(tuple(parse_angle(a, "tactor angle") for a in angles))

    @classmethod
    def parse(cls, text: str) -> Layout:
        """Parse ``"30,90,150"`` into a layout."""
        parts = [p.strip() for p in text.split(",") if p.strip()]
        return cls.from_angles(parts)

    @property
    def n(self) -> int:
        """Number of tactors."""
        return len(self.angles_deg)

    def __len__(self) -> int:
        return self.n

    @property
    def angles(self) -> FloatArray:
        """Tactor angles as a read-only NumPy array."""
        return self._cache["angles"]

    def gaps_deg(self) -> FloatArray:
        """Clockwise gap from each tactor to its clockwise neighbour (read-only), by index."""
        return self._cache["gaps"]

    def gaps_ccw_deg(self) -> FloatArray:
        """Gap from each tactor's counter-clockwise neighbour to it (read-only), by index:
        ``gaps_deg()[neighbour_indices()[1]]``."""
        return self._cache["gaps_ccw"]

    def neighbour_indices(self) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        """For each tactor, the index of its clockwise and counter-clockwise neighbours."""
        return self._cache["cw"], self._cache["ccw"]

    def neighbours(self, angle: ArrayLike) -> tuple[Any, Any]:
        """The two tactors that bracket each angle.

        Returns ``(ccw, cw)``: the index of the nearest tactor at or counter-clockwise
        of the angle and of the next tactor clockwise. For an angle exactly on tactor k,
        ``ccw == k``. Scalars in, ints out; arrays in, arrays out.
        """
        x = normalize(angle)
        xa = np.atleast_1d(np.asarray(x, dtype=float))
        order = np.array(self._sorted_idx)
        sorted_angles = self.angles[order]
        # position of x among sorted angles, with tolerance for "on tactor"
        pos = np.searchsorted(sorted_angles, xa + ANGLE_TOLERANCE_DEG, side="right") - 1
        pos = np.where(pos < 0, len(order) - 1, pos)
        ccw = order[pos]
        cw = order[(pos + 1) % len(order)]
        if np.ndim(x) == 0:
            return int(ccw[0]), int(cw[0])
        return ccw, cw

    def tactor_at(self, angle: ArrayLike) -> Any:
        """Index of the tactor at each angle, or -1 where the angle is between tactors."""
        d = np.abs(wrap(np.subtract.outer(np.atleast_1d(normalize(angle)), self.angles)))
        hit = d < ANGLE_TOLERANCE_DEG
        idx = np.where(hit.any(axis=1), hit.argmax(axis=1), -1)
        return int(idx[0]) if np.ndim(angle) == 0 else idx

    def is_on_tactor(self, angle: ArrayLike) -> Any:
        """True where an angle coincides with a tactor angle."""
        idx = self.tactor_at(angle)
        return bool(idx >= 0) if np.ndim(idx) == 0 else idx >= 0

    def to_list(self) -> list[float]:
        """Tactor angles as a plain list (for JSON and TOML)."""
        return list(self.angles_deg)


@dataclass(frozen=True)
class TargetSet:
    """The directions a study can show: ``M`` targets at ``k*360/M`` by default."""

    angles_deg: tuple[float, ...]

    def __post_init__(self) -> None:
        angles = tuple(float(normalize(a)) for a in self.angles_deg)
        if not angles:
            raise ConfigError("a target set needs at least 1 target")
        object.__setattr__(self, "angles_deg", angles)

    @classmethod
    def even(cls, m: int = 24) -> TargetSet:
        """M targets at ``k*360/M``, starting at the navel."""
        if isinstance(m, bool) or int(m) != m or int(m) < 1:
            raise ConfigError(f"target count must be a positive integer, got {m!r}")
        m = int(m)
        return cls(tuple(k * 360.0 / m for k in range(m)))

    @property
    def m(self) -> int:
        return len(self.angles_deg)

    def __len__(self) -> int:
        return self.m

    def __iter__(self) -> Iterator[float]:
        return iter(self.angles_deg)

    @property
    def angles(self) -> FloatArray:
        return np.array(self.angles_deg, dtype=float)

    def on_tactor(self, layout: Layout) -> NDArray[np.bool_]:
        """Which targets coincide with a tactor of ``layout``."""
        return np.asarray(layout.is_on_tactor(self.angles), dtype=bool)

    def nearest(self, angle: ArrayLike) -> Any:
        """The target nearest in angle to each angle (ties go to the lower index)."""
        d = np.abs(wrap(np.subtract.outer(np.atleast_1d(normalize(angle)), self.angles)))
        best = self.angles[d.argmin(axis=1)]
        return float(best[0]) if np.ndim(angle) == 0 else best


_REGIONS = ("front", "right-front", "right", "right-back", "back", "left-back", "left",
            "left-front")


def region_name(angle_deg: float) -> str:
    """The body region of an angle: 8 sectors of 45 degrees centred on 0, 45, ..."""
    k = int(((float(angle_deg) % 360.0) + 22.5) // 45.0) % 8
    return _REGIONS[k]
