"""The ERM vibration motor's physics: :class:`ErmParams` and the exact solution of its speed.

Each motor's speed follows a first-order response to its drive level, with a rise and a
fall time constant and no spin below the start level (the dead zone); the vibration
amplitude grows with the square of the speed. The drive is piecewise constant (it changes
only at commands and at 1 kHz render ticks), and on each piece the speed relaxes
exponentially towards its steady state with the rise or the fall time constant:

- :func:`erm_speed` solves a whole drive history vectorised (over tactors and time, by
  cumulative products), with the rise/fall choice found by fixed-point iteration;
- a drive that changes at few steps is solved stretch by stretch in closed form
  (:func:`_erm_segments`);
- :class:`_Response` is the speed under a periodic render started from rest, from which
  :mod:`tactorbelt.devices.sim` takes later states by superposition;
- :func:`sample_grid` is the drift-free integer-nanosecond sampling grid every query uses.

The simulated belt (:mod:`tactorbelt.devices.sim`) keeps the command history and asks this
module for speeds; the onset validator's analytic checks use :class:`ErmParams`.

Pure: NumPy and the standard library; no tactorbelt module but ``_errors``.
"""

from __future__ import annotations

import functools
import itertools
import math
from dataclasses import dataclass
from fractions import Fraction
from typing import Any, Final

import numpy as np
from numpy.typing import NDArray

from .._errors import ConfigError

__all__ = ["BRAKE", "DRIVES", "LEAD_TICKS", "PREROLL_NS", "RENDER_TICK_NS", "ErmParams", "Shaper",
           "drive_relax", "erm_speed", "kick_duration_s", "sample_grid"]

#: The drive modes a belt plays with: ``plain`` (each level straight to the motor) and
#: ``shaped`` (overdrive and active braking, :class:`Shaper`).
DRIVES: Final = ("plain", "shaped")
#: The signed drive that short-brakes a motor: both H-bridge inputs high, no voltage
#: across it, its back-EMF braking it. Negative zero: a drive's sign bit says the bridge
#: drives in reverse or brakes (``np.signbit``), +0.0 is coast (both inputs low).
BRAKE: Final = -0.0

