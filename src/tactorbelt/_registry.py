"""One registry helper for every registry of tactorbelt (belts, sensors, task kinds,
stores, commands, input kinds): entries by name, imported only when used.

- :func:`resolve` imports ``"module:attr"`` (:func:`pkgutil.resolve_name`)::

      opener = resolve("tactorbelt.devices.sim:open_sim")

- :func:`check_option` raises the one "unknown X" error::

      check_option("law", law, LAWS)   # ConfigError: unknown law 'x'; allowed: a, b, c

- :class:`Registry` holds typed entries by name; :meth:`Registry.get` checks the name::

      KINDS: Registry[InputKind] = Registry("input kind", [InputKind("keyboard", ...)])
      KINDS.get("mouse")               # ConfigError: unknown input kind 'mouse'; allowed: ...

  Entries are any objects with a ``name`` attribute.
- :func:`parse_url` splits ``scheme:target?key=value&...`` for belts and sensors alike:
  the entry's :class:`UrlOption` s type and range-check the options::

      entry, target, options = parse_url(url, BACKENDS, "belt URL")

- :func:`lazy_attributes` is a package's module-level ``__getattr__`` (PEP 562)::

      __getattr__ = lazy_attributes(__name__, {"Belt": ".base", "open_belt": ".registry"})

Imports only the standard library and tactorbelt._errors.
"""

from __future__ import annotations

import importlib
import math
import pkgutil
from collections.abc import Callable, Iterable, Iterator, Mapping
from dataclasses import dataclass
from typing import Any, Generic, Protocol, TypeVar

from ._errors import ConfigError

__all__ = ["Registry", "UrlEntry", "UrlOption", "check_option", "lazy_attributes",
           "parse_url", "resolve"]

T = TypeVar("T")
E = TypeVar("E", bound="UrlEntry")


def resolve(spec: str) -> Any:
    """The object ``"package.module:attr"`` names, its module imported now."""
    return pkgutil.resolve_name(spec)


def check_option(what: str, value: object, allowed: Iterable[object],
                 error: type[Exception] = ConfigError) -> None:
    """Raise ConfigError (or ``error``) ``unknown {what} {value!r}; allowed: a, b, c``
    unless ``value`` is one of ``allowed``."""
    allowed = list(allowed)
    if value not in allowed:
        raise error(f"unknown {what} {value!r}; allowed: "
                          f"{', '.join(str(a) for a in allowed) or 'none'}")


class Registry(Generic[T]):
    """Entries of one kind by name, in the order registered (a read-only mapping).

    Args:
        what: what an entry is, for the error (``"input kind"``).
        entries: the entries, each named by its ``name`` attribute.
    """

    def __init__(self, what: str, entries: Iterable[T]) -> None:
        self.what = what
        self._entries: dict[str, T] = {}
        for entry in entries:
            name = str(entry.name)  # type: ignore[attr-defined]
            if name in self._entries:
                raise ValueError(f"{what} {name!r} registered twice")
            self._entries[name] = entry

    def get(self, name: str) -> T:
        """The entry ``name``; ConfigError naming the allowed ones when there is none."""
        check_option(self.what, name, self._entries)
        return self._entries[name]

    def __getitem__(self, name: str) -> T:
        return self._entries[name]

    def __contains__(self, name: object) -> bool:
        return name in self._entries

    def __iter__(self) -> Iterator[str]:
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def names(self) -> tuple[str, ...]:
        return tuple(self._entries)

    def values(self) -> Iterable[T]:
        return self._entries.values()


