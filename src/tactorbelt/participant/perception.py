"""Perception of the model participant: from per-tactor vibration to a chosen target.

The observer never sees the target angle. Its input is the vibration amplitude of each
tactor over time (what the ``sim`` belt models, or any array you compute), and it
works in two steps:

1. :func:`sense_cues` (deterministic): location weights ``w_k = A_k**gamma``, the
   strongest adjacent pair (a, b) by time-averaged weight (a counter-clockwise of b),
   which tactors are felt at all, the time-averaged weights of a and b (the *static*
   cue), how long each of a and b dominated the pair (the *dynamic* cue: dwell times),
   and how much of the time both were felt together.
2. :func:`perceive` (noisy, vectorised over trials): the position within the pair from
   the two cues, combined by their reliabilities in log-ratio units; the body site
   (which tactor or which pair) felt with direction-dependent noise and a bias towards
   the navel and the spine; a chance of feeling two points instead of one; a lapse
   rate; and the answer, the target nearest to the felt direction.

See docs/participant-model.md for the reasoning and the sources (ModelParams).

Pure: imports NumPy, tactorbelt.geometry and participant.params; never an I/O layer.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, fields

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .._errors import ConfigError
from ..geometry import Layout, TargetSet, normalize, wrap
from .params import ModelParams

__all__ = [
    "KIND_FUNNELLED",
    "KIND_NONE",
    "KIND_SINGLE",
    "Cues",
    "Percepts",
    "bias_deg",
    "localisation_sd_deg",
    "perceive",
    "perceive_vibration",
    "sense_cues",
]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.intp]
BoolArray = NDArray[np.bool_]

#: Percept kinds: nothing felt, one point at a tactor, one funnelled point between two.
KIND_NONE, KIND_SINGLE, KIND_FUNNELLED = 0, 1, 2

_TINY = 1e-12
#: SDs below this are treated as this (the ideal observer's likelihoods stay finite).
_SD_FLOOR = 1e-9


def localisation_sd_deg(theta_deg: ArrayLike, params: ModelParams) -> FloatArray:
    """SD of the felt body site at direction theta: smallest at navel and spine."""
    s = np.sin(np.radians(np.asarray(theta_deg, dtype=float)))
    lo, hi = params.loc_sd_min_deg, params.loc_sd_max_deg
    return np.asarray(lo + (hi - lo) * s * s)


def bias_deg(theta_deg: ArrayLike, params: ModelParams) -> FloatArray:
    """Bias of the felt body site: towards the navel (0) and the spine (180)."""
    return np.asarray(-params.midline_bias_deg
                      * np.sin(np.radians(2.0 * np.asarray(theta_deg, dtype=float))))


@dataclass(frozen=True)
class Cues:
    """What the vibration of one observed window offers, for a batch of windows.

    Every attribute is an array of shape (n,), one entry per window.

    Attributes:
        pair: the counter-clockwise tactor a of the strongest adjacent pair (a, b).
        w_a, w_b: time-averaged location weights of a and b (the static cue).
        felt_a, felt_b: whether a and b were felt at all (peak amplitude above the
            detection level; with a level of 0, any vibration is felt).
        dwell_a_s, dwell_b_s: how long a and b dominated the pair (the dynamic cue).
        overlap: share of the felt time during which a and b were both felt.
        duration_s: length of the window.
    """

    pair: IntArray
    w_a: FloatArray
    w_b: FloatArray
    felt_a: BoolArray
    felt_b: BoolArray
    dwell_a_s: FloatArray
    dwell_b_s: FloatArray
    overlap: FloatArray
    duration_s: FloatArray

    @property
    def n(self) -> int:
        return int(self.pair.shape[0])

    def take(self, index: ArrayLike) -> Cues:
        """The cues of the given windows (e.g. one entry per trial from per-stimulus cues)."""
        idx = np.asarray(index, dtype=np.intp)
        return Cues(*(np.asarray(getattr(self, f))[idx] for f in _CUE_FIELDS))


_CUE_FIELDS = tuple(f.name for f in fields(Cues))


def _sample_durations(t_s: FloatArray) -> FloatArray:
    """How long each sample stands for (the step to the next one; the last repeats)."""
    n = t_s.shape[0]
    if n == 1:
        return np.array([1e-3])
    dt = np.empty(n)
    np.subtract(t_s[1:], t_s[:-1], out=dt[:-1])
    if not dt[:-1].min() > 0:
        raise ConfigError("vibration sample times must be strictly increasing")
    dt[-1] = dt[-2]
    return dt


def sense_cues(t_s: ArrayLike, vib: ArrayLike, layout: Layout,
               params: ModelParams | None = None) -> Cues:
    """Extract the cues from sampled vibration (deterministic; no noise).

    Args:
        t_s: sample times in seconds, shape (n,), strictly increasing (any origin).
        vib: vibration amplitude of each tactor in [0, 1], shape (n, N), or a batch of
            windows sampled at the same times, shape (K, n, N).
        layout: the belt's layout (N tactors).
        params: the observer (gamma, detection level, dominance margin).

    Returns:
        :class:`Cues` with one entry per window (1 or K).

    Raises:
        ConfigError: shapes that do not match, an empty window, or times that do not
            increase.
    """
    p = params if params is not None else ModelParams()
    t = np.asarray(t_s, dtype=float).reshape(-1)
    v = np.asarray(vib, dtype=float)
    if v.ndim == 2:
        v = v[None]
    if v.ndim != 3 or v.shape[-1] != layout.n:
        raise ConfigError(f"vibration must have shape (samples, {layout.n}) or "
                          f"(windows, samples, {layout.n}), got {np.shape(vib)}")
    if t.shape[0] == 0 or v.shape[1] != t.shape[0]:
        raise ConfigError(f"{t.shape[0]} sample times for {v.shape[1]} vibration samples; "
                          "a window needs at least one sample and one time per sample")
    lo, hi = float(v.min()), float(v.max())  # NaN and infinities reach both
    if not (math.isfinite(lo) and math.isfinite(hi)):
        raise ConfigError("vibration amplitudes must be finite")
    if lo < 0.0 or hi > 1.0:
        v = np.clip(v, 0.0, 1.0)
    dt = _sample_durations(t)
    total = float(dt.sum())
    w = v**p.gamma                                            # (K, n, N)
    w_mean = np.einsum("knj,n->kj", w, dt) / total            # (K, N)
    cw, _ = layout.neighbour_indices()
    pair = np.argmax(w_mean + w_mean[:, cw], axis=1)          # (K,)
    if v.shape[0] == 1:
        return _sense_one(v[0], w[0], w_mean[0], int(pair[0]), int(cw[pair[0]]), dt, total, p)
    return _sense_many(v, w, w_mean, pair, cw[pair], dt, total, p)


def _sense_many(v: FloatArray, w: FloatArray, w_mean: FloatArray, pair: IntArray,
                b: IntArray, dt: FloatArray, total: float, p: ModelParams) -> Cues:
    """:func:`sense_cues` of a batch of windows (``v``, ``w``: (K, n, N)) once each one's
    pair (``pair``, ``b``) is known."""
    rows = np.arange(v.shape[0])
    peak = v.max(axis=1)                                      # (K, N)
    felt_a = peak[rows, pair] > p.detect_amplitude
    felt_b = peak[rows, b] > p.detect_amplitude
    va, vb = v[rows, :, pair], v[rows, :, b]                  # (K, n)
    wa, wb = w[rows, :, pair], w[rows, :, b]
    tot = wa + wb
    share_b = np.divide(wb, tot, out=np.full_like(tot, 0.5), where=tot > 0)
    on_a, on_b = va > p.detect_amplitude, vb > p.detect_amplitude
    active = on_a | on_b
    dom_b = active & (share_b > 0.5 + p.dominance_margin)
    dom_a = active & (share_b < 0.5 - p.dominance_margin)
    felt_time = active @ dt
    overlap = np.divide((on_a & on_b) @ dt, felt_time, out=np.zeros_like(felt_time),
                        where=felt_time > 0)
    return Cues(
        pair=np.asarray(pair, dtype=np.intp),
        w_a=w_mean[rows, pair], w_b=w_mean[rows, b],
        felt_a=np.asarray(felt_a), felt_b=np.asarray(felt_b),
        dwell_a_s=dom_a @ dt, dwell_b_s=dom_b @ dt,
        overlap=np.asarray(overlap),
        duration_s=np.full(v.shape[0], total),
    )


def _sense_one(v: FloatArray, w: FloatArray, w_mean: FloatArray, a: int, b: int,
               dt: FloatArray, total: float, p: ModelParams) -> Cues:
    """:func:`sense_cues` of one window (``v``, ``w``: (n, N)) once its pair (a, b) is
    known: the same arithmetic on the pair's columns only."""
    det = p.detect_amplitude
    va, vb = v[:, a], v[:, b]
    wa, wb = w[:, a], w[:, b]
    tot = wa + wb
    share_b = np.divide(wb, tot, out=np.full_like(tot, 0.5), where=tot > 0)
    on_a, on_b = va > det, vb > det
    active = on_a | on_b
    dom_b = active & (share_b > 0.5 + p.dominance_margin)
    dom_a = active & (share_b < 0.5 - p.dominance_margin)
    felt_time = active[None] @ dt
    overlap = np.divide((on_a & on_b)[None] @ dt, felt_time, out=np.zeros_like(felt_time),
                        where=felt_time > 0)
    return Cues(
        pair=np.array([a], dtype=np.intp),
        w_a=w_mean[a : a + 1], w_b=w_mean[b : b + 1],
        felt_a=np.array([va.max() > det]), felt_b=np.array([vb.max() > det]),
        dwell_a_s=dom_a[None] @ dt, dwell_b_s=dom_b[None] @ dt,
        overlap=np.asarray(overlap),
        duration_s=np.array([total]),
    )


