"""Whether the experiment window can be shown, asked before anything heavy is imported:
``tactorbelt run`` without a display fails at once (:func:`check_display`), not after
loading the study, the store and the runner.

Imports the standard library and tactorbelt._errors only.
"""

from __future__ import annotations

import os
import sys

from .._errors import ConfigError

__all__ = ["check_display", "has_display"]


def has_display(environ: dict[str, str] | None = None, platform: str = sys.platform) -> bool:
    """Whether a window can be shown: an explicit ``SDL_VIDEODRIVER`` (tests use
    ``dummy``), or on Linux and the BSDs ``DISPLAY`` or ``WAYLAND_DISPLAY``."""
    env = os.environ if environ is None else environ
    if env.get("SDL_VIDEODRIVER"):
        return True
    if platform.startswith(("linux", "freebsd", "openbsd", "netbsd")):
        return bool(env.get("DISPLAY") or env.get("WAYLAND_DISPLAY"))
    return True


def check_display(window: bool) -> None:
    """ConfigError when a run with the ``window`` has no display to show it on."""
    if window and not has_display():
        raise ConfigError("no display (DISPLAY and WAYLAND_DISPLAY are not set) for the "
                          "experiment window; use --headless with --input model or scripted")
