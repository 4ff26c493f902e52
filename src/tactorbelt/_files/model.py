"""A user's TOML file read through a pydantic model; an error names the file and the field.

A file's model (:class:`FileModel`: no unknown keys) declares its keys; a check with a
wording of its own raises ValueError in a validator, and ``"@sub@ message"`` puts the
message on ``sub`` below where the validator runs (``"@index@ ..."`` on a row's
``index``, ``"@[2]@ ..."`` on item 2 of a list). :func:`parse` validates a parsed
document and turns the first error into ``ConfigError("FILE: field: message")``
(``cal.toml: tactor[2].start: must be in [0, 1], got 1.5``); an unknown key says
``unknown key; allowed: ...``, a missing one what ``missing`` says of it.

Used by the motor calibration (:mod:`tactorbelt.devices.calibration`) and the wearer
profile (:mod:`tactorbelt.wearer.file`) when they read a file (pydantic is not imported
with them). Imports pydantic, the standard library and tactorbelt._errors.
"""

from __future__ import annotations

import math
import typing
from collections.abc import Callable, Mapping, Sequence
from typing import Any, TypeVar

from pydantic import BaseModel, BeforeValidator, ConfigDict, ValidationError

from .._errors import ConfigError

__all__ = ["FileModel", "checked", "is_number", "number", "parse"]

M = TypeVar("M", bound=BaseModel)


class FileModel(BaseModel):
    """A table of a file: no unknown keys; types are checked by the validators."""

    model_config = ConfigDict(extra="forbid", frozen=True)


def is_number(v: Any) -> bool:
    """A finite int or float (not a bool)."""
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def checked(check: Callable[[Any], Any]) -> BeforeValidator:
    """A validator running ``check(value)`` (which returns the value or raises)."""
    return BeforeValidator(check)


def number(low: float, high: float, *, low_open: bool = False,
           kind: str = "a finite number", unit: str = "") -> BeforeValidator:
    """A finite number in [low, high] (``low_open``: (low, high]), as a float; errors
    ``must be {kind}, got ...`` and ``must be in [low, high]{unit}, got ...``."""
    interval = f"{'(' if low_open else '['}{low:g}, {high:g}]{unit}"

    def check(v: Any) -> float:
        if not is_number(v):
            raise ValueError(f"must be {kind}, got {v!r}")
        if not (low < v <= high if low_open else low <= v <= high):
            raise ValueError(f"must be in {interval}, got {v!r}")
        return float(v)

    return BeforeValidator(check)


def parse(model: type[M], doc: Mapping[str, Any], source: str,
          missing: Mapping[str, str] | None = None) -> M:
    """``doc`` validated by ``model``; the first error as ConfigError naming ``source``
    and the field (see the module docstring)."""
    try:
        return model.model_validate(doc)
    except ValidationError as exc:
        raise _error(model, exc, source, missing or {}) from None


def _where(loc: Sequence[str | int]) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else part)
    return out


def _keys(model: type[BaseModel], loc: Sequence[str | int]) -> list[str]:
    """The keys of the table at ``loc`` below ``model``."""
    tp: Any = model
    for part in loc:
        if isinstance(part, str):
            tp = tp.model_fields[part].annotation
        while typing.get_origin(tp) is not None:  # list[Row], Row | None, Annotated[...]
            tp = next(a for a in typing.get_args(tp)
                      if (isinstance(a, type) and issubclass(a, BaseModel))
                      or typing.get_origin(a) is not None)
    return sorted(f.alias or name for name, f in tp.model_fields.items())


def _error(model: type[BaseModel], exc: ValidationError, source: str,
           missing: Mapping[str, str]) -> ConfigError:
    errors = exc.errors()
    e = next((x for x in errors if x["type"] == "extra_forbidden"), errors[0])
    loc = list(e["loc"])
    if e["type"] == "extra_forbidden":
        message = f"unknown key; allowed: {', '.join(_keys(model, loc[:-1]))}"
    elif e["type"] == "missing":
        message = missing.get(str(loc[-1]), "missing")
    else:
        message = str(e["msg"]).removeprefix("Value error, ")
    where = _where(loc)
    if message.startswith("@"):
        sub, _, message = message[1:].partition("@ ")
        where += sub if sub.startswith("[") or not where else f".{sub}"
    return ConfigError(f"{source}: {where}: {message}")
