"""A direction display for applications: keep any direction shown on a belt, smoothly.

The study shows 24 fixed targets, one at a time. An application (navigation, say)
needs any direction, changing as the wearer turns. :class:`DirectionDisplay` keeps one
direction displayed and moves it smoothly:

- ``show(angle_deg)`` asks for a body angle (any angle, any call rate). The *displayed*
  angle slews toward the *requested* one the short way round at ``slew_deg_per_s`` at
  most (default 180 deg/s: a half turn in 1 s), so a new direction never makes the
  amplitudes jump and never leaves a gap.
- ``show_bearing(bearing_deg, heading_deg, t_s)`` shows a world bearing for a wearer
  whose heading is ``heading_deg``: body angle = bearing - heading. The heading goes
  through a One Euro filter (:class:`~tactorbelt.filters.OneEuroFilter`) first.
- Every request goes through a :class:`~tactorbelt.filters.Hysteresis` (default 4 deg):
  the dominant (nearest) tactor changes only when the requested angle is past the edge
  of its sector by the margin, so an angle jittering around a sector edge does not make
  the cue flicker between two tactors.
- ``hide()`` turns every motor off. The display is a context manager (``hide`` on exit);
  it does not close the belt.

Two ways to drive a belt, chosen by ``device_render`` (default: automatic):

- **Streaming** (any belt): frames at ``rate_hz`` (default the belt's ``stream_rate_hz``)
  computed from the displayed angle at each frame time, on the deadlines of a
  :class:`~tactorbelt.clock.Deadlines` (frame i due at onset + i/rate; a frame woken up
  late is skipped, never sent in a burst). On a wall clock a render thread writes them;
  on a simulated clock call :meth:`DirectionDisplay.pump` (which moves the clock) or
  :meth:`DirectionDisplay.update`, so nothing sleeps.
- **Device rendering** (``belt.can_render(stimulus)`` with an identity calibration): the belt
  renders a static or dynamic stimulus itself (PLAY_TARGET, ``belt.play(stimulus, None)``).
  A tick at ``device_rate_hz`` (20 Hz) slews the displayed angle and sends a new
  PLAY_TARGET only when it differs from the one last sent by more than ``step_deg``
  (default 2 deg, far below the ~15-deg resolution of the display, so the device is
  never told about a change nobody can feel, and a slow link is not flooded). Within
  ``step_deg`` of the requested angle the tick aims at the requested angle itself, so
  after a move the device ends exactly on it; a later request within ``step_deg`` of
  what the device shows sends nothing.

The dynamic perturbation and its phase (the rule):

- Streaming: the felt location runs on the paper's trapezoid (dwell, transit, dwell,
  transit, as :meth:`~tactorbelt.stimuli.Stimulus.location`) within the *pair* of tactors
  that brackets the displayed angle. Its phase is kept (it keeps running) while the
  displayed angle stays in the same pair; the dwell times follow the angle at every frame,
  which is continuous, so sliding within a pair (even across its midpoint, where the
  nearer tactor swaps) never jumps. When the displayed angle crosses a tactor into another
  pair, the phase restarts at the start of the dwell on the new pair's nearer tactor (the
  crossed one), and the restart waits until the old waveform is dwelling on that tactor
  (at most ``2*transit_s``), so the felt location never jumps. An angle exactly on a
  tactor renders static, as in the paper.
- Device rendering: the device restarts the perturbation with every PLAY_TARGET (t = 0
  starts the dwell on the nearer tactor). So, in dynamic mode, a new PLAY_TARGET is sent
  only at the tick when the device's current stimulus *starts* its dwell on the new
  stimulus's nearer tactor: the start of a period when the nearer tactor is the same,
  the start of the far dwell when the angle crossed the pair's midpoint. The felt
  location is then continuous and every dwell keeps the paper's timing (a stream of
  small changes cannot keep restarting a dwell); a change waits at most one period
  (``period_s``), and after two periods it is sent anyway.

Imports NumPy, tactorbelt (geometry, laws, stimuli, filters, clock, devices.base) and
the standard library (threading); no I/O library.
"""

from __future__ import annotations

