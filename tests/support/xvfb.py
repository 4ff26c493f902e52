"""A private X server for tests that open real windows (PsychoPy's ``visual.Window``).

    from support.xvfb import Xvfb, XvfbError

    with Xvfb() as display:              # ":3": Xvfb chose a free display number
        env = {**os.environ, "DISPLAY": display}
        subprocess.run([...], env=env)   # the window opens there (Mesa's llvmpipe)

Xvfb picks the display number itself (``-displayfd``: the first one with no lock file
and no socket), so tests running at the same time, other engineers' servers and a
desktop's ``:0`` never clash. It starts within ``start_timeout_s`` or raises
:class:`XvfbError`; leaving the ``with`` block ends it (SIGTERM, then SIGKILL after
``stop_timeout_s``), only that process. ``Xvfb.available()`` says whether the binary is
installed (skip with a reason when it is not).

The server has no window manager and no vertical blank: a window's ``flip()`` returns as
soon as Mesa has drawn the frame (a few hundred microseconds), not at 60 Hz.
"""

from __future__ import annotations

import contextlib
import os
import select
import shutil
import signal
import subprocess
import tempfile
import time
from types import TracebackType

__all__ = ["Xvfb", "XvfbError"]


class XvfbError(RuntimeError):
    """Xvfb did not start (its stderr is in the message)."""


class Xvfb:
    """An Xvfb server for the duration of a ``with`` block (module doc).

    Args:
        size: the screen's width, height and depth.
        start_timeout_s: how long the server may take to accept connections.
        stop_timeout_s: how long it may take to end on SIGTERM before SIGKILL.
    """

    def __init__(self, size: tuple[int, int, int] = (1024, 768, 24), *,
                 start_timeout_s: float = 20.0, stop_timeout_s: float = 5.0) -> None:
        self.size = size
        self.start_timeout_s = start_timeout_s
        self.stop_timeout_s = stop_timeout_s
        self.display: str | None = None
        self._proc: subprocess.Popen[bytes] | None = None
        self._log_path: str | None = None

    @staticmethod
    def available() -> bool:
        """True when the ``Xvfb`` binary is on PATH."""
        return shutil.which("Xvfb") is not None

    def start(self) -> str:
        """Start the server; returns its display (``":N"``)."""
        exe = shutil.which("Xvfb")
        if exe is None:
            raise XvfbError("Xvfb is not installed (apt-get install xvfb)")
        w, h, depth = self.size
        read_fd, write_fd = os.pipe()
        log_fd, self._log_path = tempfile.mkstemp(prefix="xvfb-", suffix=".log")
        try:
            self._proc = subprocess.Popen(
                [exe, "-displayfd", str(write_fd), "-screen", "0", f"{w}x{h}x{depth}",
                 "-nolisten", "tcp", "-noreset"],
                pass_fds=(write_fd,), stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                stderr=log_fd, start_new_session=True)
        finally:
            os.close(write_fd)
            os.close(log_fd)
        try:
            number = self._read_display(read_fd)
        except BaseException:
            os.close(read_fd)
            self.stop()
            raise
        os.close(read_fd)
        self.display = f":{number}"
        return self.display

    def _read_display(self, fd: int) -> int:
        """The display number Xvfb writes to ``-displayfd`` when it is ready."""
        assert self._proc is not None
        deadline = time.monotonic() + self.start_timeout_s
        got = b""
        while not got.endswith(b"\n"):
            left = deadline - time.monotonic()
            if left <= 0:
                raise XvfbError(f"Xvfb did not start within {self.start_timeout_s:g} s"
                                f"{self._log()}")
            ready, _, _ = select.select([fd], [], [], min(left, 0.2))
            if ready:
                chunk = os.read(fd, 64)
                if not chunk:  # the server closed the pipe: it exited
                    break
                got += chunk
            elif self._proc.poll() is not None:
                break
        if not got.strip().isdigit():
            raise XvfbError(f"Xvfb exited (status {self._proc.poll()}) before it was ready"
                            f"{self._log()}")
        return int(got.strip())

    def _log(self) -> str:
        if self._log_path is None:
            return ""
        with open(self._log_path, "rb") as f:
            text = f.read().decode(errors="replace").strip()
        return f": {text[-2000:]}" if text else ""

    def stop(self) -> None:
        """End the server (again: nothing)."""
        proc, self._proc = self._proc, None
        if proc is not None and proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(self.stop_timeout_s)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(self.stop_timeout_s)
        if self._log_path is not None:
            with contextlib.suppress(OSError):
                os.unlink(self._log_path)
            self._log_path = None
        self.display = None

    def __enter__(self) -> str:
        return self.start()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.stop()
