"""What ``validate onsets`` and ``validate stimulus`` share: the ``--drive`` option and the
``--sense`` help."""

from __future__ import annotations

import click

__all__ = ["DRIVE", "sense_help"]

DRIVE = click.option("--drive", type=click.Choice(["plain", "shaped"]), default=None,
                     help="Play plain, or shaped (overdrive kicks and brake pulses; "
                     "docs/belts.md) [default: the belt's].")


def sense_help() -> str:
    from ..validation.registry import sense_url_help

    return ("What senses the vibration [default: the belt's own model, for the sim belt]: "
            + sense_url_help() + ". Options: URL?key=value (docs/validation.md).")
