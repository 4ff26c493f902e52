"""Shared command-line options for stimuli: mode, law, falloff, layout, period, transit.

``@stimulus_options`` adds the options to a click command; ``build_stimulus(angle, **opts)``
validates them and returns a Stimulus. Every bad value becomes a ConfigError, which the
CLI prints as ``error: ...`` with exit code 2.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar

import click

from .._errors import ConfigError

if TYPE_CHECKING:
    from ..geometry import Layout
    from ..stimuli import Stimulus

F = TypeVar("F", bound=Callable[..., Any])

__all__ = ["build_layout", "build_stimulus", "parse_number", "stimulus_options"]


def parse_number(text: object, what: str) -> float:
    """A finite float from text, or ConfigError naming the option."""
    try:
        value = float(text)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise ConfigError(f"{what} must be a number, got {text!r}") from None
    if not math.isfinite(value):
        raise ConfigError(f"{what} must be a finite number, got {text!r}")
    return value


def stimulus_options(func: F) -> F:
    """Add --mode --law --falloff --tactors --tactor-angles --period --transit."""
    options = [
        click.option("--mode", type=click.Choice(["static", "dynamic"]), default="static",
                     show_default=True, help="Static amplitudes or the dynamic perturbation."),
        click.option("--law", type=click.Choice(["paper", "linear", "energy"]),
                     default="paper", show_default=True, help="Amplitude law."),
        click.option("--falloff", default="15", show_default=True,
                     help="T of the paper law, degrees."),
        click.option("--tactors", default=None,
                     help="Number of evenly spaced tactors [default: 6]."),
        click.option("--tactor-angles", default=None,
                     help="Explicit tactor angles in degrees, e.g. 30,90,150,210,270,330."),
        click.option("--period", default="1.0", show_default=True,
                     help="Period of the dynamic perturbation, seconds."),
        click.option("--transit", default="0.1", show_default=True,
                     help="Time to move between the two tactors, seconds."),
    ]
    for option in reversed(options):
        func = option(func)
    return func


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
    from ..geometry import parse_angle
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
