"""The ``keyboard`` input kind: a person answering the perceptual calibration with keys
in the terminal (:class:`~tactorbelt.calibration.perceptual.KeyboardRespondent`); it
gives no cursor, so it runs no session.

Imports tactorbelt.calibration (the respondent).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .._errors import ConfigError
from ..calibration.perceptual import KeyboardRespondent

if TYPE_CHECKING:
    from .kinds import InputContext

__all__ = ["respondent"]


def respondent(ctx: InputContext) -> KeyboardRespondent:
    """The terminal's keys (``ctx.read_key``) and prompts (``ctx.say``)."""
    if ctx.read_key is None or ctx.say is None:
        raise ConfigError("the keyboard respondent needs read_key and say")
    return KeyboardRespondent(ctx.read_key, ctx.say)
