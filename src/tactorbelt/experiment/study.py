"""Study files: a TOML description of a between-tactor study, validated with pydantic.

A study fixes the layout, the targets, the stimulus parameters, the blocks (a
training block and one test block per condition), the randomisation, the
counterbalancing of the test blocks across participants, breaks, the inter-trial
interval and the response rule. ``tactorbelt study init`` writes the paper's
protocol (:func:`paper_study`); :func:`load_study` reads and checks a file and raises
:class:`~tactorbelt.StudyFileError` naming the file, line and field of the first
problem, and what is allowed there (the mapping from pydantic's errors is in
:mod:`.study_errors`). The templates ``study init`` writes are package data
(``experiment/templates/*.toml``); what ``study check`` prints is :mod:`.description`.

Pure: imports the standard library, pydantic, tomli-w, tactorbelt.geometry and the task
kinds; never an I/O layer (devices, inputs, gui, store).
"""

from __future__ import annotations

import difflib
import hashlib
import itertools
import math
import re
import tomllib
from importlib import resources
from pathlib import Path
from typing import Any, Literal, cast

import tomli_w
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    ValidationError,
    ValidationInfo,
    field_validator,
    model_validator,
)

from .. import _lawnames
from .._errors import ConfigError, StudyFileError
from ..factors import CONDITION, LOAD, TARGETS, Factor, added_factors, factors
from ..geometry import Layout, TargetSet
from ..tasks.spec import RESERVED_RESPONSES, TaskSpec
from .study_errors import study_error

__all__ = [
    "CONDITIONS",
    "RESERVED_RESPONSES",
    "BlockSpec",
    "DesignSpec",
    "LayoutSpec",
    "QuestionnaireSpec",
    "ResponseSpec",
    "SessionSpec",
    "StimulusSpec",
    "Study",
    "TargetsSpec",
    "TaskSpec",
    "TrainingSpec",
    "load_study",
    "paper_study",
    "plural",
    "template_toml",
]

Condition = Literal["static", "dynamic"]
#: The levels of the condition factor (:data:`tactorbelt.factors.CONDITION`).
CONDITIONS: tuple[Condition, ...] = cast("tuple[Condition, ...]", tuple(CONDITION.levels))
#: The key holding the levels of the factors declared beyond condition, targets and load
#: (:func:`tactorbelt.factors.register`); a study file names them as keys of their own.
LEVELS_KEY = "levels"


def _gather_levels(data: Any, where: str, many: bool) -> Any:
    """Move the keys of added factors (``posture = "standing"``) into ``levels``, each
    checked against its declaration; an error names ``where.KEY``."""
    if not isinstance(data, dict):
        return data
    given = data.get(LEVELS_KEY, {})
    added = {f.key: f for f in added_factors()}
    if not isinstance(given, dict) or not set(given) <= set(added):
        raise _at(f"{where}.{LEVELS_KEY}", f"unknown key {LEVELS_KEY!r}: name each "
                  "declared factor as a key of its own")
    levels: dict[str, Any] = {}
    for key, f in added.items():
        if key in data or key in given:
            v = data[key] if key in data else given[key]
            try:
                levels[key] = f.check_levels(v) if many else f.check(v)
            except ValueError as exc:
                raise _at(f"{where}.{key}", str(exc)) from None
    if not levels and LEVELS_KEY not in data:
        return data
    out = {k: v for k, v in data.items() if k not in levels}
    out[LEVELS_KEY] = levels
    return out


class _Model(BaseModel):
    """Strict, frozen, no unknown keys."""

    model_config = ConfigDict(extra="forbid", strict=True, frozen=True)


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


def _check_law(v: str | None) -> str | None:
    """``v`` when it names a registered amplitude law (``_lawnames.LAWS`` as it is when the
    file is read, so a law added there is a law here), else a ValueError naming them."""
    names = _lawnames.LAWS
    if v is None or v in names:
        return v
    close = difflib.get_close_matches(v, names, n=1)
    raise ValueError("should be " + ", ".join(repr(n) for n in names[:-1])
                     + f" or {names[-1]!r} (got {v!r}"
                     + (f"; did you mean {close[0]!r}?)" if close else ")"))


