"""The ``sim`` belt: N simulated ERM vibration motors, on the wall clock or a simulated one.

:class:`SimBelt` is a real :class:`~tactorbelt.devices.base.Belt`: the runner, the
player and the command line use it exactly as they use hardware. It

- records every command with its time on the belt's clock (``set_amplitudes`` frames,
  ``stop``, and ``play`` of a whole stimulus), in a compact log that keeps only a
  bounded horizon (``horizon_s``, default 120 s), so a 10,000-trial session does not
  grow memory without bound;
- renders a played stimulus itself, lazily, like the firmware: from the onset
  (``clock.now_ns()`` at the call) the commanded levels at time t are
  ``calibration(stimulus.amplitudes(k / 1000))`` with ``k`` the whole number of
  milliseconds since onset (a 1 kHz tick), until ``stop``, the end of the duration or
  the next command;
- models each motor with :mod:`tactorbelt.devices.erm` (:class:`ErmParams`: first-order
  speed response with a rise and a fall time constant, no spin below the start level,
  vibration amplitude growing with the square of the speed).

:meth:`SimBelt.commanded` and :meth:`SimBelt.vibration` sample the drive levels and the
modelled vibration over any interval; the model participant and the tests read them.

The physics and its exact solution are in :mod:`tactorbelt.devices.erm`; this module keeps
the commands and walks them piece by piece: a constant drive in closed form, a periodic
render from its response from rest (solved once per process, ``erm._Response``) by
superposition where the rise/fall pattern holds, otherwise the vectorised recurrence
(:func:`~tactorbelt.devices.erm.erm_speed`). No Python loop per sample (docs/belts.md).

Imports NumPy and tactorbelt (geometry, clock, stimuli types, devices.base); never an
I/O library.
"""

from __future__ import annotations

import bisect
import math
import threading
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Final

import numpy as np
from numpy.typing import NDArray

from .._errors import ConfigError
from ..clock import Clock, WallClock
from ..geometry import Layout
from .base import Belt
from .calibration import Calibration
from .erm import (
    _MAX_DECAY,
    _RESPONSE_MAX_TICKS,
    _SETTLED,
    _TIE,
    RENDER_TICK_NS,
    ErmParams,
    FloatArray,
    IntArray,
    Shaper,
    _decay_factors,
    _fall_factor_to,
    _grid_period,
    _relax,
    _relax_to,
    _Response,
    _sorted_unique,
    budget_bounds_ns,
    budget_cut,
    drive_relax,
    erm_speed,
    is_over,
    is_reverse,
    relax_f,
    relax_terms,
    sample_grid,
    saturated_run,
    shape_tick,
    shape_whole_tick,
    spend,
)

if TYPE_CHECKING:
    from ..stimuli import Stimulus

__all__ = ["DEFAULT_HORIZON_S", "RENDER_TICK_NS", "ErmParams", "SimBelt", "SimCommand",
           "erm_speed", "open_sim", "sample_grid"]

#: How much command history a sim belt keeps by default (seconds).
DEFAULT_HORIZON_S: Final = 120.0
#: History is pruned in steps of at least this much (or an eighth of the horizon), at a
#: checkpoint, so pruning replays nothing.
_PRUNE_SLACK_NS: Final = 1_000_000_000
#: Render ticks per second (1 kHz).
_TICKS_PER_S: Final = 1e9 / RENDER_TICK_NS
#: A checkpoint is taken at least every this many commands (cheap: ~0.3 ms each).
_CHECKPOINT_EVERY: Final = 256
#: Memory for the one-period tables of periodic renders kept per process (the oldest
#: go first; a dynamic stimulus's 1 s period on 6 tactors takes 48 KB).
_TABLES_BUDGET: Final = 8 * 2**20
#: Checkpoints of the motor state kept to start later simulations from.
_MAX_CHECKPOINTS: Final = 64
#: Memory for the responses from rest of periodic renders kept per process
#: (:class:`_Response`, the oldest go first; a dynamic stimulus on its 2
#: moving motors takes ~110 KB: 220 stimuli).
_RESPONSES_BUDGET: Final = 24 * 2**20

_OPTIONS: Final = ("layout", "clock", "calibration", "params", "horizon_s", "name", "drive",
                   "overdrive", "brake", "supply_v", "kick_ms", "shaper")
#: The sim belt's motor supply by default (V): the motors' maximum voltage, so the
#: shaper may overdrive them up to it (docs/hardware.md, "Power").
DEFAULT_SUPPLY_V: Final = 3.6
#: Shaped checkpoints kept (decision points of the shaper with the motor state).
_MAX_SHAPED_CHECKPOINTS: Final = 512
#: The dtypes of a shaped walk's decisions: times, drives, motor and predicted speeds, budgets.
_COLUMNS: Final = (np.int64, float, float, float, np.int64)

@dataclass(frozen=True)
class SimCommand:
    """One recorded command.

    Attributes:
        t_ns: when it was given (the belt's clock).
        levels: the drive levels from then on (calibrated), or None for a played stimulus.
        stimulus: the stimulus being rendered from ``t_ns`` (None for a levels command).
        end_ns: when the rendered stimulus ends (None: until the next command).
    """

    t_ns: int
    levels: FloatArray | None
    stimulus: Stimulus | None = None
    end_ns: int | None = None


class _Period:
    """One period of a periodic render: its levels tick by tick and the ticks where they
    change from the tick before (cyclically; none for a constant stimulus)."""

    __slots__ = ("changes", "const", "levels")

    @property
    def nbytes(self) -> int:
        return int(self.levels.nbytes + self.changes.nbytes)

    def __init__(self, levels: FloatArray) -> None:
        levels.setflags(write=False)
        self.levels = levels
        self.changes: IntArray = np.flatnonzero(
            np.any(levels != np.roll(levels, 1, axis=0), axis=1)).astype(np.int64)
        #: the levels of a period that never changes (a static stimulus), or None
        self.const: FloatArray | None = levels[0] if self.changes.size == 0 else None


#: One-period tables of periodic renders, by (stimulus, calibration), for every sim belt of
#: the process, oldest first; and the lock that guards changes to it and to
#: ``_RESPONSES``.
_PERIODS: dict[tuple[Stimulus, Calibration], _Period] = {}
_CACHE_LOCK = threading.Lock()


def _remember(cache: dict[Any, Any], key: Any, value: Any, budget: int) -> None:
    """Add ``value`` (with an ``nbytes``) and drop the oldest entries while the cache's
    memory exceeds ``budget`` (the newest stays)."""
    with _CACHE_LOCK:
        cache[key] = value
        total = sum(v.nbytes for v in cache.values())
        while total > budget and len(cache) > 1:
            total -= cache.pop(next(iter(cache))).nbytes


class _Render:
    """A stimulus the sim belt renders itself from ``onset_ns`` (1 kHz ticks).

    Levels are computed per tick; for a periodic stimulus whose period is a whole
    number of ticks (the usual case) one period is computed once and reused.
    """

    #: Periods up to this many ticks are tabulated.
    MAX_TABLE: Final = 20_000

    def __init__(self, stimulus: Stimulus, onset_ns: int, end_ns: int | None,
                 calibration: Calibration) -> None:
        self.stimulus = stimulus
        self.onset_ns = onset_ns
        self.end_ns = end_ns
        self.calibration = calibration
        self._table: _Period | None = None
        self._table_ticks = 0
        self._response: tuple[ErmParams, _Response] | None = None
        #: the shaped memo last found for this stimulus (shared by the renders of the same
        #: stimulus object, :meth:`share`): (motor params, shaper, tactors, memo), so a
        #: walk finds it without hashing the stimulus
        self.memo_box: list[tuple[ErmParams, Shaper, int, _ShapedMemo] | None] = [None]
        #: whether the shaper of the belt that plays it was at rest at the onset (every
        #: motor and predicted speed and budget zero): None until asked
        #: (:meth:`SimBelt._at_rest`)
        self.rest: bool | None = None
        if not stimulus.is_dynamic:
            self._table_ticks = 1
        else:
            per = stimulus.period_s * _TICKS_PER_S
            if abs(per - round(per)) < 1e-9 and 0 < round(per) <= self.MAX_TABLE:
                self._table_ticks = round(per)

    def _period(self) -> _Period:
        """One period's levels tick by tick (periodic renders only), shared by the renders
        of the same stimulus and calibration in the process (read-only)."""
        if self._table is None:
            key = (self.stimulus, self.calibration)
            period = _PERIODS.get(key)
            if period is None:
                k = np.arange(self._table_ticks)
                period = _Period(self.calibration.apply(
                    self.stimulus.amplitudes(k / _TICKS_PER_S)))
                _remember(_PERIODS, key, period, _TABLES_BUDGET)
            self._table = period
        return self._table

    def change_ticks(self, k0: int, k1: int, lead: int = 0) -> IntArray:
        """The ticks in [k0, k1) (counted from the onset) at which the levels may differ
        from the tick before: every tick, or for a periodic render only those where its
        period's table changes (none for a constant one). ``lead``: of the levels
        ``lead`` ticks ahead (:meth:`levels`)."""
        if lead:
            return np.asarray(self.change_ticks(k0 + lead, k1 + lead) - lead)
        if not self._table_ticks:
            return np.arange(k0, k1, dtype=np.int64)
        c, period = self._period().changes, self._table_ticks
        if c.size == 0 or k1 <= k0:
            return np.zeros(0, dtype=np.int64)
        p0, p1 = k0 // period, (k1 - 1) // period
        ks = (np.arange(p0, p1 + 1, dtype=np.int64)[:, None] * period + c[None, :]).ravel()
        return np.asarray(ks[(ks >= k0) & (ks < k1)])

    def share(self, other: _Render) -> None:
        """Take the period table and the response ``other`` (the same stimulus and
        calibration) has found or will find."""
        self._table = other._period() if self._table_ticks else None
        self._response = other._response
        self.memo_box = other.memo_box

    def constant(self) -> FloatArray | None:
        """The drive levels of a render that never changes (a static stimulus), or None."""
        if not self._table_ticks:
            return None
        return self._period().const

    def response(self, params: ErmParams) -> _Response | None:
        """The motors' response from rest to a periodic render (None: not periodic)."""
        if not self._table_ticks:
            return None
        if self._response is None or self._response[0] is not params:
            # the process-wide response of this stimulus (made on first use)
            key = (self.stimulus, self.calibration, params)
            resp = _RESPONSES.get(key)
            if resp is None:
                resp = _Response(self._period().levels, params)
                _remember(_RESPONSES, key, resp, _RESPONSES_BUDGET)
            self._response = (params, resp)
        return self._response[1]

    def end_ahead(self, lead: int) -> int | None:
        """The end of the render as a shaper with a preview of ``lead`` ticks sees it
        (``lead`` ticks early, not before the onset), or None."""
        if self.end_ns is None:
            return None
        return max(self.onset_ns, self.end_ns - lead * RENDER_TICK_NS)

    def levels(self, times: IntArray, lead: int = 0) -> FloatArray:
        """Drive levels at ``times`` (all at or after the onset); with a ``lead``, those
        ``lead`` ticks later (the shaper's preview: zero from :meth:`end_ahead`)."""
        ticks = (times - self.onset_ns) // RENDER_TICK_NS + lead
        if self._table_ticks:
            levels = self._period().levels[ticks % self._table_ticks]
        else:
            levels = self.calibration.apply(self.stimulus.amplitudes(ticks / _TICKS_PER_S))
        end = self.end_ahead(lead)
        if end is not None:
            levels[times >= end] = 0.0
        return np.asarray(levels)


