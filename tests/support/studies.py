"""Study files for tests: the paper's protocol with keyword overrides.

    from support.studies import make_study, study_toml, write_study

    text = study_toml(tactors=4, targets=8, repetitions=1, training=0, timeout_s=3.0)
    path = write_study(tmp_path, conditions=["dynamic"], iti_s=0.05)
    study = make_study(condition_order="latin")

The base is ``PAPER_STUDY_TOML`` (what ``tactorbelt study init`` writes), so a test
states only what it changes. Keywords:

- ``name``, ``description``;
- ``tactors``: a count (``[layout] tactors``) or a list of angles (``angles_deg``);
- ``targets``: the target count;
- any key of ``[stimulus]``, ``[response]`` or ``[session]`` by its own name
  (``law``, ``period_s``, ``timeout_s``, ``home_radius``, ``iti_s``, ``break_every``,
  ``seed``, ``condition_order``, ...);
- ``training``: the number of training passes (0: none); ``training_conditions``,
  ``training_order``;
- ``conditions`` (one test block per condition, in order; default static, dynamic) and
  ``repetitions`` (of every such block; default 5), or ``blocks`` for full control: a
  list of ``{"condition": ..., "repetitions": ..., "name": ...}`` tables;
- ``design``: a ``[design]`` table (``{"targets": [12, 24], "condition": [...], ...}``);
  it replaces the ``[[test]]`` blocks unless ``blocks`` is given too (to test that
  conflict), and drops ``session.condition_order`` unless ``condition_order`` is given;
- ``tasks``: ``{"nback2": {"kind": "nback", "n": 2}}``, written as ``[tasks.NAME]``
  tables; ``questionnaire``: the ``[questionnaire]`` table (``{"tlx": True}``);
- ``minimal=True``: only the required keys (name, layout, targets, test), so the
  file's defaults apply to everything else.

A value of ``None`` leaves the key out. Nothing is validated here (a test of a bad
value writes it as it is); :func:`make_study` parses the text with ``Study.from_toml``.
An unknown keyword raises ``TypeError``, so a typo cannot pass silently.
"""

from __future__ import annotations

import tomllib
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import tomli_w

from tactorbelt.experiment.study import (
    PAPER_STUDY_TOML,
    ResponseSpec,
    SessionSpec,
    StimulusSpec,
    Study,
)

__all__ = ["make_study", "study_dict", "study_toml", "write_study"]

#: keyword -> the table that holds it, for the tables whose keys are unique names
_TABLE_OF: dict[str, str] = {
    **{k: "stimulus" for k in StimulusSpec.model_fields},
    **{k: "response" for k in ResponseSpec.model_fields},
    **{k: "session" for k in SessionSpec.model_fields},
}
_TABLE_ORDER = ("layout", "targets", "stimulus", "response", "session", "training",
                "design", "tasks", "questionnaire")
_REQUIRED = ("name", "layout", "targets", "test")
#: "not given": the paper's value stays (None, by contrast, leaves the key out)
_KEEP: Any = type("_Keep", (), {"__repr__": lambda self: "<paper value>"})()


def study_dict(
    *,
    minimal: bool = False,
    tactors: Any = _KEEP,
    targets: Any = _KEEP,
    training: Any = _KEEP,
    training_conditions: Any = _KEEP,
    training_order: Any = _KEEP,
    conditions: Any = _KEEP,
    repetitions: Any = _KEEP,
    blocks: Any = _KEEP,
    design: Any = _KEEP,
    tasks: Any = _KEEP,
    questionnaire: Any = _KEEP,
    **keys: Any,
) -> dict[str, Any]:
    """The study as plain TOML data (see the module docstring for the keywords)."""
    data: dict[str, Any] = tomllib.loads(PAPER_STUDY_TOML)
    if minimal:
        data = {k: data[k] for k in _REQUIRED}
        data["test"] = [{k: v for k, v in b.items() if k != "name"} for b in data["test"]]
    if tactors is not _KEEP:
        data["layout"] = {}
        if isinstance(tactors, int):
            data["layout"]["tactors"] = tactors
        elif tactors is not None:
            data["layout"]["angles_deg"] = list(tactors)
    _put(data, "targets", "count", targets)
    _put(data, "training", "passes", training)
    _put(data, "training", "conditions",
         list(training_conditions) if isinstance(training_conditions, Sequence)
         else training_conditions)
    _put(data, "training", "order", training_order)
    if blocks is not _KEEP:
        if conditions is not _KEEP or repetitions is not _KEEP:
            raise TypeError("give blocks, or conditions and repetitions, not both")
        data["test"] = [dict(b) for b in blocks]
    elif conditions is not _KEEP or repetitions is not _KEEP:
        reps = 5 if repetitions is _KEEP else repetitions
        conds = [b["condition"] for b in data["test"]] if conditions is _KEEP else conditions
        data["test"] = [{"condition": c, "repetitions": reps} for c in conds]
    if design is not _KEEP and design is not None:
        data["design"] = dict(design)
        if blocks is _KEEP:
            data.pop("test", None)
        if "condition_order" not in keys:  # design.order replaces it
            data.get("session", {}).pop("condition_order", None)
    for table, value in (("tasks", tasks), ("questionnaire", questionnaire)):
        if value is not _KEEP and value is not None:
            data[table] = {k: dict(v) if isinstance(v, dict) else v for k, v in value.items()}
    for key, value in keys.items():
        if key in ("name", "description"):
            if value is None:
                data.pop(key, None)
            else:
                data[key] = value
        elif key in _TABLE_OF:
            _put(data, _TABLE_OF[key], key, value)
        else:
            raise TypeError(f"study_toml: unknown keyword {key!r}")
    return data


def _put(data: dict[str, Any], table: str, key: str, value: Any) -> None:
    if value is _KEEP:
        return
    if value is None:
        data.get(table, {}).pop(key, None)
    else:
        data.setdefault(table, {})[key] = value


def _value(v: Any) -> str:
    """One TOML value; a list of plain values on one line, as people write them."""
    if isinstance(v, list) and not any(isinstance(x, dict | list) for x in v):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    return tomli_w.dumps({"v": v}).removeprefix("v = ").rstrip("\n")


def study_toml(**overrides: Any) -> str:
    """TOML text of the study, laid out as a person writes it (``[[test]]`` blocks)."""
    data = study_dict(**overrides)
    lines = [f"{k} = {_value(v)}" for k, v in data.items() if not isinstance(v, dict | list)]
    for table in (*_TABLE_ORDER, *(k for k in data if k not in _TABLE_ORDER)):
        value = data.get(table)
        if isinstance(value, dict):
            plain = {k: v for k, v in value.items() if not isinstance(v, dict)}
            if plain or len(plain) == len(value):
                lines += ["", f"[{table}]", *(f"{k} = {_value(v)}" for k, v in plain.items())]
            for sub, inner in value.items():
                if isinstance(inner, dict):
                    lines += ["", f"[{table}.{sub}]",
                              *(f"{k} = {_value(v)}" for k, v in inner.items())]
    for block in data.get("test", []):
        lines += ["", "[[test]]", *(f"{k} = {_value(v)}" for k, v in block.items())]
    return "\n".join(lines) + "\n"


def make_study(**overrides: Any) -> Study:
    """The validated :class:`Study` (raises ``StudyFileError`` like a file would)."""
    return Study.from_toml(study_toml(**overrides), path="<support.studies>")


def write_study(directory: Path, filename: str = "study.toml", **overrides: Any) -> Path:
    """Write the study to ``directory / filename`` and return the path."""
    path = Path(directory) / filename
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(study_toml(**overrides), encoding="utf-8")
    return path
