"""Wearer profiles: what per-wearer perceptual calibration changes in the stimulus engine.

A belt feels different on every wearer: motors differ, and skin sensitivity varies around
the torso. :class:`WearerProfile` holds, for one wearer on one belt layout,

- ``gains``: one per tactor, multiplying that tactor's amplitude (law output) so every
  tactor feels as strong as the reference tactor (the result is clipped to 1);
- ``warps``: one per adjacent pair (a, b) with b the clockwise neighbour of a, a monotone
  map from the *intended* position in the gap (0 at a, 1 at b) to the *rendered* one,
  piecewise linear through knots ``(intended, rendered)`` that always include (0, 0) and
  (1, 1). Pair k is tactor k and its clockwise neighbour.

A stimulus made with a profile (:func:`tactorbelt.stimuli.make_stimulus`, ``profile=``)
renders ``gains * law(warp(location(t)))``: static stimuli are moved to where the wearer
feels the intended point; the dynamic perturbation's dwell on each tactor is unchanged
(the warp keeps tactors in place) and its transit is warped like a static point.

A profile is stored as TOML (:meth:`WearerProfile.to_toml`, :meth:`WearerProfile.load`)::

    format = "tactorbelt-wearer-profile"
    version = 1
    participant = "P01"
    law = "paper"                  # the law and falloff it was measured with
    falloff_deg = 15.0
    tactor_angles_deg = [30.0, 90.0, 150.0, 210.0, 270.0, 330.0]
    gains = [1.0, 1.08, 0.95, 1.0, 1.02, 0.97]
    reference_tactor = 0

    [[pair]]                       # one per adjacent pair, pair k = tactors k, k+1
    intended = [0.25, 0.5, 0.75]   # inner knots; 0 and 1 are implied
    rendered = [0.31, 0.5, 0.69]

Validation refuses a wrong number of gains or pairs for the tactor angles, gains outside
(0, 10], and warps that are not strictly increasing (``error: FILE: pair[2].rendered: ...``).

It sits below the stimulus engine that applies it (:mod:`tactorbelt.stimuli`) and the
perceptual calibration that measures it.

Pure: NumPy, the standard library, tactorbelt.geometry and the reading of user files
(tactorbelt._files); pydantic when a file is read
(its model: :mod:`.file`), tomli-w when one is saved.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._errors import ConfigError
from .._files import read_toml, read_user_text
from ..geometry import Layout, normalize
from .rules import EPS, FORMAT, VERSION, warp_problem

__all__ = ["FORMAT", "PairWarp", "WearerProfile", "isotonic"]


def isotonic(values: Sequence[float], lo: float = 0.0, hi: float = 1.0,
             min_step: float = 0.01) -> list[float]:
    """The closest non-decreasing sequence (pool adjacent violators), clipped to
    [lo + min_step, hi - min_step] and spread to rise by at least ``min_step`` per knot:
    what turns measured points of subjective equality into a strictly monotone warp."""
    blocks: list[list[float]] = []  # [mean, weight]
    for v in values:
        blocks.append([float(v), 1.0])
        while len(blocks) > 1 and blocks[-2][0] > blocks[-1][0]:
            m2, w2 = blocks.pop()
            m1, w1 = blocks.pop()
            blocks.append([(m1 * w1 + m2 * w2) / (w1 + w2), w1 + w2])
    out: list[float] = []
    for m, w in blocks:
        out += [m] * int(w)
    n = len(out)
    for i in range(n):  # room for the knots before and after
        out[i] = min(max(out[i], lo + min_step * (i + 1)), hi - min_step * (n - i))
    for i in range(1, n):
        out[i] = max(out[i], out[i - 1] + min_step)
    return out


@dataclass(frozen=True)
class PairWarp:
    """The warp of one pair: inner knots ``intended -> rendered``, both strictly increasing
    in (0, 1); (0, 0) and (1, 1) are implied."""

    intended: tuple[float, ...] = ()
    rendered: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        problem = warp_problem(self.intended, self.rendered)
        if problem:
            field_, message = problem
            raise ConfigError(f"warp {field_}: {message}")

    @property
    def is_identity(self) -> bool:
        return all(abs(i - r) < EPS for i, r in zip(self.intended, self.rendered, strict=True))

    def apply(self, fraction: NDArray[np.float64]) -> NDArray[np.float64]:
        """Rendered fractions for intended ones (vectorised)."""
        xs = np.concatenate([[0.0], self.intended, [1.0]])
        ys = np.concatenate([[0.0], self.rendered, [1.0]])
        return np.asarray(np.interp(fraction, xs, ys))


@dataclass(frozen=True)
class WearerProfile:
    """One wearer's perceptual calibration for a belt layout (see the module docstring).

    Attributes:
        tactor_angles_deg: the layout it was measured on (N tactors).
        gains: N per-tactor amplitude gains.
        warps: N pair warps, pair k = tactor k and its clockwise neighbour.
        participant: who it belongs to.
        law, falloff_deg: the amplitude law it was measured with.
        reference_tactor: the tactor the others were matched to.
        belt: the belt URL it was measured on (informative).
        created: when (ISO 8601, informative).
        fit: per-track results (PSE, slope, trials) for the record; not used to render.
    """

    tactor_angles_deg: tuple[float, ...]
    gains: tuple[float, ...]
    warps: tuple[PairWarp, ...]
    participant: str = ""
    law: str = "paper"
    falloff_deg: float = 15.0
    reference_tactor: int = 0
    belt: str = ""
    created: str = ""
    fit: tuple[Mapping[str, Any], ...] = field(default=(), compare=False)

    def __post_init__(self) -> None:
        n = len(self.tactor_angles_deg)
        if len(self.gains) != n:
            raise ConfigError(f"a wearer profile for {n} tactors needs {n} gains, "
                              f"got {len(self.gains)}")
        if len(self.warps) != n:
            raise ConfigError(f"a wearer profile for {n} tactors needs {n} pair warps, "
                              f"got {len(self.warps)}")
        for k, g in enumerate(self.gains):
            if not (math.isfinite(g) and 0.0 < g <= 10.0):
                raise ConfigError(f"gain of tactor {k} must be in (0, 10], got {g!r}")

    @classmethod
    def identity(cls, layout: Layout, **info: Any) -> WearerProfile:
        """The profile that changes nothing (gains 1, identity warps)."""
        return cls(tuple(layout.angles_deg), (1.0,) * layout.n,
                   tuple(PairWarp() for _ in range(layout.n)), **info)

    @property
    def n(self) -> int:
        return len(self.gains)

    @property
    def is_identity(self) -> bool:
        """True when rendering with the profile changes nothing."""
        return all(g == 1.0 for g in self.gains) and all(w.is_identity for w in self.warps)

    def layout(self) -> Layout:
        return Layout(tuple(self.tactor_angles_deg))

    def check_layout(self, layout: Layout, source: str = "wearer profile") -> None:
        """Raise ConfigError unless the profile was measured on ``layout``."""
        if layout.n != self.n:
            raise ConfigError(f"{source}: tactor_angles_deg: the profile has {self.n} tactors "
                              f"but the belt has {layout.n}; calibrate this wearer on this belt")
        if not np.allclose(layout.angles_deg, self.tactor_angles_deg, atol=1e-6):
            raise ConfigError(f"{source}: tactor_angles_deg: measured on tactors at "
                              f"{list(self.tactor_angles_deg)}, the belt has "
                              f"{list(layout.angles_deg)}")

    # -- rendering ------------------------------------------------------------------------
    def warp_deg(self, layout: Layout, x: ArrayLike) -> NDArray[np.float64]:
        """Rendered locations for intended ones (degrees, any shape; vectorised).

        A location is placed in its gap (pair k: from tactor k clockwise to k + 1) and
        its fraction of the gap mapped by that pair's warp; tactors stay where they are.
        """
        xa = np.asarray(x, dtype=float)
        if all(w.is_identity for w in self.warps):
            return xa
        angles = layout.angles
        gaps = layout.gaps_deg()
        off = np.mod(xa[..., None] - angles, 360.0)            # clockwise from each tactor
        inside = off < gaps                                      # exactly one k (the gap)
        k = np.argmax(inside, axis=-1)
        frac = np.take_along_axis(off, k[..., None], axis=-1)[..., 0] / gaps[k]
        out = np.array(frac, dtype=float, copy=True)
        for j, w in enumerate(self.warps):
            if not w.is_identity:
                sel = k == j
                out[sel] = w.apply(frac[sel])
        return np.asarray(normalize(angles[k] + out * gaps[k]), dtype=float)

    def apply_gains(self, amplitudes: NDArray[np.float64]) -> NDArray[np.float64]:
        """Amplitudes (last axis = tactors) times the gains, clipped to [0, 1]."""
        if all(g == 1.0 for g in self.gains):
            return amplitudes
        return np.asarray(np.clip(amplitudes * np.asarray(self.gains), 0.0, 1.0))

    # -- files ----------------------------------------------------------------------------
    def to_mapping(self) -> dict[str, Any]:
        doc: dict[str, Any] = {"format": FORMAT, "version": VERSION}
        for key in ("participant", "belt", "created"):
            if getattr(self, key):
                doc[key] = getattr(self, key)
        doc.update(law=self.law, falloff_deg=float(self.falloff_deg),
                   tactor_angles_deg=[float(a) for a in self.tactor_angles_deg],
                   gains=[float(g) for g in self.gains],
                   reference_tactor=int(self.reference_tactor))
        doc["pair"] = [{"index": k, "tactors": [k, (k + 1) % self.n],
                        "intended": [float(v) for v in w.intended],
                        "rendered": [float(v) for v in w.rendered]}
                       for k, w in enumerate(self.warps)]
        if self.fit:
            doc["fit"] = [dict(f) for f in self.fit]
        return doc

    def to_toml(self) -> str:
        import tomli_w

        head = ("# tactorbelt wearer profile: per-tactor gains and per-pair warps "
                "(docs/calibration-perceptual.md)\n")
        return head + tomli_w.dumps(self.to_mapping())

    def save(self, path: str | Path) -> Path:
        p = Path(path)
        try:
            if p.parent != Path(""):
                p.parent.mkdir(parents=True, exist_ok=True)
            p.write_text(self.to_toml(), encoding="utf-8")
        except OSError as exc:
            raise ConfigError(f"cannot write wearer profile {str(p)!r}: {exc.strerror}") from None
        return p

    @classmethod
    def load(cls, path: str | Path) -> WearerProfile:
        """Read a profile file; errors name the file and the field."""
        p = Path(path)
        return cls.from_toml(read_user_text(p, "wearer profile"), source=str(p))

    @classmethod
    def from_toml(cls, text: str, source: str = "<wearer profile>") -> WearerProfile:
        return cls.from_mapping(read_toml(text, source), source)

    @classmethod
    def from_mapping(cls, doc: Mapping[str, Any], source: str = "<wearer profile>"
                     ) -> WearerProfile:
        """Build and validate a profile from its TOML structure (its file model:
        :class:`.file.File`)."""
        from .._files.model import parse
        from .file import File

        f = parse(File, doc, source)
        return cls(tuple(map(float, f.tactor_angles_deg)), tuple(map(float, f.gains)),
                   tuple(PairWarp(tuple(map(float, r.intended)), tuple(map(float, r.rendered)))
                         for r in f.pair),
                   participant=str(f.participant), law=f.law, falloff_deg=float(f.falloff_deg),
                   reference_tactor=f.reference_tactor, belt=str(f.belt),
                   created=str(f.created), fit=tuple(f.fit) if isinstance(f.fit, list) else ())