import bisect
import math
import threading
from types import TracebackType
from typing import TYPE_CHECKING, Final

import numpy as np
from numpy.typing import NDArray

from .._errors import ConfigError, TactorbeltError
from ..clock import Clock, Deadlines, WallClock
from ..geometry import ANGLE_TOLERANCE_DEG, Layout, normalize, parse_number, wrap
from ..laws import DEFAULT_FALLOFF_DEG
from ..stimuli import DEFAULT_PERIOD_S, DEFAULT_TRANSIT_S, Stimulus, make_stimulus
from .filters import (
    DEFAULT_BETA,
    DEFAULT_D_CUTOFF_HZ,
    DEFAULT_HYSTERESIS_DEG,
    DEFAULT_MIN_CUTOFF_HZ,
    Hysteresis,
    OneEuroFilter,
)

if TYPE_CHECKING:
    from ..devices.base import Belt
    from ..wearer import WearerProfile

__all__ = [
    "DEFAULT_DEVICE_RATE_HZ",
    "DEFAULT_SLEW_DEG_PER_S",
    "DEFAULT_STEP_DEG",
    "DirectionDisplay",
]

#: Default top speed of the displayed angle (deg/s).
DEFAULT_SLEW_DEG_PER_S: Final = 180.0
#: Default smallest change that sends a new PLAY_TARGET to a device-render belt (deg).
DEFAULT_STEP_DEG: Final = 2.0
#: Default tick rate of the device-render loop (Hz).
DEFAULT_DEVICE_RATE_HZ: Final = 20.0
#: A device-render change waits at most this many periods for a seamless moment.
_MAX_WAIT_PERIODS: Final = 2.0
#: A location within this of a tactor is on that tactor (for the seamless checks).
_ON_TACTOR_DEG: Final = 1e-6

FloatArray = NDArray[np.float64]
Pair = tuple[int, int]

# the segments of the perturbation's trapezoid within a pair (ccw tactor A, cw tactor B)
_DWELL_A, _TO_B, _DWELL_B, _TO_A = range(4)


def _positive(value: object, what: str, allow_inf: bool = False) -> float:
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ConfigError(f"{what} must be a positive number, got {value!r}") from None
    if math.isnan(v) or v <= 0 or (math.isinf(v) and not allow_inf):
        raise ConfigError(f"{what} must be a positive, finite number, got {value!r}")
    return v


def _normalize1(a: float) -> float:
    """:func:`~tactorbelt.geometry.normalize` of one float (Python's float % is
    NumPy's mod: the same result, bit for bit)."""
    a = a % 360.0
    return 0.0 if a >= 360.0 else a


def _wrap1(a: float) -> float:
    """:func:`~tactorbelt.geometry.wrap` of one float (bit for bit)."""
    w = 180.0 - (180.0 - a) % 360.0
    return 180.0 if w <= -180.0 else w


def _clip01(v: float) -> float:
    """``np.clip(v, 0.0, 1.0)`` of one float, bit for bit (-0.0 gives 0.0, NaN stays)."""
    return 0.0 if v <= 0.0 else (1.0 if v >= 1.0 else v)


