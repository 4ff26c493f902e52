"""Study files: a TOML description of a between-tactor study, validated with pydantic.

A study fixes the layout, the targets, the stimulus parameters, the blocks (a
training block and one test block per condition), the randomisation, the
counterbalancing of the test blocks across participants, breaks, the inter-trial
interval and the response rule. ``tactorbelt study init`` writes the paper's
protocol (:func:`paper_study`); :func:`load_study` reads and checks a file and raises
:class:`~tactorbelt.StudyFileError` naming the file, line and field of the first
problem, and what is allowed there.

Pure: imports the standard library, pydantic, tomli-w, tactorbelt.geometry and
tactorbelt.stimuli; never an I/O layer (devices, inputs, gui, store).
"""

from __future__ import annotations

import difflib
import hashlib
import itertools
import math
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)

from .._errors import ConfigError, StudyFileError
from .._lawnames import LawName
from ..geometry import Layout, TargetSet
from ..tasks.kinds import NO_TASK, task_kind

__all__ = [
    "CONDITIONS",
    "RESERVED_RESPONSES",
    "BlockSpec",
    "Cell",
    "DesignSpec",
    "LayoutSpec",
    "QuestionnaireSpec",
    "ResponseSpec",
    "SessionSpec",
    "StimulusSpec",
    "Study",
    "StudyDescription",
    "TargetsSpec",
    "TaskSpec",
    "TrainingSpec",
    "describe",
    "load_study",
    "paper_study",
    "plural",
    "template_toml",
]

Condition = Literal["static", "dynamic"]
CONDITIONS: tuple[Condition, ...] = ("static", "dynamic")



