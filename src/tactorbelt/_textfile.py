"""Reading a user's text file (calibration, wearer profile) with errors in their words."""

from __future__ import annotations

from pathlib import Path

from ._errors import ConfigError

__all__ = ["read_user_text"]


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
