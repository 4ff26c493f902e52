"""Read any pattern file (AHAP, ``.haptic``, ``.tact``, ``tactorbelt.pattern/1``) and write
the exports (CSV, multichannel WAV, AHAP).

The kind of a file is its extension (``.ahap``, ``.haptic``, ``.tact``, ``.json``), or,
for another extension, what its JSON holds (``Pattern``, ``signals``, ``project``,
``format``).

Imports the standard library, NumPy and the pattern modules (pure + files).
"""

from __future__ import annotations

import wave
from pathlib import Path
from typing import Any, Final

import numpy as np

from .._errors import ConfigError
from .._registry import check_option
from ..geometry import Layout
from .ahap import pattern_from_ahap, write_ahap
from .haptic import pattern_from_haptic
from .model import Pattern, PatternFileError, pattern_from_dict, read_json
from .render import DEFAULT_RATE_HZ, PatternPlayback, render_pattern
from .tact import pattern_from_tact

__all__ = ["EXPORT_FORMATS", "IMPORT_FORMATS", "export_pattern", "pattern_layout",
           "read_any", "require_events"]

#: The file kinds ``read_any`` takes, by extension.
IMPORT_FORMATS: Final = {".ahap": "ahap", ".haptic": "haptic", ".tact": "tact",
                         ".json": "tactorbelt"}
#: What ``export_pattern`` writes.
EXPORT_FORMATS: Final = ("wav", "csv", "ahap")
#: The WAV export's sample rate and carrier unless told otherwise.
WAV_RATE_HZ: Final = 48000
CARRIER_HZ: Final = 250.0


def _kind(path: Path, doc: Any) -> str:
    kind = IMPORT_FORMATS.get(path.suffix.lower())
    if kind is not None:
        return kind
    if isinstance(doc, dict):
        for key, k in (("format", "tactorbelt"), ("Pattern", "ahap"), ("signals", "haptic"),
                       ("project", "tact")):
            if key in doc:
                return k
    raise PatternFileError("not a pattern file this tactorbelt reads (AHAP .ahap, Meta "
                           "Haptics Studio .haptic, bHaptics .tact, tactorbelt .json)",
                           path=str(path))


def read_any(path: str | Path, angle_deg: float = 0.0) -> Pattern:
    """Read a pattern file of any kind tactorbelt knows; AHAP and ``.haptic`` are placed at
    ``angle_deg`` (they have no place on the body), ``.tact`` keeps its layout's places.

    Raises:
        PatternFileError: unreadable, of an unknown kind, or invalid (file, field, reason).
    """
    p = Path(path)
    doc = read_json(p)
    kind = _kind(p, doc)
    if kind == "ahap":
        return pattern_from_ahap(doc, str(p), angle_deg % 360.0)
    if kind == "haptic":
        return pattern_from_haptic(doc, str(p), angle_deg % 360.0)
    if kind == "tact":
        return pattern_from_tact(doc, str(p))
    return pattern_from_dict(doc, str(p))


def require_events(pattern: Pattern, source: str | None) -> None:
    """Refuse a pattern with nothing in it (there is nothing to play, export or draw)."""
    if not pattern.events:
        raise PatternFileError("the pattern has no events: nothing to play, export or draw",
                               path=source, field="events")


def pattern_layout(pattern: Pattern, layout: Layout | None) -> Layout:
    """The layout an export renders on: the one asked for, else the pattern's own places
    (``.tact``), else the default 6-tactor belt."""
    if layout is not None:
        return layout
    if len(pattern.layout_deg) >= 2:
        return Layout(pattern.layout_deg)
    return Layout.even(6)


def export_pattern(pattern: Pattern, fmt: str, out: str | Path, *, layout: Layout | None = None,
                   law: str | None = None, rate_hz: float | None = None,
                   carrier_hz: float = CARRIER_HZ, source: str | None = None) -> list[str]:
    """Write ``pattern`` as ``fmt`` (``wav``, ``csv`` or ``ahap``) to ``out``.

    - ``csv``: ``t_s,tactor_0,...`` at ``rate_hz`` (default 1000), 9 decimals, on
      ``layout`` (see :func:`pattern_layout`);
    - ``wav``: one channel per tactor, 16-bit PCM at ``rate_hz`` (default 48000): each
      tactor's amplitude times a sine carrier of ``carrier_hz`` (0: the amplitude
      itself, for drivers that take a level), for Syntacts and audio belts;
    - ``ahap``: one actuator, every event with its intensity, envelope and sharpness.

    Returns:
        What the export could not carry (said on the terminal).

    Raises:
        PatternFileError: an empty pattern. ConfigError: a bad format, rate or carrier.
    """
    require_events(pattern, source)
    check_option("export format", fmt, EXPORT_FORMATS)
    if fmt == "ahap":
        return write_ahap(pattern, out)
    playback = PatternPlayback(pattern, pattern_layout(pattern, layout), law, source=source)
    if fmt == "csv":
        rate = DEFAULT_RATE_HZ if rate_hz is None else float(rate_hz)
        t, amps = render_pattern(playback, rate)
        header = "t_s," + ",".join(f"tactor_{k}" for k in range(amps.shape[1]))
        np.savetxt(out, np.column_stack([t, amps]), delimiter=",", fmt="%.9f", header=header,
                   comments="")
        return []
    rate = WAV_RATE_HZ if rate_hz is None else int(rate_hz)
    if not 1000 <= rate <= 768_000:
        raise ConfigError(f"WAV sample rate must be in 1000..768000 Hz, got {rate_hz!r}")
    if not 0.0 <= carrier_hz < rate / 2:
        raise ConfigError(f"carrier must be in [0, {rate / 2:g}) Hz (below half the sample "
                          f"rate), got {carrier_hz!r}")
    write_wav(playback, out, rate, carrier_hz)
    return []


def write_wav(playback: PatternPlayback, out: str | Path, rate: int, carrier_hz: float) -> None:
    """Render ``playback`` to a 16-bit multichannel WAV, a block at a time."""
    n = round(playback.duration_s * rate)
    block = rate  # one second at a time
    with wave.open(str(out), "wb") as w:
        w.setnchannels(playback.layout.n)
        w.setsampwidth(2)
        w.setframerate(rate)
        for i0 in range(0, n, block):
            i = np.arange(i0, min(n, i0 + block), dtype=np.int64)
            t = i / rate
            amps = playback.amplitudes(t)
            if carrier_hz > 0:
                amps = amps * np.sin(2.0 * np.pi * carrier_hz * t)[:, None]
            pcm = np.round(np.clip(amps, -1.0, 1.0) * 32767.0).astype("<i2")
            w.writeframes(pcm.tobytes())