class _Model(BaseModel):
    """Strict, frozen, no unknown keys."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)


def _finite(v: float, what: str) -> float:
    if not math.isfinite(v):
        raise ValueError(f"{what} must be a finite number")
    return v


class LayoutSpec(_Model):
    """Where the tactors are: ``tactors = N`` (evenly spaced) or ``angles_deg = [...]``."""

    tactors: int | None = Field(default=None, ge=2, le=64)
    angles_deg: list[float] | None = Field(default=None, min_length=2, max_length=64)

    @model_validator(mode="after")
    def _one_of(self) -> LayoutSpec:
        if self.tactors is None and self.angles_deg is None:
            raise ValueError("give the tactor count (tactors = 6) or their angles (angles_deg)")
        if (self.tactors is not None and self.angles_deg is not None
                and len(self.angles_deg) != self.tactors):
            raise ValueError(
                f"tactors = {self.tactors} but angles_deg lists {len(self.angles_deg)} "
                "angles; give one of the two"
            )
        if self.angles_deg is not None:
            try:
                Layout.from_angles(self.angles_deg)
            except ConfigError as exc:
                raise ValueError(str(exc)) from None
        return self

    def to_layout(self) -> Layout:
        """The :class:`~tactorbelt.geometry.Layout` this describes."""
        if self.angles_deg is not None:
            return Layout.from_angles(self.angles_deg)
        assert self.tactors is not None
        return Layout.even(self.tactors)


class TargetsSpec(_Model):
    """The candidate targets: ``count`` directions at ``k*360/count``."""

    count: int = Field(ge=1, le=360)

    def to_target_set(self) -> TargetSet:
        return TargetSet.even(self.count)


class StimulusSpec(_Model):
    """How targets are rendered (docs/conventions.md, "Amplitude laws" and "Stimuli")."""

    law: LawName = "paper"
    falloff_deg: float = Field(default=15.0, gt=0, le=360)
    period_s: float = Field(default=1.0, gt=0, le=60)
    transit_s: float = Field(default=0.1, gt=0, le=30)
    max_presentation_s: float = Field(default=10.0, gt=0, le=600)

    @model_validator(mode="after")
    def _transit(self) -> StimulusSpec:
        if 2 * self.transit_s >= self.period_s:
            raise ValueError(
                f"2*transit_s ({2 * self.transit_s:g} s) must be shorter than period_s "
                f"({self.period_s:g} s)"
            )
        return self


class ResponseSpec(_Model):
    """The response rule, in cursor units (the response ellipse has radius 1).

    The cursor must be within ``home_radius`` of the centre before a trial starts. A
    response is acquired when the cursor's distance from the centre passes
    ``threshold`` (and, with ``dwell_s > 0``, stays beyond it that long); it selects
    the target nearest in angle. No acquisition within ``timeout_s`` of onset is a
    timeout.
    """

    home_radius: float = Field(default=0.15, gt=0, lt=1)
    threshold: float = Field(default=0.9, gt=0, le=1)
    dwell_s: float = Field(default=0.0, ge=0, le=10)
    timeout_s: float = Field(default=10.0, gt=0, le=600)

    @model_validator(mode="after")
    def _home_inside(self) -> ResponseSpec:
        if self.home_radius >= self.threshold:
            raise ValueError(
                f"home_radius ({self.home_radius:g}) must be smaller than threshold "
                f"({self.threshold:g})"
            )
        return self


class SessionSpec(_Model):
    """Pacing, randomisation and counterbalancing."""

    seed: int = Field(default=1, ge=0, le=2**63 - 1)
    iti_s: float = Field(default=1.0, ge=0, le=60)
    break_every: int = Field(default=48, ge=0)
    randomise: Literal["per_repetition", "full", "none"] = "per_repetition"
    condition_order: Literal["fixed", "alternate", "latin"] = "alternate"
    sample_rate_hz: float = Field(default=100.0, gt=0, le=1000)


class TrainingSpec(_Model):
    """The training block: each target felt while its location is shown on screen."""

    passes: int = Field(default=1, ge=0, le=100)
    conditions: list[Condition] = Field(default_factory=lambda: list(CONDITIONS))
    order: Literal["sequential", "random"] = "sequential"

    @field_validator("conditions")
    @classmethod
    def _some(cls, v: list[str]) -> list[str]:
        if len(set(v)) != len(v):
            raise ValueError("each condition at most once")
        return v


def plural(n: int, word: str, many: str | None = None) -> str:
    """``1 repetition``, ``2 repetitions``, ``1 pass``, ``3 passes``."""
    if n == 1:
        return f"{n} {word}"
    if many is None:
        many = word + ("es" if word.endswith(("s", "x", "ch", "sh")) else "s")
    return f"{n} {many}"


_NAME = r"^[A-Za-z][A-Za-z0-9_\-]*$"


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


class TaskSpec(_Model):
    """A secondary task (``[tasks.NAME]``), run during the test blocks whose load is NAME.

    Every task is go/no-go: the participant presses ``response`` on a go item (n-back:
    the item equals the one ``n`` back; arithmetic ``a+b``: the sum is odd). One item
    every ``interval_s`` from the task's start, independent of the trials' timing; each
    lasts ``stimulus_s``. ``practice`` items of the task alone come before the first
    block with this load, then ``baseline`` items alone (the single-task baseline of
    the dual-task cost). ``kind = "none"`` is a load with no task.
    """

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
            raise _at("interval_s", f"interval_s ({self.interval_s:g} s) must be longer than "
                      f"stimulus_s ({self.stimulus_s:g} s): one item ends before the next")
        return self

    @property
    def response_device(self) -> str:
        """``key``, ``joystick`` or ``mouse``."""
        return self.response.split(":", 1)[0]

    @property
    def response_button(self) -> str:
        """The key name, the joystick button number or the mouse button (as text)."""
        return self.response.split(":", 1)[1]

    @property
    def active(self) -> bool:
        """A task runs (``kind`` is not ``none``)."""
        return self.kind != NO_TASK


class QuestionnaireSpec(_Model):
    """Questionnaires: ``tlx = true`` asks the raw NASA-TLX after each test block."""

    tlx: bool = False


class CalibrationSpec(_Model):
    """``perceptual = true``: the study renders for each wearer's perceptual profile,
    measured before training when none is kept (docs/calibration-perceptual.md)."""

    perceptual: bool = False


class BlockSpec(_Model):
    """A test block: every target ``repetitions`` times in one condition.

    ``targets`` overrides ``[targets] count`` for this block, ``load`` names the
    secondary task (``none`` or a ``[tasks.NAME]`` table), and any ``[stimulus]`` key
    given here overrides the study's stimulus for this block.
    """

    name: str | None = Field(default=None, min_length=1, max_length=64)
    condition: Condition
    repetitions: int = Field(ge=1, le=1000)
    targets: int | None = Field(default=None, ge=1, le=360)
    load: str = Field(default="none", min_length=1, max_length=64)
    law: Literal["paper", "linear", "energy"] | None = None
    falloff_deg: float | None = Field(default=None, gt=0, le=360)
    period_s: float | None = Field(default=None, gt=0, le=60)
    transit_s: float | None = Field(default=None, gt=0, le=30)
    max_presentation_s: float | None = Field(default=None, gt=0, le=600)

    @property
    def label(self) -> str:
        return self.name or self.condition

    def stimulus_overrides(self) -> dict[str, Any]:
        """The ``[stimulus]`` keys this block sets."""
        return {k: getattr(self, k) for k in StimulusSpec.model_fields
                if getattr(self, k) is not None}


Order = Literal["williams", "latin", "fixed", "random"]


def _check_counts(v: Any) -> Any:
    if isinstance(v, list):
        for x in v:
            if isinstance(x, bool) or not isinstance(x, int) or not 1 <= x <= 360:
                raise ValueError(
                    f"target counts must be whole numbers from 1 to 360 (got {x!r})")
        if len(set(v)) != len(v):
            raise ValueError(f"each target count at most once (got {v!r})")
    return v


class DesignSpec(_Model):
    """A full factorial of the test blocks: targets x condition x load.

    Each cell is one test block of ``repetitions`` passes over its targets; ``order``
    counterbalances the blocks across participants (see
    :func:`tactorbelt.experiment.schedule.block_order`).
    """

    targets: list[int] = Field(min_length=1, max_length=26)
    condition: list[Condition] = Field(min_length=1, max_length=2)
    load: list[str] = Field(default_factory=lambda: ["none"], min_length=1, max_length=26)
    repetitions: int = Field(ge=1, le=1000)
    order: Order = "williams"

    _counts = field_validator("targets", mode="before")(_check_counts)

    @field_validator("condition", "load")
    @classmethod
    def _unique(cls, v: list[str]) -> list[str]:
        if len(set(v)) != len(v):
            raise ValueError(f"each value at most once (got {v!r})")
        return v

    def n_blocks(self) -> int:
        return len(self.targets) * len(self.condition) * len(self.load)

    def blocks(self) -> list[BlockSpec]:
        """The cells as test blocks, targets slowest, load fastest (the canonical order).

        Block names: ``static-24`` or, with a load, ``static-24-nback2``.
        """
        out = []
        for n, cond, load in itertools.product(self.targets, self.condition, self.load):
            name = f"{cond}-{n}" + ("" if load == "none" else f"-{load}")
            out.append(BlockSpec(name=name, condition=cond, repetitions=self.repetitions,
                                 targets=n, load=load))
        return out


def _at(loc: str, message: str) -> ValueError:
    """A ValueError that :func:`_study_error` reports at field ``loc`` (``design.load``)."""
    return ValueError(f"@{loc}@ {message}")


class Study(_Model):
    """A whole study. Build it with :func:`load_study`, :meth:`from_toml` or :func:`paper_study`.

    Attributes:
        name: a short name, stored with every session.
        description: free text.
        authors: the people who ran the study (the BIDS export's ``Authors``).
        layout, targets, stimulus, response, session, training: see the classes.
        test: the test blocks, in their default (participant 1) order.
    """

    name: str = Field(min_length=1, max_length=200)
    description: str = ""
    authors: list[str] = Field(default_factory=list, max_length=500)
    layout: LayoutSpec
    targets: TargetsSpec
    stimulus: StimulusSpec = Field(default_factory=StimulusSpec)
    response: ResponseSpec = Field(default_factory=ResponseSpec)
    session: SessionSpec = Field(default_factory=SessionSpec)
    training: TrainingSpec = Field(default_factory=TrainingSpec)
    test: list[BlockSpec] = Field(default_factory=list, max_length=26)
    design: DesignSpec | None = None
    tasks: dict[str, TaskSpec] = Field(default_factory=dict)
    questionnaire: QuestionnaireSpec = Field(default_factory=QuestionnaireSpec)
    calibration: CalibrationSpec = Field(default_factory=CalibrationSpec)

    @field_validator("authors")
    @classmethod
    def _authors(cls, v: list[str]) -> list[str]:
        names = [a.strip() for a in v]
        if not all(names):
            raise ValueError("each author is a name, not an empty string")
        return names

    @model_validator(mode="before")
    @classmethod
    def _design_or_test(cls, data: Any) -> Any:
        if isinstance(data, dict) and data.get("design") is not None and data.get("test"):
            raise _at("design", "give either [design] or [[test]] blocks, not both")
        return data

    @model_validator(mode="after")
    def _names_unique(self) -> Study:
        for name in self.tasks:
            if name == "none" or not re.match(_NAME, name):
                raise _at(f"tasks.{name}", "a task name is a letter then letters, digits, "
                          "_ or -, and not 'none'")
        if self.design is not None:
            if self.design.n_blocks() > 26:
                raise _at("design", f"{self.design.n_blocks()} blocks "
                          f"({len(self.design.targets)} target counts x "
                          f"{len(self.design.condition)} conditions x "
                          f"{len(self.design.load)} loads); at most 26 are allowed")
            if "condition_order" in self.session.model_fields_set:
                raise _at("session.condition_order", "applies to [[test]] blocks; with "
                          "[design] set design.order (williams, latin, fixed or random)")
            for i, load in enumerate(self.design.load):
                self._check_load(load, f"design.load[{i}]")
            object.__setattr__(self, "test", self.design.blocks())
        elif not self.test:
            raise _at("test", "required but missing: give [[test]] blocks or a [design]")
        for i, b in enumerate(self.test):
            if self.design is None:
                self._check_load(b.load, f"test[{i}].load")
            merged = {**self.stimulus.model_dump(), **b.stimulus_overrides()}
            try:
                StimulusSpec.model_validate(merged)
            except ValidationError as exc:
                raise _at(f"test[{i}]", exc.errors(include_url=False)[0]["msg"]
                          .removeprefix("Value error, ")) from None
        labels = [b.label for b in self.test]
        dup = sorted({x for x in labels if labels.count(x) > 1})
        if dup:
            raise ValueError(
                f"test blocks need distinct names; {', '.join(dup)} appears twice "
                "(add name = \"...\" to each block)"
            )
        return self

    def _check_load(self, load: str, loc: str) -> None:
        if load != "none" and load not in self.tasks:
            known = ", ".join(repr(k) for k in ["none", *self.tasks])
            hint = difflib.get_close_matches(load, ["none", *self.tasks], n=1)
            raise _at(loc, f"unknown load {load!r}: use {known}, or declare "
                      f"[tasks.{load}]" + (f" (did you mean {hint[0]!r}?)" if hint else ""))

    # -- derived values ----------------------------------------------------------
    def layout_obj(self) -> Layout:
        """The tactor layout."""
        return self.layout.to_layout()

    def target_set(self) -> TargetSet:
        """The candidate targets."""
        return self.targets.to_target_set()

    def block_n_targets(self, block: BlockSpec) -> int:
        """The target count of a test block (its ``targets``, else ``[targets] count``)."""
        return block.targets if block.targets is not None else self.targets.count

    def block_targets(self, block: BlockSpec) -> TargetSet:
        """The candidate targets of a test block."""
        return TargetSet.even(self.block_n_targets(block))

    def block_stimulus(self, block: BlockSpec) -> StimulusSpec:
        """The stimulus of a test block: ``[stimulus]`` with the block's overrides."""
        return self.stimulus.model_copy(update=block.stimulus_overrides())

    def test_block(self, name: str) -> BlockSpec | None:
        """The test block labelled ``name`` (a scheduled trial's ``block_name``), or None."""
        return next((b for b in self.test if b.label == name), None)

    def trial_stimulus(self, block_name: str) -> StimulusSpec:
        """The stimulus of a scheduled trial: its test block's (:meth:`block_stimulus`),
        ``[stimulus]`` for training trials (and a block name the study does not have)."""
        block = self.test_block(block_name)
        return self.stimulus if block is None else self.block_stimulus(block)

    def target_counts(self) -> list[int]:
        """Every target count of the test blocks, ascending (what training covers)."""
        return sorted({self.block_n_targets(b) for b in self.test})

    def n_training_trials(self) -> int:
        return self.training.passes * len(self.training.conditions) * sum(self.target_counts())

    def n_test_trials(self) -> int:
        return sum(b.repetitions * self.block_n_targets(b) for b in self.test)

    def n_trials(self) -> int:
        return self.n_training_trials() + self.n_test_trials()

    def used_tasks(self) -> dict[str, TaskSpec]:
        """The tasks that run: those of the test blocks' loads (not ``kind = "none"``),
        in the order of their first block in the file."""
        out: dict[str, TaskSpec] = {}
        for b in self.test:
            spec = self.tasks.get(b.load)
            if spec is not None and spec.active and b.load not in out:
                out[b.load] = spec
        return out

    def estimate_duration_s(self, response_s: float = 2.0, break_s: float = 60.0,
                            rating_s: float = 60.0) -> float:
        """A rough session length: each trial takes ``response_s`` plus the ITI, plus
        breaks, the secondary tasks' practice and baseline runs, and ``rating_s`` per
        NASA-TLX (after each test block with ``[questionnaire] tlx``)."""
        n = self.n_trials()
        rt = min(response_s, self.response.timeout_s)
        n_breaks = (n - 1) // self.session.break_every if self.session.break_every else 0
        alone = sum((t.practice + t.baseline) * t.interval_s for t in self.used_tasks().values())
        ratings = len(self.test) * rating_s if self.questionnaire.tlx else 0.0
        return n * (rt + self.session.iti_s) + n_breaks * break_s + alone + ratings

    # -- TOML --------------------------------------------------------------------
    @classmethod
    def from_toml(cls, text: str, path: str | Path | None = None) -> Study:
        """Parse and validate a study from TOML text.

        Raises:
            StudyFileError: malformed TOML, an unknown key, a wrong type or an
                impossible value; names the file, line and field.
        """
        where = str(path) if path is not None else "<study>"
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            line = getattr(exc, "lineno", None)
            msg = str(exc)
            m = re.search(r"\(at line (\d+), column (\d+)\)", msg)
            if line is None and m:
                line = int(m.group(1))
            msg = re.sub(r"\s*\(at line \d+, column \d+\)", "", msg)
            msg = re.sub(r"\s*\(at end of document\)", "", msg)
            raise StudyFileError(
                f"not valid TOML: {msg}", path=where, line=line
            ) from None
        try:
            return cls.model_validate(data)
        except ValidationError as exc:
            raise _study_error(exc, text, where) from None

    def to_toml(self) -> str:
        """TOML text that :meth:`from_toml` reads back to an equal study."""
        import tomli_w

        data = self.model_dump(mode="python", exclude_none=True)
        if self.design is not None:
            data.pop("test")
            data["session"].pop("condition_order")
        else:
            data.pop("design", None)
            data["test"] = [{k: v for k, v in b.items() if not (k == "load" and v == "none")}
                            for b in data["test"]]
        if not self.tasks:
            data.pop("tasks")
        if self.questionnaire == QuestionnaireSpec():
            data.pop("questionnaire")
        if self.calibration == CalibrationSpec():
            data.pop("calibration")
        return tomli_w.dumps(data)

    def sha256(self) -> str:
        """SHA-256 of :meth:`to_toml` (used when no file text is at hand)."""
        return hashlib.sha256(self.to_toml().encode()).hexdigest()


def load_study(path: str | Path) -> Study:
    """Read and validate a study file.

    Raises:
        StudyFileError: the file cannot be read, or is not a valid study.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise StudyFileError("no such file; create one with 'tactorbelt study init FILE'",
                             path=str(p)) from None
    except IsADirectoryError:
        raise StudyFileError("is a directory, not a study file", path=str(p)) from None
    except UnicodeDecodeError:
        raise StudyFileError("not a text file (TOML must be UTF-8)", path=str(p)) from None
    except OSError as exc:
        raise StudyFileError(f"cannot read: {exc.strerror}", path=str(p)) from None
    return Study.from_toml(text, path=p)


# -- error mapping -----------------------------------------------------------------

_HEADER = re.compile(r"^\s*(\[\[?)\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
_KEY = re.compile(r"^\s*([A-Za-z0-9_\-\.\"' ]+?)\s*=")


def _key_lines(text: str) -> dict[tuple[str | int, ...], int]:
    """Map each key path in a TOML text (('test', 1, 'repetitions')) to its 1-based line."""
    lines: dict[tuple[str | int, ...], int] = {}
    table: tuple[str | int, ...] = ()
    array_counts: dict[tuple[str | int, ...], int] = {}
    for lineno, raw in enumerate(text.splitlines(), start=1):
        m = _HEADER.match(raw)
        if m:
            parts = tuple(p.strip().strip("\"'") for p in m.group(2).split("."))
            if m.group(1) == "[[":
                idx = array_counts.get(parts, -1) + 1
                array_counts[parts] = idx
                table = (*parts, idx)
            else:
                table = parts
            lines.setdefault(table, lineno)
            if table and isinstance(table[-1], int):
                lines.setdefault(table[:-1], lineno)
            continue
        k = _KEY.match(raw)
        if k and not raw.lstrip().startswith("#"):
            key = tuple(p.strip().strip("\"'") for p in k.group(1).split("."))
            lines.setdefault((*table, *key), lineno)
    return lines


def _line_for(loc: tuple[str | int, ...], lines: dict[tuple[str | int, ...], int]) -> int | None:
    for n in range(len(loc), 0, -1):
        if loc[:n] in lines:
            return lines[loc[:n]]
    return None


def _model_at(loc: tuple[str | int, ...]) -> Any:
    """The pydantic model that holds the last key of ``loc`` (None if not a model)."""
    model: Any = Study
    ann: Any = None
    for part in loc[:-1]:
        if ann is not None:  # the key of a dict (tasks.NAME) or an index of a list
            ann = None
            continue
        if isinstance(part, int):
            continue
        field = model.model_fields.get(part) if model is not None else None
        if field is None:
            return None
        ann = field.annotation
        args = [a for a in getattr(ann, "__args__", ()) if a is not type(None)]
        if isinstance(ann, type) and issubclass(ann, BaseModel):
            model, ann = ann, None
        elif args and isinstance(args[-1], type) and issubclass(args[-1], BaseModel):
            model = args[-1]
            if getattr(ann, "__origin__", None) is None:  # X | None
                ann = None
        else:
            return None
    return model


def _allowed_keys(loc: tuple[str | int, ...]) -> list[str]:
    model = _model_at(loc)
    return list(model.model_fields) if model is not None else []


def _range_text(loc: tuple[str | int, ...]) -> str | None:
    """The allowed range of a numeric field, e.g. ``(0, 1]``, from its constraints."""
    model = _model_at(loc)
    if model is None or not isinstance(loc[-1], str) or loc[-1] not in model.model_fields:
        return None
    lo = hi = None
    lo_open = hi_open = True
    for m in model.model_fields[loc[-1]].metadata:
        if getattr(m, "ge", None) is not None:
            lo, lo_open = m.ge, False
        if getattr(m, "gt", None) is not None:
            lo, lo_open = m.gt, True
        if getattr(m, "le", None) is not None:
            hi, hi_open = m.le, False
        if getattr(m, "lt", None) is not None:
            hi, hi_open = m.lt, True
    if lo is None and hi is None:
        return None
    left = "(" if lo_open or lo is None else "["
    right = ")" if hi_open or hi is None else "]"
    lo_s = "-inf" if lo is None else f"{lo:g}"
    hi_s = "inf" if hi is None else f"{hi:g}"
    return f"{left}{lo_s}, {hi_s}{right}"


def _parse_loc(dotted: str) -> tuple[str | int, ...]:
    out: list[str | int] = []
    for part in dotted.split("."):
        m = re.fullmatch(r"([^\[]+)((?:\[\d+\])*)", part)
        if not m:
            out.append(part)
            continue
        out.append(m.group(1))
        out += [int(i) for i in re.findall(r"\[(\d+)\]", m.group(2))]
    return tuple(out)


def _dotted(loc: tuple[str | int, ...]) -> str | None:
    text = ".".join(f"[{p}]" if isinstance(p, int) else str(p) for p in loc).replace(".[", "[")
    return text or None


def _clean_loc(raw: tuple[Any, ...], key_last: bool = False) -> tuple[str | int, ...]:
    """``raw`` without pydantic's labels of validators and unions (``function-after[...]``).
    ``key_last``: the last part is the file's own key (an unknown key's error), kept
    whatever it holds (a key may be ``"["``)."""
    head, last = (raw[:-1], raw[-1:]) if key_last else (raw, ())
    return (*(p for p in head if not (isinstance(p, str) and "[" in p)), *last)


def _study_error(exc: ValidationError, text: str, where: str) -> StudyFileError:
    errors = exc.errors(include_url=False)
    err = errors[0]
    loc = _clean_loc(err["loc"], key_last=err["type"] == "extra_forbidden")
    lines = _key_lines(text)
    kind = err["type"]
    msg = err["msg"]
    got = err.get("input")
    # a misspelt required key: report the unknown key and the missing one together
    missing = {_clean_loc(e["loc"]) for e in errors if e["type"] == "missing"}
    extra = [_clean_loc(e["loc"], key_last=True) for e in errors
             if e["type"] == "extra_forbidden"]
    pair = None
    for x in extra:
        for m in missing:
            if (x[:-1] == m[:-1] and isinstance(x[-1], str) and isinstance(m[-1], str)
                    and difflib.get_close_matches(x[-1], [m[-1]], n=1)):
                pair = (x, m)
                break
        if pair:
            break
    if pair is not None:
        loc, kind, got = pair[0], "extra_forbidden", None
    m_at = re.match(r"^(?:Value error, )?@([^@]+)@ (.*)$", msg, re.S) if kind == "value_error" \
        else None
    if m_at:
        loc = (*loc, *_parse_loc(m_at.group(1)))
        msg = m_at.group(2)
    line = _line_for(loc, lines)
    dotted = _dotted(loc)
    if kind == "extra_forbidden":
        allowed = _allowed_keys(loc)
        close = difflib.get_close_matches(str(loc[-1]), allowed, n=1)
        msg = f"unknown key {loc[-1]!r}"
        if pair is not None:
            msg += (f" (did you mean {pair[1][-1]!r}?); {pair[1][-1]!r} is required but "
                    "missing")
        elif close:
            msg += f" (did you mean {close[0]!r}?)"
        if allowed:
            msg += f"; allowed here: {', '.join(allowed)}"
    elif kind == "missing":
        msg = "required but missing"
    elif kind == "value_error":
        msg = msg.removeprefix("Value error, ")
    elif kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        rng = _range_text(loc)
        msg = (f"must be in {rng}" if rng else msg) + f" (got {got!r})"
    elif kind in ("int_type", "float_type", "string_type", "bool_type", "list_type"):
        what = {"int_type": "an integer", "float_type": "a number", "string_type": "a string",
                "bool_type": "true or false", "list_type": "a list"}[kind]
        rng = _range_text(loc)
        msg = f"must be {what}" + (f" in {rng}" if rng else "") + f" (got {got!r})"
    else:
        msg = msg[0].lower() + msg[1:]
        if not isinstance(got, dict | list):
            msg += f" (got {got!r})"
    return StudyFileError(msg, path=where, line=line, field=dotted)


# -- the paper's protocol ------------------------------------------------------------

#: The [stimulus] and [response] tables and the start of [session] that the templates
#: share (the paper's values, commented).
_STIMULUS_RESPONSE_SESSION_TOML = '''\
[stimulus]
law = "paper"             # paper | linear | energy
falloff_deg = 15.0        # T of the paper's Eq. 1
period_s = 1.0            # period of the dynamic perturbation
transit_s = 0.1           # time to move between the two tactors (2*transit < period)
max_presentation_s = 10.0 # the stimulus stops at acquisition or after this long

[response]
home_radius = 0.15        # the cursor must be this close to the centre to start a trial
threshold = 0.9           # acquisition: distance from the centre passes this, in (0, 1]
dwell_s = 0.0             # ... and stays beyond it this long (0 = at once)
timeout_s = 10.0          # no acquisition this long after onset: the trial times out

[session]
seed = 1                  # randomisation seed (with the participant id); --seed overrides
iti_s = 1.0               # inter-trial interval
'''

PAPER_STUDY_TOML = '''\
# tactorbelt study file: the protocol of Eguchi et al., "Between-Tactor Display
# Using Dynamic Tactile Stimuli". Edit it, then check it with
#   tactorbelt study check THIS_FILE
# Angles are degrees, 0 = navel (front), growing clockwise seen from above.

name = "between-tactor-paper"
description = "6 tactors, 24 targets; training, then static and dynamic test blocks"
# authors = ["A. Researcher", "B. Researcher"]  # the BIDS export's Authors

[layout]
# Either the number of evenly spaced tactors (at 180/N + k*360/N, so the two front
# tactors are equally distant from the navel) ...
tactors = 6
# ... or their angles, one per tactor (tactor k is the k-th angle):
# angles_deg = [30, 90, 150, 210, 270, 330]

[targets]
count = 24                # targets at k*360/count; on-tactor where one meets a tactor

''' + _STIMULUS_RESPONSE_SESSION_TOML + '''\
break_every = 48          # a break after every N trials (0 = no breaks)
randomise = "per_repetition"  # per_repetition (each pass a new permutation) | full | none
condition_order = "alternate" # fixed | alternate (even participants reversed) | latin
sample_rate_hz = 100.0    # cursor sampling rate

[training]
# Each target is felt while its location is shown; the participant points at it.
passes = 1                # 0 = no training
conditions = ["static", "dynamic"]
order = "sequential"      # sequential (around the belt) | random

# Test blocks, in the order participant 1 gets them (see condition_order).
[[test]]
name = "static"
condition = "static"      # static | dynamic (on-tactor targets are always static)
repetitions = 5           # every target this many times

[[test]]
name = "dynamic"
condition = "dynamic"
repetitions = 5
'''


def paper_study() -> Study:
    """The paper's protocol: 6 tactors, 24 targets, T = 15, training, static and dynamic blocks."""
    return Study.from_toml(PAPER_STUDY_TOML, path="<paper study>")


