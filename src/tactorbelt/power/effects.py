"""The effect a model-participant power analysis looks for (``tactorbelt power --effect``).

- ``dynamic vs static``: per-participant between-tactor accuracy over every block,
  paired Wilcoxon; found when p < alpha and dynamic is higher;
- ``dynamic vs static at N``: the same in the blocks of N targets;
- ``interaction`` (also ``resolution x condition``): whether the dynamic-minus-static
  difference in between-tactor accuracy changes with the target count: Friedman test
  over the target counts on the per-participant differences (paired Wilcoxon with two
  counts); found when p < alpha, either way;
- ``load`` (``load NAME``): per-participant between-tactor accuracy (both conditions)
  without a load vs under a load (every load, or the load NAME), paired Wilcoxon;
  found when p < alpha and accuracy under load is lower.

Pure.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass

from .._errors import ConfigError

__all__ = ["Effect", "parse_effect"]


@dataclass(frozen=True)
class Effect:
    """The effect a factorial power analysis looks for (see :func:`parse_effect`).

    Attributes:
        kind: ``condition`` (dynamic vs static), ``interaction`` or ``load``.
        n_targets: the target count of a ``condition`` effect (None: every block).
        text: how the user named it.
        load: the load of a ``load`` effect (None: every load but ``none``).
    """

    kind: str
    n_targets: int | None = None
    text: str = "dynamic vs static"
    load: str | None = None

    def describe(self) -> str:
        if self.kind == "load":
            which = "any load" if self.load is None else f"load {self.load}"
            return (f"between-tactor accuracy (static and dynamic blocks) without a load vs "
                    f"under {which} (paired Wilcoxon; found = p < alpha and lower under "
                    "load)")
        if self.kind == "interaction":
            return ("resolution x condition interaction: does the dynamic-minus-static "
                    "between-tactor accuracy change with the target count? (Friedman test "
                    "over the target counts; Wilcoxon with two)")
        where = "every block" if self.n_targets is None else f"the {self.n_targets}-target blocks"
        return (f"dynamic vs static between-tactor accuracy in {where} (paired Wilcoxon; "
                "found = p < alpha and dynamic higher)")


_CONDITION = re.compile(r"^\s*(dynamic\s+vs\.?\s+static|static\s+vs\.?\s+dynamic|condition)"
                        r"(?:\s+at\s+(\d+)(?:\s+targets)?)?\s*$", re.I)
_LOAD = re.compile(r"^\s*load(?:\s+([A-Za-z][A-Za-z0-9_\-]*))?\s*$", re.I)
_INTERACTION = re.compile(r"^\s*(interaction|resolution\s*x\s*condition|condition\s*x\s*"
                          r"resolution|targets\s*x\s*condition|condition\s*x\s*targets)\s*$", re.I)


def parse_effect(text: str | None, counts: Sequence[int],
                 loads: Sequence[str] = ("none",)) -> Effect:
    """Read ``--effect``: ``dynamic vs static``, ``dynamic vs static at 36``,
    ``interaction`` (``resolution x condition``) or ``load`` (``load NAME``).

    Raises:
        ConfigError: an effect it does not know, a target count or load the study
            lacks, an interaction in a study with one target count, or a load effect in
            a study without blocks with and without a load.
    """
    if text is None or not text.strip():
        return Effect("condition")
    m = _CONDITION.match(text)
    if m:
        n = int(m.group(2)) if m.group(2) else None
        if n is not None and n not in counts:
            raise ConfigError(f"effect {text!r}: the study has no blocks of {n} targets "
                              f"(it has {', '.join(map(str, counts))})")
        return Effect("condition", n, text.strip())
    m = _LOAD.match(text)
    if m:
        name = m.group(1)
        loaded = [lv for lv in loads if lv != "none"]
        if "none" not in loads or not loaded:
            raise ConfigError(f"effect {text!r} needs test blocks without a load and blocks "
                              f"under one; the study's loads are {', '.join(loads)}")
        if name is not None and name not in loaded:
            raise ConfigError(f"effect {text!r}: the study has no load {name!r} (it has "
                              f"{', '.join(loaded)})")
        return Effect("load", None, text.strip(), name)
    if _INTERACTION.match(text):
        if len(counts) < 2:
            raise ConfigError(f"effect {text!r} needs at least two target counts; the study "
                              f"has {', '.join(map(str, counts))}")
        return Effect("interaction", None, text.strip())
    raise ConfigError(f"unknown effect {text!r}; use 'dynamic vs static', 'dynamic vs "
                      "static at N' (N a target count of the study), 'interaction' "
                      "(resolution x condition) or 'load' ('load NAME': one load)")