class StimulusSpec(_Model):
    """How targets are rendered (docs/conventions.md, "Amplitude laws" and "Stimuli")."""

    law: str = "paper"
    falloff_deg: float = Field(default=15.0, gt=0, le=360)
    period_s: float = Field(default=1.0, gt=0, le=60)
    transit_s: float = Field(default=0.1, gt=0, le=30)
    max_presentation_s: float = Field(default=10.0, gt=0, le=600)
    #: ``plain`` or ``shaped`` (overdrive and braking, docs/belts.md "Drive shaping"),
    #: set on the belt for the whole session; None: the belt's own default.
    drive: Literal["plain", "shaped"] | None = None
    #: A haptic pattern played instead of the law's rendering, turned so its 0 degrees
    #: is on the trial's target: a ``[patterns]`` name of the study, else a file
    #: (any kind ``pattern import`` reads) relative to the study file (docs/study.md).
    pattern: str | None = Field(default=None, min_length=1, max_length=500)

    _law = field_validator("law")(_check_law)

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


def plural(n: int, word: str) -> str:
    """``1 repetition``, ``2 repetitions``, ``1 pass``, ``3 passes``."""
    if n == 1:
        return f"{n} {word}"
    return f"{n} {word}{'es' if word.endswith(('s', 'x', 'ch', 'sh')) else 's'}"


