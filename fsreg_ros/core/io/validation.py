"""Pydantic validation errors as one-line, path-precise file errors.

Scenario and lexicon files are both validated with pydantic models; this module
turns the first problem pydantic finds (by line) into one
:class:`~fsreg_ros.core.io.yaml_source.SourceError` naming the file, the path inside it
and the line: ``table1.yaml:12: domains.faces.threshold: must be a number, got 'x'``.
"""

from __future__ import annotations

from typing import Any, Callable, Mapping, Optional

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError

from .yaml_source import SourceError, describe_value, find_line, render_path


class Strict(BaseModel):
    """Base of every file model: unknown keys are errors, types are strict."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)


_EXPECTED = {
    "string_type": "must be a string",
    "float_type": "must be a number",
    "int_type": "must be a whole number",
    "list_type": "must be a list",
    "dict_type": "must be a mapping",
    "model_type": "must be a mapping",
    "model_attributes_type": "must be a mapping",
    "finite_number": "must be a finite number",
    "string_too_short": "must not be empty",
}


def validate(
    model: type[BaseModel],
    data: Any,
    source: str,
    root: Optional[yaml.Node],
    error: type[SourceError],
    known_keys: Callable[[list], tuple],
    clean: Callable[[list], list] = list,
) -> Any:
    """Return ``model`` validated from ``data``, or raise ``error`` for its first problem.

    ``known_keys(loc)`` lists the keys allowed in the mapping at ``loc`` (for
    "unknown key" messages); ``clean(loc)`` drops pydantic's internal segments
    (union tags) from an error location.  A missing key ranks after every other
    problem: with a misspelt key, "unknown key ..., known: ..." is the helpful one.
    """
    try:
        return model.model_validate(data)
    except ValidationError as err:
        errors = err.errors()
        problems = [_problem(e, source, root, error, known_keys, clean) for e in errors]
        ranked = sorted(
            zip(errors, problems),
            key=lambda pair: (pair[0]["type"] == "missing", pair[1].line is None, pair[1].line or 0),
        )
        raise ranked[0][1] from None


def _problem(
    problem: Mapping[str, Any],
    source: str,
    root: Optional[yaml.Node],
    error: type[SourceError],
    known_keys: Callable[[list], tuple],
    clean: Callable[[list], list],
) -> SourceError:
    loc = clean(list(problem["loc"]))
    kind, value = problem["type"], problem.get("input")
    if loc and loc[-1] == "[key]":
        loc.pop()
        key = loc[-1] if loc else value
        message = f"key {expected(kind, problem['msg'])}, got {describe_value(key)}"
        line, _ = find_line(root, tuple(loc))
        return error(source, render_path(loc[:-1] + [str(key)]), message, line)
    if kind == "extra_forbidden":
        message = f"unknown key '{loc[-1]}' (known: {', '.join(known_keys(loc[:-1]))})"
    elif kind == "missing":
        parent = loc[:-1]
        line, _ = find_line(root, tuple(parent))
        return error(source, render_path(parent), f"missing required key '{loc[-1]}'", line)
    elif kind == "value_error":
        message = str(problem["msg"]).removeprefix("Value error, ")
    else:
        message = f"{expected(kind, problem['msg'])}, got {describe_value(value)}"
    line, _ = find_line(root, tuple(loc))
    return error(source, render_path(loc), message, line)


def expected(kind: str, pydantic_message: str) -> str:
    """Return what a value must be, in this project's words, for pydantic error ``kind``."""
    if kind in _EXPECTED:
        return _EXPECTED[kind]
    return pydantic_message.replace("Input should be", "must be")
