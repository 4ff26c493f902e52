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

import hashlib
import math
import re
import tomllib
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator

from .._errors import ConfigError, StudyFileError
from ..geometry import Layout, TargetSet

__all__ = [
    "CONDITIONS",
    "BlockSpec",
    "LayoutSpec",
    "ResponseSpec",
    "SessionSpec",
    "StimulusSpec",
    "Study",
    "TargetsSpec",
    "TrainingSpec",
    "load_study",
    "paper_study",
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
    """How targets are rendered (DESIGN.md, "Amplitude laws" and "Stimuli")."""

    law: Literal["paper", "linear", "energy"] = "paper"
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


class BlockSpec(_Model):
    """A test block: every target ``repetitions`` times in one condition."""

    name: str | None = Field(default=None, min_length=1, max_length=64)
    condition: Condition
    repetitions: int = Field(ge=1, le=1000)

    @property
    def label(self) -> str:
        return self.name or self.condition


class Study(_Model):
    """A whole study. Build it with :func:`load_study`, :meth:`from_toml` or :func:`paper_study`.

    Attributes:
        name: a short name, stored with every session.
        description: free text.
        layout, targets, stimulus, response, session, training: see the classes.
        test: the test blocks, in their default (participant 1) order.
    """

    name: str = Field(min_length=1, max_length=200)
    description: str = ""
    layout: LayoutSpec
    targets: TargetsSpec
    stimulus: StimulusSpec = Field(default_factory=StimulusSpec)
    response: ResponseSpec = Field(default_factory=ResponseSpec)
    session: SessionSpec = Field(default_factory=SessionSpec)
    training: TrainingSpec = Field(default_factory=TrainingSpec)
    test: list[BlockSpec] = Field(min_length=1, max_length=26)

    @model_validator(mode="after")
    def _names_unique(self) -> Study:
        labels = [b.label for b in self.test]
        dup = sorted({x for x in labels if labels.count(x) > 1})
        if dup:
            raise ValueError(
                f"test blocks need distinct names; {', '.join(dup)} appears twice "
                "(add name = \"...\" to each block)"
            )
        return self

    # -- derived values ----------------------------------------------------------
    def layout_obj(self) -> Layout:
        """The tactor layout."""
        return self.layout.to_layout()

    def target_set(self) -> TargetSet:
        """The candidate targets."""
        return self.targets.to_target_set()

    def n_training_trials(self) -> int:
        return self.training.passes * len(self.training.conditions) * self.targets.count

    def n_test_trials(self) -> int:
        return sum(b.repetitions for b in self.test) * self.targets.count

    def n_trials(self) -> int:
        return self.n_training_trials() + self.n_test_trials()

    def estimate_duration_s(self, response_s: float = 2.0, break_s: float = 60.0) -> float:
        """A rough session length: each trial takes ``response_s`` plus the ITI, plus breaks."""
        n = self.n_trials()
        rt = min(response_s, self.response.timeout_s)
        n_breaks = (n - 1) // self.session.break_every if self.session.break_every else 0
        return n * (rt + self.session.iti_s) + n_breaks * break_s

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
    for part in loc[:-1]:
        if isinstance(part, int):
            continue
        field = model.model_fields.get(part)
        if field is None:
            return None
        ann = field.annotation
        inner = getattr(ann, "__args__", None)
        if isinstance(ann, type) and issubclass(ann, BaseModel):
            model = ann
        elif inner and isinstance(inner[0], type) and issubclass(inner[0], BaseModel):
            model = inner[0]
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


def _study_error(exc: ValidationError, text: str, where: str) -> StudyFileError:
    err = exc.errors(include_url=False)[0]
    loc = tuple(p for p in err["loc"] if not (isinstance(p, str) and "[" in p))
    lines = _key_lines(text)
    line = _line_for(loc, lines)
    dotted = ".".join(f"[{p}]" if isinstance(p, int) else str(p) for p in loc).replace(".[", "[")
    kind = err["type"]
    msg = err["msg"]
    got = err.get("input")
    if kind == "extra_forbidden":
        allowed = _allowed_keys(loc)
        msg = f"unknown key {loc[-1]!r}" + (
            f"; allowed here: {', '.join(allowed)}" if allowed else ""
        )
    elif kind == "missing":
        msg = "required but missing"
        if line is None and len(loc) == 1:
            line = None
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
    if not dotted:
        dotted = None  # type: ignore[assignment]
    return StudyFileError(msg, path=where, line=line, field=dotted)


# -- the paper's protocol ------------------------------------------------------------

PAPER_STUDY_TOML = '''\
# tactorbelt study file: the protocol of Eguchi et al., "Between-Tactor Display
# Using Dynamic Tactile Stimuli". Edit it, then check it with
#   tactorbelt study check THIS_FILE
# Angles are degrees, 0 = navel (front), growing clockwise seen from above.

name = "between-tactor-paper"
description = "6 tactors, 24 targets; training, then static and dynamic test blocks"

[layout]
# Either the number of evenly spaced tactors (at 180/N + k*360/N, so the two front
# tactors are equally distant from the navel) ...
tactors = 6
# ... or their angles, one per tactor (tactor k is the k-th angle):
# angles_deg = [30, 90, 150, 210, 270, 330]

[targets]
count = 24                # targets at k*360/count; on-tactor where one meets a tactor

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