_NAME = r"^[A-Za-z][A-Za-z0-9_\-]*$"


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
    given here overrides the study's stimulus for this block. A factor declared beyond
    these (:func:`tactorbelt.factors.register`) is a key of its own, one level, kept in
    ``levels``.
    """

    name: str | None = Field(default=None, min_length=1, max_length=64)
    condition: Condition
    repetitions: int = Field(ge=1, le=1000)
    targets: int | None = Field(default=None, ge=TARGETS.low, le=TARGETS.high)
    load: str = Field(default=LOAD.default, min_length=1, max_length=64)
    law: str | None = None
    falloff_deg: float | None = Field(default=None, gt=0, le=360)
    period_s: float | None = Field(default=None, gt=0, le=60)
    transit_s: float | None = Field(default=None, gt=0, le=30)
    max_presentation_s: float | None = Field(default=None, gt=0, le=600)
    pattern: str | None = Field(default=None, min_length=1, max_length=500)
    levels: dict[str, Any] = Field(default_factory=dict)

    _law = field_validator("law")(_check_law)

    @model_validator(mode="before")
    @classmethod
    def _added_factors(cls, data: Any) -> Any:
        return _gather_levels(data, "test", many=False)

    @property
    def label(self) -> str:
        return self.name or self.condition

    def level(self, f: Factor) -> Any:
        """This block's level of factor ``f`` (the target count: None when the block
        leaves it to ``[targets] count``; see :meth:`Study.block_level`)."""
        if f.key in type(self).model_fields and f.key != LEVELS_KEY:
            return getattr(self, f.key)
        return self.levels.get(f.key, f.default)

    def stimulus_overrides(self) -> dict[str, Any]:
        """The ``[stimulus]`` keys this block sets."""
        return {k: getattr(self, k) for k in StimulusSpec.model_fields
                if k in type(self).model_fields and getattr(self, k) is not None}

    def toml_dict(self) -> dict[str, Any]:
        """The block as a study file writes it (added factors as keys of their own)."""
        d = self.model_dump(mode="python", exclude_none=True)
        if d.get("load") == "none":
            d.pop("load")
        return {**{k: v for k, v in d.items() if k != LEVELS_KEY}, **d.get(LEVELS_KEY, {})}


Order = Literal["williams", "latin", "fixed", "random"]


_LOW, _HIGH = int(TARGETS.low or 1), int(TARGETS.high or 360)


def _check_counts(v: Any) -> Any:
    if isinstance(v, list):
        for x in v:
            if isinstance(x, bool) or not isinstance(x, int) or not _LOW <= x <= _HIGH:
                raise ValueError(f"target counts must be whole numbers from {_LOW} "
                                 f"to {_HIGH} (got {x!r})")
        if len(set(v)) != len(v):
            raise ValueError(f"each target count at most once (got {v!r})")
    return v


class DesignSpec(_Model):
    """A full factorial of the test blocks: targets x condition x load (x any factor
    declared beyond these, a key of its own: :func:`tactorbelt.factors.register`).

    Each cell is one test block of ``repetitions`` passes over its targets; ``order``
    counterbalances the blocks across participants (see
    :func:`tactorbelt.experiment.schedule.block_order`).
    """

    targets: list[int] = Field(min_length=1, max_length=TARGETS.max_levels)
    condition: list[Condition] = Field(min_length=1, max_length=CONDITION.max_levels)
    load: list[str] = Field(default_factory=lambda: [LOAD.default], min_length=1,
                            max_length=LOAD.max_levels)
    repetitions: int = Field(ge=1, le=1000)
    order: Order = "williams"
    levels: dict[str, list[Any]] = Field(default_factory=dict)

    _counts = field_validator("targets", mode="before")(_check_counts)

    @model_validator(mode="before")
    @classmethod
    def _added_factors(cls, data: Any) -> Any:
        return _gather_levels(data, "design", many=True)

    @field_validator("condition", "load")
    @classmethod
    def _unique(cls, v: list[str]) -> list[str]:
        if len(set(v)) != len(v):
            raise ValueError(f"each value at most once (got {v!r})")
        return v

    def factor_levels(self, f: Factor) -> list[Any]:
        """The levels the design crosses of factor ``f`` (its default alone when the
        design does not name it)."""
        if f.key in type(self).model_fields and f.key != LEVELS_KEY:
            return list(getattr(self, f.key))
        return list(self.levels.get(f.key, [f.default]))

    def n_blocks(self) -> int:
        return math.prod(len(self.factor_levels(f)) for f in factors())

    def size_words(self) -> str:
        """``2 target counts x 2 conditions x 1 loads`` (each crossed factor's count)."""
        words = {"targets": "target counts", "condition": "conditions", "load": "loads"}
        return " x ".join(f"{len(self.factor_levels(f))} {words.get(f.key, f.key + ' levels')}"
                          for f in sorted(factors(), key=lambda f: f.cross_rank)
                          if f.key in words or f.key in self.levels)

    def blocks(self) -> list[BlockSpec]:
        """The cells as test blocks, targets slowest, load fastest (the canonical order;
        added factors faster still).

        Block names: ``static-24`` or, with a load, ``static-24-nback2``; an added
        factor's level is appended (``static-24-standing``).
        """
        crossed = sorted(factors(), key=lambda f: f.cross_rank)
        named = sorted(factors(), key=lambda f: f.name_rank)
        out = []
        for combo in itertools.product(*(self.factor_levels(f) for f in crossed)):
            lv = {f.key: v for f, v in zip(crossed, combo, strict=True)}
            name = "-".join(p for p in (f.name_part(lv[f.key]) for f in named) if p)
            out.append(BlockSpec(
                name=name, condition=lv["condition"], repetitions=self.repetitions,
                targets=lv["targets"], load=lv["load"],
                levels={k: v for k, v in lv.items() if k in self.levels}))
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
    #: The patterns the stimuli name, by name: each a ``tactorbelt.pattern/1`` table
    #: (written in the file, or read from the file a stimulus names when the study file
    #: is loaded: :meth:`session_toml` keeps them with a session).
    patterns: dict[str, dict[str, Any]] = Field(default_factory=dict)

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
                          f"({self.design.size_words()}); at most 26 are allowed")
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

    @model_validator(mode="after")
    def _patterns(self, info: ValidationInfo) -> Study:
        """Check every pattern a stimulus names and keep it in :attr:`patterns`: a
        ``[patterns]`` table, else the file beside the study file (``base_dir`` in the
        validation context; without one, a pattern neither written nor found stays a
        name, refused when a trial plays it)."""
        for name in self.patterns:
            self._pattern(name, f"patterns.{name}")
        uses = [(self.stimulus.pattern, "stimulus.pattern")] + [
            (b.pattern, f"test[{i}].pattern") for i, b in enumerate(self.test)]
        used = [(n, loc) for n, loc in uses if n is not None]
        if used and self.calibration.perceptual:
            raise _at("calibration.perceptual", "a wearer profile is not applied to a "
                      f"pattern stimulus ({used[0][1]} = {used[0][0]!r}): measure and "
                      "run pattern studies without [calibration] perceptual")
        base = (info.context or {}).get("base_dir")
        found: dict[str, dict[str, Any]] = {}
        for name, loc in used:
            if base is not None and name not in self.patterns and name not in found:
                found[name] = _read_pattern_file(Path(base), name, loc)
        if found:
            object.__setattr__(self, "patterns", {**self.patterns, **found})
        for name, loc in used:
            if name in self.patterns:
                self._pattern(name, loc)
        return self

    def _pattern(self, name: str, loc: str) -> Any:
        """The :class:`~tactorbelt.patterns.model.Pattern` kept under ``name``, checked on
        the study's layout (a ValueError at ``loc`` naming the reason)."""
        from ..patterns.model import PatternFileError, pattern_from_dict
        from ..patterns.render import PatternPlayback

        try:
            pattern = pattern_from_dict(self.patterns[name], name)
            if not pattern.events:
                raise PatternFileError("the pattern has no events: nothing to play",
                                       path=name, field="events")
            PatternPlayback(pattern, self.layout_obj(), pattern.law or self.stimulus.law,
                            self.stimulus.falloff_deg, source=name)
        except ConfigError as exc:
            raise _at(loc, str(exc)) from None
        return pattern

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

    def block_n_targets(self, block: BlockSpec) -> int:
        """The target count of a test block (its ``targets``, else ``[targets] count``)."""
        return block.targets if block.targets is not None else self.targets.count

    def block_level(self, block: BlockSpec, f: Factor) -> Any:
        """A test block's level of factor ``f`` (the target count: :meth:`block_n_targets`)."""
        return self.block_n_targets(block) if f.key == "targets" else block.level(f)

    def block_stimulus(self, block: BlockSpec) -> StimulusSpec:
        """The stimulus of a test block: ``[stimulus]`` with the block's overrides."""
        return self.stimulus.model_copy(update=block.stimulus_overrides())

    def pattern(self, name: str) -> Any:
        """The pattern a stimulus names (:class:`~tactorbelt.patterns.model.Pattern`).

        Raises:
            StudyFileError: the study neither holds it nor was read from a file beside it
                (a stored session's study text from before patterns were kept with it).
        """
        if name not in self.patterns:
            raise StudyFileError(
                f"the pattern {name!r} is not in the study's [patterns] and the study was not "
                "read from its file (load it with load_study, or write the pattern into "
                "[patterns])", field="stimulus.pattern")
        try:
            return self._pattern(name, "stimulus.pattern")
        except ValueError as exc:
            raise StudyFileError(str(exc).split("@ ", 1)[-1], field="stimulus.pattern") from None

    def make_stimulus(self, spec: StimulusSpec, layout: Layout, target_deg: float,
                      condition: str, profile: Any = None, belt: Any = None) -> Any:
        """The stimulus of a trial with ``spec`` (its block's :meth:`trial_stimulus`) on
        ``layout``: :func:`tactorbelt.stimuli.make_stimulus` with the spec's law, falloff,
        period and transit; or, when the spec names a pattern, a
        :class:`~tactorbelt.patterns.stimulus.PatternStimulus` turned to ``target_deg``
        (checked against ``belt``'s vibration channels when a belt is given).

        Raises:
            ConfigError: from make_stimulus; PatternFileError: a pattern ``belt`` cannot
                show; StudyFileError: a pattern the study does not hold.
        """
        if spec.pattern is None:
            from ..stimuli import make_stimulus

            return make_stimulus(layout, target_deg, condition, spec.law, spec.falloff_deg,
                                 spec.period_s, spec.transit_s, profile=profile)
        from ..patterns.stimulus import PatternStimulus, check_on_belt

        if profile is not None:
            raise ConfigError("a wearer profile is not applied to a pattern stimulus "
                              f"({spec.pattern!r})")
        pattern = self.pattern(spec.pattern)
        stim = PatternStimulus(pattern, layout, target_deg, condition,
                               pattern.law or spec.law, spec.falloff_deg, name=spec.pattern)
        if belt is not None:
            check_on_belt(belt, stim)
        return stim

    def check_belt(self, belt: Any) -> None:
        """Refuse, before a session starts, a pattern stimulus ``belt`` cannot show at any
        of its block's targets (more distinct intensities at once than the belt's
        vibration channels); nothing to check for a study without patterns.

        Raises:
            PatternFileError: naming the pattern, the instant and the belt's limit.
        """
        specs = [(self.stimulus, self.target_counts())] + [
            (self.block_stimulus(b), [self.block_n_targets(b)]) for b in self.test]
        seen: set[tuple[Any, ...]] = set()
        for spec, counts in specs:
            if spec.pattern is None:
                continue
            for n in counts:
                for angle in TargetSet.even(n).angles_deg:
                    key = (spec.pattern, spec.law, spec.falloff_deg, float(angle))
                    if key not in seen:
                        seen.add(key)
                        self.make_stimulus(spec, belt.layout, float(angle), "static",
                                           belt=belt)

    def session_toml(self, text: str) -> str:
        """The study text a session stores: ``text`` itself, and, when a stimulus names a
        pattern file, that pattern as a ``[patterns]`` table appended to it, so the
        session holds what it played (export, analysis and resume read it from the
        store, wherever the file went). A study without pattern files: ``text``."""
        try:
            written = tomllib.loads(text).get("patterns", {})
        except tomllib.TOMLDecodeError:
            return text
        extra = {k: v for k, v in self.patterns.items()
                 if not isinstance(written, dict) or k not in written}
        if not extra:
            return text
        return (text.rstrip("\n") + "\n\n# written by tactorbelt: the pattern files the "
                "stimuli name, as this session played them\n"
                + tomli_w.dumps({"patterns": extra}))

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
    def from_toml(cls, text: str, path: str | Path | None = None,
                  base_dir: str | Path | None = None) -> Study:
        """Parse and validate a study from TOML text.

        Pattern files the stimuli name are read relative to ``base_dir`` (default: the
        directory of ``path`` when that is a file; else only ``[patterns]`` tables are
        read).

        Raises:
            StudyFileError: malformed TOML, an unknown key, a wrong type or an
                impossible value; names the file, line and field.
        """
        where = str(path) if path is not None else "<study>"
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            m = re.search(r"\(at line (\d+), column \d+\)", str(exc))
            line = getattr(exc, "lineno", None) or (int(m.group(1)) if m else None)
            msg = re.sub(r"\s*\(at (line \d+, column \d+|end of document)\)", "", str(exc))
            raise StudyFileError(f"not valid TOML: {msg}", path=where, line=line) from None
        if base_dir is None and path is not None and Path(path).is_file():
            base_dir = Path(path).parent
        context = {"base_dir": Path(base_dir)} if base_dir is not None else None
        try:
            return cls.model_validate(data, context=context)
        except ValidationError as exc:
            raise study_error(exc, text, where, cls) from None

    def to_toml(self) -> str:
        """TOML text that :meth:`from_toml` reads back to an equal study."""
        data = self.model_dump(mode="python", exclude_none=True)
        if self.design is not None:
            data.pop("test")
            data["session"].pop("condition_order")
            data["design"].update(data["design"].pop(LEVELS_KEY))
        else:
            data.pop("design", None)
            data["test"] = [b.toml_dict() for b in self.test]
        for key, empty in (("tasks", {}), ("questionnaire", QuestionnaireSpec()),
                           ("calibration", CalibrationSpec()), ("patterns", {})):
            if getattr(self, key) == empty:
                data.pop(key)
        return tomli_w.dumps(data)

    def sha256(self) -> str:
        """SHA-256 of :meth:`to_toml` (used when no file text is at hand)."""
        return hashlib.sha256(self.to_toml().encode()).hexdigest()


