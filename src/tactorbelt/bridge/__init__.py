"""The browser bridge: ``tactorbelt serve`` (docs/browser.md).

A local WebSocket server that lets a browser page (the jsPsych plugins in ``web/``,
served from ``static/``) play stimuli on a belt, with onsets on the page's clock, and
store each trial in the same store ``tactorbelt run`` writes. :func:`serve` runs it;
:class:`BridgeConfig` says what it serves.

The modules: :mod:`.server` (the WebSocket door, the pages and their sessions,
heartbeats, signals), :mod:`.messages` (parsing a page's messages, the clock handshake;
pure), :mod:`.http` (the static files and ``/study.json``), :mod:`.belt` (the belt on one
thread). Sessions and trials are stored through the runner's session seam
(:class:`tactorbelt.experiment.recorder.SessionRecorder`).

Imports nothing at import time beyond this docstring's names (lazily).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._registry import lazy_attributes

if TYPE_CHECKING:
    from .server import DEFAULT_PORT, BridgeConfig, serve

__all__ = ["DEFAULT_PORT", "BridgeConfig", "serve"]

__getattr__ = lazy_attributes(__name__, dict.fromkeys(__all__, ".server"))