# -- the resolution study ------------------------------------------------------------

RESOLUTION_STUDY_TOML = '''\
# tactorbelt study file: how finely can directions be told apart between tactors?
# A full factorial of target resolution (12, 24, 36, 48 targets) x condition (static,
# dynamic), each cell one test block, ordered across participants by a balanced Latin
# square (Williams). Check it with
#   tactorbelt study check THIS_FILE
# Angles are degrees, 0 = navel (front), growing clockwise seen from above.

name = "between-tactor-resolution"
description = "6 tactors; 12/24/36/48 targets x static/dynamic; Williams order"
# authors = ["A. Researcher", "B. Researcher"]  # the BIDS export's Authors

[layout]
tactors = 6               # evenly spaced at 180/N + k*360/N

[targets]
count = 24                # not used by the [design] blocks (they set their own counts)

''' + _STIMULUS_RESPONSE_SESSION_TOML + '''\
break_every = 60          # a break after every N trials (0 = no breaks)
randomise = "per_repetition"  # per_repetition (each pass a new permutation) | full | none
sample_rate_hz = 100.0    # cursor sampling rate

[training]
# Before the first test block, each target of every count (12, then 24, 36, 48) is
# felt while its location is shown; the participant points at it.
passes = 1                # 0 = no training
conditions = ["static", "dynamic"]
order = "sequential"      # sequential (around the belt) | random

[design]
# One test block per cell: 4 target counts x 2 conditions = 8 blocks.
targets = [12, 24, 36, 48]     # targets at k*360/count
condition = ["static", "dynamic"]
load = ["none"]                # "none" or the name of a [tasks.NAME] table
repetitions = 2                # every target of a block this many times
order = "williams"             # williams | latin | fixed | random (across participants)

# A secondary task, used by naming it in design.load (e.g. load = ["none", "nback2"]):
# [tasks.nback2]
# kind = "nback"               # nback | arithmetic | none
# n = 2
# modality = "auditory"        # auditory | visual
# interval_s = 2.5

# [questionnaire]
# tlx = true                   # raw NASA-TLX after each test block
'''

