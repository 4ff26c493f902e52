"""A secondary task of a study (``[tasks.NAME]``): its fields and their rules.

:class:`TaskSpec` is one table of a study file (:mod:`tactorbelt.experiment.study` reads
the file); it lives with the tasks that run it (:mod:`.session`, :mod:`.schedule`) and
the kinds whose rules it checks (:mod:`.kinds`).

Imports the standard library, pydantic and the task kinds.
"""

from __future__ import annotations

import re
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator, model_validator

from .kinds import NO_TASK, task_kind

__all__ = ["RESERVED_RESPONSES", "TaskSpec"]


#: Responses that go on or confirm a localisation in the window: a task may not use them.
RESERVED_RESPONSES: dict[str, str] = {
    "key:space": "Space goes on from the window's screens",
    "key:return": "Return goes on from the window's screens",
    "key:enter": "Enter (keypad) goes on from the window's screens",
    "joystick:0": "joystick button 0 confirms a localisation and goes on",
    "mouse:left": "the left mouse button confirms a localisation and goes on",
}
_RESPONSE = re.compile(r"^(key:[a-z0-9][a-z0-9 _\[\]\-]*|joystick:\d{1,2}|"
                       r"mouse:(left|middle|right))$")


class TaskSpec(BaseModel):
    """A secondary task (``[tasks.NAME]``), run during the test blocks whose load is NAME.

    Every task is go/no-go: the participant presses ``response`` on a go item (n-back:
    the item equals the one ``n`` back; arithmetic ``a+b``: the sum is odd). One item
    every ``interval_s`` from the task's start, independent of the trials' timing; each
    lasts ``stimulus_s``. ``practice`` items of the task alone come before the first
    block with this load, then ``baseline`` items alone (the single-task baseline of
    the dual-task cost). ``kind = "none"`` is a load with no task.
    """

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)

    kind: str
    n: int = Field(default=2, validate_default=True)
    modality: Literal["auditory", "visual"] = "auditory"
    interval_s: float = Field(default=2.5, gt=0, le=60)
    stimulus_s: float = Field(default=0.5, gt=0, le=60)
    response: str = "joystick:1"
    match_rate: float = Field(default=0.3, gt=0, lt=1)
    practice: int = Field(default=12, ge=0, le=200)
    baseline: int = Field(default=0, ge=0, le=500)

    @field_validator("kind")
    @classmethod
    def _kind(cls, v: str) -> str:
        if v != NO_TASK:
            task_kind(v)  # ValueError naming the registered kinds
        return v

    @field_validator("n")
    @classmethod
    def _n(cls, v: int, info: ValidationInfo) -> int:
        kind = info.data.get("kind")
        if kind is not None and kind != NO_TASK:
            task_kind(kind).check_fields(v)
        return v

    @field_validator("response")
    @classmethod
    def _response(cls, v: str) -> str:
        text = v.strip().lower()
        if text in RESERVED_RESPONSES:
            raise ValueError(
                f"{v!r} is taken: {RESERVED_RESPONSES[text]}; give the task another button, "
                "e.g. \"joystick:1\", \"key:j\" or \"mouse:right\"")
        if not _RESPONSE.match(text):
            raise ValueError(
                f"unknown response {v!r}: use \"key:NAME\" (a pygame key name, e.g. key:j), "
                "\"joystick:K\" (button K, e.g. joystick:1) or \"mouse:left|middle|right\"")
        return text

    @model_validator(mode="after")
    def _interval(self) -> TaskSpec:
        if self.interval_s <= self.stimulus_s:
            # "@interval_s@": the study file's error reports it at that field
            raise ValueError(f"@interval_s@ interval_s ({self.interval_s:g} s) must be longer "
                             f"than stimulus_s ({self.stimulus_s:g} s): one item ends before "
                             "the next")
        return self

    @property
    def active(self) -> bool:
        """A task runs (``kind`` is not ``none``)."""
        return self.kind != NO_TASK
