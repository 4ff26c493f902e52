"""The direction display for applications: keep a bearing shown on a belt as it changes.

- :mod:`.direction`: :class:`DirectionDisplay` (a render thread on the one deadline loop,
  static or dynamic rendering, smooth moves between bearings);
- :mod:`.filters`: heading filters (One Euro, hysteresis) and their measured lag;
- :mod:`.heading`: heading readers, replay and sweep for ``tactorbelt point``.

``from tactorbelt.display import DirectionDisplay`` is the public entry (docs/direction-display.md).
"""

from __future__ import annotations

from .direction import DirectionDisplay

__all__ = ["DirectionDisplay"]
