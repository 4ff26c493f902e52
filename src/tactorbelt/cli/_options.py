"""Shared command-line options, one definition per concept for every command
(docs/cli.md): the stimulus, the belt, ``-o/--output``, ``--seed``, numbers, an ANGLE.

- ``output_option(kind, help)``: ``-o/--output FILE|DIRECTORY`` (the old ``--out`` still
  works, not shown); ``seed_option(help)``: ``--seed INTEGER``; ``FLOAT``, ``POSITIVE``,
  ``number(...)``: typed numbers with one error wording (``_types.Number``).

- ``@stimulus_options`` adds --mode --law --falloff --tactors --tactor-angles --period
  --transit; ``build_stimulus(angle, **opts)`` validates them and returns a Stimulus
  (its ``layout`` is the layout asked for); ``layout_given(**opts)`` says whether the
  user chose a layout.
- ``@belt_option()`` adds --belt (help from the backend registry), ``@belt_options``
  --belt and --calibration; ``AngleCommand`` (``_types``): a negative ANGLE without ``--``.

Every bad value becomes a ConfigError (or click.BadParameter), printed as ``error: ...``
with exit code 2. Imports click at module level; NumPy and the devices in functions.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypeVar

import click

from .._errors import ConfigError
from .._lawnames import LAWS
from ._types import AliasOption, AngleCommand, HiddenArgument, Number

if TYPE_CHECKING:
    from ..devices.calibration import Calibration
    from ..geometry import Layout
    from ..stimuli import Stimulus

F = TypeVar("F", bound=Callable[..., Any])

__all__ = [
    "FLOAT",
    "POSITIVE",
    "AngleCommand",
    "HiddenArgument",
    "Number",
    "belt_option",
    "belt_options",
    "build_layout",
    "build_stimulus",
    "layout_given",
    "load_calibration",
    "number",
    "output_option",
    "seed_option",
    "stimulus_options",
]

#: Any finite number; a number above 0.
FLOAT = Number(float)
POSITIVE = Number(float, 0, lo_open=True)


#: A typed number (``FLOAT`` or ``INTEGER`` in help) with a range:
#: ``number(kind, lo, hi, lo_open, hi_open)``.
number = Number


def output_option(kind: str, help: str, default: Any = None, required: bool = False,
                  old: tuple[str, ...] = ("--out",)) -> Callable[[F], F]:
    """``-o/--output FILE`` (``kind="file"``) or ``DIRECTORY``, into parameter ``out``;
    the ``old`` spellings still work but are not shown."""
    is_dir = kind == "directory"
    # no default=None with required: click 8.3+ counts an explicit None as a default given
    # and would not ask for the option
    extra: dict[str, Any] = {} if default is None else {"default": default}
    return click.option("-o", "--output", "out", cls=AliasOption, hidden_aliases=old,
                        type=click.Path(file_okay=not is_dir, dir_okay=is_dir, path_type=Path),
                        metavar="DIRECTORY" if is_dir else "FILE", required=required,
                        show_default=default is not None, help=help, **extra)


def seed_option(help: str, default: int | None = None) -> Callable[[F], F]:
    """``--seed INTEGER`` (0 to 2**63 - 1)."""
    return click.option("--seed", type=Number(int, 0, 2**63 - 1), default=default,
                        show_default=default is not None, help=help)


#: The stimulus options by parameter name, in the order ``--help`` lists them.
_STIMULUS_OPTIONS = {
    "mode": click.option("--mode", type=click.Choice(["static", "dynamic"]), default="static",
                         show_default=True, help="Static amplitudes or the dynamic perturbation."),
    "law": click.option("--law", type=click.Choice(LAWS),
                        default="paper", show_default=True, help="Amplitude law."),
    "falloff": click.option("--falloff", type=POSITIVE, default=15.0, show_default=True,
                            help="T of the paper law, degrees."),
    "tactors": click.option("--tactors", type=Number(int, 2), default=None,
                            help="Number of evenly spaced tactors [default: 6]."),
    "tactor_angles": click.option(
        "--tactor-angles", default=None,
        help="Explicit tactor angles in degrees, e.g. 30,90,150,210,270,330."),
    "period": click.option("--period", type=POSITIVE, default=1.0, show_default=True,
                           help="Period of the dynamic perturbation, seconds."),
    "transit": click.option("--transit", type=POSITIVE, default=0.1, show_default=True,
                            help="Time to move between the two tactors, seconds."),
}


def stimulus_options(*names: str) -> Callable[[F], F]:
    """Add the stimulus options ``names`` (parameter names: ``"law"``, ``"falloff"``), or
    all of --mode --law --falloff --tactors --tactor-angles --period --transit."""
    def add(func: F) -> F:
        for name in reversed(names or tuple(_STIMULUS_OPTIONS)):
            func = _STIMULUS_OPTIONS[name](func)
        return func

    return add


def build_layout(tactors: object | None, tactor_angles: str | None) -> Layout:
    """The layout from --tactors or --tactor-angles (exclusive; default 6 even)."""
    from ..geometry import Layout

    if tactors is not None and tactor_angles is not None:
        raise ConfigError("give either --tactors or --tactor-angles, not both")
    if tactor_angles is not None:
        return Layout.parse(tactor_angles)
    if tactors is None:
        return Layout.even(6)
    try:
        n = int(str(tactors))
    except ValueError:
        raise ConfigError(f"--tactors must be an integer of at least 2, got {tactors!r}") from None
    return Layout.even(n)


def build_stimulus(angle: str, *, mode: str, law: str, falloff: object, tactors: object | None,
                   tactor_angles: str | None, period: object, transit: object) -> Stimulus:
    """Validate the stimulus options and build the stimulus for ANGLE."""
    from ..geometry import parse_angle, parse_number
    from ..stimuli import make_stimulus

    layout = build_layout(tactors, tactor_angles)
    return make_stimulus(
        layout,
        parse_angle(angle, "ANGLE"),
        mode=mode,
        law=law,
        falloff_deg=parse_number(falloff, "--falloff"),
        period_s=parse_number(period, "--period"),
        transit_s=parse_number(transit, "--transit"),
    )


def layout_given(tactors: object | None = None, tactor_angles: str | None = None,
                 **_: Any) -> bool:
    """True when the user chose a layout (--tactors or --tactor-angles)."""
    return tactors is not None or tactor_angles is not None


def belt_option(what: str = "The belt") -> Callable[[F], F]:
    """The one ``--belt URL`` option; its help lists the registered backends."""
    from ..devices.registry import belt_url_help

    return click.option("--belt", "belt_url", default="sim", show_default=True, metavar="URL",
                        help=f"{what}: {belt_url_help()}")


def belt_options(func: F) -> F:
    """Add --belt URL and --calibration FILE."""
    return belt_option()(click.option(
        "--calibration", "calibration_file", default=None, metavar="FILE",
        help="Motor calibration file (TOML, from `tactorbelt calibrate`).")(func))


def load_calibration(path: str | None) -> Calibration | None:
    """Load --calibration FILE (None when not given)."""
    if path is None:
        return None
    from ..devices.calibration import Calibration

    return Calibration.load(path)
