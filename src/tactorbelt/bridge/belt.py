"""The bridge's belt: opened, played, stopped and asked from one thread.

:class:`BeltPort` owns the belt and a :class:`~tactorbelt.player.Player` on the wall
clock, and runs every call on one worker thread (the event loop never blocks on the
belt, and the belt never sees two threads); a belt that drives nothing real (the sim
belt, ``hardware`` False) is used from the event loop's thread instead, where its calls
cost less than the hand-over to a thread and back. A play returns its :class:`Onset`: the
command time on the wall clock (``time.perf_counter_ns``, the clock the belts map
their device onsets to) and, where the belt reports it (``Belt.reports_onsets``), the
device-true onset with its uncertainty. Raw amplitudes are set at once and stopped
after their duration unless another play came first.

I/O edge: imports the devices, the player and the clock.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, TypeVar

from ..clock import WallClock
from ..devices import open_belt
from ..experiment.runner import check_layout
from ..player import Player

if TYPE_CHECKING:
    from ..devices.base import Belt
    from ..devices.calibration import Calibration
    from ..geometry import Layout
    from ..stimuli import Stimulus

__all__ = ["BeltPort", "Onset"]

T = TypeVar("T")


@dataclass(frozen=True)
class Onset:
    """When a play started.

    Attributes:
        play: the play's number (a later play replaces it).
        onset_ns: the command time (wall clock, ns): when the belt was told to start.
        device_ns: the device-true onset on the wall clock, or None (not reported).
        uncertainty_ns: how far off ``device_ns`` may be (0 without it).
        duration_s: how long it plays at most.
    """

    play: int
    onset_ns: int
    device_ns: int | None
    uncertainty_ns: int
    duration_s: float

    @property
    def best_ns(self) -> int:
        """The device onset where known, else the command time."""
        return self.device_ns if self.device_ns is not None else self.onset_ns

    @property
    def end_ns(self) -> int:
        """When it stops at the latest (its duration after the onset)."""
        return self.best_ns + round(self.duration_s * 1e9)


class BeltPort:
    """A belt used from one worker thread (see the module docstring).

    Args:
        url: the belt URL.
        layout: the study's layout (the sim belt takes it; a hardware belt must match).
        calibration: the motor calibration, or None (the belt's own).
        drive: the study's drive (``plain`` or ``shaped``), or None (the belt's).
    """

    def __init__(self, url: str, layout: Layout, calibration: Calibration | None = None,
                 drive: str | None = None) -> None:
        self.url = url
        self.layout = layout
        self.calibration_file = calibration
        self.drive = drive
        self.clock = WallClock()
        self._exec = ThreadPoolExecutor(1, thread_name_prefix="tactorbelt-belt")
        self._belt: Belt | None = None
        self._player: Player | None = None
        self._play = 0
        self._stop_handle: asyncio.TimerHandle | None = None
        self._inline = False  # set by open: calls on the event loop's thread

    # -- on the worker thread ---------------------------------------------------------------
    async def call(self, fn: Callable[..., T], *args: Any) -> T:
        """Run ``fn(*args)`` on the belt's thread (the event loop's own for a belt that
        drives nothing real: the sim belt's calls are computations that never wait, and
        two thread hand-overs fewer take the scheduler's delays out of every onset)."""
        if self._inline:
            return fn(*args)
        return await asyncio.get_running_loop().run_in_executor(self._exec, fn, *args)

    @property
    def belt(self) -> Belt:
        """The open belt (read its layout and calibration anywhere; play it through
        :meth:`call`)."""
        if self._belt is None:
            raise RuntimeError("the belt is not open")
        return self._belt

    def open(self) -> Belt:
        """Open the belt (on the worker thread: ``await port.call(port.open)``)."""
        kwargs: dict[str, Any] = {"clock": self.clock, "layout": self.layout}
        if self.calibration_file is not None:
            kwargs["calibration"] = self.calibration_file
        belt = open_belt(self.url, **kwargs)
        try:
            check_layout(self.layout, belt, "serve a study file for this belt")
            if self.drive is not None:
                belt.set_drive(self.drive)
            self._player = Player(belt, self.clock)
        except BaseException:
            belt.close()
            raise
        self._belt = belt
        return belt

    async def aopen(self) -> Belt:
        """:meth:`open` on the worker thread; a belt that drives nothing real (the sim
        belt, ``hardware`` False) is then used from the event loop's thread."""
        belt = await self.call(self.open)
        self._inline = not belt.hardware
        return belt

    def _onset(self, onset_ns: int, duration_s: float, device: tuple[int, int] | None
               ) -> Onset:
        if device is None:
            return Onset(self._play, onset_ns, None, 0, duration_s)
        return Onset(self._play, onset_ns, int(device[0]), int(device[1]), duration_s)

    def play_stimulus(self, stimulus: Stimulus, duration_s: float) -> Onset:
        """Play a stimulus for ``duration_s`` (replacing what plays)."""
        assert self._player is not None
        self._play += 1
        onset = int(self._player.start(stimulus, duration_s=duration_s))
        return self._onset(onset, duration_s, self._player.device_onset())

    def play_levels(self, amplitudes: Sequence[float], duration_s: float) -> Onset:
        """Set every tactor's amplitude (0..1) now; :meth:`stop_play` ends it."""
        assert self._player is not None
        if self._player.playing:
            self._player.stop()
        self._play += 1
        onset = int(self.clock.now_ns())
        self.belt.set_amplitudes(amplitudes)
        return self._onset(onset, duration_s, self.belt.last_onset())

    def stop(self) -> int:
        """Motors off now; the time they were turned off (wall clock, ns)."""
        try:
            if self._player is not None and self._player.playing:
                self._player.stop()  # the motors off too
                return int(self.clock.now_ns())
        except BaseException:
            self.belt.stop()
            raise
        self.belt.stop()
        return int(self.clock.now_ns())

    def stop_play(self, play: int) -> None:
        """Motors off when play number ``play`` is still the last one."""
        if play == self._play:
            self.stop()

    def playing(self, play: int) -> bool:
        """True while play number ``play`` is the last one and still plays."""
        if play != self._play or self._player is None:
            return False
        levels = self.belt.levels
        return bool(self._player.playing or (levels is not None and levels.any()))

    def status(self) -> dict[str, Any]:
        """The belt's state, as the ``status`` reply gives it."""
        belt = self.belt
        levels = belt.levels
        return {
            "url": belt.session_url,
            "name": belt.name,
            "tactors": belt.n_tactors,
            "angles_deg": list(belt.tactor_angles_deg),
            "connected": not belt.closed,
            "playing": self.playing(self._play),
            "levels": None if levels is None else [float(v) for v in levels],
            "capabilities": {
                "renders": belt.can_render(),
                "reports_onsets": belt.reports_onsets,
                "can_shape": belt.can_shape,
                "can_brake": belt.can_brake,
                "drive": belt.drive,
                "hardware": belt.hardware,
                "models_vibration": belt.models_vibration,
                "stream_rate_hz": belt.stream_rate_hz,
                "firmware_version": belt.firmware_version,
            },
        }

    def close(self) -> None:
        """Motors off and the belt released (best effort)."""
        belt, self._belt = self._belt, None
        if belt is None:
            return
        with contextlib.suppress(Exception):
            if self._player is not None and self._player.playing:
                self._player.stop()
        belt.close()

    # -- from the event loop ----------------------------------------------------------------
    def stop_later(self, onset: Onset) -> None:
        """Turn a raw-amplitude play off after its duration (unless replaced)."""
        loop = asyncio.get_running_loop()
        if self._stop_handle is not None:
            self._stop_handle.cancel()
        self._stop_handle = loop.call_later(
            onset.duration_s, lambda: loop.create_task(self.call(self.stop_play, onset.play)))

    async def aclose(self) -> None:
        """:meth:`close` on the worker thread, then end the thread."""
        if self._stop_handle is not None:
            self._stop_handle.cancel()
        try:
            await self.call(self.close)
        finally:
            self._exec.shutdown(wait=False)

    def close_now(self) -> None:
        """:meth:`close` from any thread (the last resort on the way out)."""
        with contextlib.suppress(Exception):
            self.close()