#: Played stimuli are rendered at 1 kHz, like the firmware.
RENDER_TICK_NS: Final = 1_000_000
#: A step's decay exponent is capped here: exp(-300) is zero for every purpose.
_MAX_DECAY: Final = 300.0
#: Speed differences below this are ties for the rise/fall choice.
_TIE: Final = 1e-12
#: Fixed-point iterations for the rise/fall choice before finishing step by step.
_MAX_ITERATIONS: Final = 12
#: A drive that changes at fewer steps than this is solved stretch by stretch in closed
#: form (:func:`_erm_segments`), cheaper than the vectorised recurrence.
_SEGMENT_STEPS: Final = 16
#: A response from rest is solved for this many ticks (3 s; half the model participant's
#: queries reach 2 s into a render, 1 % 3 s); a query further into a render takes the
#: general solution.
_RESPONSE_MAX_TICKS: Final = 3_072

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class ErmParams:
    """Constants of the ERM motor model (one set for every tactor).

    Speed ``w`` is normalised so that full drive (level 1) spins the motor at its rated
    speed (``w = 1``); vibration amplitude is normalised so that rated speed gives 1.

    Attributes:
        rise_tau_s: time constant of the speed while it rises (0.040 s). Source:
            Precision Microdrives, AB-004 "Understanding ERM vibration motor
            characteristics", and the rise times listed in their datasheets of 7-10 mm
            ERMs (several tens of ms to reach half the rated vibration). With amplitude
            ~ speed squared, 50 % amplitude is reached after ``-tau*ln(1 - 0.5**0.5)``
            = 1.23 tau = 49 ms. Not measured on the paper's motor: an assumption within
            that range.
        fall_tau_s: time constant while the speed falls (0.050 s); source as above
            (AB-004's stop time, longer than the rise since only friction and back-EMF
            brake an undriven motor). An assumption within the quoted range.
        start_level: the dead zone (0.25): below this drive level the motor does not
            start. The paper's motor (Vybronics VZ7AL2B1692082, 3 V rated) has a start
            voltage well below its rated voltage; 0.25 of full drive is an assumption
            (measure your motors with ``tactorbelt calibrate``).
        amplitude_exponent: vibration amplitude ~ speed ** exponent (2.0): the
            centripetal force of the eccentric mass is ``m * r * w**2`` (Precision
            Microdrives AB-004, AB-028). Physics, not an assumption.
    """

    rise_tau_s: float = 0.040
    fall_tau_s: float = 0.050
    start_level: float = 0.25
    amplitude_exponent: float = 2.0
    #: time constant while the motor is driven against its motion (reverse drive, short
    #: brake): the winding is closed, so the back-EMF current brakes it with the driven
    #: (mechanical) time constant, the one it rises with. An assumption (0.040 s).
    brake_tau_s: float = 0.040
    #: the drive at level 1 (V): the VZ7AL2B1692082's rated voltage, 3.0 V DC.
    rated_voltage_v: float = 3.0
    #: the most the motor may be driven with (V): 3.6 V for the VZ7AL2B1692082
    #: (docs/belts.md, "Drive shaping", for the source and what is assumed).
    max_voltage_v: float = 3.6

    def __post_init__(self) -> None:
        for name in ("rise_tau_s", "fall_tau_s", "amplitude_exponent", "brake_tau_s",
                     "rated_voltage_v", "max_voltage_v"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not (
                math.isfinite(v) and v > 0
            ):
                raise ConfigError(f"ErmParams.{name} must be a positive, finite number, got {v!r}")
        if self.max_voltage_v < self.rated_voltage_v:
            raise ConfigError(f"ErmParams.max_voltage_v ({self.max_voltage_v:g} V) is below "
                              f"the rated voltage ({self.rated_voltage_v:g} V)")
        s = self.start_level
        if isinstance(s, bool) or not isinstance(s, int | float) or not (0.0 <= s < 1.0):
            raise ConfigError(f"ErmParams.start_level must be in [0, 1), got {s!r}")

    def overdrive_bound(self, supply_v: float | None = None) -> float:
        """The largest forward drive, in levels (1 = rated voltage): the motor's maximum
        voltage, or the supply when lower, over its rated voltage (at least 1)."""
        top = self.max_voltage_v if supply_v is None else min(self.max_voltage_v,
                                                               float(supply_v))
        return max(1.0, top / self.rated_voltage_v)

    def kick_overdrive(self, supply_v: float, kick_ms: float,
                       rise_tau_s: Any = None) -> float:
        """The shaper's largest drive (levels, 1 = rated) on a motor supply of ``supply_v``
        when a kick may apply the whole supply, above the motor's maximum voltage, for at
        most ``kick_ms`` (0: never; the bound is then :meth:`overdrive_bound`).

        A kick above the maximum is short and bounded: the shaper drives the overdrive ``k``
        only while its model of the motor is below the level, so a kick lasts at most
        ``rise_tau * ln(k / (k - 1))`` plus a render tick (from rest to full level), and the
        winding heat of a start to full speed is ``(k - 1/2) J w**2`` against ``J w**2 / 2``
        plain (docs/belts.md, "The kick bound"). ``rise_tau_s``: the shaper's rise time
        constants (one per tactor, or one); the supply is refused when a kick to full level
        at it would outlast ``kick_ms``.

        Raises:
            ConfigError: a supply or limit out of range, or a kick that would last longer.
        """
        for name, v, lo in (("supply_v", supply_v, 0.5), ("kick_ms", kick_ms, 0.0)):
            if isinstance(v, bool) or not isinstance(v, int | float) or not (
                    math.isfinite(v) and v >= lo):
                raise ConfigError(f"{name} must be a number >= {lo:g}, got {v!r}")
        if kick_ms == 0 or supply_v <= self.max_voltage_v:
            return self.overdrive_bound(supply_v)
        k = float(supply_v) / self.rated_voltage_v
        taus = np.atleast_1d(np.asarray(self.rise_tau_s if rise_tau_s is None else rise_tau_s,
                                        dtype=float))
        longest = float(kick_duration_s(k, float(taus.max())))
        if longest * 1e3 > kick_ms:
            raise ConfigError(
                f"a kick at the {supply_v:g} V supply ({k:.3g} x the rated "
                f"{self.rated_voltage_v:g} V) lasts up to {longest * 1e3:.1f} ms with a rise "
                f"time constant of {taus.max() * 1e3:.1f} ms, longer than kick_ms="
                f"{kick_ms:g}: raise kick_ms, or lower the supply")
        return k

    def steady_speed(self, levels: FloatArray) -> FloatArray:
        """Steady-state speed for drive levels: 0 below the start level, else the level."""
        lv = np.asarray(levels, dtype=float)
        return np.asarray(np.where(lv >= self.start_level, lv, 0.0))

    def amplitude(self, speed: FloatArray) -> FloatArray:
        """Vibration amplitude in [0, 1] for a normalised speed."""
        return self._amplitude_of(np.clip(np.asarray(speed, dtype=float), 0.0, 1.0))

    def _amplitude_of(self, w: FloatArray) -> FloatArray:
        """:meth:`amplitude` of speeds already in [0, 1] (float)."""
        if self.amplitude_exponent == 2.0:
            return np.asarray(w * w)
        return np.asarray(w**self.amplitude_exponent)


def kick_duration_s(overdrive: float, rise_tau_s: float) -> float:
    """The longest kick the shaper holds at ``overdrive`` (levels) to reach full level from
    rest: ``rise_tau * ln(k / (k - 1))`` plus the render tick that lands it (s). No
    command sequence holds a kick longer (tests/test_drive_shaping.py)."""
    k = float(overdrive)
    if k <= 1.0:
        return math.inf
    return rise_tau_s * math.log(k / (k - 1.0)) + RENDER_TICK_NS * 1e-9


_INT64_MAX: Final = 2**63 - 1


@functools.lru_cache(maxsize=64)
def _grid_period(rate: float) -> tuple[int, int]:
    """The sampling period of ``rate`` Hz as the fraction p/q ns."""
    period = Fraction(10**9) / Fraction(rate).limit_denominator(1_000_000)
    return period.numerator, period.denominator


def sample_grid(t0_ns: int, t1_ns: int, rate_hz: float) -> IntArray:
    """Sample times ``t0 + round-down(i * 1e9 / rate)`` in [t0, t1), integer ns, no drift."""
    try:
        rate = float(rate_hz)
    except (TypeError, ValueError):
        raise ConfigError(f"rate must be a positive number of Hz, got {rate_hz!r}") from None
    if not (math.isfinite(rate) and rate > 0):
        raise ConfigError(f"rate must be a positive, finite number of Hz, got {rate_hz!r}")
    t0, t1 = int(t0_ns), int(t1_ns)
    if t1 < t0:
        raise ConfigError(f"the interval ends ({t1} ns) before it starts ({t0} ns)")
    p, q = _grid_period(rate)
    # number of i with floor(i*p/q) < t1 - t0, i.e. i*p < (t1 - t0)*q
    n = -((-(t1 - t0) * q) // p)
    i = np.arange(n, dtype=np.int64)
    if n and (n - 1) * p > _INT64_MAX // 2:
        raise ConfigError("interval too long for this rate")
    return np.asarray(t0 + (i * p) // q, dtype=np.int64)


def _sorted_unique(a: IntArray) -> IntArray:
    """``np.unique`` for a 1-D int array, by sorting (faster than hashing here)."""
    a = np.sort(a)
    if a.shape[0] < 2:
        return a
    keep = np.empty(a.shape[0], dtype=bool)
    keep[0] = True
    np.not_equal(a[1:], a[:-1], out=keep[1:])
    return np.asarray(a[keep])


def _blocks(step_decay: FloatArray) -> list[tuple[int, int]]:
    """Cut steps into blocks whose total decay stays below about 2 * _MAX_DECAY."""
    m = step_decay.shape[0]
    total = np.cumsum(step_decay)
    if m == 0 or total[-1] < _MAX_DECAY:
        return [(0, m)] if m else []
    block = np.floor(total / _MAX_DECAY).astype(np.int64)
    cuts = np.flatnonzero(np.diff(block)) + 1
    bounds = [0, *cuts.tolist(), m]
    return [(s, e) for s, e in itertools.pairwise(bounds) if e > s]


def _linear_recurrence(w0: FloatArray, log_a: FloatArray, c: FloatArray,
                       blocks: list[tuple[int, int]]) -> FloatArray:
    """Solve ``w[:, j+1] = exp(log_a[:, j]) * w[:, j] + c[:, j]`` for every row at once.

    Rows are motors, columns are steps. ``log_a <= 0`` and ``c >= 0``, so the
    cumulative sums below never cancel; within a block the total decay stays below
    ~600 (exp(600) ~ 1e260), so the cumulative products neither overflow nor underflow.
    """
    n, m = log_a.shape
    out = np.empty((n, m + 1))
    out[:, 0] = w0
    for s, e in blocks:
        lb = np.cumsum(log_a[:, s:e], axis=1)
        acc = np.cumsum(c[:, s:e] * np.exp(-lb), axis=1)
        acc += out[:, s : s + 1]
        out[:, s + 1 : e + 1] = np.exp(lb) * acc
    return out


def erm_speed(t_ns: IntArray, levels: FloatArray, w0: FloatArray,
              params: ErmParams) -> FloatArray:
    """Motor speed at each time of a piecewise-constant drive, exactly.

    On a step of length h with drive u (steady speed ``s(u)``) the speed relaxes as
    ``w' = s + (w - s) * exp(-h / tau)``, tau = rise time constant if ``s > w`` else the
    fall one (the speed moves monotonically within a step, so the choice is exact).

    Args:
        t_ns: increasing times (m,); ``levels[j]`` is the drive on ``[t_ns[j], t_ns[j+1])``.
        levels: drive levels (m, N) in [0, 1].
        w0: the speed of each motor at ``t_ns[0]`` (N,).
        params: the motor constants.

    Returns:
        Speeds (m, N): row j is the speed at ``t_ns[j]``.
    """
    m, n = levels.shape
    w0 = np.asarray(w0, dtype=float)
    out = np.zeros((m, n))
    out[0] = w0
    if m <= 1:
        return out
    starts = np.flatnonzero(np.any(levels[1:-1] != levels[:-2], axis=1)) + 1
    if starts.shape[0] < _SEGMENT_STEPS:
        return _erm_segments(t_ns, levels, w0, params, [0, *starts.tolist(), m - 1])
    target = params.steady_speed(levels[:-1])  # (m-1, N)
    # only motors that move at all need solving
    cols = np.flatnonzero(target.any(axis=0) | (w0 > 0.0))
    if cols.size == 0:
        return out
    u = np.ascontiguousarray(target[:, cols].T)  # (motors, steps)
    h = np.diff(t_ns).astype(float) * 1e-9
    k_rise = np.minimum(h / params.rise_tau_s, _MAX_DECAY)
    k_fall = np.minimum(h / params.fall_tau_s, _MAX_DECAY)
    blocks = _blocks(np.maximum(k_rise, k_fall))
    g_rise = -np.expm1(-k_rise)
    g_fall = -np.expm1(-k_fall)
    start = w0[cols]
    # first guess: the mean time constant; then fix the rise/fall choice until stable
    tau_mid = 2.0 / (1.0 / params.rise_tau_s + 1.0 / params.fall_tau_s)
    k_mid = np.minimum(h / tau_mid, _MAX_DECAY)
    w = _linear_recurrence(start, np.broadcast_to(-k_mid, u.shape), -np.expm1(-k_mid) * u,
                           blocks)
    rising = u > w[:, :-1]
    for _ in range(_MAX_ITERATIONS):
        k = np.where(rising, k_rise, k_fall)
        w = _linear_recurrence(start, -k, np.where(rising, g_rise, g_fall) * u, blocks)
        gap = u - w[:, :-1]
        new_rising = gap > 0.0
        changed = new_rising != rising
        # a choice that flips where the speed already equals its target (to 1e-12) changes
        # the result by less than 1e-14: such near-ties count as settled
        if not np.any(changed & (np.abs(gap) > _TIE)):
            break
        rising = new_rising
    else:
        # not settled (pathological ties): finish exactly, step by step, from the first
        # step whose choice was still changing (everything before it is right)
        bad = np.flatnonzero((new_rising != rising).any(axis=0))
        for j in range(int(bad[0]) if bad.size else u.shape[1], u.shape[1]):
            kj = np.where(u[:, j] > w[:, j], k_rise[j], k_fall[j])
            w[:, j + 1] = u[:, j] + (w[:, j] - u[:, j]) * np.exp(-kj)
    out[:, cols] = np.clip(w.T, 0.0, 1.0)
    return out


def _erm_segments(t_ns: IntArray, levels: FloatArray, w0: FloatArray, params: ErmParams,
                  bounds: list[int]) -> FloatArray:
    """:func:`erm_speed` for a drive that changes at few steps (``bounds``: the first
    step of each constant stretch, then the last time's index): each stretch in closed
    form from its start, ``w = s + (w0 - s) * exp(-t / tau)``, the time constant chosen
    at its start (the speed moves monotonically towards ``s``, so the choice holds)."""
    m, n = levels.shape
    out = np.empty((m, n))
    out[0] = w0
    w = w0
    for a, b in itertools.pairwise(bounds):
        seg = _relax(params.steady_speed(levels[a]), w, t_ns[a + 1 : b + 1] - t_ns[a], params)
        out[a + 1 : b + 1] = seg
        w = seg[-1]
    return np.asarray(np.clip(out, 0.0, 1.0))


def _relax(u: FloatArray, w: FloatArray, dt_ns: IntArray, params: ErmParams) -> FloatArray:
    """Speeds ``dt_ns`` after a state ``w`` under a constant drive whose steady speeds are
    ``u`` (rows: times; ``u`` and ``w`` one row, or one row per time): the closed form of
    one stretch, the time constant chosen at its start (the speed moves monotonically)."""
    tau = np.where(u > w, params.rise_tau_s, params.fall_tau_s)
    return np.asarray(u + (w - u) * _decay_factors(dt_ns, tau))


def _decay_factors(dt_ns: IntArray, tau: FloatArray | float) -> FloatArray:
    """``exp(-dt / tau)`` (rows: times; columns: the time constants, one for a single
    one), the exponent capped at ``_MAX_DECAY``: the decay of a stretch under a constant
    drive."""
    dt = dt_ns.astype(float) * 1e-9
    return np.asarray(np.exp(-np.minimum(dt[:, None] / tau, _MAX_DECAY)))


def _relax_to(u: FloatArray, w: FloatArray, dt_ns: int, params: ErmParams) -> FloatArray:
    """:func:`_relax` at one time: the state (N,) ``dt_ns`` after ``w`` (the same
    arithmetic)."""
    tau = np.where(u > w, params.rise_tau_s, params.fall_tau_s)
    dt = float(dt_ns) * 1e-9
    return np.asarray(u + (w - u) * np.exp(-np.minimum(dt / tau, _MAX_DECAY)))


def _fall_factor_to(dt_ns: int, params: ErmParams) -> np.float64:
    """How much an undriven motor's speed falls in ``dt_ns``: :func:`_relax_to` with ``u = 0``
    is ``w`` times it, ``exp(-dt / fall_tau)``, the same factor for every motor (the same
    arithmetic as :func:`_decay_factors` with the fall time constant; NumPy's exp gives a
    scalar what it gives an array)."""
    dt = float(dt_ns) * 1e-9
    return np.float64(np.exp(-min(dt / params.fall_tau_s, _MAX_DECAY)))


class _Response:
    """The speed of the moving motors under a periodic render started from rest.

    ``cols`` are the motors the render ever drives above the dead zone; the others are
    driven at 0 all along (a constant drive, in closed form). For the moving ones and the
    ticks ``0..K`` (K = ``_RESPONSE_MAX_TICKS``) it keeps the speed at each tick's start
    ``w`` (from rest at tick 0) and the cumulative decay exponent ``d`` along the
    rise/fall choices (tick k rises when ``u[k] > w[k]``, ``u`` the steady speed of its
    drive, ``u_period[k % P]``). From any other state at a tick ``k0`` the speed at a
    later tick ``k`` is, by superposition, ``w[k] + (state - w[k0]) * exp(-(d[k] -
    d[k0]))``: exact as long as every tick in between makes the same rise/fall choice.
    The offset ``state - w[k0]`` only shrinks, so that holds wherever it is within the
    limits (``rise_limit``: the least ``u - w`` over rising ticks, ``fall_limit``: the
    least ``w - u`` over the others, each plus the tie tolerance); otherwise
    :meth:`SimBelt._moving` checks each tick and, where a choice differs, the general
    solution is taken.

    Solved once, on first use, and shared by every sim belt of the process (keyed by the
    stimulus, the calibration and the motor constants; read-only): ~110 KB for a dynamic
    stimulus on its 2 moving motors.
    """

    __slots__ = ("cols", "d", "fall_limit", "rise_limit", "u_period", "w")

    def __init__(self, period_levels: FloatArray, params: ErmParams) -> None:
        u_period = params.steady_speed(period_levels)
        self.cols: IntArray = np.flatnonzero(u_period.any(axis=0)).astype(np.int64)
        self.u_period: FloatArray = np.ascontiguousarray(u_period[:, self.cols])
        ticks = np.arange(_RESPONSE_MAX_TICKS + 1, dtype=np.int64)
        u = self.u(ticks)  # steady speeds are their own drive levels
        w = erm_speed(ticks * RENDER_TICK_NS, u, np.zeros(self.cols.shape[0]), params)
        rising = u[:-1] > w[:-1]
        h = float(RENDER_TICK_NS) * 1e-9
        d = np.zeros(w.shape)
        np.cumsum(np.where(rising, min(h / params.rise_tau_s, _MAX_DECAY),
                           min(h / params.fall_tau_s, _MAX_DECAY)), axis=0, out=d[1:])
        gap = u[:-1] - w[:-1]
        # the largest offsets up and down that change no choice beyond a tie: the margins
        # plus the tie tolerance
        self.rise_limit: FloatArray = np.where(rising, gap, np.inf).min(axis=0) + _TIE
        self.fall_limit: FloatArray = np.where(rising, np.inf, -gap).min(axis=0) + _TIE
        self.w: FloatArray = w
        self.d: FloatArray = d
        for a in (self.u_period, self.w, self.d, self.rise_limit, self.fall_limit):
            a.setflags(write=False)

    @property
    def nbytes(self) -> int:
        return int(self.w.nbytes + self.d.nbytes + self.u_period.nbytes)

    def u(self, ticks: IntArray | int) -> FloatArray:
        """Steady speeds of the moving motors during the given ticks."""
        return np.asarray(self.u_period[np.asarray(ticks) % self.u_period.shape[0]])

    def within_limits(self, offset: FloatArray) -> bool:
        """True when a state ``offset`` from the response at a tick changes no rise/fall
        choice from there on (so superposition on the response is exact)."""
        return bool((offset <= self.rise_limit).all() and (-offset <= self.fall_limit).all())

    def decay(self, k0: int, a: int, b: int) -> FloatArray:
        """``exp(-exponent)`` from tick ``k0`` to each tick in ``a..b-1``, along the
        response's choices (rows: ticks; columns: the moving motors)."""
        return np.asarray(np.exp(-(self.d[a:b] - self.d[k0])))


# -- signed drive and drive shaping ------------------------------------------------------
#: A shaper counts a tactor as at its target when its predicted speed is this close.
_SETTLED: Final = 1e-9
#: The largest preview a shaper takes (render ticks).
MAX_LEAD_TICKS: Final = 50
#: The shaper's preview of a rendered stimulus (render ticks, 3 ms): the firmware's
#: renderer takes the same (``kShapeLeadTicks``, firmware/tactorbelt/src/core/drive.h).
#: Measured on the paper's stimuli (docs/belts.md, "The goals, measured"): the between-
#: tactor dynamic error is least at 3-4 ticks with a 5 V kick, 6 at 3.6 V.
LEAD_TICKS: Final = 3
#: The shaped drive's pre-roll (ns, 3 ms): a stimulus played through the player on a
#: shaped belt has its onset this long after the command, so the kick from rest starts
#: before the onset a session stores, and the shaper aims each tick at what the study
#: means the pre-roll and its preview later (docs/belts.md, "Pre-roll"). Measured on the
#: paper's stimuli (benchmarks/bench_drive.py --stimulus, 0 to 16 ms): at 3 ms the worst
#: static onset error at 3.6 V falls from 12.0 to 9.0 ms and the 5 V kick's dynamic error
#: is least; longer pre-rolls make the 5 V kick's worse.
PREROLL_NS: Final = 3 * RENDER_TICK_NS


def relax_terms(drive: FloatArray, w: FloatArray, params: ErmParams
                ) -> tuple[FloatArray, FloatArray]:
    """The signed steady speed a constant signed drive relaxes a speed ``w`` towards, and
    the time constant it relaxes with (:func:`drive_relax`'s terms): forward (>= +0.0) as
    ErmParams.steady_speed (no spin below the start level) with the rise or the fall
    time constant; reverse the drive itself (the motor is pushed towards spinning
    backwards; it is already turning, so no dead zone), a short brake (BRAKE) 0, with
    the brake time constant."""
    d = np.asarray(drive, dtype=float)
    u = np.where(np.signbit(d), d, np.where(d >= params.start_level, d, 0.0))
    tau = np.where(np.signbit(d), params.brake_tau_s,
                   np.where(u > w, params.rise_tau_s, params.fall_tau_s))
    return u, tau


def drive_relax(drive: FloatArray, w: FloatArray, dt_s: float | FloatArray,
                params: ErmParams) -> FloatArray:
    """The signed speed ``dt_s`` after ``w`` under a constant signed drive.

    Forward drive (coast at +0.0, above 1 overdrive) relaxes with the rise or the fall
    time constant as in :func:`erm_speed` (the same arithmetic for drives in [0, 1]);
    reverse drive and the short brake with the brake time constant, towards the drive
    (a motor held in reverse past a stop spins backwards: the speed goes negative).
    """
    w = np.asarray(w, dtype=float)
    u, tau = relax_terms(drive, w, params)
    dt = np.asarray(dt_s, dtype=float)
    if dt.ndim == 1 and tau.ndim == 2:  # one time per row
        dt = dt[:, None]
    return np.asarray(u + (w - u) * np.exp(-np.minimum(dt / tau, _MAX_DECAY)))


@dataclass(frozen=True)
class Shaper:
    """Drive shaping: every change of a tactor's level played as a kick or a brake pulse.

    At each decision (a render tick, a new frame) the shaper predicts each motor's speed
    with its model (``params``, per tactor the time constants ``rise_tau_s``,
    ``fall_tau_s``, ``brake_tau_s`` when tuned) and chooses the drive until the next
    decision, ``h`` later:

    - at the target speed (the steady speed of the level): the level itself;
    - below it: the overdrive (bounded by ``overdrive``, the motor's maximum voltage or
      the supply over its rated voltage), or on the last tick of the kick the drive that
      lands the predicted speed exactly on the target (no overshoot);
    - above it: a lower forward drive when that lands on it within ``h`` (a small fall);
      else reverse drive (``brake``: the bridge has both inputs), as strong as landing
      needs, at most ``overdrive``; without braking, coast. Where neither lands without
      passing the target, the level itself (the motor coasts down to it).

    So a kick lasts the time the model gives to reach the new level,
    ``tau * ln((k - w0) / (k - s))`` (k the overdrive), a brake pulse likewise, and the
    drive never stays beyond the target: the predicted speed cannot pass it, so no command
    sequence holds overdrive past ``rise_tau * ln(k / (k - 1))`` plus a tick, nor reverse
    drive past ``brake_tau * ln((k + k) / k)`` plus a tick.
    """

    params: ErmParams
    overdrive: float
    brake: bool = True
    rise_tau_s: tuple[float, ...] | None = None
    fall_tau_s: tuple[float, ...] | None = None
    brake_tau_s: tuple[float, ...] | None = None
    #: preview (render ticks): a rendered stimulus is known ahead, so the shaper aims each
    #: tick at the level the render will have this many ticks later (its end included),
    #: the felt envelope then tracks the intended one instead of lagging it. Frames and
    #: stops are not known ahead and take no lead.
    lead_ticks: int = LEAD_TICKS

    def __post_init__(self) -> None:
        lt = self.lead_ticks
        if isinstance(lt, bool) or not isinstance(lt, int) or not 0 <= lt <= MAX_LEAD_TICKS:
            raise ConfigError(f"the shaper's lead must be a whole number of render ticks in "
                              f"[0, {MAX_LEAD_TICKS}], got {lt!r}")
        od = self.overdrive
        if isinstance(od, bool) or not isinstance(od, int | float) or not (
                math.isfinite(od) and 1.0 <= od <= 4.0):
            raise ConfigError(f"overdrive must be a number in [1, 4] (times the rated "
                              f"drive), got {od!r}")
        for name in ("rise_tau_s", "fall_tau_s", "brake_tau_s"):
            v = getattr(self, name)
            if v is not None and not all(isinstance(x, int | float) and math.isfinite(x)
                                         and 0.0 < x < 10.0 for x in v):
                raise ConfigError(f"Shaper.{name} must be time constants in (0, 10) s, "
                                  f"got {v!r}")

    def taus(self, n: int) -> tuple[FloatArray, FloatArray, FloatArray]:
        """The rise, fall and brake time constants of ``n`` tactors (s)."""
        p = self.params
        out = []
        for given, default in ((self.rise_tau_s, p.rise_tau_s), (self.fall_tau_s,
                               p.fall_tau_s), (self.brake_tau_s, p.brake_tau_s)):
            if given is None:
                out.append(np.full(n, default))
            elif len(given) != n:
                raise ConfigError(f"the shaping has time constants for {len(given)} "
                                  f"tactors, the belt {n}")
            else:
                out.append(np.asarray(given, dtype=float))
        return out[0], out[1], out[2]

    def landing(self, levels: FloatArray, prev: FloatArray, h_s: float,
                taus: tuple[FloatArray, FloatArray, FloatArray]
                ) -> tuple[FloatArray, NDArray[np.bool_]]:
        """The shaper's drive (the rule of :class:`Shaper`) for many decisions at once,
        each from a predicted speed at the previous target (``prev``: rows are
        decisions): the drive of each and whether every tactor lands on its target within
        ``h_s`` (the decision then ends on the target; where one does not, the decision is
        taken one by one)."""
        rise, fall, brake = taus
        start = self.params.start_level
        lv = np.asarray(levels, dtype=float)
        s = np.where(lv >= start, lv, 0.0)
        gap = s - prev
        er, ef = np.exp(-h_s / rise), np.exp(-h_s / fall)
        up = (s - prev * er) / (1.0 - er)
        fwd = (s - prev * ef) / (1.0 - ef)
        ok_up = up <= self.overdrive
        ok_fwd = (fwd >= start) & (s > 0.0)
        d = np.where(gap > _SETTLED, up, np.where(gap < -_SETTLED, fwd, lv))
        ok = np.where(gap > _SETTLED, ok_up, np.where(gap < -_SETTLED, ok_fwd, True))
        if self.brake:
            eb = np.exp(-h_s / brake)
            rev = (s - prev * eb) / (1.0 - eb)
            use_rev = (gap < -_SETTLED) & ~ok_fwd
            ok_rev = (rev <= 0.0) & (rev >= -self.overdrive)
            d = np.where(use_rev, np.copysign(np.abs(rev), -1.0), d)
            ok = np.where(use_rev, ok_rev, ok)
        return np.asarray(d), np.asarray(ok.all(axis=-1))


def budget_bounds_ns(overdrive: float, rise: FloatArray, brake: FloatArray
                     ) -> tuple[list[int], list[int]]:
    """The firmware's per-tactor bounds on the time above the rated drive and in reverse
    (``DriveParams::prepare`` in firmware/tactorbelt/src/core/drive.cpp), in ns: a kick from
    rest to the rated drive, ``rise_tau * ln(k / (k - 1))``, and a full reverse from full
    speed to rest, ``brake_tau * ln(2)``, each plus a tick, truncated to whole
    microseconds as the board does (0 above the rated drive when ``k`` is 1: nothing goes
    above it)."""
    k = float(overdrive)
    tick_us = RENDER_TICK_NS / 1000
    over = [int(r * math.log(k / (k - 1.0)) * 1e6 + tick_us) * 1000 if k > 1.0 else 0
            for r in np.asarray(rise, dtype=float).tolist()]
    rev = [int(b * math.log(2.0) * 1e6 + tick_us) * 1000
           for b in np.asarray(brake, dtype=float).tolist()]
    return over, rev


def spend(used: int, h_ns: int, driving: bool) -> int:
    """A bound's budget after ``h_ns`` (the firmware's ``budget``): the time used grows
    while the drive is what the bound limits, else shrinks, never below 0."""
    if driving:
        return used + h_ns
    return used - h_ns if used > h_ns else 0


def budget_cut(d: float, level: float, over_used: int, rev_used: int, over_bound: int,
               rev_bound: int) -> bool:
    """Whether the firmware's bounds turn the decision ``d`` into the level itself for the
    tick (controller.cpp, ``update_outputs``): a reverse drive whose budget has no tick
    left, or a forward drive above the rated one (1) and the level whose budget has none."""
    if is_reverse(d):
        return rev_used + RENDER_TICK_NS > rev_bound
    return d > level and is_over(d) and over_used + RENDER_TICK_NS > over_bound


def is_over(d: float) -> bool:
    """A forward drive above the rated one (what the firmware's over budget counts)."""
    return d > 1.0


def is_reverse(d: float) -> bool:
    """A reverse drive or the short brake (IN2 high: what the reverse budget counts)."""
    return math.copysign(1.0, d) < 0.0


def shape_tick(level: float, e: float, h_s: float, start: float, overdrive: float,
               brake: bool, rise: float, fall: float, brake_tau: float) -> tuple[float, float]:
    """The drive of :class:`Shaper` for one tactor, in plain floats (the sim belt's walk
    through the decisions), and its predicted speed ``h_s`` later (at most a tick):
    ``(drive, speed)``. The decision is for a whole render tick."""
    tick_s = RENDER_TICK_NS * 1e-9
    d = _shape_decision(level, e, start, overdrive, brake, math.exp(-tick_s / rise),
                        math.exp(-tick_s / fall), math.exp(-tick_s / brake_tau))
    return d, relax_f(d, e, h_s, start, rise, fall, brake_tau)


def relax_f(d: float, w: float, h: float, start: float, rise: float, fall: float,
            brake: float) -> float:
    """:func:`drive_relax` of one motor, in plain floats."""
    if math.copysign(1.0, d) < 0.0:
        u, tau = d, brake
    else:
        u = d if d >= start else 0.0
        tau = rise if u > w else fall
    return u + (w - u) * math.exp(-min(h / tau, _MAX_DECAY))


def shape_whole_tick(level: float, e: float, start: float, overdrive: float, brake: bool,
                     xr: float, xf: float, xb: float) -> tuple[float, float]:
    """:func:`shape_tick` for a whole render tick, with the tick's decay factors of the rise,
    fall and brake time constants given (``exp(-tick / tau)``, computed once per tactor):
    the same arithmetic, so the same floats, without the three ``exp`` of every call."""
    d = _shape_decision(level, e, start, overdrive, brake, xr, xf, xb)
    if math.copysign(1.0, d) < 0.0:
        return d, d + (e - d) * xb
    u = d if d >= start else 0.0
    return d, u + (e - u) * (xr if u > e else xf)


def _shape_decision(level: float, e: float, start: float, overdrive: float, brake: bool,
                    xr: float, xf: float, xb: float) -> float:
    """The drive of one tactor's decision for a render tick, from its speed ``e`` and the
    tick's decay factors of the rise, fall and brake time constants."""
    s = level if level >= start else 0.0
    gap = s - e
    if gap > _SETTLED:
        d = min((s - e * xr) / (1.0 - xr), overdrive)
    elif gap < -_SETTLED:
        fwd = (s - e * xf) / (1.0 - xf)
        if fwd >= start and s > 0.0:
            d = fwd
        elif brake:
            rev = (s - e * xb) / (1.0 - xb)
            d = math.copysign(min(-rev, overdrive), -1.0) if rev <= 0.0 else level
        else:
            d = 0.0 if fwd < 0.0 else level
    else:
        d = level
    return d


def saturated_run(level: float, e: float, start: float, overdrive: float, brake: bool,
                  xr: float, xf: float, xb: float) -> int:
    """How many whole render ticks from the predicted speed ``e`` the shaper's decision
    (:func:`_shape_decision`) stays at the saturated drive, the kick ``overdrive`` or the
    full reverse ``-overdrive``: the speed after ``j`` such ticks is ``d + (e - d) x**j``
    (``x`` the tick's decay factor of the rise or the brake time constant), so the run is
    found in closed form (a logarithm, checked against the decision itself) instead of
    tick by tick. 0 when this tick's decision is not saturated (it lands, or there is no
    gap)."""
    s = level if level >= start else 0.0
    gap = s - e
    if gap > _SETTLED:
        d, x = overdrive, xr
        thr = (s - overdrive * (1.0 - xr)) / xr  # the kick lands from above it

        def saturated(w: float) -> bool:
            return s - w > _SETTLED and (s - w * xr) / (1.0 - xr) >= overdrive
    elif gap < -_SETTLED and brake:
        d, x = -overdrive, xb
        thr = (s + overdrive * (1.0 - xb)) / xb  # a weaker reverse lands from below it
        if s > 0.0:  # a forward drive lands from below this one
            thr = max(thr, (s - start * (1.0 - xf)) / xf)

        def saturated(w: float) -> bool:
            if s - w >= -_SETTLED:
                return False
            if (s - w * xf) / (1.0 - xf) >= start and s > 0.0:
                return False
            rev = (s - w * xb) / (1.0 - xb)
            return rev <= 0.0 and -rev >= overdrive
    else:
        return 0
    if not saturated(e):
        return 0
    # the last tick j with a saturated decision: e_j = d + (e - d) x**j crosses thr
    ratio = (d - thr) / (d - e)
    j = max(math.floor(math.log(ratio) / math.log(x)), 0) if ratio > 0.0 else 0
    while j > 0 and not saturated(d + (e - d) * x**j):
        j -= 1
    while saturated(d + (e - d) * x ** (j + 1)):
        j += 1
    return j + 1
