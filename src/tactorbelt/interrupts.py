"""Termination signals as an exception, so every command ends them like Ctrl-C.

:func:`terminate_on_signals` makes SIGTERM and SIGHUP raise :class:`Terminated` in the
main thread. It derives from BaseException (as KeyboardInterrupt does): ``except
Exception`` does not swallow it, and every ``finally`` and context manager on the way
out runs (motors off, the trial in flight stored ``aborted``). The command line exits
with ``128 + signal number`` (143 for SIGTERM, 129 for SIGHUP).

Imports only the standard library.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from types import FrameType

__all__ = ["Terminated", "terminate_on_signals"]

#: The signals :func:`terminate_on_signals` turns into :class:`Terminated`.
SIGNALS = tuple(s for s in (getattr(signal, "SIGTERM", None), getattr(signal, "SIGHUP", None))
                if s is not None)


class Terminated(BaseException):
    """The process was asked to end by a signal (SIGTERM, SIGHUP).

    Attributes:
        signum: the signal's number.
        name: its name (``SIGTERM``).
        exit_code: ``128 + signum``.
    """

    def __init__(self, signum: int) -> None:
        self.signum = int(signum)
        self.name = signal.Signals(self.signum).name
        self.exit_code = 128 + self.signum
        super().__init__(f"terminated by {self.name}")


def _raise(signum: int, frame: FrameType | None) -> None:
    raise Terminated(signum)


@contextlib.contextmanager
def terminate_on_signals() -> Iterator[None]:
    """Within the block, SIGTERM and SIGHUP raise :class:`Terminated` (main thread only;
    elsewhere this does nothing). The previous handlers come back after the block."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {}
    for s in SIGNALS:
        with contextlib.suppress(OSError, ValueError):
            old[s] = signal.signal(s, _raise)
    try:
        yield
    finally:
        for s, h in old.items():
            with contextlib.suppress(OSError, ValueError, TypeError):
                signal.signal(s, h)
