"""What the commands that drive a belt by hand share: a belt's one-line description,
and single key presses from a terminal (or characters from piped input).

Imports click only.
"""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING

import click

if TYPE_CHECKING:
    from ..devices.base import Belt

__all__ = ["Keys", "describe_belt"]


def describe_belt(belt: Belt) -> str:
    """``name (url, N tactors)``."""
    return f"{belt.name} ({belt.url}, {belt.n_tactors} tactors)"


class Keys:
    """Single key presses from a terminal, or characters from piped input."""

    def __init__(self) -> None:
        self._stdin = sys.stdin
        self._tty = self._stdin.isatty()
        self._last = ""

    def read(self) -> str:
        while True:
            ch = click.getchar() if self._tty else self._stdin.read(1)
            if ch == "":
                raise click.UsageError("input ended before the calibration was finished; "
                                       "nothing was written")
            prev, self._last = self._last, ch
            if ch == "\n" and prev == "\r":  # a CR LF pair is one enter
                continue
            return ch