# -- the cognitive-load study --------------------------------------------------------

LOAD_STUDY_TOML = '''\
# tactorbelt study file: does a concurrent task (cognitive load) change between-tactor
# localisation? A full factorial of condition (static, dynamic) x load (none, auditory
# 2-back), 24 targets, each cell one test block, ordered across participants by a
# balanced Latin square (Williams); raw NASA-TLX after every test block. Check it with
#   tactorbelt study check THIS_FILE
# Angles are degrees, 0 = navel (front), growing clockwise seen from above.

name = "between-tactor-load"
description = "6 tactors, 24 targets; static/dynamic x no load/auditory 2-back; NASA-TLX"
# authors = ["A. Researcher", "B. Researcher"]  # the BIDS export's Authors

[layout]
tactors = 6               # evenly spaced at 180/N + k*360/N

[targets]
count = 24                # targets at k*360/count; on-tactor where one meets a tactor

''' + _STIMULUS_RESPONSE_SESSION_TOML + '''\
break_every = 48          # a break after every N trials (0 = no breaks)
randomise = "per_repetition"  # per_repetition (each pass a new permutation) | full | none
sample_rate_hz = 100.0    # cursor sampling rate

[training]
# Localisation alone, before any test block: each target is felt while its location
# is shown; the participant points at it.
passes = 1                # 0 = no training
conditions = ["static", "dynamic"]
order = "sequential"      # sequential (around the belt) | random

[design]
# One test block per cell: 2 conditions x 2 loads = 4 blocks.
targets = [24]
condition = ["static", "dynamic"]
load = ["none", "nback2"]      # "none" or the name of a [tasks.NAME] table
repetitions = 2                # every target of a block this many times
order = "williams"             # williams | latin | fixed | random (across participants)

# The secondary task of the blocks whose load is "nback2". Every task is go/no-go:
# press the response button when the item is the same as the one n items back.
# It runs on its own clock (one item every interval_s from the block's first trial),
# whatever the localisation trials do.
[tasks.nback2]
kind = "nback"            # nback | arithmetic (odd/even of "a+b") | none (no task)
n = 2                     # 1, 2 or 3
modality = "auditory"     # auditory (tones) | visual (a letter off the response ellipse)
interval_s = 2.5          # one item every interval_s (longer than stimulus_s)
stimulus_s = 0.5          # how long a tone or a letter lasts
response = "joystick:1"   # key:NAME | joystick:K | mouse:middle|right (not Space, Return,
                          # joystick:0 or the left mouse button: they confirm a localisation)
match_rate = 0.3          # share of go items (matches)
practice = 12             # items of the task alone before its first block
baseline = 24             # then items alone for the single-task baseline (the
                          # dual-task cost compares it with the task during the trials)

[questionnaire]
tlx = true                # raw NASA-TLX (6 items, 0-100) after each test block
'''

