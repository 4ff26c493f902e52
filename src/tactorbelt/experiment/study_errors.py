"""Where a study file is wrong, in a person's words: pydantic's validation errors mapped to
the file, line and dotted field of the first problem (:func:`study_error`).

Pure: the standard library and pydantic's error objects; the study's model is passed in.
"""

from __future__ import annotations

import difflib
import re
import types
import typing
from typing import Any

from pydantic import BaseModel, ValidationError

from .._errors import StudyFileError

__all__ = ["key_lines", "study_error"]


_HEADER = re.compile(r"^\s*(\[\[?)\s*([^\]]+?)\s*\]\]?\s*(#.*)?$")
_KEY = re.compile(r"^\s*([A-Za-z0-9_\-\.\"' ]+?)\s*=")


def key_lines(text: str) -> dict[tuple[str | int, ...], int]:
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


def _model_at(root: Any, loc: tuple[str | int, ...]) -> Any:
    """The pydantic model that holds the last key of ``loc`` (None if not a model)."""
    tp: Any = root
    for part in loc[:-1]:
        if isinstance(tp, type) and issubclass(tp, BaseModel):
            field = tp.model_fields.get(str(part))
            tp = None if field is None else field.annotation
            args = [a for a in typing.get_args(tp) if a is not type(None)]
            if isinstance(tp, types.UnionType) and len(args) == 1:  # X | None
                tp = args[0]
        else:  # the key of a dict (tasks.NAME) or an index of a list
            tp = (typing.get_args(tp) or (None,))[-1]
    return tp if isinstance(tp, type) and issubclass(tp, BaseModel) else None


def _range_text(root: Any, loc: tuple[str | int, ...]) -> str | None:
    """The allowed range of a numeric field, e.g. ``(0, 1]``, from its constraints."""
    model = _model_at(root, loc)
    if model is None or not isinstance(loc[-1], str) or loc[-1] not in model.model_fields:
        return None
    c = {k: getattr(m, k) for m in model.model_fields[loc[-1]].metadata
         for k in ("ge", "gt", "le", "lt") if getattr(m, k, None) is not None}
    lo, hi = c.get("ge", c.get("gt")), c.get("le", c.get("lt"))
    if lo is None and hi is None:
        return None
    lo_s = "-inf" if lo is None else f"{lo:g}"
    hi_s = "inf" if hi is None else f"{hi:g}"
    return f"{'[' if 'ge' in c else '('}{lo_s}, {hi_s}{']' if 'le' in c else ')'}"


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


def study_error(exc: ValidationError, text: str, where: str, root: Any) -> StudyFileError:
    """The StudyFileError for pydantic's ``exc`` on a study ``text`` (file ``where``): the
    first problem, with its line, dotted field and words a person reads; ``root`` is the
    model the text was validated as."""
    errors = exc.errors(include_url=False)
    err = errors[0]
    loc = _clean_loc(err["loc"], key_last=err["type"] == "extra_forbidden")
    lines = key_lines(text)
    kind = err["type"]
    msg = err["msg"]
    got = err.get("input")
    # a misspelt required key: report the unknown key and the missing one together
    missing = {_clean_loc(e["loc"]) for e in errors if e["type"] == "missing"}
    extra = [_clean_loc(e["loc"], key_last=True) for e in errors
             if e["type"] == "extra_forbidden"]
    pair = next(((x, m) for x in extra for m in missing
                 if x[:-1] == m[:-1] and isinstance(x[-1], str) and isinstance(m[-1], str)
                 and difflib.get_close_matches(x[-1], [m[-1]], n=1)), None)
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
        model = _model_at(root, loc)
        allowed = list(model.model_fields) if model is not None else []
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
        rng = _range_text(root, loc)
        msg = (f"must be in {rng}" if rng else msg) + f" (got {got!r})"
    elif kind in ("int_type", "float_type", "string_type", "bool_type", "list_type"):
        what = {"int_type": "an integer", "float_type": "a number", "string_type": "a string",
                "bool_type": "true or false", "list_type": "a list"}[kind]
        rng = _range_text(root, loc)
        msg = f"must be {what}" + (f" in {rng}" if rng else "") + f" (got {got!r})"
    else:
        msg = msg[0].lower() + msg[1:]
        if not isinstance(got, dict | list):
            msg += f" (got {got!r})"
    return StudyFileError(msg, path=where, line=line, field=dotted)

