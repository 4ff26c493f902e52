"""Belts by hand: one tactor at a time (``belt-test``) and the calibration walk-through.

- :class:`ConstantFrame`: a constant frame played like a stimulus; :class:`SingleTactor`:
  one with one tactor on.
- :func:`pulse_each`: pulse each tactor in turn (a wiring check).
- :func:`walk_calibration`: for each tactor, let the experimenter raise the level until
  it is just felt (its start level), then to a comfortable maximum (its ceiling); keys
  come from a callable, so a terminal, a pipe or a test can drive it.

Imports NumPy, the player and the calibration types.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, cast

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..geometry import Layout

if TYPE_CHECKING:
    from ..clock import Clock
    from ..devices.base import Belt
    from ..devices.calibration import Calibration
    from ..stimuli import Stimulus

__all__ = ["KEYS_HELP", "CalibrationQuit", "ConstantFrame", "SingleTactor", "pulse_each",
           "walk_calibration"]

KEYS_HELP = ("keys: + / - = up / down by one step, ] / [ = five steps, enter = accept, "
             "q = quit without saving")
_MOVES = {"+": 1, "=": 1, "-": -1, "_": -1, "]": 5, "[": -5}


class CalibrationQuit(Exception):
    """The experimenter quit the calibration (``q``); nothing was written."""


class ConstantFrame:
    """A constant frame (one amplitude per tactor): what the player needs of a stimulus
    (``layout`` and ``amplitudes(t)``), nothing it renders on a device."""

    def __init__(self, layout: Layout, frame: NDArray[np.float64]) -> None:
        self.layout = layout
        self.frame = frame

    def amplitudes(self, t: ArrayLike) -> NDArray[np.float64]:
        """The frame at each time in ``t`` (shape ``(*t.shape, n)``)."""
        ta = np.asarray(t, dtype=float)
        return np.broadcast_to(self.frame, (*ta.shape, self.frame.shape[0])).copy()

    def as_stimulus(self) -> Stimulus:
        """For :class:`~tactorbelt.player.Player` (it reads ``layout`` and ``amplitudes``)."""
        return cast("Stimulus", self)


class SingleTactor(ConstantFrame):
    """One tactor on at a constant level.

    Args:
        layout: the belt's layout.
        tactor: the tactor's index.
        level: its amplitude in [0, 1] (through the belt's calibration).
    """

    def __init__(self, layout: Layout, tactor: int, level: float) -> None:
        if not 0 <= tactor < layout.n:
            raise IndexError(f"tactor {tactor} is not on a {layout.n}-tactor belt")
        super().__init__(layout, np.zeros(layout.n))
        self.tactor = tactor
        self.level = float(level)
        self.frame[tactor] = self.level


def pulse_each(belt: Belt, clock: Clock, *, seconds_each: float, gap: float, level: float,
               say: Callable[[int, float], None]) -> None:
    """Pulse each tactor in turn for ``seconds_each`` with ``gap`` seconds between;
    ``say(k, angle_deg)`` before each. The frames are streamed (never device-rendered)."""
    from ..player import Player

    player = Player(belt, clock=clock, device_render=False)
    for k, angle in enumerate(belt.tactor_angles_deg):
        say(k, angle)
        player.play(SingleTactor(belt.layout, k, level).as_stimulus(), seconds_each)
        if gap > 0 and k + 1 < belt.n_tactors:
            clock.sleep_until_ns(clock.now_ns() + round(gap * 1e9))


def _adjust(read_key: Callable[[], str], show: Callable[[float], None], level: float,
            step: float, lo: float) -> float:
    """Move ``level`` within [lo, 1] with the keys until enter; return it."""
    show(level)
    while True:
        ch = read_key()
        if ch in ("\r", "\n"):
            return level
        if ch in ("q", "Q"):
            raise CalibrationQuit("calibration abandoned; nothing was written")
        if ch in _MOVES:
            level = round(min(1.0, max(lo, level + _MOVES[ch] * step)), 6)
            show(level)


def walk_calibration(belt: Belt, clock: Clock, read_key: Callable[[], str], step: float,
                     say: Callable[[str], None],
                     region: Callable[[float], str] = lambda a: f"{a:g} deg") -> Calibration:
    """Walk through each tactor of ``belt``; return the calibration (motors off after
    each tactor). ``say`` gets each prompt; ``region(angle)`` names a tactor's place.
    On a simulated clock the levels are set directly; on a real one they are streamed
    (a hardware belt's heartbeat needs frames).

    Raises:
        CalibrationQuit: the experimenter pressed ``q``.
    """
    from ..devices.calibration import Calibration, TactorCalibration
    from ..player import Player

    player = None if clock.simulated else Player(belt, clock=clock, device_render=False)
    rows: list[TactorCalibration] = []
    for k, angle in enumerate(belt.tactor_angles_deg):
        show = _shower(belt, player, k, say)
        say(f"tactor {k} at {angle:g} deg ({region(angle)}): raise the level until you "
            "just feel it, then press enter")
        start = _adjust(read_key, show, 0.0, step, 0.0)
        say(f"tactor {k}: now raise it to a comfortable maximum, then press enter")
        ceiling = max(_adjust(read_key, show, max(start, step), step, start), start)
        if player is not None:
            player.stop()
        belt.stop()
        rows.append(TactorCalibration(start=start, gain=1.0, ceiling=ceiling))
        say(f"tactor {k}: start {start:.2f}, ceiling {ceiling:.2f}")
    return Calibration(tuple(rows))


def _shower(belt: Belt, player: Any, k: int, say: Callable[[str], None]
            ) -> Callable[[float], None]:
    def show(level: float) -> None:
        one = SingleTactor(belt.layout, k, level)
        if player is None:
            belt.set_amplitudes(one.frame)
        elif level <= 0:
            player.stop()
        elif player.playing:
            player.switch(one.as_stimulus())
        else:
            player.start(one.as_stimulus())
        say(f"  tactor {k}: level {level:.2f}")
    return show