TEMPLATES: dict[str, str] = {"paper": PAPER_STUDY_TOML, "resolution": RESOLUTION_STUDY_TOML,
                             "load": LOAD_STUDY_TOML}


def template_toml(name: str = "paper") -> str:
    """The commented TOML of a study template: ``paper``, ``resolution`` or ``load``.

    Raises:
        ConfigError: an unknown template name (the message lists the names).
    """
    try:
        return TEMPLATES[name]
    except KeyError:
        raise ConfigError(f"unknown study template {name!r}; use one of: "
                          f"{', '.join(TEMPLATES)}") from None


# -- what `study check` prints -------------------------------------------------------


def _minutes(seconds: float) -> str:
    m, s = divmod(round(seconds), 60)
    return f"{m} min {s:02d} s" if m else f"{s} s"


@dataclass(frozen=True)
class Cell:
    """One cell of the test design (one test block)."""

    block: str
    n_targets: int
    condition: str
    load: str
    repetitions: int

    @property
    def trials(self) -> int:
        return self.n_targets * self.repetitions


@dataclass(frozen=True)
class StudyDescription:
    """What ``tactorbelt study check`` reports about a study (:func:`describe`).

    Attributes:
        study: the study.
        participant: whose block order ``order`` is.
        cells: the test blocks in the file's (canonical) order.
        order: the block labels in the participant's running order.
        order_rule: ``design.order`` or ``session.condition_order``.
        balance_participants: participants per complete balance of the order.
        n_breaks: breaks in a session.
        duration_s, max_duration_s: the estimate with 2 s responses, and with every
            trial timing out.
    """

    study: Study
    participant: str
    cells: tuple[Cell, ...]
    order: tuple[str, ...]
    order_rule: str
    balance_participants: int
    n_breaks: int
    duration_s: float
    max_duration_s: float

    def to_text(self) -> str:
        """The report as lines of text (two-space indent; the CLI prints 'FILE: ok' first)."""
        s = self.study
        layout = s.layout_obj()
        counts = s.target_counts()
        out = [f"  study       {s.name}",
               f"  layout      {plural(layout.n, 'tactor')} at "
               f"{', '.join(f'{a:g}' for a in layout.angles_deg)} deg"]
        for n in counts:
            on = int(TargetSet.even(n).on_tactor(layout).sum())
            out.append(f"  targets     {n} ({on} on-tactor, {n - on} between-tactor)")
        st = s.stimulus
        out.append(f"  stimulus    law {st.law}, falloff {st.falloff_deg:g} deg, period "
                   f"{st.period_s:g} s, transit {st.transit_s:g} s, at most "
                   f"{st.max_presentation_s:g} s")
        r = s.response
        out.append(f"  response    home {r.home_radius:g}, threshold {r.threshold:g}, dwell "
                   f"{r.dwell_s:g} s, timeout {r.timeout_s:g} s")
        if s.design is not None:
            d = s.design
            out.append(f"  design      {plural(len(d.targets), 'target count')} x "
                       f"{plural(len(d.condition), 'condition')} x "
                       f"{plural(len(d.load), 'load')} = {plural(len(self.cells), 'cell')}, "
                       f"{plural(d.repetitions, 'repetition')} of every target")
        out.append("  blocks")
        tr = s.training
        n_tr = s.n_training_trials()
        width = max(9, *(len(c.block) for c in self.cells))
        if n_tr:
            tgt = (plural(counts[0], "target") if len(counts) == 1
                   else f"({' + '.join(str(n) for n in counts)}) targets")
            out.append(f"    {'training':<{width}s} {n_tr:4d} trials "
                       f"({plural(tr.passes, 'pass')} x "
                       f"{plural(len(tr.conditions), 'condition')} x {tgt}, {tr.order})")
        for c in self.cells:
            load = "" if c.load == "none" else f", load {c.load}"
            out.append(f"    {c.block:<{width}s} {c.trials:4d} trials "
                       f"({c.condition}{load}, {plural(c.repetitions, 'repetition')} x "
                       f"{plural(c.n_targets, 'target')})")
        for name, t in s.used_tasks().items():
            what = task_kind(t.kind).describe(t)
            out.append(f"  task        {name}: {t.modality} {what}, an item every "
                       f"{t.interval_s:g} s ({t.stimulus_s:g} s long), press {t.response} "
                       f"on {t.match_rate:.0%} go items; {plural(t.practice, 'practice item')}"
                       f", {plural(t.baseline, 'baseline item')} before its first block")
        if s.questionnaire.tlx:
            out.append("  ratings     raw NASA-TLX (6 items, 0-100) after each test block")
        out.append(f"  total       {s.n_trials()} trials ({s.n_test_trials()} test)")
        out.append(f"  order       {self.order_rule} (balanced over "
                   f"{plural(self.balance_participants, 'participant')}); "
                   f"{self.participant}: {' -> '.join(self.order)}")
        out.append(f"  breaks      {self.n_breaks} (every {s.session.break_every} trials)"
                   if self.n_breaks else "  breaks      none")
        extra = (" + the tasks' practice and baseline" if s.used_tasks() else "") + (
            " + 1 min per NASA-TLX" if s.questionnaire.tlx else "")
        out.append(f"  duration    about {_minutes(self.duration_s)} "
                   f"(2 s per response + {s.session.iti_s:g} s ITI per trial + 1 min per "
                   f"break{extra}); at most {_minutes(self.max_duration_s)}")
        return "\n".join(out)


def describe(study: Study, participant: str = "P01", seed: int | None = None) -> StudyDescription:
    """The ``study check`` report: cells, trials per cell, block order, duration.

    Also builds the participant's schedule, so a study that cannot be scheduled fails
    here. ``seed`` (default ``session.seed``) matters for ``design.order = "random"``.
    """
    from .schedule import block_order, make_schedule, order_rows, order_rule

    cells = tuple(Cell(b.label, study.block_n_targets(b), b.condition, b.load, b.repetitions)
                  for b in study.test)
    idx = block_order(study, participant, seed)
    rule = order_rule(study)
    n = study.n_trials()
    every = study.session.break_every
    make_schedule(study, participant, seed)
    return StudyDescription(
        study=study, participant=participant, cells=cells,
        order=tuple(study.test[i].label for i in idx), order_rule=rule,
        balance_participants=order_rows(rule, len(cells)),
        n_breaks=(n - 1) // every if every else 0,
        duration_s=study.estimate_duration_s(),
        max_duration_s=study.estimate_duration_s(response_s=study.response.timeout_s),
    )