@dataclass(frozen=True)
class Percepts:
    """What the observer felt and answered, one entry per trial.

    Attributes:
        response_deg: the chosen target (one of the candidate targets).
        response_index: its index among the candidates.
        perceived_deg: the felt direction (identified site plus position in the pair).
        site_deg: the felt body site before identification (with bias and noise).
        fraction: felt position within the pair, 0 at a (ccw) to 1 at b (cw).
        kind: KIND_NONE, KIND_SINGLE or KIND_FUNNELLED.
        two_points: two tactors were felt as two points (answered at the stronger).
        dynamic_cue: the dwell-time cue was available and used.
        guessed: a lapse, or nothing was felt: a random target.
    """

    response_deg: FloatArray
    response_index: IntArray
    perceived_deg: FloatArray
    site_deg: FloatArray
    fraction: FloatArray
    kind: IntArray
    two_points: BoolArray
    dynamic_cue: BoolArray
    guessed: BoolArray


def perceive(cues: Cues, layout: Layout, targets: TargetSet | ArrayLike,
             params: ModelParams, rng: np.random.Generator) -> Percepts:
    """Turn cues into felt directions and answers, with the observer's noise.

    Random draws are taken in a fixed order (one block per trial batch), so a seeded
    generator gives the same answers every time.

    Args:
        cues: one entry per trial (see :func:`sense_cues`, :meth:`Cues.take`).
        layout: the body map (the tactor angles the observer learned in training).
        targets: the candidate targets.
        params: the observer.
        rng: the random generator.
    """
    p = params
    tgt = (targets.angles if isinstance(targets, TargetSet)
           else np.atleast_1d(np.asarray(targets, dtype=float)))
    if tgt.size == 0:
        raise ConfigError("perceive needs at least one candidate target")
    n = cues.n
    z = rng.standard_normal((3, n))
    u = rng.random((2, n))
    if n == 1:
        # one draw without a size is the draw of size 1 (the same bits, the same state
        # after), at a fifth of the cost; tests/test_participant.py checks it
        return _perceive_one(cues, _sites(layout, p), tgt, p, z[:, 0].tolist(),
                             u[:, 0].tolist(), int(rng.integers(0, tgt.size)))
    guess_idx = rng.integers(0, tgt.size, size=n)
    cw, _ = layout.neighbour_indices()
    return _perceive_many(cues, layout.angles, cw, layout.gaps_deg(), tgt, p, z, u, guess_idx)


