"""A pattern placed on a belt's layout: per-tactor amplitudes at any times, vectorised.

How each place is shown (docs/patterns.md, "On a belt"):

- a ``tactor`` event sits at its layout's angle: where the belt has a tactor there (within
  the layout tolerance) that tactor is driven alone at the event's intensity; elsewhere
  the angle is rendered with the amplitude law, between the belt's tactors;
- an ``angle_deg`` event is rendered with the law (as a static stimulus at that angle);
- a ``path`` event moves its location linearly over the event and the law renders each
  instant (as the stimulus engine renders a dynamic stimulus's transit).

An event's gain at time t is ``intensity * envelope(t)``; events that overlap combine by
the maximum per tactor, so every value stays in [0, 1].

:class:`PatternPlayback` has what the :class:`~tactorbelt.player.Player` streams
(``layout``, ``amplitudes(t)``), so a pattern plays on any belt on the player's deadlines.

Imports NumPy and tactorbelt's geometry and laws (pure).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..geometry import Layout
from ..laws import DEFAULT_FALLOFF_DEG, amplitudes, check_law
from .model import Event, Pattern, PatternFileError

__all__ = ["DEFAULT_RATE_HZ", "PatternPlayback", "render_pattern"]

#: The rate of ``render_pattern``, ``export`` and ``show`` unless told otherwise.
DEFAULT_RATE_HZ: Final = 1000.0


@dataclass(frozen=True)
class _Placed:
    start_s: float
    end_s: float
    env_t: NDArray[np.float64]
    env_g: NDArray[np.float64]
    vector: NDArray[np.float64] | None  # a fixed place; None: a path
    path: tuple[float, float] | None


class PatternPlayback:
    """``pattern`` on ``layout``, with the amplitude law ``law`` for angles and paths.

    Attributes:
        layout: the belt's layout (what the Player checks).
        pattern: the pattern played.
        duration_s: the pattern's length.
    """

    def __init__(self, pattern: Pattern, layout: Layout, law: str | None = None,
                 falloff_deg: float = DEFAULT_FALLOFF_DEG, source: str | None = None,
                 rotate_deg: float = 0.0) -> None:
        self.pattern = pattern
        #: every place of the pattern is turned by this much (clockwise): a study plays a
        #: pattern with its 0 degrees on the trial's target
        self.rotate_deg = float(rotate_deg)
        self.layout = layout
        self.law = law or pattern.law or "paper"
        check_law(self.law, falloff_deg)
        self.falloff_deg = float(falloff_deg)
        self.duration_s = pattern.duration_s
        places = [layout.tactor_at(a + self.rotate_deg) for a in pattern.layout_deg]
        self._events = tuple(self._place(e, places, i, source) for i, e in
                             enumerate(pattern.events))
        self._starts = np.array([p.start_s for p in self._events])
        self._ends = np.array([p.end_s for p in self._events])

    def _place(self, e: Event, places: list[int], i: int, source: str | None) -> _Placed:
        if e.envelope:
            env_t = np.array([t for t, _ in e.envelope]) / 1000.0
            env_g = np.array([g for _, g in e.envelope]) * e.intensity
        else:
            env_t, env_g = np.zeros(1), np.array([e.intensity])
        vector = None
        if e.tactor is not None:
            if e.tactor >= len(places):
                raise PatternFileError(f"tactor {e.tactor} is not in the pattern's layout",
                                       path=source, field=f"events[{i}].tactor")
            k = places[e.tactor]
            if k >= 0:
                vector = np.zeros(self.layout.n)
                vector[k] = 1.0
            else:
                vector = self._law(self.pattern.layout_deg[e.tactor] + self.rotate_deg)
        elif e.angle_deg is not None:
            vector = self._law(e.angle_deg + self.rotate_deg)
        path = e.path
        if path is not None and self.rotate_deg:
            path = (path[0] + self.rotate_deg, path[1] + self.rotate_deg)
        return _Placed(e.at_ms / 1000.0, e.end_ms / 1000.0, env_t, env_g, vector, path)

    def _law(self, x: ArrayLike) -> NDArray[np.float64]:
        return amplitudes(self.layout, x, self.law, self.falloff_deg)

    def amplitudes(self, t: ArrayLike) -> NDArray[np.float64]:
        """Amplitude of every tactor at times ``t`` (seconds from the pattern's start):
        shape ``(len(t), N)``, values in [0, 1]; zero before, after and between events."""
        ts = np.atleast_1d(np.asarray(t, dtype=float))
        out = np.zeros((ts.size, self.layout.n))
        if not self._events or ts.size == 0:
            return out
        lo, hi = float(ts.min()), float(ts.max())
        live = np.flatnonzero((self._starts <= hi) & (self._ends > lo))
        for j in live:
            p = self._events[j]
            m = (ts >= p.start_s) & (ts < p.end_s)
            if not m.any():
                continue
            since = ts[m] - p.start_s
            gain = np.interp(since, p.env_t, p.env_g)
            if p.vector is not None:
                v = gain[:, None] * p.vector[None, :]
            else:
                assert p.path is not None
                a, b = p.path
                frac = since / (p.end_s - p.start_s)
                v = gain[:, None] * self._law(a + (b - a) * frac)
            out[m] = np.maximum(out[m], v)
        return out


def render_pattern(playback: PatternPlayback, rate_hz: float = DEFAULT_RATE_HZ
                   ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Sample ``playback`` at ``t = i/rate`` for ``i in range(round(duration*rate))``
    (an empty pattern gives no samples)."""
    n = round(playback.duration_s * float(rate_hz))
    t = np.arange(n, dtype=float) / float(rate_hz)
    return t, playback.amplitudes(t)
