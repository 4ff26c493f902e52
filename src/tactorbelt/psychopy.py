"""Drive a belt from a PsychoPy experiment, in step with the screen (docs/psychopy.md).

A component-like helper: open the belt once, then ask for a stimulus on the next flip::

    from psychopy import core, visual
    from tactorbelt.psychopy import TactileBelt

    win = visual.Window()
    belt = TactileBelt(win, "serial:auto")        # opened once; motors off at the end
    belt.present(45.0, "dynamic")                 # starts on the next win.flip()
    win.flip()                                    # the stimulus starts right after it
    thisExp.addData("belt.started", belt.onset_s)
    ...
    belt.stop_on_flip(); win.flip()               # ends with the next frame
    core.quit()                                   # motors off (atexit)

:meth:`TactileBelt.present` schedules the start with ``win.callOnFlip``, which PsychoPy
calls immediately after the buffer swap of the next ``win.flip()``, so the stimulus
onset is locked to the frame that shows the visual stimulus (to the time the flip
returns, within a few hundred microseconds, plus the belt's own latency; the onset time
is in :attr:`TactileBelt.onset_s`). Motors go off:

- at ``core.quit()`` and any other interpreter exit (PsychoPy's ``core.quit`` ends with
  ``sys.exit``; the helper registers an ``atexit`` handler), and on an exception that
  ends the script;
- when the window is closed with ``win.close()`` (the helper wraps that method of the
  window it was given), even mid-stimulus;
- on :meth:`TactileBelt.stop`, :meth:`TactileBelt.close`, or leaving ``with``.

It uses only two calls of PsychoPy's API (``win.callOnFlip`` and ``win.close``) and
imports no PsychoPy module, so it runs with any PsychoPy version that has them (all
since 1.8x), and in tests against a stand-in window.

I/O edge: opens a belt (tactorbelt.devices) and plays stimuli (tactorbelt.player).
"""

from __future__ import annotations

import atexit
import contextlib
import threading
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from ._errors import TactorbeltError
from .clock import Clock, WallClock

if TYPE_CHECKING:
    from .devices.base import Belt
    from .geometry import Layout
    from .stimuli import Stimulus

__all__ = ["TactileBelt"]


class TactileBelt:
    """A belt for a PsychoPy window (module doc).

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
        clock: the clock of the onsets (default: the wall clock, ``time.perf_counter``,
            the clock of PsychoPy's ``core.getTime()`` on Linux and Windows without
            Psychtoolbox).

    Attributes:
        onset_s: the onset of the last stimulus started, seconds on ``clock`` (None
            before the first); where the belt reports device-true onsets (firmware 1.1),
            :meth:`device_onset_s` gives the device's.
        belt: the open belt.
    """

    def __init__(self, win: Any, belt: str | Belt = "sim", *, law: str = "paper",
                 falloff_deg: float = 15.0, period_s: float = 1.0, transit_s: float = 0.1,
                 duration_s: float | None = None, layout: Layout | None = None,
                 calibration: Any = None, clock: Clock | None = None) -> None:
        from .devices import open_belt
        from .player import Player
        from .stimuli import make_stimulus

        self.win = win
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
            # a bad law or falloff fails here, at setup, not at the first flip
            self.stimulus(0.0, "dynamic")
        except BaseException:
            self.belt.close()
            raise
        self.duration_s = duration_s
        self.player = Player(self.belt, self.clock)
        self.onset_s: float | None = None
        self._lock = threading.Lock()
        self._closed = False
        self._window_close: Callable[..., Any] | None = win.close
        win.close = self._close_window  # motors off when the window closes
        atexit.register(self.close)  # core.quit() ends with sys.exit

    # -- stimuli ---------------------------------------------------------------------------
    def stimulus(self, target_deg: float, mode: str = "static") -> Stimulus:
        """The stimulus for a direction (made once per direction and mode)."""
        key = (float(target_deg), mode)
        if key not in self._stimuli:
            self._stimuli[key] = self._make(self.belt.layout, float(target_deg), mode,
                                            self.law, self.falloff_deg, self.period_s,
                                            self.transit_s)
        return self._stimuli[key]

    def present(self, target_deg: float, mode: str = "static",
                duration_s: float | None = None) -> None:
        """Start the stimulus for ``target_deg`` (degrees, 0 = navel, clockwise) right
        after the next ``win.flip()``, for ``duration_s`` (default: the helper's; None:
        until :meth:`stop`). A stimulus still playing then is replaced.

        Raises:
            ConfigError: a bad angle or mode (at once, not at the flip).
            TactorbeltError: the helper is closed.
        """
        self._check_open()
        stim = self.stimulus(target_deg, mode)
        d = self.duration_s if duration_s is None else duration_s
        self.win.callOnFlip(self._start, stim, d)

    def stop_on_flip(self) -> None:
        """Turn the motors off right after the next ``win.flip()``."""
        self.win.callOnFlip(self.stop)

    def _start(self, stimulus: Stimulus, duration_s: float | None) -> None:
        with self._lock:
            if self._closed:
                return
            onset = self.player.start(stimulus, duration_s=duration_s)
            self.onset_s = onset / 1e9

    def stop(self) -> None:
        """Turn the motors off now."""
        with self._lock:
            self._stop()

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

    def device_onset_s(self, timeout_s: float = 0.1) -> float | None:
        """The device-true onset of the last stimulus (seconds on the wall clock), or
        None when the belt cannot tell (``Belt.reports_onsets``)."""
        got = self.belt.last_onset(timeout_s) if self.belt.reports_onsets else None
        return None if got is None else got[0] / 1e9

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
        atexit.unregister(self.close)

    def _close_window(self, *args: Any, **kwargs: Any) -> Any:
        self.close()
        close = self._window_close
        if close is None:
            return None
        return close(*args, **kwargs)

    def __enter__(self) -> TactileBelt:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
