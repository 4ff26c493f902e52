"""``pattern play``: a pattern on any belt, streamed by the Player on its deadlines.

Imports the devices, the player and the pattern modules (I/O).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ..devices import open_belt_for
from ..player import Player, PlayerStats
from .io import require_events
from .model import Pattern
from .render import PatternPlayback

if TYPE_CHECKING:
    from ..devices.base import Belt
    from ..devices.calibration import Calibration

__all__ = ["PatternPlay", "play_pattern"]


@dataclass(frozen=True)
class PatternPlay:
    """What one playback did: the belt's description, the law, the rate, the timing."""

    belt: str
    law: str
    rate_hz: float
    stats: PlayerStats


def play_pattern(pattern: Pattern, belt_url: str, *, law: str | None = None,
                 falloff_deg: float = 15.0, rate_hz: float | None = None,
                 calibration: Calibration | None = None, calibration_file: str | None = None,
                 source: str | None = None,
                 started: Callable[[Belt, PatternPlayback, Player], None] | None = None
                 ) -> PatternPlay:
    """Play ``pattern`` once on the belt at ``belt_url`` (motors off on every exit path).

    The pattern is placed on the belt's own layout (its angles and paths with ``law``) and
    streamed at ``rate_hz`` (default: the belt's rate), frame i due at onset + i/rate.
    ``started(belt, playback, player)`` is called just before it starts (to say what plays).

    Raises:
        PatternFileError: an empty pattern. ConfigError, DeviceError: from the belt.
    """
    require_events(pattern, source)
    belt, _ = open_belt_for(belt_url, None, calibration=calibration,
                            calibration_file=calibration_file)
    with belt:
        playback = PatternPlayback(pattern, belt.layout, law, falloff_deg, source=source)
        player = Player(belt, rate_hz=rate_hz, device_render=False)
        if started is not None:
            started(belt, playback, player)
        with player:
            stats = player.play(playback, pattern.duration_s)  # type: ignore[arg-type]
        return PatternPlay(f"{belt.name} ({belt.url}, {belt.n_tactors} tactors)",
                           playback.law, player.rate_hz, stats)
