"""Drive a belt from a PsychoPy experiment, in step with the screen (docs/psychopy.md).

A component-like helper: open the belt once, then ask for a stimulus on the next flip::

    from psychopy import core, visual
    from tactorbelt.psychopy import TactileBelt

    win = visual.Window()
    belt = TactileBelt(win, "serial:auto")        # opened once; motors off at the end
    belt.present(45.0, "dynamic")                 # starts on the next win.flip()
    win.flip()                                    # the stimulus starts right after it
    belt.add_data(thisExp)                        # belt.started, ... in this trial's row
    ...
    belt.stop_on_flip(); win.flip()               # ends with the next frame
    core.quit()                                   # motors off (atexit)

:meth:`TactileBelt.present` schedules the start with ``win.callOnFlip``, which PsychoPy
calls immediately after the buffer swap of the next ``win.flip()``, so the stimulus
onset is locked to the frame that shows the visual stimulus. Every time the helper
reports (:attr:`~TactileBelt.onset_s`, ``tStart``, ``tStartRefresh``, ``tStop``,
:meth:`~TactileBelt.device_onset_s`) is on PsychoPy's clock, the one ``win.flip()``
returns (``psychopy.logging.defaultClock``: ``core.monotonicClock``, or the clock a
Builder script gives ``logging.setDefaultClock``); the belt itself is timed on
``time.perf_counter`` and each onset is converted at the moment it happens.

Nothing raised while a flip runs the helper's work (a device error at the start) stays
queued on the window: the error comes out of that ``win.flip()``, and the next flips
work (PsychoPy would otherwise run the failed call, and raise, at every later flip).

Motors go off:

- at ``core.quit()`` and any other interpreter exit (PsychoPy's ``core.quit`` ends with
  ``sys.exit``; the helper registers an ``atexit`` handler), and on an exception that
  ends the script;
- on SIGTERM and SIGHUP (a process manager, ``kill``, a closed terminal): the helper
  makes them end the script like ``sys.exit(128 + signal)`` (143 for SIGTERM), so
  ``finally`` blocks and ``atexit`` handlers run, as the command line does
  (:mod:`tactorbelt.interrupts`); a second one ends the script at once, as without the
  helper; a handler the script installed itself is left alone;
- when the window is closed with ``win.close()`` (the helper wraps that method of the
  window it was given), even mid-stimulus;
- on :meth:`TactileBelt.stop`, :meth:`TactileBelt.close`, or leaving ``with``.

It uses only ``win.callOnFlip``, ``win.close`` and, where the window has it,
``win.timeOnFlip`` (``tStartRefresh``), and imports no PsychoPy module (it reads
``psychopy.logging.defaultClock`` when PsychoPy is loaded), so it runs with any PsychoPy
version that has them, and in tests against a stand-in window.

I/O edge: opens a belt (tactorbelt.devices) and plays stimuli (tactorbelt.player).
"""

from __future__ import annotations

import atexit
import contextlib
import math
import numbers
import os
import signal
import sys
import threading
from collections.abc import Callable
from types import FrameType
from typing import TYPE_CHECKING, Any, Final

from .._errors import ConfigError, TactorbeltError
from ..clock import Clock, WallClock
from ..interrupts import SIGNALS

if TYPE_CHECKING:
    from ..devices.base import Belt
    from ..geometry import Layout
    from ..stimuli import Stimulus

__all__ = ["FINISHED", "NOT_STARTED", "STARTED", "TactileBelt"]

#: ``status`` values, PsychoPy's (``psychopy.constants``).
NOT_STARTED: Final = 0
STARTED: Final = 1
FINISHED: Final = -1


