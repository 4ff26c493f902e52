"""The names of the amplitude laws, importable without NumPy (for option lists).

A new law is a name here and its function in :data:`tactorbelt.laws.LAW_FUNCTIONS`
(docs/architecture.md, "Adding things"). Imports only the standard library.
"""

from __future__ import annotations

from typing import Final, Literal, get_args

__all__ = ["LAWS", "LawName"]

#: An amplitude law's name (docs/conventions.md, "Amplitude laws").
LawName = Literal["paper", "linear", "energy"]
#: Every law's name, the default first.
LAWS: Final[tuple[str, ...]] = get_args(LawName)
