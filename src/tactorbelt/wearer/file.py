"""The file of a wearer profile (``tactorbelt-wearer-profile``, version 1) as a pydantic
model: :class:`File` (its pairs :class:`Pair`), with the messages of every check; read by
:meth:`tactorbelt.wearer.WearerProfile.from_mapping`.

Imports pydantic, tactorbelt._files.model, the law names and :mod:`.rules`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Annotated, Any

from pydantic import Field, model_validator

from .._files.model import FileModel, checked, is_number
from .._lawnames import LAWS
from .._registry import check_option
from .rules import FORMAT, VERSION, warp_problem

__all__ = ["File", "Pair"]


def _rule(ok: Any, message: str) -> Any:
    """A check of a key by ``ok(value)``, else ``message``."""
    def check(v: Any) -> Any:
        if not ok(v):
            raise ValueError(message.format(v=v))
        return v
    return checked(check)


_ABSENT = Field(default=None, validate_default=True)  # checked also when absent (None)


def _pairs(v: Any) -> Any:
    if not isinstance(v, list):
        raise ValueError("missing: add one [[pair]] table per adjacent pair")
    for k, row in enumerate(v):
        if not isinstance(row, Mapping):
            raise ValueError(f"@[{k}]@ must be a table with intended and rendered")
        if "index" in row and row["index"] != k:
            raise ValueError(f"@[{k}].index@ must be {k} (pairs in order), got "
                             f"{row['index']!r}")
    return v


class Pair(FileModel):
    index: Any = None
    tactors: Any = None
    intended: Any = []  # noqa: RUF012 - validated, never changed
    rendered: Any = []  # noqa: RUF012

    @model_validator(mode="after")
    def _warp(self) -> Pair:
        if not isinstance(self.intended, list) or not isinstance(self.rendered, list):
            raise ValueError("intended and rendered must be lists of fractions in (0, 1)")
        problem = warp_problem(self.intended, self.rendered)
        if problem:
            raise ValueError(f"@{problem[0]}@ {problem[1]}")
        return self


# the keys' types and checks (a key checked also when absent: _ABSENT)
Format = Annotated[Any, _rule(lambda v: v == FORMAT, f"must be {FORMAT!r}, got {{v!r}}"),
                   _ABSENT]
Version = Annotated[Any, _rule(lambda v: v == VERSION,
                              f"unsupported version {{v!r}}; allowed: {VERSION}"), _ABSENT]
Angles = Annotated[list[float], _rule(
    lambda v: isinstance(v, list) and len(v) >= 2 and all(map(is_number, v)),
    "must be a list of at least 2 angles (degrees)"), _ABSENT]
Gains = Annotated[list[float], _rule(lambda v: isinstance(v, list) and all(map(is_number, v)),
                                    "must be a list of numbers, one per tactor"), _ABSENT]
Law = Annotated[str, checked(lambda v: check_option("law", v, LAWS) or v)]
Falloff = Annotated[Any, _rule(lambda v: is_number(v) and v > 0,
                               "must be a positive number of degrees, got {v!r}")]
Pairs = Annotated[list[Pair], checked(_pairs), _ABSENT]


class File(FileModel):
    format: Format
    version: Version
    tactor_angles_deg: Angles
    gains: Gains
    reference_tactor: Any = 0
    law: Law = "paper"
    falloff_deg: Falloff = 15.0
    pair: Pairs
    participant: Any = ""
    belt: Any = ""
    created: Any = ""
    fit: Any = []  # noqa: RUF012

    @model_validator(mode="after")
    def _counts(self) -> File:
        n = len(self.tactor_angles_deg)
        if len(self.gains) != n:
            raise ValueError(f"@gains@ has {len(self.gains)} values for {n} tactors; give "
                             "one gain per tactor")
        for k, g in enumerate(self.gains):
            if not 0.0 < g <= 10.0:
                raise ValueError(f"@gains[{k}]@ must be in (0, 10], got {g!r}")
        ref = self.reference_tactor
        if isinstance(ref, bool) or not isinstance(ref, int) or not 0 <= ref < n:
            raise ValueError(f"@reference_tactor@ must be a tactor index in 0..{n - 1}, "
                             f"got {ref!r}")
        if len(self.pair) != n:
            raise ValueError(f"@pair@ has {len(self.pair)} tables for {n} tactors; give "
                             "one [[pair]] per adjacent pair (pair k = tactors k and k + 1)")
        for k, row in enumerate(self.pair):
            if row.tactors is not None and list(row.tactors) != [k, (k + 1) % n]:
                raise ValueError(f"@pair[{k}].tactors@ must be [{k}, {(k + 1) % n}], got "
                                 f"{row.tactors!r}")
        return self
