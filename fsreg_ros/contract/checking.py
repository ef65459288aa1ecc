"""Checking a decoded message against its schema, with one-line errors naming the field."""

from __future__ import annotations

import types
from typing import Any, Literal, Union, get_args, get_origin

from pydantic import BaseModel, ValidationError

from ..codec import MessageError, describe, printable


def check(model: type[BaseModel], data: dict) -> dict:
    """Return ``data`` unchanged if it fits ``model``; else raise :class:`MessageError` naming the field."""
    try:
        model.model_validate(data)
    except ValidationError as err:
        raise MessageError(_first_problem(model, err)) from None
    return data


def _field_spec(annotation: Any) -> Any:
    """Return a :func:`~fsreg_ros.codec.describe` spec for a schema field's annotation."""
    origin, args = get_origin(annotation), get_args(annotation)
    if origin is Union:
        members = [a for a in args if a is not type(None)]
        nullable = len(members) < len(args)
        if set(members) == {int, float}:
            members = [float]
        specs = tuple(_field_spec(a) for a in members) + ((None,) if nullable else ())
        return specs[0] if len(specs) == 1 else specs
    if origin is Literal:
        return str
    if origin in (list, dict):
        return origin[tuple(_field_spec(a) for a in args)] if args else origin
    return annotation if isinstance(annotation, type) and annotation is not Any else object


_UNION_TAGS = {"str", "int", "float", "bool", "none"}


def _is_tag(part: Any) -> bool:
    """Return True for a pydantic location part that names a union member, not a key."""
    return isinstance(part, str) and (part in _UNION_TAGS or "[" in part)


def _item_spec(spec: Any) -> Any:
    """Return the spec of one item of a list/dict spec (or of the first such member of a union)."""
    for member in spec if isinstance(spec, tuple) else (spec,):
        if isinstance(member, types.GenericAlias):
            return member.__args__[-1]
    return object


def _first_problem(model: type[BaseModel], err: ValidationError) -> str:
    first = err.errors(include_url=False)[0]
    loc = first.get("loc", ())
    message = str(first.get("msg", "invalid")).removeprefix("Value error, ")
    field = loc[0] if loc and isinstance(loc[0], str) and loc[0] in model.model_fields else None
    if field is None:  # a check of the whole message (e.g. "exactly one of text and description")
        return printable(message, 200)
    if first.get("type") == "missing":
        return f"missing field '{field}'"
    keys = [p for p in loc[1:] if not _is_tag(p)]
    where = f"field '{field}'" + "".join(f"[{p!r}]" for p in keys)
    spec = _field_spec(model.model_fields[field].annotation)
    for _ in keys:
        spec = _item_spec(spec)
    got = printable(repr(first.get("input")), 60)
    if first.get("type") in ("literal_error", "value_error") or spec is object:
        return printable(f"{where}: {message}, got {got}", 300)
    return printable(f"{where}: expected {describe(spec)}, got {got}", 300)
