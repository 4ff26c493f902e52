"""Amplitude laws: how strongly each tactor vibrates for a felt location.

For tactor k at angle d_k and a location x: ``D = |wrap(x - d_k)|`` and ``s`` is the
angular distance from d_k to its neighbour on x's side (for an uneven layout the two
sides differ; when x is exactly on d_k the clockwise side is used).

- ``paper`` (default; Eguchi et al. Eq. 1, T = falloff): ``max(1 - exp(-(s - D)/T), 0)``,
  not renormalised: on a tactor of the default layout it gives ``1 - e^-4``.
- ``linear``: ``max(1 - D/s, 0)``.
- ``energy`` (Tactile Brush, Israr & Poupyrev 2011): ``sqrt(max(1 - D/s, 0))``.

Every law is vectorised: locations of any shape ``S`` give amplitudes of shape
``S + (N,)``. Values are in [0, 1]; 0 means off.

Off means exactly 0: a tactor is off where ``s - D <= ROUNDING_FLOOR_DEG`` (1e-10 deg),
i.e. where the location is at its neighbour up to floating-point rounding. D and s come
from different sums of angles below 720 deg (ulp 1.1e-13), so a location exactly on a
tactor can leave its neighbour a residue of ~1e-14; the energy law's sqrt turns that into
~1e-7, and a calibration drives every non-zero amplitude at least at its start level.
The floor is some 1000 ulp of 360 deg, four orders below ``ANGLE_TOLERANCE_DEG`` (1e-6),
so every amplitude it zeroes is below one 16-bit drive level (``sqrt(1e-10/s)`` < 1.5e-5
for every gap s >= 0.5 deg).

A law is its name in :mod:`tactorbelt._lawnames` and its function in
:data:`LAW_FUNCTIONS`; :data:`LAWS` and :func:`check_law` read the names when they are
used, so a law registered after this module was imported is a law here too.

Pure: imports only NumPy, tactorbelt.geometry and the kernel (_errors, _lawnames, _registry).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from . import _lawnames
from ._errors import ConfigError
from ._registry import check_option, lazy_attributes
from .geometry import Layout, wrap

if TYPE_CHECKING:
    from ._lawnames import LAWS

__all__ = ["DEFAULT_FALLOFF_DEG", "LAWS", "LAW_FUNCTIONS", "ROUNDING_FLOOR_DEG", "amplitudes",
           "check_law"]

DEFAULT_FALLOFF_DEG: Final = 15.0
#: A tactor is off where ``s - D`` is at most this (degrees): rounding, not geometry.
ROUNDING_FLOOR_DEG: Final = 1e-10


# LAWS is _lawnames.LAWS as it is now, not a copy taken at import
__getattr__ = lazy_attributes(__name__, {"LAWS": "tactorbelt._lawnames"})


def check_law(law: str, falloff_deg: float = DEFAULT_FALLOFF_DEG) -> None:
    """Raise ConfigError for an unknown law or a falloff that is not positive and finite."""
    check_option("law", law, _lawnames.LAWS)
    if not (isinstance(falloff_deg, int | float) and math.isfinite(falloff_deg)) or (
        falloff_deg <= 0
    ):
        raise ConfigError(
            f"falloff must be a positive, finite number of degrees, got {falloff_deg!r}"
        )


def _distances(layout: Layout, x: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """D (distance to each tactor) and s (spacing on x's side), both of shape S + (N,)."""
    xa = np.asarray(x, dtype=float)
    d = layout.angles
    signed = wrap(xa[..., None] - d)  # (-180, 180]
    dist = np.abs(signed)
    gaps_cw = layout.gaps_deg()  # k -> its clockwise neighbour
    gaps_ccw = layout.gaps_ccw_deg()  # k's counter-clockwise neighbour -> k
    spacing = np.where(signed >= 0.0, gaps_cw, gaps_ccw)
    return np.asarray(dist), np.asarray(spacing)


def amplitudes(
    layout: Layout,
    x: ArrayLike,
    law: str = "paper",
    falloff_deg: float = DEFAULT_FALLOFF_DEG,
) -> NDArray[np.float64]:
    """Amplitude of every tactor for felt location(s) ``x`` (degrees).

    Args:
        layout: where the tactors are.
        x: location angle(s), any shape ``S``.
        law: a name in :data:`LAWS` (``paper``, ``linear``, ``energy``).
        falloff_deg: T of the paper law (ignored by the others).

    Returns:
        An array of shape ``S + (N,)`` with values in [0, 1].
    """
    check_law(law, falloff_deg)
    dist, spacing = _distances(layout, x)
    off = spacing - dist <= ROUNDING_FLOOR_DEG  # at (or past) the neighbour: exactly 0
    y = LAW_FUNCTIONS[law](dist, spacing, falloff_deg)
    # np.clip(y, 0, 1) as two ufuncs (np.clip's Python layers cost more than the work);
    # the same values: y is never -0.0, and below 0 only where ``off`` masks it
    return np.asarray(np.where(off, 0.0, np.minimum(np.maximum(y, 0.0), 1.0)))


def _paper(dist: NDArray[np.float64], spacing: NDArray[np.float64],
           falloff_deg: float) -> NDArray[np.float64]:
    # far tactors: exp may overflow to inf (clipped to 0), only with a falloff this small
    quiet = (np.errstate(over="ignore") if falloff_deg < _NO_OVERFLOW_FALLOFF_DEG
             else contextlib.nullcontext())
    with quiet:
        return np.asarray(1.0 - np.exp(-(spacing - dist) / falloff_deg))


#: With a falloff of at least this, the paper law's exponent (below 180 / falloff: D is at
#: most 180 degrees, s more than 0) stays under 709, where exp overflows: no warning to
#: silence (np.errstate costs more than the law on 6 tactors).
_NO_OVERFLOW_FALLOFF_DEG: Final = 0.26


def _linear(dist: NDArray[np.float64], spacing: NDArray[np.float64],
            falloff_deg: float) -> NDArray[np.float64]:
    return np.asarray(np.clip(1.0 - dist / spacing, 0.0, 1.0))


def _energy(dist: NDArray[np.float64], spacing: NDArray[np.float64],
            falloff_deg: float) -> NDArray[np.float64]:
    return np.asarray(np.sqrt(_linear(dist, spacing, falloff_deg)))


#: Each law's amplitude before the off mask and the clip to [0, 1]: ``f(D, s, falloff)``,
#: vectorised. The keys are exactly :data:`LAWS`.
LAW_FUNCTIONS: Final[dict[str, Callable[[NDArray[np.float64], NDArray[np.float64], float],
                                         NDArray[np.float64]]]] = {
    "paper": _paper,
    "linear": _linear,
    "energy": _energy,
}
