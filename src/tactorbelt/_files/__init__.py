"""A user's files (the motor calibration, the wearer profile): their text and TOML read
with errors in their words; :mod:`.model` reads a document through a pydantic model.

Imports the standard library and tactorbelt._errors.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from .._errors import ConfigError

__all__ = ["read_toml", "read_user_text"]


def read_user_text(path: str | Path, what: str) -> str:
    """The UTF-8 text of ``path``.

    Raises:
        ConfigError: ``<what> 'path' not found``, ``... is a directory``, ``path: not a
            text (UTF-8) <what>``, or ``cannot read <what> 'path': reason``.
    """
    p = Path(path)
    try:
        return p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"{what} {str(p)!r} not found") from None
    except IsADirectoryError:
        raise ConfigError(f"{what} {str(p)!r} is a directory") from None
    except UnicodeDecodeError:
        raise ConfigError(f"{p}: not a text (UTF-8) {what}") from None
    except OSError as exc:
        raise ConfigError(f"cannot read {what} {str(p)!r}: {exc.strerror}") from None


def read_toml(text: str, source: str) -> dict[str, Any]:
    """The TOML document ``text``; ConfigError ``{source}: not valid TOML: ...``."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{source}: not valid TOML: {exc}") from None
