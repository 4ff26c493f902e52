"""Haptic patterns: the ``tactorbelt.pattern/1`` format, import from AHAP, Meta Haptics
Studio ``.haptic`` and bHaptics ``.tact``, export to CSV, multichannel WAV and AHAP, a
figure, and playback on any belt (docs/patterns.md).

- :mod:`.model`: :class:`Pattern`, :class:`Event`, reading and writing the format, and
  :class:`PatternFileError` (file, field, reason); the JSON Schema is ``schema.json``
  beside it (:func:`schema`);
- :mod:`.render`: :class:`PatternPlayback`, a pattern on a belt's layout (what the Player
  streams);
- :mod:`.ahap`, :mod:`.haptic`, :mod:`.tact`: the formats of other tools;
- :mod:`.io`: read any of them, export; :mod:`.show`: the PNG; :mod:`.play`: playback.

Layer: beside ``display`` (above the devices and the player, which ``play`` uses); the
model, the renderer and the formats are pure. Importing this package imports nothing
heavy; the names below are loaded on first use.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from .._registry import lazy_attributes

__all__ = ["FORMAT", "Event", "Pattern", "PatternFileError", "PatternPlayback", "export_pattern",
           "play_pattern", "read_any", "save_pattern", "schema", "show_pattern"]

_WHERE = {"FORMAT": ".model", "Event": ".model", "Pattern": ".model",
          "PatternFileError": ".model", "save_pattern": ".model",
          "PatternPlayback": ".render", "export_pattern": ".io", "read_any": ".io",
          "show_pattern": ".show", "play_pattern": ".play"}


def schema() -> dict[str, Any]:
    """The JSON Schema of ``tactorbelt.pattern/1`` (``schema.json`` in this package)."""
    doc: dict[str, Any] = json.loads((Path(__file__).parent / "schema.json").read_text())
    return doc


__getattr__ = lazy_attributes(__name__, _WHERE)
