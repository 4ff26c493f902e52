"""The exception hierarchy of tactorbelt.

    TactorbeltError            base of every error tactorbelt raises on purpose
     +-- ConfigError           a bad argument or value (angle, rate, layout, law, ...)
     +-- StudyFileError        a study file that cannot be used (file, line, field)
     +-- StoreError            a session store that cannot be opened or written
     +-- DeviceError           a belt that cannot be reached or stopped answering
          +-- ProtocolError    bytes on the wire that break protocol v1

The command line prints ``error: <message>`` and exits 2 for every error but
``DeviceError`` (and its subclasses), which exit 3.

Imports nothing from tactorbelt.
"""

from __future__ import annotations

__all__ = [
    "ConfigError",
    "DeviceError",
    "ProtocolError",
    "StoreError",
    "StudyFileError",
    "TactorbeltError",
]


class TactorbeltError(Exception):
    """Base class of every error tactorbelt raises on purpose."""


class ConfigError(TactorbeltError, ValueError):
    """A bad argument or value: the message says what is wrong and what is allowed."""


class StudyFileError(TactorbeltError):
    """A study file that cannot be used.

    Args:
        message: what is wrong and what is allowed.
        path: the study file, when known.
        line: 1-based line in the file, when known.
        field: dotted name of the field, when known (``stimulus.falloff_deg``).
    """

    def __init__(
        self,
        message: str,
        *,
        path: str | None = None,
        line: int | None = None,
        field: str | None = None,
    ) -> None:
        self.path = path
        self.line = line
        self.field = field
        self.reason = message
        where = ""
        if path is not None:
            where = str(path)
            if line is not None:
                where += f":{line}"
            where += ": "
        if field:
            where += f"{field}: "
        super().__init__(where + message)


class StoreError(TactorbeltError):
    """A session store (SQLite file) that cannot be opened, read or written."""


class DeviceError(TactorbeltError):
    """A belt that cannot be opened, or that stopped answering. Names the port."""


class ProtocolError(DeviceError):
    """Bytes that break protocol v1 (bad CRC, framing, length or version)."""