class DirectionDisplay:
    """Keep one direction displayed on a belt; move it smoothly when it changes.

    Args:
        belt: an open belt (any backend).
        law: amplitude law (``paper``, ``linear``, ``energy``).
        mode: ``static`` or ``dynamic`` (the paper's perturbation).
        falloff_deg: T of the paper law.
        period_s: period of the dynamic perturbation.
        transit_s: time of each move between the two tactors.
        clock: the clock (default: the belt's ``clock`` if it has one, else the wall clock).
        step_deg: device rendering: the smallest change of direction that sends a new
            PLAY_TARGET (default 2 deg).
        slew_deg_per_s: top speed of the displayed angle (default 180 deg/s; ``math.inf``
            jumps at once).
        hysteresis_deg: hysteresis margin past a sector edge (default 4 deg; 0 = off).
        rate_hz: streaming frame rate (default: the belt's ``stream_rate_hz``).
        device_render: True to send PLAY_TARGET, False to stream frames, None (default)
            to render on the device when the belt can (``can_render(stimulus)``) and its
            calibration is the identity (the device does not apply host calibration).
        device_rate_hz: tick rate of the device-render loop (default 20 Hz).
        min_cutoff_hz, beta, d_cutoff_hz: the heading filter's parameters (see
            :mod:`tactorbelt.filters`).
        profile: render for this wearer's perceptual profile (:mod:`tactorbelt.wearer`);
            one that is not the identity is streamed (the firmware cannot apply it).

    Raises:
        ConfigError: a bad parameter, or ``device_render=True`` on a belt that cannot.
    """

    def __init__(
        self,
        belt: Belt,
        law: str = "paper",
        mode: str = "static",
        falloff_deg: float = DEFAULT_FALLOFF_DEG,
        period_s: float = DEFAULT_PERIOD_S,
        transit_s: float = DEFAULT_TRANSIT_S,
        clock: Clock | None = None,
        step_deg: float = DEFAULT_STEP_DEG,
        slew_deg_per_s: float = DEFAULT_SLEW_DEG_PER_S,
        hysteresis_deg: float = DEFAULT_HYSTERESIS_DEG,
        rate_hz: float | None = None,
        device_render: bool | None = None,
        device_rate_hz: float = DEFAULT_DEVICE_RATE_HZ,
        min_cutoff_hz: float = DEFAULT_MIN_CUTOFF_HZ,
        beta: float = DEFAULT_BETA,
        d_cutoff_hz: float = DEFAULT_D_CUTOFF_HZ,
        profile: WearerProfile | None = None,
    ) -> None:
        self.belt = belt
        self.layout: Layout = belt.layout
        self.profile = profile
        # validates mode, law, falloff, period, transit and the profile's layout together
        probe = make_stimulus(self.layout, 0.0, mode, law, falloff_deg, period_s, transit_s,
                              profile=profile)
        self._probe = probe  # its law, falloff and profile render the streamed frames
        self.mode = probe.mode
        self.law = probe.law
        self.falloff_deg = probe.falloff_deg
        self.period_s = probe.period_s
        self.transit_s = probe.transit_s
        self.step_deg = parse_number(step_deg, "step_deg")
        if self.step_deg < 0:
            raise ConfigError(f"step_deg must be >= 0 degrees, got {step_deg!r}")
        self.slew_deg_per_s = _positive(slew_deg_per_s, "slew_deg_per_s", allow_inf=True)
        self.device_rate_hz = _positive(device_rate_hz, "device_rate_hz")
        if rate_hz is None:
            rate_hz = belt.stream_rate_hz
        self.rate_hz = _positive(rate_hz, "rate_hz")
        # every stimulus the display sends has the probe's law, mode and timing
        can = belt.can_render(probe)
        identity = belt.calibration.is_identity or belt.renders_calibrated
        if device_render is None:
            device_render = belt.renders_with_calibration(probe)
        elif device_render and not can:
            raise ConfigError(f"belt {belt.url!r} cannot render stimuli on the device; "
                              "use device_render=False (stream frames)")
        elif device_render and not identity:
            raise ConfigError(f"belt {belt.url!r} has a calibration, which the device would "
                              "ignore; use device_render=False (stream frames)")
        self.device_render = bool(device_render)
        if clock is None:
            clock = belt.clock
        self.clock: Clock = clock if isinstance(clock, Clock) else WallClock()
        self.hysteresis = Hysteresis(self.layout, hysteresis_deg)
        self.heading_filter = OneEuroFilter(min_cutoff_hz, beta, d_cutoff_hz, angular=True)

        self._lock = threading.RLock()
        self._angle_list = [float(a) for a in self.layout.angles]
        order = sorted(range(self.layout.n), key=lambda k: self._angle_list[k])
        self._sorted_order = order
        self._sorted_angles = [self._angle_list[k] for k in order]
        self._gap_list = [float(g) for g in self.layout.gaps_deg()]
        self._hold_s = self.period_s - 2.0 * self.transit_s
        self._tick_rate_hz = self.device_rate_hz if self.device_render else self.rate_hz
        self._tick_ns = 1e9 / self._tick_rate_hz
        self._dl = Deadlines(self.clock, self._tick_rate_hz, onset_ns=0)
        self._thread: threading.Thread | None = None
        self._stop_event = threading.Event()
        self._error: BaseException | None = None
        self._reset_state()
        #: Frames written (streaming).
        self.frames_written = 0
        #: PLAY_TARGET commands sent (device rendering).
        self.plays_sent = 0
        #: Times the perturbation restarted in another pair (streaming, dynamic).
        self.pair_changes = 0
        #: Largest change of any tactor's amplitude between two consecutive frames.
        self.max_frame_change = 0.0
        #: The last heading given to show_bearing, after the filter (None before).
        self.filtered_heading_deg: float | None = None

    # -- state ----------------------------------------------------------------------------
    def _reset_state(self) -> None:
        self._requested: float | None = None
        self._displayed: float | None = None
        self._t_ns = 0  # time the displayed angle was last advanced to
        self._pair: Pair | None = None
        self._seg = _DWELL_A  # where the perturbation is on its trapezoid
        self._seg_start_ns = 0  # when that segment started
        self._last_frame_ns = 0
        self._last_amps: FloatArray | None = None
        self._sent: Stimulus | None = None  # device rendering: the stimulus playing
        self._sent_ns = 0
        self._pending_since_ns: int | None = None

    @property
    def playing(self) -> bool:
        """True while a direction is shown (between the first show and hide)."""
        return self._displayed is not None

    @property
    def requested_deg(self) -> float | None:
        """The angle asked for (after hysteresis), or None when hidden."""
        return self._requested

    @property
    def displayed_deg(self) -> float | None:
        """The angle displayed now (slewing toward the requested one), or None."""
        return self._displayed

    @property
    def dominant_tactor(self) -> int | None:
        """The tactor the hysteresis holds as dominant, or None when hidden."""
        return self.hysteresis.dominant if self.playing else None

    @property
    def device_angle_deg(self) -> float | None:
        """Device rendering: the direction of the PLAY_TARGET last sent (None: none)."""
        return None if self._sent is None else self._sent.target_deg

    # -- the public interface -------------------------------------------------------------
    def show(self, angle_deg: float) -> float:
        """Display body angle ``angle_deg`` (degrees, 0 = navel, clockwise).

        Returns at once: the displayed angle slews toward it. May be called at any rate,
        from any thread.

        Returns:
            The requested angle after hysteresis (what the display moves toward).
        """
        x = parse_number(angle_deg, "angle")
        self._raise_thread_error()
        with self._lock:
            held = self.hysteresis(float(normalize(x)))
            self._requested = held
            if self._displayed is None:
                self._start(held)
            # otherwise the next frame or device tick (thread, pump or update) takes it:
            # show() itself never waits for the belt after the first call
        return held

    def show_bearing(self, bearing_deg: float, heading_deg: float,
                     t_s: float | None = None) -> float:
        """Display a world bearing for a wearer facing ``heading_deg``.

        The heading is filtered (One Euro, on the unwrapped angle); the body angle is
        ``bearing - filtered heading``, then goes through :meth:`show`.

        Args:
            bearing_deg: direction to show, degrees clockwise from north (or any fixed
                world reference the heading shares).
            heading_deg: the wearer's heading in the same reference (noisy is fine).
            t_s: when the heading was measured, seconds (default: the display's clock).

        Returns:
            The requested body angle after hysteresis.
        """
        b = parse_number(bearing_deg, "bearing")
        h = parse_number(heading_deg, "heading")
        t = self.clock.now_ns() / 1e9 if t_s is None else parse_number(t_s, "heading time")
        with self._lock:
            hf = self.heading_filter(h, t)
            self.filtered_heading_deg = hf
            return self.show(float(normalize(b - hf)))

    def hide(self) -> None:
        """Stop displaying: the render loop ends and every motor is off."""
        self._stop_thread()
        with self._lock:
            self._reset_state()
            self.hysteresis.reset()
            if not self.belt.closed:
                self.belt.stop()
        self._raise_thread_error()

    def close(self) -> None:
        """Same as :meth:`hide` (the belt stays open)."""
        self.hide()

    def __enter__(self) -> DirectionDisplay:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        try:
            self.hide()
        except TactorbeltError:
            if exc is None:
                raise

    def update(self, now_ns: int | None = None) -> FloatArray | None:
        """Advance the display to ``now_ns`` (default: the clock) and drive the belt once.

        Streaming: writes one frame for ``now_ns`` and returns its amplitudes.
        Device rendering: slews, sends a PLAY_TARGET if one is due, returns None.
        For applications that run their own loop; the render thread and :meth:`pump`
        call the same code.
        """
        self._raise_thread_error()
        now = self.clock.now_ns() if now_ns is None else int(now_ns)
        with self._lock:
            if self._displayed is None:
                return None
            if self.device_render:
                self._device_tick(now)
                self._defer(now)
                return None
            amps = self._frame(max(now, self._t_ns))
            self._write(amps)
            self._defer(now)
            return amps

    def pump(self, until_ns: int) -> None:
        """Drive the belt up to ``until_ns`` on a simulated clock (moves the clock).

        Streaming: writes every frame due before ``until_ns``, each at its time.
        Device rendering: runs every tick due before ``until_ns``. The clock ends at
        ``until_ns``. Does nothing but move the clock while hidden.

        Raises:
            TactorbeltError: the display runs its own thread (a wall clock).
        """
        if self._threaded:
            raise TactorbeltError("this display renders in its own thread on the wall clock; "
                                  "pump() is for simulated clocks")
        until = int(until_ns)
        with self._lock:
            if self._displayed is not None:
                dl = self._dl
                now = self.clock.now_ns()
                i = dl.next_index
                if dl.deadline(i) < now:  # the clock was moved by someone else: skip ahead
                    i = dl.last_due(now - 1) + 1
                end = max(i, dl.last_due(until - 1) + 1)  # frames due before ``until``
                dl.next_index = end
                for t in [dl.deadline(k) for k in range(i, end)]:
                    self.clock.sleep_until_ns(t)
                    if self.device_render:
                        self._device_tick(t)
                    else:
                        self._write(self._frame(t))
            self.clock.sleep_until_ns(until)

    # -- starting and the render thread -----------------------------------------------------
    @property
    def _threaded(self) -> bool:
        return not self.clock.simulated

    def _start(self, angle: float) -> None:
        now = self.clock.now_ns()
        self._displayed = angle
        self._t_ns = now
        self._dl = Deadlines(self.clock, self._tick_rate_hz, onset_ns=now)
        self._pair = None
        self._last_frame_ns = now
        self._sent = None
        self._last_amps = None
        if self.device_render:
            self._device_tick(now)
            self._dl.next_index = 1
        if self._threaded:
            self._stop_event.clear()
            self._error = None
            self._thread = threading.Thread(target=self._run, name="tactorbelt-display",
                                            daemon=True)
            self._thread.start()

    def _defer(self, now: int) -> None:
        """After a frame or tick driven by hand at ``now``: the next one is a period on."""
        nxt = now + round(self._tick_ns)
        if self._dl.deadline(self._dl.next_index) < nxt:
            self._dl = Deadlines(self.clock, self._tick_rate_hz, onset_ns=nxt)

    def _run(self) -> None:
        try:
            while not self._stop_event.is_set():
                with self._lock:
                    dl = self._dl
                _, now = dl.wait()  # a frame woken up late is skipped: no burst
                if self._stop_event.is_set():
                    break
                with self._lock:
                    if self._displayed is None:
                        break
                    if self.device_render:
                        self._device_tick(now)
                    else:
                        self._write(self._frame(now))
        except BaseException as exc:  # surfaced by the next call from the application
            self._error = exc

    def _stop_thread(self) -> None:
        thread = self._thread
        if thread is not None:
            self._stop_event.set()
            if thread is not threading.current_thread():
                thread.join(timeout=5.0)
            self._thread = None

    def _raise_thread_error(self) -> None:
        err = self._error
        if err is not None:
            self._error = None
            raise err

    # -- the displayed angle -----------------------------------------------------------------
    def _slew(self, t: int) -> float:
        """The displayed angle at ``t``; advances the state to ``t``."""
        assert self._displayed is not None and self._requested is not None
        target = self._requested
        diff = _wrap1(target - self._displayed)
        travel = self.slew_deg_per_s * (float(max(t - self._t_ns, 0)) * 1e-9)
        if math.isinf(self.slew_deg_per_s) or travel >= abs(diff):
            x = target
        else:
            x = _normalize1(self._displayed + math.copysign(1.0, diff) * travel)
        self._displayed = x
        self._t_ns = max(self._t_ns, t)
        return x

    # -- streaming --------------------------------------------------------------------------
    def _frame(self, t: int) -> FloatArray:
        """The amplitudes (one per tactor) of the frame at ``t``; advances the state."""
        x = self._slew(t)
        loc = np.array([self._location1(t, x) if self.mode == "dynamic" else x])
        return self._probe.amplitudes_at(loc)[0]

    def _write(self, row: FloatArray) -> None:
        if self._last_amps is not None:
            change = float(np.abs(row - self._last_amps).max())
            if change > self.max_frame_change:
                self.max_frame_change = change
        self.belt.set_amplitudes(row)
        self._last_amps = row
        self.frames_written += 1

    def _pair_at(self, x: float) -> Pair:
        """The pair bracketing ``x``: (ccw, cw), or (k, k) on tactor k (as
        Layout.tactor_at and Layout.neighbours find them, in plain Python)."""
        xn = _normalize1(x)  # as Layout.tactor_at and Layout.neighbours, on floats
        for k, ang in enumerate(self._angle_list):
            if abs(_wrap1(xn - ang)) < ANGLE_TOLERANCE_DEG:
                return k, k
        order = self._sorted_order
        pos = bisect.bisect_right(self._sorted_angles, xn + ANGLE_TOLERANCE_DEG) - 1
        if pos < 0:
            pos = len(order) - 1
        return order[pos], order[(pos + 1) % len(order)]

    def _r1(self, pair: Pair, x: float) -> float:
        """Where ``x`` sits in ``pair``: 0 at its ccw tactor, 1 at its cw tactor.

        Clamped to [0, 1]: an angle that has just left the pair counts as on its edge.
        """
        a, _ = pair
        gap = self._gap_list[a]
        off = _wrap1(x - self._angle_list[a] - gap / 2.0) + gap / 2.0
        return _clip01(off / gap)

    def _enter_pair(self, pair: Pair, t_ns: int, x: float) -> None:
        """Start the perturbation in ``pair`` at the dwell on its nearer tactor."""
        if self._pair is not None:
            self.pair_changes += 1
        self._pair = pair
        a, b = pair
        r = self._r1(pair, x) if a != b else 0.0
        # nearer = ccw tactor when r <= 0.5 (at an exact midpoint too, as make_stimulus does)
        self._seg = _DWELL_A if r <= 0.5 else _DWELL_B
        self._seg_start_ns = t_ns

    def _dwelling_on(self, k: int) -> bool:
        """True when the felt location is dwelling on tactor k (current pair)."""
        assert self._pair is not None
        a, b = self._pair
        if a == b:
            return k == a
        return (self._seg == _DWELL_A and k == a) or (self._seg == _DWELL_B and k == b)

    def _crossed(self, x: float) -> int:
        """The tactor of the current pair nearest ``x`` (the one being crossed)."""
        assert self._pair is not None
        a, b = self._pair
        da = abs(_wrap1(x - self._angle_list[a]))
        db = abs(_wrap1(x - self._angle_list[b]))
        return a if da <= db else b

    def _location1(self, t: int, x: float) -> float:
        """The felt location of the streamed perturbation in the frame at ``t``, the
        displayed angle being ``x`` (see the module docstring)."""
        target = self._pair_at(x)
        loc: float | None = None
        if target != self._pair:
            if self._pair is not None and self._pair[0] != self._pair[1]:
                s = self._crossed(x)
                if s in target:  # wait until dwelling on the crossed tactor
                    loc = self._segment1(t, x, stop_on=s)
            if loc is None:
                self._enter_pair(target, t, x)
        if loc is None:
            loc = self._segment1(t, x)
        assert loc is not None
        self._last_frame_ns = t
        return _normalize1(loc)

    def _segment1(self, t: int, x: float, stop_on: int | None = None) -> float | None:
        """The location of the frame at ``t`` in the current pair, moving along the
        trapezoid; None when ``stop_on`` stops it (then the frame is not rendered).

        The trapezoid is a small state machine: dwell on the ccw tactor (for
        ``hold*(1-r)``), transit to the cw tactor (``transit_s``), dwell there (for
        ``hold*r``), transit back. Dwell lengths follow r at every frame; a transit
        always runs at its nominal speed, so the felt location moves no faster than
        in the paper's stimulus, whatever the display does. With ``stop_on``, it stops
        at the first frame at which the location is dwelling on that tactor.
        """
        assert self._pair is not None
        a, b = self._pair
        if a == b:
            return None if stop_on is not None else self._angle_list[a]
        ang_a, gap = self._angle_list[a], self._gap_list[a]
        tr_ns = self.transit_s * 1e9
        hold_ns = self._hold_s * 1e9
        while True:
            if stop_on is not None and self._dwelling_on(stop_on):
                return None
            seg, s0 = self._seg, self._seg_start_ns
            elapsed = float(t - s0)
            if seg == _DWELL_A:
                dur = hold_ns * (1.0 - self._r1(self._pair, x))
            elif seg == _DWELL_B:
                dur = hold_ns * self._r1(self._pair, x)
            else:
                dur = tr_ns
            if not elapsed >= dur:
                if seg == _DWELL_A:
                    return ang_a
                if seg == _DWELL_B:
                    return ang_a + gap
                frac = _clip01(elapsed / tr_ns)
                return ang_a + gap * (frac if seg == _TO_B else 1.0 - frac)
            # the segment ended at s0 + dur, before this frame: the next one from there
            end = int(s0 + round(dur))
            self._seg = (seg + 1) % 4
            self._seg_start_ns = max(end, self._last_frame_ns)

    # -- device rendering ---------------------------------------------------------------------
    def _stimulus(self, angle: float) -> Stimulus:
        return make_stimulus(self.layout, angle, self.mode, self.law, self.falloff_deg,
                             self.period_s, self.transit_s, profile=self.profile)

    def _device_tick(self, now: int) -> None:
        """Slew to ``now``; send a PLAY_TARGET when the direction moved by > step_deg."""
        x = self._slew(max(now, self._t_ns))
        assert self._requested is not None
        if abs(float(wrap(self._requested - x))) <= self.step_deg:
            x = self._requested  # within a step of the goal: aim at the goal itself
        sent = self._sent
        if sent is not None and abs(float(wrap(x - sent.target_deg))) <= self.step_deg:
            self._pending_since_ns = None
            return
        stim = self._stimulus(x)
        if sent is not None and sent.is_dynamic and not self._seamless(sent, stim, now):
            if self._pending_since_ns is None:
                self._pending_since_ns = now
            if now - self._pending_since_ns < _MAX_WAIT_PERIODS * self.period_s * 1e9:
                return
        self.belt.play(stim, None)
        self._sent = stim
        self._sent_ns = now
        self._pending_since_ns = None
        self.plays_sent += 1

    def _seamless(self, playing: Stimulus, new: Stimulus, now: int) -> bool:
        """True when ``playing`` is just starting its dwell on ``new``'s nearer tactor.

        "Just": within one tick after the dwell starts, so the new stimulus (which
        starts with that dwell) takes over the dwell with the paper's timing, and a
        stream of small changes cannot keep restarting (and so lengthening) a dwell.
        """
        phase = ((now - self._sent_ns) * 1e-9) % playing.period_s
        window = 1.0 / self.device_rate_hz
        if new.near_idx == playing.near_idx:
            start = 0.0
        elif new.near_idx == playing.far_idx:
            start = playing.dwell_near_s + playing.transit_s
        else:  # the direction jumped past the pair: nothing to keep continuous
            return True
        return start <= phase < start + window
