"""What several commands share on the terminal: a belt's one-line description, single key
presses from a terminal (or characters from piped input), a counting progress bar.

Imports click only.
"""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Callable, Iterator
from typing import TYPE_CHECKING

import click

if TYPE_CHECKING:
    from ..devices.base import Belt

__all__ = ["Keys", "counting_progress", "describe_belt"]


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


@contextlib.contextmanager
def counting_progress(label: str) -> Iterator[Callable[[int, int], None]]:
    """A rich progress bar counting done of total, on stderr when it is a terminal
    (nothing shown otherwise); yields ``progress(done, total)``."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TimeElapsedColumn

    console = Console(stderr=True)
    with Progress("[progress.description]{task.description}", BarColumn(),
                  MofNCompleteColumn(), TimeElapsedColumn(), console=console,
                  disable=not console.is_terminal) as bar:
        task = bar.add_task(label, total=None)

        def progress(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        yield progress
