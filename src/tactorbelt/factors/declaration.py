"""A study factor's declaration: :class:`Factor` (the registry is :mod:`tactorbelt.factors`)."""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

from .._errors import ConfigError
from .._registry import check_option

__all__ = ["Changes", "Factor"]

#: What a factor changes in a session.
Changes = Literal["stimulus", "targets", "task", "nothing"]

_NAME = re.compile(r"^[a-z][a-z0-9_]{0,31}$")


@dataclass(frozen=True)
class Factor:
    """One study factor.

    Attributes:
        key: its key in ``[design]`` (a list of levels) and in a ``[[test]]`` block (one level).
        column: the scheduled trial's field, the stored and exported column, and the
            model's variable.
        type: ``text`` or ``int``: how a level is written in a study file and stored.
        description: one sentence, for codebooks and sidecars.
        levels: the allowed levels and what each means (empty: any value of ``type``).
        default: the level of a block that does not name the factor, of a training
            trial, and of a trial stored before the factor was declared.
        term: its term in the mixed model's formula (``factor(n_targets)`` models a
            count as categories); empty: the column itself.
        changes: what it changes in a session: the ``stimulus`` (condition), the
            ``targets`` (target count), the secondary ``task`` (load), or ``nothing``
            (recorded and analysed only).
        name_rank: where its level goes in a ``[design]`` block's name (lower first).
        cross_rank: where it goes when ``[design]`` crosses the factors (lower is
            slower: the target counts are the outer loop).
        block_name: its part of a ``[design]`` block's name (None: the level itself).
        measure: its measurement level in the tidy export's codebook.
        max_levels: how many levels ``[design]`` may cross.
        low, high: the range of an ``int`` factor's levels (None: unbounded).
    """

    key: str
    column: str
    type: Literal["text", "int"]
    description: str
    levels: Mapping[str, str] = field(default_factory=dict)
    default: Any = None
    term: str = ""
    changes: Changes = "nothing"
    name_rank: int = 99
    cross_rank: int = 99
    block_name: Callable[[Any], str] | None = None
    measure: str = "nominal"
    max_levels: int = 26
    low: int | None = None
    high: int | None = None

    def __post_init__(self) -> None:
        for what, name in (("key", self.key), ("column", self.column)):
            if not _NAME.match(name):
                raise ConfigError(f"factor {what} {name!r}: a lower-case letter, then "
                                  "letters, digits or _ (at most 32)")
        if self.type not in ("text", "int"):
            raise ConfigError(f"factor {self.key!r}: type is 'text' or 'int', not {self.type!r}")
        if self.default is not None:
            self.check(self.default)

    @property
    def model_term(self) -> str:
        """Its term in the mixed model's formula."""
        return self.term or self.column

    def check(self, level: Any) -> Any:
        """``level`` if it is one of this factor's; ValueError saying what is allowed."""
        if self.type == "int":
            lo = -(2**31) if self.low is None else self.low
            hi = 2**31 - 1 if self.high is None else self.high
            if isinstance(level, bool) or not isinstance(level, int) or not lo <= level <= hi:
                raise ValueError(f"a {self.key} level is a whole number from {lo} to {hi} "
                                 f"(got {level!r})")
        elif not isinstance(level, str) or not level:
            raise ValueError(f"a {self.key} level is a non-empty string (got {level!r})")
        if self.levels:
            check_option(self.key, str(level), self.levels, ValueError)
        return level

    def check_levels(self, levels: Sequence[Any]) -> list[Any]:
        """A ``[design]`` list of levels, checked: at least one, each once, each allowed."""
        if not isinstance(levels, list) or not levels:
            raise ValueError(f"design.{self.key} is a list of at least one level")
        if len(levels) > self.max_levels:
            raise ValueError(f"design.{self.key}: at most {self.max_levels} levels")
        for v in levels:
            self.check(v)
        if len(set(levels)) != len(levels):
            raise ValueError(f"each value at most once (got {levels!r})")
        return list(levels)

    def name_part(self, level: Any) -> str:
        """This factor's part of a ``[design]`` block's name ("" for none)."""
        return str(level) if self.block_name is None else self.block_name(level)

    def stored(self, level: Any) -> Any:
        """A level as stored (None stays None; the default stands for a missing one)."""
        return self.default if level is None else level
