"""Parameter types and option classes behind the shared options of ``_options.py``.

- :class:`Number`: a finite float (``FLOAT``) or a whole number (``INTEGER``) with an
  optional range; every bad value gets the same wording, e.g. ``Invalid value for
  '--seconds': must be more than 0, got '-1'.``
- :class:`AliasOption`: an option with old spellings that still work but are not shown
  in ``--help`` (``--out`` for ``-o/--output``).
- :class:`AngleCommand`: a command whose ANGLE argument may be negative
  (``tactorbelt play -30``) without ``--``.
- :class:`HiddenArgument`: a positional argument kept for old scripts, left out of the
  usage line.

Imports click only.
"""

from __future__ import annotations

import math
import re
from typing import Any

import click

__all__ = ["AliasOption", "AngleCommand", "HiddenArgument", "Number"]


def _fmt(v: float) -> str:
    return "2^63 - 1" if v == 2**63 - 1 else f"{v:g}"


class Number(click.ParamType):
    """A finite number: ``Number(float, lo, hi, lo_open, hi_open)`` or ``Number(int, ...)``."""

    def __init__(self, kind: type = float, lo: float | None = None, hi: float | None = None,
                 lo_open: bool = False, hi_open: bool = False) -> None:
        self.kind = kind
        self.name = "integer" if kind is int else "float"
        self.lo, self.hi, self.lo_open, self.hi_open = lo, hi, lo_open, hi_open

    def get_metavar(self, param: click.Parameter, *args: Any, **kwargs: Any) -> str:
        return self.name.upper()

    def describe(self) -> str:
        """The range in words (``more than 0``, ``in [0, 1)``), or ``""``."""
        lo, hi = self.lo, self.hi
        if lo is not None and hi is not None:
            return (f"in {'(' if self.lo_open else '['}{_fmt(lo)}, {_fmt(hi)}"
                    f"{')' if self.hi_open else ']'}")
        if lo is not None:
            return f"{'more than' if self.lo_open else 'at least'} {_fmt(lo)}"
        if hi is not None:
            return f"{'less than' if self.hi_open else 'at most'} {_fmt(hi)}"
        return ""

    def convert(self, value: Any, param: click.Parameter | None,
                ctx: click.Context | None) -> Any:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            number = value
        else:
            text = str(value).strip()
            try:
                number = float(text)
            except ValueError:
                self.fail(f"must be a {'whole ' if self.kind is int else ''}number, "
                          f"got {value!r}", param, ctx)
        if not math.isfinite(number):
            self.fail(f"must be a finite number, got {value!r}", param, ctx)
        if self.kind is int:
            if number != int(number):
                self.fail(f"must be a whole number, got {value!r}", param, ctx)
            number = int(number)
        lo, hi = self.lo, self.hi
        if ((lo is not None and (number < lo or (self.lo_open and number == lo)))
                or (hi is not None and (number > hi or (self.hi_open and number == hi)))):
            self.fail(f"must be {self.describe()}, got {value!r}", param, ctx)
        return self.kind(number)


class AliasOption(click.Option):
    """An option whose ``hidden_aliases`` are accepted but not shown in ``--help``."""

    def __init__(self, *args: Any, hidden_aliases: tuple[str, ...] = (), **kwargs: Any) -> None:
        decls = list(args[0]) if args else list(kwargs.pop("param_decls", []))
        super().__init__([*decls, *hidden_aliases], *args[1:], **kwargs)
        self.hidden_aliases = tuple(hidden_aliases)

    def get_error_hint(self, ctx: click.Context | None) -> str:
        return " / ".join(f"'{o}'" for o in self.opts if o not in self.hidden_aliases)

    def get_help_record(self, ctx: click.Context) -> tuple[str, str] | None:
        shown = self.opts
        self.opts = [o for o in shown if o not in self.hidden_aliases]
        try:
            return super().get_help_record(ctx)
        finally:
            self.opts = shown


class HiddenArgument(click.Argument):
    """A positional argument left out of the usage line (kept for old command lines)."""

    def get_usage_pieces(self, ctx: click.Context) -> list[str]:
        return []


_NEGATIVE = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


class AngleCommand(click.Command):
    """A command whose positional ANGLE may be a negative number (``-30``).

    click would read ``-30`` as an unknown option; this class moves a bare negative
    number that is not an option's value behind ``--`` before parsing.
    """

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        if "--" not in args:
            takes_value: set[str] = set()
            for param in self.params:
                if isinstance(param, click.Option) and not param.is_flag and not param.count:
                    takes_value.update(param.opts)
                    takes_value.update(param.secondary_opts)
            rest: list[str] = []
            moved: list[str] = []
            skip = False
            for token in args:
                if skip:
                    rest.append(token)
                    skip = False
                elif token in takes_value:
                    rest.append(token)
                    skip = True
                elif _NEGATIVE.match(token):
                    moved.append(token)
                else:
                    rest.append(token)
            if moved:
                args = [*rest, "--", *moved]
        return super().parse_args(ctx, args)
