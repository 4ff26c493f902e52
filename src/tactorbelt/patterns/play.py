"""``pattern play``: a pattern on any belt, streamed by the Player on its deadlines.

Imports the devices, the player and the pattern modules (I/O).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..devices import open_belt_for
from ..player import Player, PlayerStats
from .io import require_events
from .model import Pattern, PatternFileError
from .render import PatternPlayback, render_pattern

if TYPE_CHECKING:
    from ..devices.base import Belt
    from ..devices.calibration import Calibration

__all__ = ["PatternPlay", "check_channels", "play_pattern"]


@dataclass(frozen=True)
class PatternPlay:
    """What one playback did: the belt's description, the law, the rate, the timing."""

    belt: str
    law: str
    rate_hz: float
    stats: PlayerStats


def check_channels(belt: Belt, playback: PatternPlayback, rate_hz: float,
                   source: str | None = None) -> None:
    """Refuse, before anything plays, a pattern with an instant that needs more distinct
    intensities than the belt keeps at once (its declared ``vibration_channels``).

    Raises:
        PatternFileError: naming the file, the first such instant and the belt's limit.
    """
    limit = belt.vibration_channels
    if limit is None:
        return
    t, amps = render_pattern(playback, rate_hz)
    levels = np.array([belt.calibration.apply(a) for a in amps]) if len(amps) else amps
    need = belt.channels_needed(levels)
    over = np.flatnonzero(need > limit)
    if over.size:
        i = int(over[0])
        raise PatternFileError(
            f"at {t[i] * 1000:g} ms the pattern needs {int(need[i])} different intensities at "
            f"once on {belt.name}, which shows at most {limit} (its vibration channels; "
            f"reserved: {', '.join(map(str, belt.reserved_channels)) or 'none'})",
            path=source, field="events")


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
        check_channels(belt, playback, player.rate_hz, source)
        if started is not None:
            started(belt, playback, player)
        with player:
            stats = player.play(playback, pattern.duration_s)  # type: ignore[arg-type]
        return PatternPlay(f"{belt.name} ({belt.url}, {belt.n_tactors} tactors)",
                           playback.law, player.rate_hz, stats)