def _duration(value: Any, what: str) -> float | None:
    """A duration in seconds (None: until stopped), or ConfigError."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Real) \
            or not (math.isfinite(float(value)) and float(value) > 0):
        raise ConfigError(f"{what} must be a positive, finite number of seconds or None, "
                          f"got {value!r}")
    return float(value)


def _angle(value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) \
            or not math.isfinite(float(value)):
        raise ConfigError(f"target_deg must be a finite number of degrees, got {value!r}")
    return float(value)


def _psychopy_time() -> Callable[[], float] | None:
    """PsychoPy's clock (the one ``win.flip()`` returns), looked up at every call so
    ``logging.setDefaultClock`` counts; None when PsychoPy is not loaded."""
    logging = sys.modules.get("psychopy.logging")
    if logging is None or not hasattr(logging, "defaultClock"):
        return None

    def now() -> float:
        return float(logging.defaultClock.getTime())

    return now


def _timebase(value: Any) -> Callable[[], float]:
    get = getattr(value, "getTime", None)
    if callable(get):
        return lambda: float(get())
    if callable(value):
        return lambda: float(value())
    raise ConfigError(f"timebase must be a clock with getTime() or a function giving "
                      f"seconds, got {value!r}")


# -- SIGTERM and SIGHUP: end the script like sys.exit, so the motors go off ---------------
_signal_lock = threading.Lock()
_open_helpers: set[int] = set()
_installed: list[int] = []
_exiting = False


def _on_signal(signum: int, frame: FrameType | None) -> None:
    global _exiting
    if _exiting:  # a second signal: end at once, as without the helper
        signal.signal(signum, signal.SIG_DFL)
        os.kill(os.getpid(), signum)
        return
    _exiting = True
    raise SystemExit(128 + signum)


def _install_signals(owner: int) -> None:
    global _exiting
    with _signal_lock:
        _open_helpers.add(owner)
        if threading.current_thread() is not threading.main_thread():
            return
        for s in SIGNALS:
            if s in _installed:
                continue
            with contextlib.suppress(OSError, ValueError):
                if signal.getsignal(s) is signal.SIG_DFL:  # the script's own handler stays
                    signal.signal(s, _on_signal)
                    _installed.append(s)
                    _exiting = False


def _release_signals(owner: int) -> None:
    with _signal_lock:
        _open_helpers.discard(owner)
        if _open_helpers or threading.current_thread() is not threading.main_thread():
            return
        for s in list(_installed):
            with contextlib.suppress(OSError, ValueError, TypeError):
                if signal.getsignal(s) is _on_signal:
                    signal.signal(s, signal.SIG_DFL)
            _installed.remove(s)


class TactileBelt(contextlib.AbstractContextManager["TactileBelt"]):
    """A belt for a PsychoPy window, shaped like a Builder component (module doc).

    Args:
        win: the PsychoPy window (``psychopy.visual.Window``): anything with
            ``callOnFlip(function, *args)`` and ``close()``.
        belt: a belt URL (``sim``, ``serial:auto``, ``ble:NAME``, ...), or a belt opened
            already (the helper then closes it at the end too).
        law, falloff_deg, period_s, transit_s: the stimulus parameters
            (docs/stimuli.md); per stimulus, :meth:`present` takes ``mode``.
        duration_s: default presentation time (None: until :meth:`stop`).
        layout: the belt's layout when opening a URL (default: the belt's own).
        calibration: a motor calibration (``tactorbelt calibrate``), when opening a URL.
        name: the component's name, the prefix of the data columns (:meth:`add_data`).
        clock: the clock the belt is played on (default: ``time.perf_counter``).
        timebase: the clock of every time the helper reports: a clock with
            ``getTime()`` or a function giving seconds. Default: PsychoPy's, the one
            ``win.flip()`` returns, when PsychoPy is loaded and no ``clock`` is given;
            else ``clock``'s.

    Attributes:
        onset_s, tStart: the onset of the last stimulus started (the belt was asked to
            start, right after the flip; on a shaped belt its pre-roll later,
            ``Belt.preroll_ns``), seconds on the timebase; None before the first and
            after a start that failed.
        tStartRefresh: the time of the flip that started it (``win.timeOnFlip``; None
            with a window that lacks it).
        tStop: when it stopped (:meth:`stop`, or its duration ran out), or None.
        status: ``NOT_STARTED``, ``STARTED`` (playing) or ``FINISHED``, PsychoPy's
            constants; settable, as Builder scripts reset it each routine.
        error: the exception of the last start that failed at a flip, else None.
        belt: the open belt.
    """

    def __init__(self, win: Any, belt: str | Belt = "sim", *, law: str = "paper",
                 falloff_deg: float = 15.0, period_s: float = 1.0, transit_s: float = 0.1,
                 duration_s: float | None = None, layout: Layout | None = None,
                 calibration: Any = None, name: str = "belt", clock: Clock | None = None,
                 timebase: Any = None) -> None:
        from ..devices import open_belt
        from ..devices.base import Belt
        from ..geometry import Layout
        from ..player import Player
        from ..stimuli import make_stimulus

        # every argument is checked before the belt is opened
        if not (callable(getattr(win, "callOnFlip", None))
                and callable(getattr(win, "close", None))):
            raise ConfigError(f"win must be a PsychoPy window (callOnFlip, close), got {win!r}")
        self.duration_s = _duration(duration_s, "duration_s")
        if not isinstance(name, str) or not name.strip():
            raise ConfigError(f"name must be a non-empty string, got {name!r}")
        if clock is not None and not isinstance(clock, Clock):
            raise ConfigError(f"clock must be a Clock (now_ns, sleep_until_ns), got {clock!r}")
        self._timebase: Callable[[], float] | None
        if timebase is not None:
            self._timebase = _timebase(timebase)
        else:
            self._timebase = _psychopy_time() if clock is None else None
        if not isinstance(belt, str | Belt):
            raise ConfigError(f"belt must be a belt URL or an open Belt, got {belt!r}")
        if not isinstance(belt, str) and (layout is not None or calibration is not None):
            raise ConfigError("layout and calibration apply when the helper opens a belt URL; "
                              "give them to open_belt for a belt opened already")
        if layout is not None and not isinstance(layout, Layout):
            raise ConfigError(f"layout must be a Layout, got {type(layout).__name__}")
        # a bad law, falloff, period or transit fails here, before the belt opens
        make_stimulus(Layout.even(6), 0.0, "dynamic", law, falloff_deg, period_s, transit_s)

        self.win = win
        self.name = name
        self.clock: Clock = clock if clock is not None else WallClock()
        if isinstance(belt, str):
            opts: dict[str, Any] = {"clock": self.clock}
            if layout is not None:
                opts["layout"] = layout
            if calibration is not None:
                opts["calibration"] = calibration
            self.belt: Belt = open_belt(belt, **opts)
        else:
            self.belt = belt
        self._make = make_stimulus
        self._stimuli: dict[tuple[float, str], Stimulus] = {}
        self.law, self.falloff_deg = law, falloff_deg
        self.period_s, self.transit_s = period_s, transit_s
        try:
            self.stimulus(0.0, "dynamic")  # on the belt's own layout
        except BaseException:
            self.belt.close()
            raise
        self.player = Player(self.belt, self.clock)
        self.onset_s: float | None = None
        self.tStart: float | None = None
        self.tStartRefresh: float | None = None
        self.tStop: float | None = None
        self.tStopRefresh: float | None = None
        self.error: BaseException | None = None
        self._status = NOT_STARTED
        self._presented: tuple[Stimulus, float | None] | None = None
        self._offset_s = 0.0  # timebase - clock at the last onset
        self._lock = threading.RLock()
        self._closed = False
        self._window_close: Callable[..., Any] | None = win.close
        win.close = self._close_window  # motors off when the window closes
        atexit.register(self.close)  # core.quit() ends with sys.exit
        _install_signals(id(self))

    # -- time ------------------------------------------------------------------------------
    def now(self) -> float:
        """The time now on the timebase (PsychoPy's clock), seconds."""
        if self._timebase is None:
            return self.clock.now_ns() / 1e9
        return self._timebase()

    def _offset(self) -> float:
        """Timebase minus the belt's clock, seconds, read now."""
        if self._timebase is None:
            return 0.0
        a = self.clock.now_ns()
        t = self._timebase()
        b = self.clock.now_ns()
        return t - (a + b) / 2e9

    # -- stimuli ---------------------------------------------------------------------------
    def stimulus(self, target_deg: float, mode: str = "static") -> Stimulus:
        """The stimulus for a direction (made once per direction and mode)."""
        key = (_angle(target_deg), mode)
        if key not in self._stimuli:
            self._stimuli[key] = self._make(self.belt.layout, key[0], mode, self.law,
                                            self.falloff_deg, self.period_s, self.transit_s)
        return self._stimuli[key]

    def present(self, target_deg: float, mode: str = "static",
                duration_s: float | None = None) -> None:
        """Start the stimulus for ``target_deg`` (degrees, 0 = navel, clockwise) right
        after the next ``win.flip()``, for ``duration_s`` (default: the helper's; None:
        until :meth:`stop`). A stimulus still playing then is replaced.

        Raises:
            ConfigError: a bad angle, mode or duration (at once, not at the flip).
            TactorbeltError: the helper is closed.
        """
        self._check_open()
        stim = self.stimulus(target_deg, mode)
        d = self.duration_s if duration_s is None else _duration(duration_s, "duration_s")
        time_on_flip = getattr(self.win, "timeOnFlip", None)
        if callable(time_on_flip):
            time_on_flip(self, "tStartRefresh")
        self._on_flip(self._start, stim, d)

    def stop_on_flip(self) -> None:
        """Turn the motors off right after the next ``win.flip()``."""
        time_on_flip = getattr(self.win, "timeOnFlip", None)
        if callable(time_on_flip) and self._status == STARTED:
            time_on_flip(self, "tStopRefresh")
        self._on_flip(self.stop)

    def _on_flip(self, function: Callable[..., None], *args: Any) -> None:
        """``win.callOnFlip(function, *args)``, run once whatever happens.

        PsychoPy removes a flip's calls from its queue only after all of them returned:
        one that raises stays queued, with those before it, and runs (and raises) again
        at every later flip. Here the call runs once; when it raises, the calls of this
        flip that have run already leave the queue, and the error comes out of this flip.
        """
        done = False

        def call() -> None:
            nonlocal done
            if done:
                return
            done = True
            try:
                function(*args)
            except BaseException:
                self._dequeue(call)
                raise

        self.win.callOnFlip(call)

    def _dequeue(self, call: Callable[[], None]) -> None:
        """Remove ``call`` and the calls queued before it from the window's queue
        (PsychoPy's ``Window._toCall``: dicts with ``function``; the stand-in's tuples)."""
        queue = getattr(self.win, "_toCall", None)
        if not isinstance(queue, list):
            return
        for i, item in enumerate(queue):
            f = item.get("function") if isinstance(item, dict) else (
                item[0] if isinstance(item, tuple) and item else None)
            if f is call:
                del queue[:i + 1]
                return

    def _start(self, stimulus: Stimulus, duration_s: float | None) -> None:
        with self._lock:
            if self._closed:
                return
            try:
                onset = self.player.start(stimulus, duration_s=duration_s)
            except BaseException as exc:  # the player turned the motors off
                self.error = exc
                self._presented = None
                self.onset_s = self.tStart = self.tStartRefresh = self.tStop = None
                self._status = FINISHED
                raise
            self._offset_s = self._offset()
            self.onset_s = self.tStart = onset / 1e9 + self._offset_s
            self.tStop = self.tStopRefresh = None
            self.error = None
            self._presented = (stimulus, duration_s)
            self._status = STARTED

    def stop(self) -> None:
        """Turn the motors off now."""
        with self._lock:
            self._update_status()
            self._stop()
            if self._status == STARTED:
                self.tStop = self.now()
                self._status = FINISHED

    def _stop(self) -> None:
        with contextlib.suppress(Exception):
            if self.player.playing:
                self.player.stop()
        with contextlib.suppress(Exception):
            self.belt.stop()

    @property
    def playing(self) -> bool:
        """True while a stimulus plays."""
        return self.player.playing

    def _update_status(self) -> None:
        if self._status == STARTED and not self.player.playing:
            self._status = FINISHED
            if self.tStop is None and self.tStart is not None and self._presented:
                d = self._presented[1]
                self.tStop = None if d is None else self.tStart + d

    @property
    def status(self) -> int:
        """``NOT_STARTED``, ``STARTED`` or ``FINISHED`` (PsychoPy's constants)."""
        self._update_status()
        return self._status

    @status.setter
    def status(self, value: int) -> None:
        self._status = value

    def device_onset_s(self, timeout_s: float = 0.1) -> float | None:
        """The device-true onset of the last stimulus (seconds on the timebase; with the
        pre-roll of a shaped belt, ``Player.device_onset``), or None when the belt cannot
        tell (``Belt.reports_onsets``)."""
        got = self.player.device_onset(timeout_s)
        return None if got is None else got[0] / 1e9 + self._offset_s

    def add_data(self, exp: Any) -> None:
        """Add the last stimulus's columns to the current row of ``exp`` (PsychoPy's
        ``ExperimentHandler`` or ``TrialHandler``: anything with ``addData``), named
        after :attr:`name`: ``.started`` (``tStart``), ``.startedRefresh``
        (``tStartRefresh``), ``.stopped`` (``tStop``), ``.target_deg``, ``.mode``,
        ``.duration_s`` and, where the belt reports onsets, ``.device_started``."""
        stim, d = self._presented if self._presented is not None else (None, None)
        self._update_status()
        p = self.name
        exp.addData(f"{p}.started", self.tStart)
        exp.addData(f"{p}.startedRefresh", self.tStartRefresh)
        exp.addData(f"{p}.stopped", self.tStop)
        exp.addData(f"{p}.target_deg", None if stim is None else stim.target_deg)
        exp.addData(f"{p}.mode", None if stim is None else stim.mode)
        exp.addData(f"{p}.duration_s", d)
        if self.belt.reports_onsets:
            exp.addData(f"{p}.device_started",
                        None if stim is None else self.device_onset_s())

    # -- the end ---------------------------------------------------------------------------
    def _check_open(self) -> None:
        if self._closed:
            raise TactorbeltError("the belt is closed (after win.close() or close())")

    def close(self) -> None:
        """Motors off and close the belt (again: nothing). Runs at interpreter exit."""
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._stop()
            with contextlib.suppress(Exception):
                self.belt.close()
            if self._status == STARTED:
                self.tStop = self.now()
                self._status = FINISHED
        atexit.unregister(self.close)
        _release_signals(id(self))

    def _close_window(self, *args: Any, **kwargs: Any) -> Any:
        self.close()
        close = self._window_close
        if close is None:
            return None
        return close(*args, **kwargs)

    def __exit__(self, *exc: object) -> None:
        self.close()
