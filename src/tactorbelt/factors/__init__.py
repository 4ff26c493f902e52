"""The study factors, each declared once.

A :class:`Factor` says what a factor is called in a study file (its ``[design]`` key and
its ``[[test]]`` block key), the column it is stored, exported and modelled under, its
type and levels, the level of a block (or an old store) that does not name it, its
term in the mixed model, and what it changes in a session. Everything that handles
factors reads these declarations: the study file's ``[design]`` and ``[[test]]``
blocks, the schedule, both stores, the exports (CSV, Parquet, tidy, BIDS, PsychoPy),
the LSL markers, the cells of the analysis, the mixed model's terms and the power
analysis.

The three factors of a between-tactor study are built in (:mod:`.builtin`):
``condition`` (how a between-tactor target is rendered), ``targets`` (the target count,
column ``n_targets``) and ``load`` (the secondary task). A study may cross further
factors that are recorded but change nothing a session plays (a posture, a garment, a
site's chair): :func:`register` one, and a study file may name it in ``[design]`` (a
list of levels) or in a ``[[test]]`` block (one level). See docs/architecture.md,
"Adding things".

Pure: the standard library only.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import Any, TypeVar

from .._errors import ConfigError
from .builtin import BUILTIN, CONDITION, LOAD, TARGETS
from .declaration import Changes, Factor

__all__ = [
    "BUILTIN",
    "CONDITION",
    "ENTRY_POINT_GROUP",
    "LOAD",
    "RESERVED",
    "TARGETS",
    "Changes",
    "Factor",
    "added_factors",
    "after_builtin",
    "factor",
    "factors",
    "register",
    "registered",
    "unregister",
]

_REGISTRY: dict[str, Factor] = {}


#: Names a declared factor may not take, as key or column: the keys of a ``[design]``
#: or ``[[test]]`` block and the columns of the trials wherever they go (the store, the
#: exports, the analysis's tables). ``tests/test_toy_factor.py`` holds it complete.
RESERVED: frozenset[str] = frozenset({
    # study-file keys of a block and of [design]
    "name", "repetitions", "targets", "law", "falloff_deg", "period_s", "transit_s",
    "max_presentation_s", "pattern", "order", "levels",
    # the trials' columns in the store, the exports and the analysis
    "abort_reason", "acquired_ns", "attempts", "block", "block_index", "block_name",
    "correct", "counted", "crossed_ns", "date", "device_onset_ns", "effort", "error_deg",
    "frustration", "is_correct", "mental", "n_samples", "notes", "on_tactor", "onset_ns",
    "onset_s", "onset_uncertainty_ns", "participant", "performance", "physical", "raw_tlx",
    "recorded_at", "repetition", "responded", "response_deg", "response_target_deg", "rt",
    "rt_s", "session", "session_id", "session_key", "session_number", "signed_error_deg",
    "skin_onset_ns", "skin_onset_s", "skin_onset_sd_ns", "skin_onset_sd_s", "status",
    "stimulus_off_ns", "target", "target_deg", "temporal", "trial", "trial_id",
    "trial_index", "t_s", "x", "y", "buttons", "sample_index",
})


def register(f: Factor) -> Factor:
    """Declare a study factor; it is crossed, stored, exported and analysed with the others.

    A declared factor is recorded: it changes nothing a session plays or shows
    (``changes = "nothing"``); the built-in ones are the factors that do.

    Raises:
        ConfigError: a factor with the same key or column is declared already; the key
            or column is a name tactorbelt uses already (:data:`RESERVED`); the factor
            claims to change the stimulus, the targets or the task.
    """
    if f.changes != "nothing":
        raise ConfigError(f"factor {f.key!r}: a declared factor is recorded and changes "
                          f"nothing a session plays (changes = 'nothing', not "
                          f"{f.changes!r}); what it plays is the runner's to change")
    for name in (f.key, f.column):
        if name in RESERVED:
            raise ConfigError(f"factor {f.key!r}: {name!r} is a name tactorbelt uses "
                              "already (a study-file key or a trials column); choose another")
    return _add(f)


def _add(f: Factor) -> Factor:
    for other in _REGISTRY.values():
        if f.key in (other.key, other.column) or f.column in (other.key, other.column):
            raise ConfigError(f"factor {f.key!r} (column {f.column!r}) clashes with the "
                              f"declared factor {other.key!r} (column {other.column!r})")
    _REGISTRY[f.key] = f
    return f


def unregister(key: str) -> None:
    """Withdraw a factor declared with :func:`register` (a built-in one stays)."""
    if key in _BUILTIN:
        raise ConfigError(f"{key!r} is a built-in factor")
    _REGISTRY.pop(key, None)


@contextmanager
def registered(f: Factor) -> Iterator[Factor]:
    """``with registered(Factor(...)):``: the factor is declared inside the block only."""
    register(f)
    try:
        yield f
    finally:
        unregister(f.key)


def factors() -> tuple[Factor, ...]:
    """Every declared factor: the built-in ones (targets, condition, load), then the
    others in the order they were declared. A ``[design]`` crosses them in this order,
    the first slowest."""
    return tuple(_REGISTRY.values())


def added_factors() -> tuple[Factor, ...]:
    """The factors declared beyond the built-in ones."""
    return tuple(f for k, f in _REGISTRY.items() if k not in _BUILTIN)


_T = TypeVar("_T")


def after_builtin(columns: Sequence[_T], extra: Sequence[_T],
                  key: Callable[[_T], Any] = lambda c: c) -> list[_T]:
    """``columns`` with ``extra`` inserted after the last built-in factor's column
    (``load``): where the added factors' columns go in every table, export and marker.

    Raises:
        ValueError: ``columns`` has no ``load`` (``key(c)`` names each column).
    """
    anchor = BUILTIN[-1].column
    i = next((i for i, c in enumerate(columns) if key(c) == anchor), None)
    if i is None:
        raise ValueError(f"no {anchor!r} column to put the added factors after")
    return [*columns[:i + 1], *extra, *columns[i + 1:]]


def factor(key: str) -> Factor:
    """The factor with this key (or column).

    Raises:
        ConfigError: no such factor (the message lists them).
    """
    for f in _REGISTRY.values():
        if key in (f.key, f.column):
            return f
    raise ConfigError(f"no factor {key!r}; declared: {', '.join(_REGISTRY)}")


#: The entry-point group of the factors installed packages declare.
ENTRY_POINT_GROUP = "tactorbelt.factors"


def _load_entry_points() -> None:
    """Register the factors of the entry points in :data:`ENTRY_POINT_GROUP`.

    Raises:
        ConfigError: an entry point that cannot be loaded, or is not a Factor (or a
            list of them), naming it.
    """
    from importlib.metadata import entry_points

    for ep in entry_points(group=ENTRY_POINT_GROUP):
        where = f"entry point {ep.name} = {ep.value} (group {ENTRY_POINT_GROUP})"
        try:
            obj = ep.load()
        except Exception as exc:
            raise ConfigError(f"{where} cannot be loaded: {type(exc).__name__}: {exc}") from None
        for f in obj if isinstance(obj, list | tuple) else [obj]:
            if not isinstance(f, Factor):
                raise ConfigError(f"{where} is a {type(f).__name__}, not a "
                                  "tactorbelt.factors.Factor")
            register(f)


for _f in BUILTIN:
    _add(_f)
_BUILTIN = tuple(f.key for f in BUILTIN)
_load_entry_points()
