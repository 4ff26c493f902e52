"""tactorbelt: directions between the motors of a vibrotactile belt.

Public API (re-exported here; the rest lives in the modules named below):

- geometry: :class:`Layout`, :class:`TargetSet`, :func:`wrap`, :func:`normalize`
- laws: :func:`amplitudes`
- stimuli: :class:`Stimulus`, :func:`make_stimulus`
- devices: :func:`open_belt`, :class:`Belt`
- errors: :class:`TactorbeltError` and its subclasses

Heavy parts (devices, analysis, the window) are imported only when used.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ._errors import (
    ConfigError,
    DeviceError,
    ProtocolError,
    StoreError,
    StudyFileError,
    TactorbeltError,
)
from ._registry import lazy_attributes

if TYPE_CHECKING:
    from .devices import Belt, open_belt
    from .geometry import Layout, TargetSet, normalize, wrap
    from .laws import amplitudes
    from .stimuli import Stimulus, make_stimulus

__version__ = "0.1.0"

__all__ = [
    "Belt",
    "ConfigError",
    "DeviceError",
    "Layout",
    "ProtocolError",
    "Stimulus",
    "StoreError",
    "StudyFileError",
    "TactorbeltError",
    "TargetSet",
    "__version__",
    "amplitudes",
    "make_stimulus",
    "normalize",
    "open_belt",
    "wrap",
]

_LAZY = {
    "Belt": "tactorbelt.devices",
    "open_belt": "tactorbelt.devices",
    "Layout": "tactorbelt.geometry",
    "TargetSet": "tactorbelt.geometry",
    "normalize": "tactorbelt.geometry",
    "wrap": "tactorbelt.geometry",
    "amplitudes": "tactorbelt.laws",
    "Stimulus": "tactorbelt.stimuli",
    "make_stimulus": "tactorbelt.stimuli",
}


__getattr__ = lazy_attributes(__name__, _LAZY)


def __dir__() -> list[str]:
    return sorted(__all__)