@dataclass(frozen=True)
class _Sites:
    """What one trial's percept reads of a layout and observer: the tactors and the pair
    midpoints as candidate sites, with their localisation SDs (floored) and the SDs'
    logs, and per site the bias and SD of a felt centre there (read-only; made once
    by :func:`_sites`)."""

    angles: FloatArray
    cw: IntArray
    gaps: FloatArray
    mids: FloatArray
    single: tuple[FloatArray, FloatArray, FloatArray]  # sites, SDs, log SDs
    pair: tuple[FloatArray, FloatArray, FloatArray]
    centre: dict[float, tuple[float, float]]  # centre -> (bias, SD at least 0)


@functools.lru_cache(maxsize=32)
def _sites(layout: Layout, p: ModelParams) -> _Sites:
    """:class:`_Sites` of a layout and observer, with the arithmetic of one trial's
    percept (each value as :func:`_perceive_one` computed it, trial by trial, before)."""
    angles = layout.angles
    cw, _ = layout.neighbour_indices()
    gaps = layout.gaps_deg()
    mids = angles + gaps / 2.0
    sd_t = np.maximum(localisation_sd_deg(angles, p), _SD_FLOOR)
    sd_m = np.maximum(localisation_sd_deg(mids, p), _SD_FLOOR)
    centre = {c: (float(bias_deg(c, p)), max(float(localisation_sd_deg(c, p)), 0.0))
              for c in [float(x) for x in angles] + [float(x) for x in mids]}
    for arr in (angles, cw, gaps, mids, sd_t, sd_m):
        arr.setflags(write=False)
    return _Sites(angles, cw, gaps, mids, (angles, sd_t, np.log(sd_t)),
                  (mids, sd_m, np.log(sd_m)), centre)