_RESPONSES: dict[tuple[Stimulus, Calibration, ErmParams], _Response] = {}

#: A shaped render's decisions from rest are kept for its first this many ticks (3 s).
_MEMO_TICKS: Final = 3_072
#: The shaped renders' decisions kept in the process (:class:`_ShapedMemo`; the oldest
#: go first): a dynamic stimulus's take ~0.3 MB.
_SHAPED_MEMOS_BUDGET: Final = 24 * 2**20


class _ShapedMemo:
    """The shaper's decisions on a render started from rest (times from its onset, ns),
    the drives, the predicted speeds and the firmware's budgets (ns above the rated drive,
    then in reverse, per tactor); read-only. With the motor model ``params`` each
    decision's steady speed, time constant and gap (:func:`~tactorbelt.devices.erm.
    drive_relax`'s terms), so :meth:`speeds` relaxes only the decisions that move."""

    __slots__ = ("d", "e", "gap", "moving", "rest_after", "steady", "t", "tau", "u")

    def __init__(self, t: IntArray, d: FloatArray, e: FloatArray, u: IntArray,
                 params: ErmParams) -> None:
        self.t, self.d, self.e, self.u = t, d, e, u
        self.steady, self.tau = relax_terms(d, e, params)
        self.gap: FloatArray = e - self.steady
        #: the decisions under which some speed changes
        self.moving: NDArray[np.bool_] = np.asarray(self.gap.any(axis=1))
        for arr in (t, d, e, u, self.steady, self.tau, self.gap, self.moving):
            arr.setflags(write=False)
        #: per decision (index) settled on its levels: how long after a stop that finds
        #: it, its budgets spent, the shaper is at rest (ns; None: it does not come to
        #: rest exactly, or the decision is not settled). Filled as stops ask
        #: (:meth:`SimBelt._rest_after_row`).
        self.rest_after: dict[int, int | None] = {}

    @property
    def nbytes(self) -> int:
        return int(sum(a.nbytes for a in (self.t, self.d, self.e, self.u, self.steady,
                                          self.tau, self.gap, self.moving)))

    def speeds(self, times: IntArray) -> FloatArray:
        """The motors' speed magnitudes at ``times`` (from the onset, increasing, at or
        after it): :func:`~tactorbelt.devices.erm.drive_relax` of the decision in force,
        the same floats, relaxed only under the decisions that move (elsewhere the speed
        is the steady one)."""
        idx = self.t.searchsorted(times, side="right") - 1
        out = self.steady[idx]
        sel = np.flatnonzero(self.moving[idx])
        if sel.size:
            r = idx[sel]
            dt = np.asarray((times[sel] - self.t[r]) * 1e-9, dtype=np.float64)[:, None]
            out[sel] = self.steady[r] + self.gap[r] * np.exp(
                -np.minimum(dt / self.tau[r], _MAX_DECAY))
        return np.abs(out)


_SHAPED_MEMOS: dict[tuple[Any, ...], _ShapedMemo] = {}
#: A shaped walk's decisions: their times, drives, motor and predicted speeds, and budgets.
_Decisions = tuple[IntArray, FloatArray, FloatArray, FloatArray, IntArray]


class _OnsetGrid:
    """The terms of a render's speeds over a regular sample grid from its onset that do not
    depend on the state at the onset (:meth:`SimBelt._onset_piece`): the undriven motors'
    fall factor ``ff`` (n, 1) and, for the moving motors, the response from rest ``tw`` and
    its decay ``d`` (n, moving) at each sample's tick. ``ff`` alone where a sample falls
    between ticks or beyond the response (then the general path is taken)."""

    __slots__ = ("d", "ff", "tw")

    def __init__(self, resp: _Response, params: ErmParams, dt: IntArray) -> None:
        self.ff: FloatArray = _decay_factors(dt, params.fall_tau_s)  # (n, 1)
        self.tw: FloatArray | None = None
        self.d: FloatArray | None = None
        tick = dt // RENDER_TICK_NS
        k_stop = int(tick[-1])
        if k_stop < _RESPONSE_MAX_TICKS and bool((dt == tick * RENDER_TICK_NS).all()):
            self.tw = resp.w[tick]
            self.d = resp.decay(0, 0, k_stop + 1)[tick]

    @property
    def nbytes(self) -> int:
        return int(self.ff.nbytes + (0 if self.tw is None or self.d is None
                                     else self.tw.nbytes + self.d.nbytes))


#: Memoised grid terms (:class:`_OnsetGrid`, and a constant drive's decay factors by its
#: rise/fall choices) of the sampling windows that start at a render's onset, for every
#: sim belt of the process, oldest first: a model participant senses each stimulus over
#: the same window trial after trial. The paper study's 36 windows take ~1 MB.
_GRIDS: dict[tuple[Any, ...], Any] = {}
_GRIDS_BUDGET: Final = 2 * 2**20


