"""A sim belt that writes down every command it receives, and can be unplugged.

    from support.recordingbelt import RecordingBelt, read_commands

    belt = RecordingBelt("/tmp/belt.log")     # a SimBelt (6 tactors, wall clock)
    ...                                       # play, stop: one line each in the file
    belt.unplugged = True                     # play and frames now raise DeviceError
    read_commands("/tmp/belt.log")            # [("play", 45.0), ("stop", None), ...]

The file is written line by line (each line reaches the file when it is written), so a
test reads what the belt received after the process that drove it has ended, however
it ended: the last command tells whether the motors were left on (``play`` or
``levels`` with a level above 0) or turned off (``stop``).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np

from tactorbelt import DeviceError
from tactorbelt.devices.sim import SimBelt

__all__ = ["RecordingBelt", "motors_on_at_end", "read_commands"]


class RecordingBelt(SimBelt):
    """A :class:`SimBelt` logging its commands to ``path`` (module doc)."""

    def __init__(self, path: str | os.PathLike[str], **options: Any) -> None:
        super().__init__(url="sim", **options)
        self._log = open(path, "a", buffering=1, encoding="utf-8")  # noqa: SIM115
        #: While True, ``play`` and frames raise DeviceError, as from a belt whose
        #: cable was pulled (``stop`` still works, so the test can clean up).
        self.unplugged = False

    def _check_plugged(self) -> None:
        if self.unplugged:
            raise DeviceError("belt 'sim' does not answer (unplugged)")

    def _write_levels(self, levels: Any) -> None:
        self._check_plugged()
        super()._write_levels(levels)
        self._log.write(f"levels {float(np.max(levels)):.6f}\n")

    def _write_play(self, stimulus: Any, duration_s: float | None) -> None:
        self._check_plugged()
        super()._write_play(stimulus, duration_s)
        self._log.write(f"play {stimulus.target_deg} {duration_s}\n")

    def _write_stop(self) -> None:
        super()._write_stop()
        self._log.write("stop\n")

    def _close(self) -> None:
        super()._close()
        self._log.write("closed\n")
        self._log.close()


def read_commands(path: str | os.PathLike[str]) -> list[tuple[str, float | None]]:
    """The commands in a RecordingBelt's file: (``play``, target), (``levels``, highest
    level), (``stop``, None), (``closed``, None)."""
    out: list[tuple[str, float | None]] = []
    for line in Path(path).read_text(encoding="utf-8").splitlines():
        word, *rest = line.split()
        out.append((word, float(rest[0]) if rest else None))
    return out


def motors_on_at_end(commands: list[tuple[str, float | None]]) -> bool:
    """True when the last command that drives the motors left them on."""
    for word, value in reversed(commands):
        if word == "stop":
            return False
        if word == "play":
            return True
        if word == "levels":
            return bool(value)
    return False