def _perceive_many(cues: Cues, angles: FloatArray, cw: IntArray, gaps: FloatArray,
                   tgt: FloatArray, p: ModelParams, z: FloatArray, u: FloatArray,
                   guess_idx: IntArray) -> Percepts:
    """:func:`perceive` of a batch of trials with their draws taken (vectorised)."""
    n = cues.n
    a = cues.pair
    b = cw[a]
    felt_a, felt_b = cues.felt_a, cues.felt_b
    both = felt_a & felt_b
    one = felt_a ^ felt_b
    nothing = ~(felt_a | felt_b)

    # -- position within the pair: static and dynamic cues in log-ratio units ----------
    sd_s = p.gamma * math.sqrt(2.0) * p.weber_amplitude
    sd_d = math.sqrt(2.0) * p.weber_duration
    ell_s = np.log((cues.w_b + _TINY) / (cues.w_a + _TINY)) + sd_s * z[0]
    dyn = both & (cues.dwell_a_s >= p.min_dwell_s) & (cues.dwell_b_s >= p.min_dwell_s)
    ell_d = np.log(np.maximum(cues.dwell_b_s, _TINY) / np.maximum(cues.dwell_a_s, _TINY))
    ell_d = ell_d + sd_d * z[1]
    rel_s = 1.0 / max(sd_s * sd_s, _TINY)
    rel_d = np.where(dyn, 1.0 / max(sd_d * sd_d, _TINY), 0.0)
    ell = (rel_s * ell_s + rel_d * ell_d) / (rel_s + rel_d)
    fraction = 1.0 / (1.0 + np.exp(-np.clip(ell, -700.0, 700.0)))

    # -- one point or two -----------------------------------------------------------------
    two = both & (u[0] < p.p_two_points * cues.overlap)
    single = one | two
    stronger_b = np.where(one, felt_b, ell_s > 0.0)
    single_at = np.where(stronger_b, b, a)
    fraction = np.where(single, stronger_b.astype(float), fraction)
    kind = np.where(nothing, KIND_NONE, np.where(single, KIND_SINGLE, KIND_FUNNELLED))

    # -- the body site: which tactor or which pair ------------------------------------
    mids = angles + gaps / 2.0
    centre = np.where(single, angles[single_at], mids[a])
    site = normalize(centre + bias_deg(centre, p)
                     + np.maximum(localisation_sd_deg(centre, p), 0.0) * z[2])
    site = np.asarray(site, dtype=float).reshape(n)
    cand_t = np.maximum(localisation_sd_deg(angles, p), _SD_FLOOR)
    cand_m = np.maximum(localisation_sd_deg(mids, p), _SD_FLOOR)
    cand = np.where(single[:, None], angles[None, :], mids[None, :])
    cand_sd = np.where(single[:, None], cand_t[None, :], cand_m[None, :])
    d = wrap(site[:, None] - cand) / cand_sd
    ident = np.argmax(-0.5 * d * d - np.log(cand_sd), axis=1)
    perceived = np.where(single, angles[ident], angles[ident] + fraction * gaps[ident])
    perceived = np.asarray(normalize(perceived), dtype=float).reshape(n)

    # -- the answer: the candidate nearest to the felt direction ----------------------
    dist = np.abs(wrap(perceived[:, None] - tgt[None, :]))
    choice = np.argmin(dist, axis=1)
    guessed = nothing | (u[1] < p.lapse)
    choice = np.where(guessed, guess_idx, choice)
    return Percepts(
        response_deg=tgt[choice], response_index=np.asarray(choice, dtype=np.intp),
        perceived_deg=perceived, site_deg=site, fraction=np.asarray(fraction),
        kind=np.asarray(kind, dtype=np.intp), two_points=np.asarray(two),
        dynamic_cue=np.asarray(dyn & ~single), guessed=np.asarray(guessed),
    )