def _read_pattern_file(base: Path, name: str, loc: str) -> dict[str, Any]:
    """The pattern file ``name`` (relative to ``base``) as a ``tactorbelt.pattern/1`` dict;
    a ValueError at ``loc`` for a missing or bad file (its path, field and reason)."""
    from ..patterns.io import read_any
    from ..patterns.model import PatternFileError, pattern_to_dict

    p = Path(name) if Path(name).is_absolute() else base / name
    if not p.is_file():
        raise _at(loc, f"no such pattern file: {p} (a pattern is a [patterns] name or a file "
                  "relative to the study file)")
    try:
        return pattern_to_dict(read_any(p))
    except PatternFileError as exc:
        raise _at(loc, str(exc)) from None


def load_study(path: str | Path) -> Study:
    """Read and validate a study file (pattern files its stimuli name are read relative to
    its directory).

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
    return Study.from_toml(text, path=p, base_dir=p.parent)


# -- templates (package data: experiment/templates/NAME.toml) ---------------------------

def _template(name: str) -> str:
    return (resources.files("tactorbelt.experiment") / "templates" / f"{name}.toml").read_text(
        encoding="utf-8")


#: The commented study files ``tactorbelt study init --template NAME`` writes.
TEMPLATES: dict[str, str] = {name: _template(name) for name in ("paper", "resolution", "load")}
#: The paper's protocol, as ``study init`` writes it.
PAPER_STUDY_TOML = TEMPLATES["paper"]


def paper_study() -> Study:
    """The paper's protocol: 6 tactors, 24 targets, T = 15, training, static and dynamic blocks."""
    return Study.from_toml(PAPER_STUDY_TOML, path="<paper study>")


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