@dataclass(frozen=True)
class UrlOption:
    """One ``?key=value`` option of a URL.

    Attributes:
        name: the key, also the keyword passed to the opener (``timeout_s``).
        kind: ``int``, ``float``, ``bool`` or ``str``.
        help: one line for the help text.
        low, high: the allowed range of a number (inclusive), or None.
    """

    name: str
    kind: type
    help: str
    low: float | None = None
    high: float | None = None

    def parse(self, text: str, url: str, noun: str) -> Any:
        """The value of ``key=text``, checked. Raises ConfigError naming the URL."""
        what = f"option {self.name!r} of {noun} {url!r}"
        if self.kind is bool:
            t = text.strip().lower()
            if t in ("1", "true", "yes", "on"):
                return True
            if t in ("0", "false", "no", "off"):
                return False
            raise ConfigError(f"{what} must be true or false, got {text!r}")
        if self.kind is str:
            return text
        try:
            value: float = int(text) if self.kind is int else float(text)
        except ValueError:
            kind = "an integer" if self.kind is int else "a number"
            raise ConfigError(f"{what} must be {kind}, got {text!r}") from None
        if not math.isfinite(value) or (self.low is not None and value < self.low) or (
                self.high is not None and value > self.high):
            raise ConfigError(f"{what} must be in {self.low:g}..{self.high:g}, got {text!r}"
                              if self.low is not None and self.high is not None
                              else f"{what} is out of range: {text!r}")
        return value


class UrlEntry(Protocol):
    """What :func:`parse_url` reads of a registry entry."""

    @property
    def scheme(self) -> str: ...
    @property
    def target(self) -> str: ...  # "PORT" when the URL needs one, "" when not
    @property
    def options(self) -> tuple[UrlOption, ...]: ...
    @property
    def examples(self) -> tuple[str, ...]: ...


def parse_url(url: str, entries: Mapping[str, E], noun: str, *,
              allowed: Iterable[str] | None = None, example: Callable[[E], str] | None = None,
              target_word: str = "target", no_target: bool = False
              ) -> tuple[E, str, dict[str, Any]]:
    """Split ``scheme:target?key=value&...`` into its entry, target and typed options.

    Args:
        url: the URL.
        entries: scheme -> entry.
        noun: ``"belt URL"`` or ``"sensor URL"``, for the errors.
        allowed: the URL forms an unknown scheme's error lists (default: the schemes).
        example: the example a missing target's error gives (default: the first).
        target_word: what a missing target is called (``target``, ``device``).
        no_target: a target given to an entry that takes none is an error.

    Raises:
        ConfigError: not a string, an unknown scheme, a missing (or unwanted) target, an
            unknown or malformed option (every message names the URL).
    """
    if not isinstance(url, str) or not url.strip():
        raise ConfigError(f"{noun} must be a non-empty string, got {url!r}")
    head, _, query = url.strip().partition("?")
    scheme, _, target = head.partition(":")
    if scheme.lower() not in entries:
        check_option(noun, url, allowed if allowed is not None else entries)
    entry = entries[scheme.lower()]
    if entry.target and not target:
        eg = example(entry) if example else entry.examples[0]
        raise ConfigError(f"{noun} {url!r} needs a {target_word}, e.g. {eg}")
    if no_target and not entry.target and target:
        raise ConfigError(f"{noun} {url!r} takes no target; use {entry.scheme!r}")
    known = {o.name: o for o in entry.options}
    options: dict[str, Any] = {}
    for item in filter(None, query.split("&")):
        key, eq, value = item.partition("=")
        if not eq:
            raise ConfigError(f"{noun} {url!r}: expected key=value after '?', got {item!r}")
        opt = known.get(key.strip())
        if opt is None:
            raise ConfigError(f"unknown option {key.strip()!r} in {noun} {url!r}; "
                              f"allowed: {', '.join(known) or 'none'}")
        options[opt.name] = opt.parse(value.strip(), url, noun)
    return entry, target, options


def lazy_attributes(package: str, where: Mapping[str, str]) -> Callable[[str], Any]:
    """A module-level ``__getattr__`` (PEP 562) importing each name from its module when
    first asked for: ``where`` maps a name to its module, absolute or relative to
    ``package`` (``".base"``)."""

    def __getattr__(name: str) -> Any:
        module = where.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(module, package), name)

    return __getattr__