def _grid_dt(n: int, grid: tuple[int, int]) -> IntArray:
    """The first ``n`` offsets of a :func:`sample_grid` from its start, ns."""
    return np.asarray((np.arange(n, dtype=np.int64) * grid[0]) // grid[1])


def _relax_grid(u: FloatArray, w: FloatArray, n: int, grid: tuple[int, int],
                params: ErmParams) -> FloatArray:
    """:func:`_relax` at the first ``n`` times of a regular grid from the stretch's start
    (the same arithmetic; the decay factors of each rise/fall choice memoised)."""
    tau = np.where(u > w, params.rise_tau_s, params.fall_tau_s)
    key = ("relax", params, n, grid, tau.tobytes())
    e = _GRIDS.get(key)
    if e is None:
        e = _decay_factors(_grid_dt(n, grid), tau)
        e.setflags(write=False)
        _remember(_GRIDS, key, e, _GRIDS_BUDGET)
    return np.asarray(u + (w - u) * e)


class SimBelt(Belt):
    """A simulated belt of N ERM motors (see the module docstring).

    Args:
        layout: tactor angles (default: 6 evenly spaced tactors).
        clock: the clock commands are timed by (default: a new WallClock).
        calibration: the drive mapping (default: identity).
        params: the motor model constants (default: :class:`ErmParams`()).
        horizon_s: how much command history to keep (default 120 s); older history
            is summarised by the motor state at the cut, and queries before the cut
            raise ConfigError.
        url, name: recorded on the belt.
        drive: ``plain`` (the default of the class: the motor model as it is driven) or
            ``shaped`` (:class:`~tactorbelt.devices.erm.Shaper`); a belt opened by URL
            (:func:`open_sim`) is shaped unless ``drive=plain``.
        shaper: the shaping (default: the motor's own model, or the time constants the
            calibration holds (``validate onsets --tune``), overdrive up to ``overdrive``,
            braking when ``brake``).
        brake: both H-bridge inputs are wired (reverse drive and short brake).
        overdrive: the shaper's largest drive, times the rated (default: the motor's
            maximum voltage, or ``supply_v`` when lower, over its rated voltage; with
            ``kick_ms``, the supply over the rated voltage).
        supply_v: the motor supply (V).
        kick_ms: a kick may apply the whole supply, above the motor's maximum voltage, if
            it lasts at most this long (ms; 0, the default: never;
            :meth:`~tactorbelt.devices.erm.ErmParams.kick_overdrive`).
    """

    def __init__(
        self,
        layout: Layout | None = None,
        clock: Clock | None = None,
        calibration: Calibration | None = None,
        params: ErmParams | None = None,
        horizon_s: float = DEFAULT_HORIZON_S,
        url: str = "sim",
        name: str | None = None,
        drive: str = "plain",
        shaper: Shaper | None = None,
        brake: bool = True,
        overdrive: float | None = None,
        supply_v: float = DEFAULT_SUPPLY_V,
        kick_ms: float = 0.0,
    ) -> None:
        layout = layout if layout is not None else Layout.even(6)
        if not isinstance(layout, Layout):
            raise ConfigError(f"layout must be a Layout, got {type(layout).__name__}")
        if clock is not None and not isinstance(clock, Clock):
            raise ConfigError(f"clock must be a Clock (now_ns, sleep_until_ns), got {clock!r}")
        if params is not None and not isinstance(params, ErmParams):
            raise ConfigError(f"params must be an ErmParams, got {type(params).__name__}")
        if calibration is not None and not isinstance(calibration, Calibration):
            raise ConfigError(
                f"calibration must be a Calibration, got {type(calibration).__name__}")
        try:
            horizon = float(horizon_s)
        except (TypeError, ValueError):
            horizon = float("nan")
        if not (math.isfinite(horizon) and horizon > 0):
            raise ConfigError(f"horizon_s must be a positive number of seconds, got {horizon_s!r}")
        super().__init__(url, name or "simulated ERM belt", layout,
                         None, calibration)
        self.clock: Clock = clock if clock is not None else WallClock()
        self.params: ErmParams = params if params is not None else ErmParams()
        self._horizon_ns = round(horizon * 1e9)
        self._slack_ns = max(_PRUNE_SLACK_NS, self._horizon_ns // 8)
        n = layout.n
        cap = 256
        self._t: IntArray = np.zeros(cap, dtype=np.int64)
        self._lv: FloatArray = np.zeros((cap, n))
        self._rid: IntArray = np.full(cap, -1, dtype=np.int64)
        self._lo = 0
        self._hi = 0
        self._renders: dict[int, _Render] = {}
        #: a kept render of each stimulus object played (by id; the render keeps the
        #: object alive, and leaves with it when the history is pruned)
        self._played: dict[int, _Render] = {}
        self._next_rid = 0
        self._base_t = int(self.clock.now_ns())
        self._base_w = np.zeros(n)
        self._zeros = np.zeros(n)  # no drive (read-only)
        self._zeros.setflags(write=False)
        self._pruned = False
        self._ck_t: list[int] = []
        self._ck_w: list[FloatArray] = []
        self._ck_spacing_ns = max(1, self._horizon_ns // 32)
        self._since_ck = 0
        if shaper is not None and not isinstance(shaper, Shaper):
            raise ConfigError(f"shaper must be a Shaper, got {type(shaper).__name__}")
        self._brake = bool(brake)
        if shaper is None:
            taus = self.calibration.shaping_taus()  # fitted by validate onsets --tune
            od = (self.params.kick_overdrive(supply_v, kick_ms, taus[0] if taus else None)
                  if overdrive is None else overdrive)
            shaper = Shaper(self.params, od, self._brake, *(taus or ()))
        self.shaper: Shaper = shaper
        if self.shaper.brake and not self._brake:
            raise ConfigError("the shaper brakes but the belt cannot (brake=0)")
        self._taus = self.shaper.taus(n)
        p = self.params
        #: the shaper predicts with the motors' own model (its time constants and start
        #: level, every tactor): the motors are its prediction
        self._exact = all(bool((tau == v).all()) for tau, v in zip(
            self._taus, (p.rise_tau_s, p.fall_tau_s, p.brake_tau_s), strict=True)
        ) and self.shaper.params.start_level == p.start_level
        #: the shaper's decision points kept: time, motor speeds, predicted speeds, and
        #: the firmware's budgets there (ns above the rated drive, then in reverse, per
        #: tactor: :func:`~tactorbelt.devices.erm.spend`)
        self._sck: list[tuple[int, FloatArray, FloatArray, IntArray]] = []
        self._base_e = np.zeros(n)
        self._base_u = np.zeros(2 * n, dtype=np.int64)
        #: the firmware's bounds on those budgets, per tactor (ns)
        self._over_bound, self._rev_bound = budget_bounds_ns(
            self.shaper.overdrive, self._taus[0], self._taus[2])
        self.set_drive(drive)

    # -- Belt backend -----------------------------------------------------------------
    def _device_renders(self, stimulus: Stimulus | None) -> bool:
        return True  # the sim belt renders every stimulus made for its layout

    @property
    def models_vibration(self) -> bool:
        return True

    @property
    def can_shape(self) -> bool:
        return True

    @property
    def can_brake(self) -> bool:
        return self._brake

    def _set_drive(self, drive: str) -> None:
        # the history so far was played with the old drive: its state now starts the new
        # one, and times before now are no longer asked for
        now = int(self.clock.now_ns())
        if self._hi > self._lo:  # never commanded: at rest either way, nothing to keep
            t, w, e, u = self._state_before(now)
            self._lo = max(self._row_in_force(t), self._lo)
            self._base_t, self._pruned = t, True
            self._base_w, self._base_e, self._base_u = w, e, u
        if drive == "plain":  # the plain solution's states are forward speeds up to 1
            self._base_w = np.clip(self._base_w, 0.0, 1.0)
        self._ck_t.clear()
        self._ck_w.clear()
        self._sck.clear()
        for render in self._renders.values():  # found under the drive before
            render.rest = None

    def _state_before(self, t_ns: int) -> tuple[int, FloatArray, FloatArray, IntArray]:
        """A time at or before ``t_ns`` the drive may restart from, with the motors' and
        the shaper's predicted speeds and its budgets there: ``t_ns`` itself when plain
        (no budget used: plain never drives above the rated level nor reverses), the
        shaper's last decision before it when shaped (so the drive after it stays as
        played)."""
        if self._drive != "shaped":
            w = self._speed_at(np.array([t_ns], dtype=np.int64))[0]
            return t_ns, w, w.copy(), np.zeros(2 * self.n_tactors, dtype=np.int64)
        ts, _, ws, es, us = self._shaped_solve(t_ns, t_ns, t_ns)
        return int(ts[-1]), ws[-1], es[-1], us[-1]

    # -- shaped drive -------------------------------------------------------------------
    def _shaped_start(self, t_first: int
                      ) -> tuple[int, FloatArray, FloatArray, IntArray]:
        """The latest kept decision of the shaper at or before ``t_first`` (time, motor
        and predicted speeds, budgets), else the base state."""
        if self._pruned and t_first < self._base_t:
            raise ConfigError(
                f"time {t_first} ns is before the kept history (from {self._base_t} ns; "
                f"the sim belt keeps {self._horizon_ns / 1e9:g} s, see horizon_s)")
        if t_first < self._base_t:
            return (t_first, np.zeros(self.n_tactors), np.zeros(self.n_tactors),
                    np.zeros(2 * self.n_tactors, dtype=np.int64))
        j = bisect.bisect_right([c[0] for c in self._sck], t_first) - 1
        if j >= 0:
            return self._sck[j]
        return self._base_t, self._base_w, self._base_e, self._base_u

    def _shaped_solve(self, t_first: int, t_last: int, keep_until: int | None = None,
                      also_keep: int | None = None) -> _Decisions:
        """The shaper's decisions from its latest kept decision at or before ``t_first``
        (:meth:`_shaped_start`) to ``t_last``: their times, drives, the motor and
        predicted speeds and the budgets at each. It decides at every command and render
        change, and a tick (1 ms, the firmware's renderer) after each decision while its
        prediction has not settled on the level; settled, it drives the level until the
        levels change. The last decision at or before ``keep_until`` (default: now, or
        ``t_last`` when earlier: no later command changes it) is kept to start later
        solutions from, and the last at or before ``also_keep`` (the first time a query
        asked for: the next query of the same window starts there).

        Where the shaper predicts with the motor's own model (``self._exact``), the motors
        are its prediction, and a run of changes each landed within its tick from the
        last target (a dynamic stimulus's transit) is solved at once
        (:meth:`~tactorbelt.devices.erm.Shaper.landing`). A render's levels are those
        the shaper's preview sees (``Shaper.lead_ticks`` ahead)."""
        t_a, w, e, u = self._shaped_start(t_first)
        if keep_until is None:
            keep_until = min(int(self.clock.now_ns()), t_last)
        keep_until = max(keep_until, t_a)
        parts: list[_Decisions] = []
        t_a, w, e, u, onsets = self._memo_prefix(t_a, w, e, u, t_last, parts)
        # then the walk from there over the changes to t_last
        lead = self.shaper.lead_ticks
        bounds = _sorted_unique(np.concatenate([np.array([t_a], dtype=np.int64),
                                                self._breakpoints(t_a, t_last, lead)]))
        parts.append(self._walk(bounds, self._levels_at(bounds, lead), t_last, w, e, u, onsets))
        t_arr, d_arr, w_arr, e_arr, u_arr = parts[0] if len(parts) == 1 else (
            np.concatenate(q) for q in zip(*parts, strict=True))
        also = keep_until if also_keep is None else min(also_keep, keep_until)
        for t_keep in {keep_until, also}:
            j = int(t_arr.searchsorted(t_keep, side="right")) - 1
            if j > 0:
                self._keep_decision(int(t_arr[j]), w_arr[j], e_arr[j], u_arr[j])
        return t_arr, d_arr, w_arr, e_arr, u_arr

    def _memo_prefix(self, t_a: int, w: FloatArray, e: FloatArray, u: IntArray, t_last: int,
                     parts: list[_Decisions],
                     ) -> tuple[int, FloatArray, FloatArray, IntArray,
                                dict[int, tuple[_Render, int]]]:
        """Where a walk starts on a render's memo (its onset at rest, or one of its
        decisions), the memo's decisions up to its cut, as the walk takes them at its first
        bound (appended to ``parts``); the start, speeds and render onsets to walk on from."""
        onsets = self._onsets(t_a, t_last)
        got = onsets.get(t_a)
        take = (self._memo_take(got, t_a, e.tolist(), u.tolist()) if got is not None
                else None)
        if take is None:
            return t_a, w, e, u, onsets
        block, t_a, e, u = take
        parts.append(block)
        return t_a, e, e, u, self._onsets(t_a, t_last)

    def _memo_take(self, got: tuple[_Render, int], t: int, e: list[float], u: list[int]
                   ) -> tuple[_Decisions, int, FloatArray, IntArray] | None:
        """The memo decisions a walk at ``t`` (predicted speeds ``e``) on the render of
        ``got`` (render, cut: :meth:`_onsets`) splices (the motors' speeds are the predicted
        ones), then the walk's next start (the memo's last decision before the cut) with
        its predicted speeds and budgets; None when the walk splices none there (no memo,
        other speeds or budgets ``u``, nothing before the cut)."""
        render, cut = got
        memo = self._memo_at(render, t, e, u)
        if memo is None:
            return None
        onset = render.onset_ns
        r0 = int(memo.t.searchsorted(t - onset))
        lim = min(cut, onset + _MEMO_TICKS * RENDER_TICK_NS)
        r = int(memo.t.searchsorted(lim - onset, side="left")) - 1
        if r <= r0:
            return None
        return ((memo.t[r0:r] + onset, memo.d[r0:r], memo.e[r0:r], memo.e[r0:r], memo.u[r0:r]),
                onset + int(memo.t[r]), memo.e[r], memo.u[r])

    def _onsets(self, t_a: int, t_last: int) -> dict[int, tuple[_Render, int]]:
        """The renders that start in (t_a, t_last]: onset -> (render, the first time after
        it at which something else commands the drive: the next command, the render's
        end, or past ``t_last``). Only where the shaper predicts with the motors' model."""
        out: dict[int, tuple[_Render, int]] = {}
        if not self._exact or self._hi == self._lo:
            return out
        first = max(self._row_in_force(t_a), self._lo)
        last = self._row_in_force(t_last)
        for row in range(first, last + 1):
            rid = int(self._rid[row])
            t_row = int(self._t[row])
            if rid < 0 or t_row > t_last:
                continue
            render = self._renders[rid]
            if render.onset_ns != t_row:
                continue
            cut = int(self._t[row + 1]) if row + 1 < self._hi else t_last + 1
            end = render.end_ahead(self.shaper.lead_ticks)
            if end is not None:
                cut = min(cut, end)
            if t_row >= t_a or t_a < cut:  # at its onset, or the walk starts inside it
                out[max(t_row, t_a)] = (render, min(cut, t_last + 1))
        return out

    def _memo_at(self, render: _Render, t: int, e: list[float], u: list[int]
                 ) -> _ShapedMemo | None:
        """The render's :meth:`_render_memo` when the walk at ``t`` is on it: a decision of
        the memo at ``t`` with the predicted speeds ``e`` and the budgets ``u`` (at the
        onset: every motor at rest with no budget used, the memo made if need be; later:
        only a memo already made)."""
        got = render.memo_box[0]
        if got is not None and got[0] is self.params and got[1] is self.shaper \
                and got[2] == self.n_tactors:
            memo = got[3]
        else:
            key = (render.stimulus, render.calibration, self.params, self.shaper,
                   self.n_tactors)
            found = _SHAPED_MEMOS.get(key)
            if found is None:
                if t != render.onset_ns or any(e) or any(u):
                    return None
                found = self._render_memo(render)
                _remember(_SHAPED_MEMOS, key, found, _SHAPED_MEMOS_BUDGET)
            memo = found
            render.memo_box[0] = (self.params, self.shaper, self.n_tactors, memo)
        r = int(memo.t.searchsorted(t - render.onset_ns))
        if r >= memo.t.shape[0] or int(memo.t[r]) != t - render.onset_ns:
            return None
        return memo if memo.e[r].tolist() == e and memo.u[r].tolist() == u else None

    def _render_memo(self, render: _Render) -> _ShapedMemo:
        """The shaper's decisions on a render started with every motor at rest, for its
        first :data:`_MEMO_TICKS` ticks: the same walk (:meth:`_walk`) on the render's own
        change ticks, shared by the sim belts of the process with the same stimulus,
        calibration, motor model and shaping (read-only; :meth:`_memo_at` keeps it)."""
        onset = render.onset_ns
        bounds = _sorted_unique(np.concatenate([
            np.array([onset], dtype=np.int64),
            onset + render.change_ticks(1, _MEMO_TICKS, self.shaper.lead_ticks)
            * RENDER_TICK_NS]))
        end, render.end_ns = render.end_ns, None
        try:
            levels = render.levels(bounds, self.shaper.lead_ticks)
        finally:
            render.end_ns = end
        zeros = np.zeros(self.n_tactors)
        t, d, _, e, u = self._walk(bounds, levels, onset + _MEMO_TICKS * RENDER_TICK_NS - 1,
                                   zeros, zeros, np.zeros(2 * self.n_tactors, dtype=np.int64),
                                   {})
        return _ShapedMemo(t - onset, d, e, u, self.params)

    def _walk(self, bounds: IntArray, levels: FloatArray, t_last: int, w: FloatArray,
              e: FloatArray, u: IntArray, onsets: dict[int, tuple[_Render, int]],
              ) -> _Decisions:
        """The walk of :meth:`_shaped_solve` over ``bounds`` (the first is a decision point
        with motor speeds ``w``, predicted ``e`` and budgets ``u``; ``levels`` the
        commanded levels from each) to ``t_last``. A render in ``onsets`` that starts with
        every motor at rest takes the decisions of :meth:`_render_memo` up to its last
        change before anything else commands the drive: the same walk on the same changes,
        so the same floats. ``t_last + 1`` is only where the caller stops asking: a run of
        kick or reverse ticks goes on past it.

        The firmware's bounds hold as on the board (controller.cpp): per tactor, the time
        the drive spends above the rated level, and in reverse, is counted up while it
        does and down while it does not (:func:`~tactorbelt.devices.erm.spend`); a
        decision that would pass a bound is the level itself for its tick
        (:func:`~tactorbelt.devices.erm.budget_cut`). So a kick that chases a rising
        render lasts at most what a kick to full level from rest does."""
        p, sh, taus = self.params, self.shaper, self._taus
        rise, fall, brake = taus
        rl, fl, bl = rise.tolist(), fall.tolist(), brake.tolist()
        tick_s = RENDER_TICK_NS * 1e-9
        xr, xf, xb = ([math.exp(-min(tick_s / x, 300.0)) for x in taus_k]
                      for taus_k in (rl, fl, bl))
        start, od, can_brake = sh.params.start_level, sh.overdrive, sh.brake
        n = self.n_tactors
        ob, rb = self._over_bound, self._rev_bound
        tick = RENDER_TICK_NS
        m = bounds.shape[0]
        ends = np.empty(m, dtype=np.int64)
        ends[:-1] = bounds[1:]
        ends[-1] = t_last + 1
        s_all = np.where(levels >= p.start_level, levels, 0.0)
        bad: IntArray = np.zeros(0, dtype=np.int64)
        lands: list[bool] = []
        d_on: FloatArray | None = None
        if self._exact and m > 2:
            d_on, ok = sh.landing(levels[1:], s_all[:-1], tick * 1e-9, taus)
            ok &= (ends[1:] - bounds[1:]) >= tick  # a landing needs its whole tick
            bad = np.flatnonzero(~ok) + 1  # the bounds where landing fails
            lands = [False, *ok.tolist()]
        # the decisions in arrays (times, drives, motor and predicted speeds, budgets), and
        # those of the decisions taken one by one since, in lists
        blocks: tuple[list[Any], ...] = ([], [], [], [], [])
        rows: tuple[list[Any], ...] = ([], [], [], [], [])
        ts, ds, ws, es, us = rows

        def flush(*arrays: Any) -> None:
            # the rows so far as arrays, then ``arrays`` (a block of each) after them
            if ts:
                for block, row, dtype, width in zip(blocks, rows, _COLUMNS, (1, n, n, n, 2 * n),
                                                    strict=True):
                    block.append(np.asarray(row, dtype=dtype).reshape(-1, width)
                                 if width > 1 else np.asarray(row, dtype=dtype))
                    row.clear()
            for block, a in zip(blocks, arrays, strict=False):
                block.append(a)

        def spend_all(d: list[float], h: int) -> None:
            # the budgets after the drives d held h ns (a budget at 0 stays at 0 unless
            # its drive counts)
            for k in range(n):
                dk = d[k]
                if ou[k] or dk > 1.0:
                    ou[k] = spend(ou[k], h, is_over(dk))
                if ru[k] or (dk <= 0.0 and is_reverse(dk)):
                    ru[k] = spend(ru[k], h, is_reverse(dk))

        exact = self._exact
        pr, pf, pb = p.rise_tau_s, p.fall_tau_s, p.brake_tau_s
        # rows as lists only where the walk visits them (a memo skips most of a render)
        bounds_l = bounds.tolist()
        ends_l = ends.tolist()
        el: list[float] = e.tolist()
        wl: list[float] = el if exact else w.tolist()
        ul = [int(x) for x in u.tolist()]
        ou, ru = ul[:n], ul[n:]
        i = 0
        t_resume: int | None = None  # a decision inside stretch i to go on from
        no_land = -1  # a bound whose landing a budget cut: decided one by one
        while i < m:
            got = onsets.get(bounds_l[i]) if onsets and t_resume is None else None
            take = self._memo_take(got, bounds_l[i], el, ou + ru) if got is not None else None
            if take is not None:
                # the memo's decisions before the cut are the walk's; it goes on from the
                # last of them
                block, t_resume, e_next, u_next = take
                flush(*block)
                el = wl = e_next.tolist()
                ul = u_next.tolist()
                ou, ru = ul[:n], ul[n:]
                i = int(bounds.searchsorted(t_resume, side="right")) - 1
                continue
            if t_resume is None and d_on is not None and i > 0 and i != no_land and lands[
                    i] and max(abs(x - y) for x, y in zip(el, s_all[i - 1].tolist(),
                                                          strict=True)) <= _SETTLED:
                k = int(bad[bad.searchsorted(i)]) if bad.size and bad[-1] >= i else m
                if k > i:  # bounds i..k-1 each land on their target within a tick
                    prev = s_all[i - 1 : k - 1]
                    longer = (ends[i:k] - bounds[i:k]) > tick  # then settled after a tick
                    n_more = int(longer.sum())
                    tt = np.concatenate([bounds[i:k], bounds[i:k][longer] + tick])
                    dd = np.concatenate([d_on[i - 1 : k - 1], levels[i:k][longer]])
                    ww = np.concatenate([prev, s_all[i:k][longer]])
                    order = np.argsort(tt, kind="stable") if n_more else None
                    if order is not None:
                        tt, dd, ww = tt[order], dd[order], ww[order]
                    uu, cut_at = self._landing_budgets(tt, dd, levels, bounds, i, k,
                                                       int(ends_l[k - 1]), ou + ru)
                    if cut_at is not None:  # a bound passed: decided one by one from there
                        no_land = cut_at
                        if cut_at == i:
                            continue
                        keep = int(tt.searchsorted(bounds_l[cut_at]))
                        tt, dd, ww, uu = tt[:keep], dd[:keep], ww[:keep], uu[:keep + 1]
                        k = cut_at
                    flush(tt, dd, ww, ww, uu[:-1])
                    ul = uu[-1].tolist()
                    ou, ru = ul[:n], ul[n:]
                    el = wl = s_all[k - 1].tolist()
                    i = k
                    continue
            t = bounds_l[i] if t_resume is None else t_resume
            t_resume = None
            b1 = ends_l[i]
            lvl = levels[i].tolist()
            sl = s_all[i].tolist()
            while t < b1:
                ts.append(t)
                ws.append(wl)
                es.append(el)
                us.append(ou + ru)
                moving = [k for k in range(n) if abs(sl[k] - el[k]) > _SETTLED]
                if all(not can_brake and sl[k] == 0.0 and el[k] >= 0.0 for k in moving):
                    # settled (or coasting to off, unbraked): the level to the stretch's end
                    ds.append(lvl)
                    h = (b1 - t) * 1e-9
                    el = [relax_f(lvl[k], el[k], h, start, rl[k], fl[k], bl[k])
                          if k in moving else el[k] for k in range(n)]
                    wl = el if exact else [relax_f(lvl[k], wl[k], h, start, pr, pf, pb)
                                           for k in range(n)]
                    spend_all(lvl, b1 - t)
                    break
                # a run of whole ticks at the kick or the full reverse (every moving
                # tactor saturated): one decision, its end in closed form. The last
                # stretch ends where the query does, not where the levels change: a run
                # there is not cut (its decision is the same whatever the query's end).
                # The budgets end a run where the board would cut its drive.
                last = i == m - 1
                if b1 - t >= 2 * tick or last:
                    run = (b1 - t) // tick if not last else _MEMO_TICKS
                    for k in moving:
                        run = min(run, saturated_run(lvl[k], el[k], start, od, can_brake,
                                                     xr[k], xf[k], xb[k]))
                        if run < 2:
                            break
                        up = sl[k] > el[k]
                        if not up or od > 1.0:  # the ticks the budget leaves
                            used, bound = (ou[k], ob[k]) if up else (ru[k], rb[k])
                            run = min(run, max((bound - tick - used) // tick + 1, 0))
                            if run < 2:
                                break
                    if run >= 2:
                        d = list(lvl)
                        el = list(el)
                        for k in moving:
                            up = sl[k] > el[k]
                            d[k] = od if up else -od
                            el[k] = d[k] + (el[k] - d[k]) * (xr[k] if up else xb[k]) ** run
                        ds.append(d)
                        h = run * tick * 1e-9
                        wl = el if exact else [relax_f(d[k], wl[k], h, start, pr, pf, pb)
                                               for k in range(n)]
                        spend_all(d, run * tick)
                        t += run * tick
                        continue
                # the decision holds a tick; each moving tactor in plain floats
                nxt = min(t + tick, b1)
                h = (nxt - t) * 1e-9
                d = list(lvl)
                el = list(el)
                if nxt - t == tick:  # a whole tick: the decay factors computed once
                    for k in moving:
                        d[k], el[k] = shape_whole_tick(lvl[k], el[k], start, od, can_brake,
                                                       xr[k], xf[k], xb[k])
                else:
                    for k in moving:
                        d[k], el[k] = shape_tick(lvl[k], el[k], h, start, od, can_brake,
                                                 rl[k], fl[k], bl[k])
                for k in moving:
                    if budget_cut(d[k], lvl[k], ou[k], ru[k], ob[k], rb[k]):
                        d[k] = lvl[k]
                        el[k] = relax_f(lvl[k], es[-1][k], h, start, rl[k], fl[k], bl[k])
                ds.append(d)
                wl = el if exact else [relax_f(d[k], wl[k], h, start, pr, pf, pb)
                                       for k in range(n)]
                spend_all(d, nxt - t)
                t = nxt
            i += 1
        flush()
        t_out, d_out, w_out, e_out, u_out = (np.concatenate(b) for b in blocks)
        return t_out, d_out, w_out, e_out, u_out

    def _landing_budgets(self, tt: IntArray, dd: FloatArray, levels: FloatArray,
                         bounds: IntArray, i: int, k: int, end: int, u0: list[int]
                         ) -> tuple[IntArray, int | None]:
        """The budgets before each decision of a run of landings (times ``tt``, drives
        ``dd``, the run's bounds ``i..k-1``, ending at ``end``) and after the last, from
        ``u0``; and the first bound whose landing a budget cuts (None: none does). The
        firmware's counter in closed form: with ``S`` the running sum of +h (the drive
        counts) and -h (it does not) from ``u0``, the budget is ``S - min(0, min S)``."""
        n = self.n_tactors
        h = np.diff(np.append(tt, end))[:, None]
        over = dd > 1.0
        rev = np.signbit(dd)
        u0a = np.asarray(u0, dtype=np.int64)
        out = np.empty((tt.shape[0] + 1, 2 * n), dtype=np.int64)
        out[0] = u0a
        for half, flag in ((slice(0, n), over), (slice(n, 2 * n), rev)):
            x = np.where(flag, h, -h)
            s = u0a[half][None, :] + np.cumsum(x, axis=0)
            out[1:, half] = s - np.minimum(np.minimum.accumulate(s, axis=0), 0)
        before = out[:-1]
        lv = levels[np.searchsorted(bounds, tt, side="right") - 1]
        cut = (rev & (before[:, n:] + RENDER_TICK_NS > np.asarray(self._rev_bound))) | (
            over & (dd > lv) & (before[:, :n] + RENDER_TICK_NS > np.asarray(self._over_bound)))
        rows = np.flatnonzero(cut.any(axis=1))
        if rows.size == 0:
            return out, None
        j = int(np.searchsorted(bounds, tt[rows[0]], side="right")) - 1
        return out, max(j, i)

    def _keep_decision(self, t: int, w: FloatArray, e: FloatArray, u: IntArray) -> None:
        """Keep a decision of the shaper (in time order; the oldest go beyond
        :data:`_MAX_SHAPED_CHECKPOINTS`): a later query starts from the latest one at or
        before its first time."""
        ck = self._sck
        times = [c[0] for c in ck]
        i = bisect.bisect_left(times, t)
        if i < len(ck) and times[i] == t:
            return
        ck.insert(i, (t, w, e, u))
        if len(ck) > _MAX_SHAPED_CHECKPOINTS:
            del ck[0]

    def _speed_shaped(self, times: IntArray) -> FloatArray:
        """:meth:`_speed_at` of the shaped drive: the motors' speed magnitude (a motor
        reverse-driven past a stop spins backwards and vibrates again)."""
        from_rest = self._from_rest(int(times[0]), int(times[-1]))
        self._since_ck = 0  # a decision up to now is kept
        if from_rest is not None:
            onset, memo = from_rest
            return memo.speeds(times - onset)
        ts, ds, ws, _, _ = self._shaped_solve(int(times[0]), int(times[-1]),
                                              also_keep=int(times[0]))
        idx = ts.searchsorted(times, side="right") - 1
        dt = np.asarray((times - ts[idx]) * 1e-9, dtype=np.float64)
        w = drive_relax(ds[idx], ws[idx], dt, self.params)
        return np.asarray(np.abs(w))

    def _from_rest(self, t0: int, t1: int) -> tuple[int, _ShapedMemo] | None:
        """The onset and the memo (:meth:`_render_memo`) of the render a query over
        [t0, t1] reads inside, when the shaper was at rest at its onset
        (:meth:`_at_rest`), the motors are its prediction (``self._exact``) and the query
        ends before anything else commands the drive, within the memo: the walk splices
        that memo there, so its decisions are the query's, without walking. None
        otherwise (the walk answers)."""
        if not self._exact or self._hi == self._lo:
            return None
        j = self._row_in_force(t0)
        rid = int(self._rid[j]) if j >= self._lo else -1
        if rid < 0:
            return None
        render = self._renders[rid]
        onset = render.onset_ns
        limit = onset + (_MEMO_TICKS - 1) * RENDER_TICK_NS
        end = render.end_ahead(self.shaper.lead_ticks)
        for c in (int(self._t[j + 1]) if j + 1 < self._hi else None, end):
            if c is not None:
                limit = min(limit, c)
        if onset != int(self._t[j]) or onset < self._base_t or t1 >= limit \
                or not self._at_rest(j):
            return None
        memo = self._memo_at(render, onset, [0.0] * self.n_tactors,
                             [0] * (2 * self.n_tactors))
        return None if memo is None else (onset, memo)

    def _rest_after_row(self, render: _Render, memo: _ShapedMemo, r: int) -> int | None:
        """How long after a stop the shaper is at rest (every predicted speed and budget
        zero), when the stop comes while the render's memo decision ``r`` holds, settled
        on its levels (none above the rated drive), and its budgets are spent: the walk
        from that decision over such a stop (ns; None when the decision is not settled,
        or the walk does not come to rest exactly within 2 s). A later onset then finds
        the shaper at rest, whenever the stop: the walk's decisions up to the rest are
        the same, and after it the speeds stay zero and the budgets spent."""
        tick, n, lead = RENDER_TICK_NS, self.n_tactors, self.shaper.lead_ticks
        t_r = render.onset_ns + int(memo.t[r])
        e_r, u_r = memo.e[r], memo.u[r]
        lv = render.levels(np.array([t_r], dtype=np.int64), lead)[0]
        s = np.where(lv >= self.shaper.params.start_level, lv, 0.0)
        if np.signbit(lv).any() or lv.max() > 1.0 or np.abs(s - e_r).max() > _SETTLED:
            return None
        stop = t_r + max(int(u_r.max()), tick)
        far = stop + 2_000_000_000
        ts, ds, _, es, us = self._walk(
            np.array([t_r, stop, far], dtype=np.int64), np.stack([lv, np.zeros(n),
                                                                  np.zeros(n)]),
            far, e_r, e_r, u_r, {})
        keep = (ts >= stop) & (ts < far)
        ts, ds, es, us = ts[keep], ds[keep], es[keep], us[keep]
        coasting = (es == 0.0).all(axis=1) & (ds == 0.0).all(axis=1) & ~np.signbit(ds).any(
            axis=1)
        if not coasting.size or not coasting[-1]:
            return None
        q = coasting.size - int(np.argmin(coasting[::-1])) if not coasting.all() else 0
        rest = int(ts[q]) + int(us[q].max())
        return rest - stop if rest < far else None

    def _at_rest(self, j: int) -> bool:
        """Whether every motor, predicted speed and budget of the shaper is zero at the
        onset of the render that row ``j`` starts (kept on the render; a decision at rest
        there is kept for later walks). Shown from the render before when the row before
        stops it (:meth:`_rest_after_stop`; back along such renders to one already
        known), else by the walk to the onset."""
        chain = [j]
        while self._renders[int(self._rid[chain[-1]])].rest is None:
            k = chain[-1] - 2  # the render the row before stops
            if k < self._lo or self._rid[k] < 0 or self._rid[k + 1] >= 0:
                break
            chain.append(k)
        n = self.n_tactors
        for k in reversed(chain):
            render = self._renders[int(self._rid[k])]
            if render.rest is not None:
                continue
            onset = render.onset_ns
            rest = self._rest_after_stop(k)
            if rest is None:
                t, w, e, u = self._state_before(onset)
                rest = t == onset and not (w.any() or e.any() or u.any())
            elif rest:
                self._keep_decision(onset, np.zeros(n), np.zeros(n),
                                    np.zeros(2 * n, dtype=np.int64))
            render.rest = rest
        return bool(self._renders[int(self._rid[j])].rest)

    def _rest_before(self, t: int, since: int) -> int | None:
        """The latest onset in (``since``, ``t``] of a render at whose onset the shaper
        was at rest (:meth:`_at_rest`), or None."""
        for k in range(self._row_in_force(t), max(self._lo, 0) - 1, -1):
            t_k = int(self._t[k])
            if t_k <= since:
                break
            rid = int(self._rid[k])
            if rid >= 0 and self._renders[rid].onset_ns == t_k and self._at_rest(k):
                return t_k
        return None

    def _rest_after_stop(self, j: int) -> bool | None:
        """:meth:`_at_rest` of the render row ``j`` starts, when the row before stops a
        render that started at rest (the paper study's trials): the walk from that
        render's last memo decision before the stop (where a walk through it resumes
        after splicing the memo) to the onset. None when the rows are not so."""
        lo, lead, n = self._lo, self.shaper.lead_ticks, self.n_tactors
        if j - 2 < lo or self._rid[j - 1] >= 0 or self._lv[j - 1].any() \
                or self._rid[j - 2] < 0:
            return None
        before = self._renders[int(self._rid[j - 2])]
        t_on = before.onset_ns
        if t_on != int(self._t[j - 2]) or before.rest is not True:
            return None
        cut = stop = int(self._t[j - 1])
        end = before.end_ahead(lead)
        if end is not None:
            cut = min(stop, end)
        memo = self._memo_at(before, t_on, [0.0] * n, [0] * (2 * n))
        if memo is None or cut > t_on + _MEMO_TICKS * RENDER_TICK_NS:
            return None
        r = int(memo.t.searchsorted(cut - t_on, side="left")) - 1
        if r < 1:
            return None
        t_r, onset = t_on + int(memo.t[r]), int(self._t[j])
        if cut == stop and stop - t_r >= int(memo.u[r].max()):
            # the stop finds decision r settled (or not) with its budgets spent: the rest
            # after it depends on that decision alone
            if r not in memo.rest_after:
                memo.rest_after[r] = self._rest_after_row(before, memo, r)
            rest_ns = memo.rest_after[r]
            if rest_ns is not None and onset - stop >= rest_ns + 2 * RENDER_TICK_NS:
                return True
        bounds = _sorted_unique(np.concatenate([np.array([t_r], dtype=np.int64),
                                                self._breakpoints(t_r, onset, lead)]))
        ts, _, _, es, us = self._walk(bounds, self._levels_at(bounds, lead), onset,
                                      memo.e[r], memo.e[r], memo.u[r], {})
        return int(ts[-1]) == onset and not (es[-1].any() or us[-1].any())

    def driven(self, t0_ns: int, t1_ns: int, rate_hz: float = 1000.0
               ) -> tuple[IntArray, FloatArray]:
        """The signed drive the motors get over [t0, t1): the commanded levels when plain;
        when shaped, the shaper's (above 1: overdrive; negative, or -0.0: reverse drive or
        the short brake, :data:`~tactorbelt.devices.erm.BRAKE`)."""
        times = sample_grid(t0_ns, t1_ns, rate_hz)
        with self._lock:
            if self._drive != "shaped" or times.shape[0] == 0:
                return times, self._levels_at(times)
            ts, ds, _, _, _ = self._shaped_solve(int(times[0]), int(times[-1]))
            return times, ds[ts.searchsorted(times, side="right") - 1]

    @property
    def hardware(self) -> bool:
        return False

    def _write_levels(self, levels: FloatArray) -> None:
        self._append(np.asarray(levels, dtype=float), -1)

    def _write_stop(self) -> None:
        self._append(np.zeros(self.n_tactors), -1)

    def _write_play(self, stimulus: Stimulus, duration_s: float | None) -> None:
        rid = self._next_rid
        self._next_rid += 1
        onset = self._append(np.zeros(self.n_tactors), rid, register=False)
        end = None if duration_s is None else onset + round(duration_s * 1e9)
        render = _Render(stimulus, onset, end, self.calibration)
        # the same stimulus object again (a study plays each of its stimuli many times):
        # its table and response without looking them up (hashing a stimulus is slow)
        before = self._played.get(id(stimulus))
        if before is not None and before.stimulus is stimulus \
                and before.calibration is self.calibration:
            render.share(before)
        else:
            self._played[id(stimulus)] = render
        self._renders[rid] = render

    # -- the log ----------------------------------------------------------------------
    def _append(self, levels: FloatArray, rid: int, register: bool = True) -> int:
        now = int(self.clock.now_ns())
        if self._hi > self._lo:
            now = max(now, int(self._t[self._hi - 1]))
        if self._hi == self._t.shape[0]:
            live = self._hi - self._lo
            if self._lo >= live:  # at least half free at the front: compact
                t, lv, r = self._t, self._lv, self._rid
            else:
                cap = 2 * self._t.shape[0]
                t, lv, r = (np.zeros(cap, dtype=np.int64), np.zeros((cap, self.n_tactors)),
                            np.full(cap, -1, dtype=np.int64))
            t[:live] = self._t[self._lo : self._hi]
            lv[:live] = self._lv[self._lo : self._hi]
            r[:live] = self._rid[self._lo : self._hi]
            self._t, self._lv, self._rid = t, lv, r
            self._lo, self._hi = 0, live
        i = self._hi
        self._t[i] = now
        self._lv[i] = levels
        self._rid[i] = rid
        self._hi += 1
        self._since_ck += 1
        # (not while a played stimulus's render is not registered yet: the checkpoint
        # would look it up; the next command checkpoints instead)
        if self._since_ck >= _CHECKPOINT_EVERY and register:
            # keep a recent state, so later queries and pruning never replay much
            self._speed_at(np.array([now], dtype=np.int64))
        if (self._hi - self._lo >= 2
                and int(self._t[self._lo + 1]) < now - self._horizon_ns - self._slack_ns):
            self.prune(now - self._horizon_ns)
        return now

    def _row_in_force(self, t_ns: int) -> int:
        """Absolute index of the command in force at ``t_ns`` (lo - 1 when none)."""
        rel = int(self._t[self._lo : self._hi].searchsorted(t_ns, side="right")) - 1
        return self._lo + rel

    def _levels_at(self, times: IntArray, lead: int = 0) -> FloatArray:
        """Commanded drive levels at each time (times need not be sorted); a render's
        ``lead`` ticks ahead (the shaper's preview)."""
        out = np.zeros((times.shape[0], self.n_tactors))
        lo, hi = self._lo, self._hi
        if hi == lo or times.shape[0] == 0:
            return out
        idx = self._t[lo:hi].searchsorted(times, side="right") - 1
        pos = np.flatnonzero(idx >= 0)
        rows = idx[pos] + lo
        rid = self._rid[rows]
        const = rid < 0
        out[pos[const]] = self._lv[rows[const]]
        if not const.all():
            for r in sorted(set(rid[~const].tolist())):
                sel = pos[rid == r]
                out[sel] = self._renders[int(r)].levels(times[sel], lead)
        return out

    def _breakpoints(self, t_a: int, t_b: int, lead: int = 0) -> IntArray:
        """Every time in (t_a, t_b] at which the commanded drive may change (a render's
        levels ``lead`` ticks ahead: :meth:`_Render.levels`)."""
        lo, hi = self._lo, self._hi
        if hi == lo:
            return np.zeros(0, dtype=np.int64)
        first = max(self._row_in_force(t_a), lo)
        last = self._row_in_force(t_b)
        if last < first:
            return np.zeros(0, dtype=np.int64)
        row_t = self._t[first : last + 1]
        parts: list[IntArray] = [row_t[row_t > t_a]]
        rids = self._rid[first : last + 1]
        for off in np.flatnonzero(rids >= 0).tolist():
            row = first + off
            render = self._renders[int(self._rid[row])]
            seg_end = int(self._t[row + 1]) if row + 1 < hi else t_b + 1
            end = render.end_ahead(lead)
            if end is not None:
                if t_a < end <= t_b and end < seg_end:  # not when a command came first
                    parts.append(np.array([end], dtype=np.int64))
                seg_end = min(seg_end, end)
            seg_start = max(int(self._t[row]), t_a + 1)
            seg_end = min(seg_end, t_b + 1)
            if seg_end <= seg_start:
                continue
            k0 = -((render.onset_ns - seg_start) // RENDER_TICK_NS)  # ceil
            k1 = -((render.onset_ns - seg_end) // RENDER_TICK_NS)
            if k1 > k0:
                parts.append(render.onset_ns + render.change_ticks(k0, k1, lead)
                             * RENDER_TICK_NS)
        return np.concatenate(parts)

    def _add_checkpoint(self, t_ns: int, w: FloatArray) -> None:
        """Remember the motor state at ``t_ns`` (after every other checkpoint).

        The newest checkpoint is always kept; older ones are kept at least
        ``_ck_spacing_ns`` apart, so about 32 cover the horizon and pruning always finds
        one close before its cut.
        """
        ck_t, ck_w = self._ck_t, self._ck_w
        if len(ck_t) >= 2 and ck_t[-1] - ck_t[-2] < self._ck_spacing_ns:
            ck_t[-1], ck_w[-1] = t_ns, w
        else:
            ck_t.append(t_ns)
            ck_w.append(w)
        if len(ck_t) > _MAX_CHECKPOINTS:
            del ck_t[0], ck_w[0]
        self._since_ck = 0

    def _speed_at(self, times: IntArray, grid: tuple[int, int] | None = None) -> FloatArray:
        """Modelled motor speed at increasing times (the state carries over exactly), in
        [0, 1]. ``grid``: the times are a :func:`sample_grid` of this ``(p, q)`` period
        from ``times[0]`` (the terms of a render from there are memoised)."""
        n = self.n_tactors
        if times.shape[0] == 0:
            return np.zeros((0, n))
        if self._drive == "shaped":
            return self._speed_shaped(times)
        t_first, t_last = int(times[0]), int(times[-1])
        if self._pruned and t_first < self._base_t:
            raise ConfigError(
                f"time {t_first} ns is before the kept history (from {self._base_t} ns; "
                f"the sim belt keeps {self._horizon_ns / 1e9:g} s, see horizon_s)"
            )
        if t_first < self._base_t:
            t_a, w_a = t_first, np.zeros(n)
        else:
            j = bisect.bisect_right(self._ck_t, t_first) - 1
            if j >= 0:
                t_a, w_a = self._ck_t[j], self._ck_w[j]
            else:
                t_a, w_a = self._base_t, self._base_w
        # the latest time no future command can change (its state is remembered)
        settled = max(min(int(self.clock.now_ns()), t_last), t_a)
        remember = settled > t_a and (not self._ck_t or settled > self._ck_t[-1])
        at = times
        if remember:
            pos = int(times.searchsorted(settled))
            if pos == times.shape[0] or int(times[pos]) != settled:
                at = np.insert(times, pos, settled)
        solved = self._speed_pieces(at, t_a, np.asarray(w_a, dtype=float),
                                    grid if at is times else None)
        if solved is None:
            return np.clip(self._speed_grid(times, t_a, w_a, settled), 0.0, 1.0)
        out = np.clip(solved, 0.0, 1.0)
        if remember:
            pos = int(at.searchsorted(settled))
            self._add_checkpoint(settled, out[pos].copy())
            if at is not times:
                out = np.delete(out, pos, axis=0)
        return np.asarray(out)

    def _pieces(self, t_a: int, t_last: int
                ) -> list[tuple[int, FloatArray | None, _Render | None]] | None:
        """The drive over [t_a, t_last] as pieces ``(start, levels, render)``, in order:
        constant levels (``render`` None; equal neighbours merged) or a changing periodic
        render (``levels`` None). None when a render is neither constant nor periodic."""
        lo, hi = self._lo, self._hi
        zeros = self._zeros
        row = self._row_in_force(t_a) if hi > lo else lo - 1
        pieces: list[tuple[int, FloatArray | None, _Render | None]] = []

        def add(start: int, levels: FloatArray | None, render: _Render | None) -> None:
            if pieces and pieces[-1][0] == start:
                pieces.pop()  # an empty piece: a later command at the same time
            if (levels is not None and pieces and pieces[-1][1] is not None
                    and (pieces[-1][1] == levels).all()):  # both (N,)
                return
            pieces.append((start, levels, render))

        if row < lo:
            add(t_a, zeros, None)
            row = lo
            if hi == lo or int(self._t[lo]) > t_last:
                return pieces
        while row < hi:
            start = max(int(self._t[row]), t_a)
            if start > t_last:
                break
            rid = int(self._rid[row])
            if rid < 0:
                add(start, self._lv[row], None)
            else:
                render = self._renders[rid]
                end = render.end_ns
                if end is not None and end <= start:
                    add(start, zeros, None)
                else:
                    const = render.constant()
                    if const is not None:
                        add(start, const, None)
                    elif render.response(self.params) is None:
                        return None
                    else:
                        add(start, None, render)
                    if end is not None and end <= t_last and (
                            row + 1 >= hi or end < int(self._t[row + 1])):
                        add(end, zeros, None)
            row += 1
        return pieces

    def _speed_pieces(self, times: IntArray, t_a: int, w_a: FloatArray,
                      grid: tuple[int, int] | None = None) -> FloatArray | None:
        """Speeds at increasing ``times`` (from ``t_a``, where the speeds are ``w_a``),
        piece by piece: a constant drive in closed form, a periodic render from its
        response from rest (:class:`_Response`). None where that does not apply (a render
        neither constant nor periodic, more than ``_RESPONSE_MAX_TICKS`` into a render, or
        a state whose rise/fall choices differ from the response's): then the caller
        takes the general solution."""
        t_last = int(times[-1])
        pieces = self._pieces(t_a, t_last)
        if pieces is None:
            return None
        p = self.params
        out = np.empty((times.shape[0], self.n_tactors))
        w = w_a
        i = 0
        # the times from ``first`` on are the grid from a piece's start: memoised terms
        first = int(times[0]) if grid is not None else None
        for k, (start, levels, render) in enumerate(pieces):
            end = pieces[k + 1][0] if k + 1 < len(pieces) else None
            j = times.shape[0] if end is None else int(times.searchsorted(end))
            if levels is not None:
                if (j == i and end is not None and (levels is self._zeros or not levels.any())
                        and w.min() >= 0.0):
                    # no drive and no time asked for: every motor falls (none is below the
                    # steady speed 0) by one factor
                    w = w * _fall_factor_to(end - start, p)
                    continue
                u = p.steady_speed(levels)
                if j > i:
                    if i == 0 and start == first:
                        assert grid is not None
                        out[:j] = _relax_grid(u, w, j, grid, p)
                    else:
                        out[i:j] = _relax(u, w, times[i:j] - start, p)
                if end is not None:
                    w = _relax_to(u, w, end - start, p)
            else:
                assert render is not None
                got = None
                if end is None and i == 0 and start == first == render.onset_ns:
                    assert grid is not None
                    got = self._onset_piece(render, w, j, grid)
                if got is None:
                    got = self._render_piece(render, start, end, w, times[i:j], t_last)
                if got is None:
                    return None
                out[i:j], w = got
            i = j
        return out

    def _onset_piece(self, render: _Render, w: FloatArray, n: int, grid: tuple[int, int]
                     ) -> tuple[FloatArray, FloatArray] | None:
        """:meth:`_render_piece` from the render's onset (state ``w``) over the first ``n``
        times of a regular grid from it, to the last of them: the same arithmetic, with
        the terms that do not depend on ``w`` memoised (:class:`_OnsetGrid`). None where
        :meth:`_moving` would check tick by tick (then the caller takes that path)."""
        p = self.params
        resp = render.response(p)
        assert resp is not None
        key = ("onset", resp, p, n, grid)
        g = _GRIDS.get(key)
        if g is None:
            g = _OnsetGrid(resp, p, _grid_dt(n, grid))
            _remember(_GRIDS, key, g, _GRIDS_BUDGET)
        out = w * g.ff
        w_end = w * g.ff[-1]
        cols = resp.cols
        if cols.shape[0]:
            if g.tw is None or g.d is None:
                return None
            offset = w[cols] - resp.w[0]
            if not resp.within_limits(offset):
                return None
            moving = g.tw + offset * g.d
            out[:, cols] = moving
            w_end[cols] = moving[-1]
        return out, w_end

    def _render_piece(self, render: _Render, start: int, end: int | None, w: FloatArray,
                      times: IntArray, t_last: int) -> tuple[FloatArray, FloatArray] | None:
        """Speeds at ``times`` in [start, end) of a periodic render, from the state ``w`` at
        ``start``, and the state at ``end`` (None: the times run to ``t_last``). The
        motors the render never drives take the closed form of a zero drive."""
        p = self.params
        resp = render.response(p)
        assert resp is not None
        stop = t_last if end is None else end
        # every motor as if undriven (a zero drive falls by one factor for all of them);
        # then the moving ones from the response
        out = (w * _decay_factors(times - start, p.fall_tau_s) if times.shape[0]
               else np.empty((0, w.shape[0])))
        w_end = w * _decay_factors(np.array([stop - start]), p.fall_tau_s)[0]
        cols = resp.cols
        if cols.shape[0]:
            got = self._moving(resp, render.onset_ns, start, stop, end is None, w[cols],
                               times)
            if got is None:
                return None
            out[:, cols], w_end[cols] = got
        return out, w_end

    def _moving(self, resp: _Response, onset: int, start: int, stop: int, open_end: bool,
                w: FloatArray, times: IntArray) -> tuple[FloatArray, FloatArray] | None:
        """:meth:`_render_piece` for the render's moving motors (``resp.cols``): by
        superposition on the response from rest, tick by tick."""
        p = self.params
        k_stop = (stop - onset) // RENDER_TICK_NS
        if k_stop >= _RESPONSE_MAX_TICKS:
            return None
        tw = resp.w
        out = np.empty((times.shape[0], w.shape[0]))
        k0 = (start - onset) // RENDER_TICK_NS
        t0 = onset + k0 * RENDER_TICK_NS
        if start != t0:  # the rest of a tick: one constant stretch
            nxt = t0 + RENDER_TICK_NS
            head = int(times.searchsorted(nxt))
            u0 = resp.u(k0)
            if head:
                out[:head] = _relax(u0, w, times[:head] - start, p)
            if stop < nxt:
                return out, _relax_to(u0, w, stop - start, p)
            w = _relax_to(u0, w, nxt - start, p)
            k0 += 1
            times, rest = times[head:], out[head:]
        else:
            rest = out
        # every tick start from k0 to k_stop, by superposition on the response from rest
        offset = w - tw[k0]
        within = resp.within_limits(offset)
        if within and not times.shape[0]:  # only the state at the end is wanted
            ws = tw[k_stop : k_stop + 1] + offset * resp.decay(k0, k_stop, k_stop + 1)
            k0 = k_stop
        else:
            ws = tw[k0 : k_stop + 1] + offset * resp.decay(k0, k0, k_stop + 1)
        if not within:
            # the offset may change a rise/fall choice: check every tick
            u = resp.u(np.arange(k0, k_stop))
            gap = u - ws[:-1]
            if (((gap > 0.0) != (u > tw[k0:k_stop])) & (np.abs(gap) > _TIE)).any():
                return None  # another rise/fall pattern than from rest
        if times.shape[0]:
            tick = (times - onset) // RENDER_TICK_NS
            base = ws[tick - k0]
            into = times - (onset + tick * RENDER_TICK_NS)
            on_tick = into == 0
            if on_tick.all():
                rest[:] = base
            else:
                rest[:] = np.where(on_tick[:, None], base, _relax(resp.u(tick), base, into, p))
        into_stop = stop - (onset + k_stop * RENDER_TICK_NS)
        if open_end or into_stop == 0:
            return out, ws[-1]
        return out, _relax_to(resp.u(k_stop), ws[-1], into_stop, p)

    def _speed_grid(self, times: IntArray, t_a: int, w_a: FloatArray,
                    settled: int) -> FloatArray:
        """:meth:`_speed_at` by the general solution: every breakpoint of the drive from
        ``t_a`` on one grid, solved by :func:`erm_speed`."""
        t_last = int(times[-1])
        grid = _sorted_unique(np.concatenate([np.array([t_a, settled], dtype=np.int64),
                                              self._breakpoints(t_a, t_last), times]))
        levels = self._levels_at(grid)
        # a breakpoint where the drive stays the same is no step: over a constant drive
        # the speed relaxes as one exponential (the times asked for are kept)
        keep = np.empty(grid.shape[0], dtype=bool)
        keep[0] = True
        np.any(levels[1:] != levels[:-1], axis=1, out=keep[1:])
        keep[grid.searchsorted(times)] = True
        keep[grid.searchsorted(settled)] = True
        if not keep.all():
            grid, levels = grid[keep], levels[keep]
        w = erm_speed(grid, levels, w_a, self.params)
        # remember the state at the latest time no future command can change
        js = int(grid.searchsorted(settled, side="right")) - 1
        if js > 0 and (not self._ck_t or int(grid[js]) > self._ck_t[-1]):
            self._add_checkpoint(int(grid[js]), w[js].copy())
        return np.asarray(w[grid.searchsorted(times)])

    # -- public queries -----------------------------------------------------------------
    @property
    def horizon_s(self) -> float:
        """How much command history the belt keeps."""
        return self._horizon_ns / 1e9

    @property
    def levels(self) -> FloatArray:
        """The drive levels commanded now (calibrated, one per tactor)."""
        with self._lock:
            return self._levels_at(np.array([self.clock.now_ns()], dtype=np.int64))[0]

    def commanded(self, t0_ns: int, t1_ns: int, rate_hz: float = 1000.0
                  ) -> tuple[IntArray, FloatArray]:
        """Commanded drive levels sampled over [t0, t1).

        Returns:
            ``(t_ns, levels)``: sample times ``t0 + i*1e9/rate`` (int ns, shape (n,))
            and drive levels (n, N) in [0, 1].
        """
        times = sample_grid(t0_ns, t1_ns, rate_hz)
        with self._lock:
            if times.size and self._pruned and int(times[0]) < self._base_t:
                raise ConfigError(f"time {int(times[0])} ns is before the kept history "
                                  f"(from {self._base_t} ns)")
            return times, self._levels_at(times)

    def vibration(self, t0_ns: int, t1_ns: int, rate_hz: float = 1000.0
                  ) -> tuple[IntArray, FloatArray]:
        """Modelled vibration amplitude over [t0, t1).

        Returns:
            ``(t_ns, amplitude)``: sample times as :meth:`commanded` and amplitudes
            (n, N) in [0, 1], 1 = a motor at rated speed.
        """
        times = sample_grid(t0_ns, t1_ns, rate_hz)
        with self._lock:  # the speeds are in [0, 1]
            return times, self.params._amplitude_of(
                self._speed_at(times, _grid_period(float(rate_hz))))

    def vibration_at(self, times_ns: Any) -> FloatArray:
        """Modelled vibration amplitude (len(times), N) at arbitrary increasing times."""
        times = np.asarray(times_ns, dtype=np.int64).reshape(-1)
        if times.size > 1 and np.any(np.diff(times) < 0):
            raise ConfigError("vibration_at needs increasing times")
        with self._lock:  # the speeds are in [0, 1]
            return self.params._amplitude_of(self._speed_at(times))

    def commands(self) -> list[SimCommand]:
        """The commands kept in the history, oldest first."""
        with self._lock:
            out: list[SimCommand] = []
            for i in range(self._lo, self._hi):
                rid = int(self._rid[i])
                if rid < 0:
                    out.append(SimCommand(int(self._t[i]), self._lv[i].copy()))
                else:
                    r = self._renders[rid]
                    out.append(SimCommand(int(self._t[i]), None, r.stimulus, r.end_ns))
            return out

    def prune(self, before_ns: int | None = None) -> None:
        """Forget history before ``before_ns`` (default: now minus the horizon).

        The motor state at the cut is kept, so later vibration stays exact.
        """
        with self._lock:
            cut = int(self.clock.now_ns()) - self._horizon_ns if before_ns is None else int(
                before_ns)
            # cut at a remembered state when there is one close before the cut: no work
            since = max(self._base_t, cut - self._slack_ns)
            j = bisect.bisect_right(self._ck_t, cut) - 1
            if j >= 0 and self._ck_t[j] > since:
                cut, w_cut = self._ck_t[j], self._ck_w[j]  # plain: no budget used
                e_cut, u_cut = w_cut.copy(), np.zeros(2 * self.n_tactors, dtype=np.int64)
            elif cut <= self._base_t:
                return
            elif self._drive == "shaped" and (kept := self._shaped_start(cut))[0] > since:
                cut, w_cut, e_cut, u_cut = kept  # a decision of the shaper
            elif self._drive == "shaped" and self._exact and (
                    rest := self._rest_before(cut, since)) is not None:
                n = self.n_tactors  # an onset at rest
                cut, w_cut, e_cut = rest, np.zeros(n), np.zeros(n)
                u_cut = np.zeros(2 * n, dtype=np.int64)
            else:
                cut, w_cut, e_cut, u_cut = self._state_before(cut)
                if cut <= self._base_t:
                    return
            keep = max(self._row_in_force(cut), self._lo)
            self._lo = keep
            self._base_t, self._base_w, self._pruned = cut, w_cut, True
            self._base_e, self._base_u = e_cut, u_cut
            self._sck = [c for c in self._sck if c[0] >= cut]
            j = bisect.bisect_left(self._ck_t, cut)
            del self._ck_t[:j], self._ck_w[:j]
            live = self._rid[self._lo : self._hi]
            live = live[live >= 0]
            oldest = int(live.min()) if live.size else self._next_rid
            for rid in [r for r in self._renders if r < oldest]:
                render = self._renders.pop(rid)
                if self._played.get(id(render.stimulus)) is render:
                    del self._played[id(render.stimulus)]


def _parse_target(target: str) -> tuple[int | None, bool]:
    n: int | None = None
    virtual = False
    for token in (p.strip().lower() for p in target.split(",")):
        if not token:
            continue
        if token == "virtual":
            virtual = True
        elif token.isdigit():
            n = int(token)
        else:
            raise ConfigError(
                f"unknown sim belt option {token!r} in 'sim:{target}'; allowed: a tactor "
                "count (sim:8) and 'virtual' (a simulated clock: sim:virtual, sim:8,virtual)"
            )
    return n, virtual


def open_sim(target: str = "", **options: Any) -> SimBelt:
    """Open the ``sim`` belt.

    Args:
        target: what follows ``sim:``: empty, a tactor count (``sim:8``), ``virtual``
            (run on a new SimClock, so nothing waits in real time), or both
            (``sim:8,virtual``).
        **options: ``layout`` (Layout), ``clock`` (Clock), ``calibration``
            (Calibration or a path to a calibration file), ``params`` (ErmParams),
            ``horizon_s`` (float), ``name`` (str), ``drive`` (``shaped``, the default, or
            ``plain``), ``overdrive`` (the shaper's largest drive, times the rated;
            default the motor's maximum voltage, or ``supply_v`` when lower, over its rated
            voltage), ``supply_v`` (V, default :data:`DEFAULT_SUPPLY_V`), ``kick_ms``
            (ms a kick may apply the whole supply above the motor's maximum voltage;
            default 0: never), ``brake``
            (bool, default True: both bridge inputs wired), ``shaper`` (a
            :class:`~tactorbelt.devices.erm.Shaper`).

    Raises:
        ConfigError: an unknown option or target, or values that do not fit together.
    """
    unknown = sorted(set(options) - set(_OPTIONS))
    if unknown:
        raise ConfigError(f"unknown option {unknown[0]!r} for the sim belt; allowed: "
                          f"{', '.join(_OPTIONS)}")
    n, virtual = _parse_target(target or "")
    layout = options.get("layout")
    if layout is None:
        layout = Layout.even(n if n is not None else 6)
    elif not isinstance(layout, Layout):
        raise ConfigError(f"layout must be a Layout, got {type(layout).__name__}")
    elif n is not None and n != layout.n:
        raise ConfigError(f"'sim:{target}' asks for {n} tactors but the layout has {layout.n}")
    clock = options.get("clock")
    if clock is None and virtual:
        from ..clock import SimClock

        clock = SimClock()
    calibration = options.get("calibration")
    if calibration is not None and not isinstance(calibration, Calibration):
        calibration = Calibration.load(calibration)
    # the other options go to SimBelt as they are (its defaults but the drive's)
    return SimBelt(**{**options, "layout": layout, "clock": clock, "calibration": calibration,
                      "url": f"sim:{target}" if target else "sim",
                      "drive": options.get("drive", "shaped")})