def _perceive_one(cues: Cues, sites: _Sites, tgt: FloatArray, p: ModelParams,
                  z: list[float], u: list[float], guess: int) -> Percepts:
    """:func:`perceive` of one trial with its draws taken: the same arithmetic on scalars
    (NumPy's functions for log, exp and the angles, Python's for + - * /, which are
    the same IEEE operations)."""
    angles, gaps = sites.angles, sites.gaps
    a = int(cues.pair[0])
    b = int(sites.cw[a])
    felt_a, felt_b = bool(cues.felt_a[0]), bool(cues.felt_b[0])
    both = felt_a and felt_b
    one = felt_a != felt_b
    nothing = not (felt_a or felt_b)
    w_a, w_b = float(cues.w_a[0]), float(cues.w_b[0])
    dwell_a, dwell_b = float(cues.dwell_a_s[0]), float(cues.dwell_b_s[0])

    sd_s = p.gamma * math.sqrt(2.0) * p.weber_amplitude
    sd_d = math.sqrt(2.0) * p.weber_duration
    ell_s = float(np.log((w_b + _TINY) / (w_a + _TINY))) + sd_s * z[0]
    dyn = both and dwell_a >= p.min_dwell_s and dwell_b >= p.min_dwell_s
    ell_d = float(np.log(max(dwell_b, _TINY) / max(dwell_a, _TINY))) + sd_d * z[1]
    rel_s = 1.0 / max(sd_s * sd_s, _TINY)
    rel_d = 1.0 / max(sd_d * sd_d, _TINY) if dyn else 0.0
    ell = (rel_s * ell_s + rel_d * ell_d) / (rel_s + rel_d)
    fraction = 1.0 / (1.0 + float(np.exp(-min(max(ell, -700.0), 700.0))))

    two = both and u[0] < p.p_two_points * float(cues.overlap[0])
    single = one or two
    stronger_b = felt_b if one else ell_s > 0.0
    single_at = b if stronger_b else a
    if single:
        fraction = float(stronger_b)
    kind = KIND_NONE if nothing else (KIND_SINGLE if single else KIND_FUNNELLED)

    centre = float(angles[single_at] if single else sites.mids[a])
    bias, sd = sites.centre[centre]
    site = float(normalize(centre + bias + sd * z[2]))
    cand, cand_sd, log_sd = sites.single if single else sites.pair
    d = wrap(site - cand) / cand_sd
    ident = int((-0.5 * d * d - log_sd).argmax())
    perceived = float(angles[ident]) if single else float(angles[ident]) + fraction * float(
        gaps[ident])
    perceived = float(normalize(perceived))

    choice = int(np.argmin(np.abs(wrap(perceived - tgt))))
    guessed = nothing or u[1] < p.lapse
    if guessed:
        choice = guess
    return Percepts(
        response_deg=tgt[choice : choice + 1], response_index=np.array([choice], dtype=np.intp),
        perceived_deg=np.array([perceived]), site_deg=np.array([site]),
        fraction=np.array([fraction]), kind=np.array([kind], dtype=np.intp),
        two_points=np.array([two]), dynamic_cue=np.array([dyn and not single]),
        guessed=np.array([guessed]),
    )


def perceive_vibration(t_s: ArrayLike, vib: ArrayLike, layout: Layout,
                       targets: TargetSet | ArrayLike, params: ModelParams | None = None,
                       rng: np.random.Generator | None = None) -> Percepts:
    """Sense and perceive one window of vibration (or a batch sampled at the same times).

    Args:
        t_s: sample times (n,), seconds.
        vib: amplitudes (n, N) or (K, n, N) in [0, 1].
        layout: the tactor layout.
        targets: the candidate targets.
        params: the observer (default: the typical observer).
        rng: random generator (default: ``np.random.default_rng(0)``).
    """
    p = params if params is not None else ModelParams()
    g = rng if rng is not None else np.random.default_rng(0)
    return perceive(sense_cues(t_s, vib, layout, p), layout, targets, p, g)
