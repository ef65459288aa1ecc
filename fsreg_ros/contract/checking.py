"""Checking a decoded message against its schema, with one-line errors naming the field.

The one translation of pydantic's errors for the wire: the first problem, as
``field 'target': expected a string, got 3`` (or the message of the project's own
check, e.g. ``field 'time': a number too large ...``), raised as
:class:`~fsreg_ros.contract.codec.MessageError`.  :func:`fsreg_ros.ros.serving.serve` and
:func:`~fsreg_ros.ros.carrier.subscribe` validate every request and message with it.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Annotated, Any, Literal, Optional, Union, get_args, get_origin

from pydantic import BaseModel, TypeAdapter, ValidationError

from .codec import MessageError, describe, printable


def check(model: Any, data: dict, limits: Optional[Any] = None) -> dict:
    """Return ``data`` unchanged if it fits ``model``; else raise :class:`MessageError` naming the field.

    ``model`` is a schema class or a union of them (a topic's or service's schema; a
    request naming an ``op`` is checked against that op's member); ``limits``
    (:class:`~fsreg_ros.contract.limits.Limits`) bounds names and lists.
    """
    model = _member_for_op(model, data)
    try:
        _adapter(model).validate_python(data, context={"limits": limits})
    except ValidationError as err:
        raise MessageError(_first_problem(model, data, err)) from None
    return data


def _member_for_op(schema: Any, data: Any) -> Any:
    """Return the union member whose ``op`` the data names (a request of one op is checked as that op)."""
    if not isinstance(data, dict) or "op" not in data:
        return schema
    for member in _members(schema):
        op = member.model_fields.get("op")
        if op is not None and get_origin(op.annotation) is Literal and data["op"] in get_args(op.annotation):
            return member
    return schema


@lru_cache(maxsize=None)
def _adapter(model: Any) -> TypeAdapter:
    return TypeAdapter(model)


def _members(schema: Any) -> list[type[BaseModel]]:
    """Return the models of a schema: itself, or the members of a union (of an ``Annotated`` union)."""
    if get_origin(schema) is Annotated:
        return _members(get_args(schema)[0])
    return [m for m in (get_args(schema) or (schema,)) if isinstance(m, type) and issubclass(m, BaseModel)]


def _model_of(schema: Any, data: Any, loc: tuple) -> tuple[type[BaseModel], tuple]:
    """Return the model an error is reported against, and the error's location within it.

    A union's errors are located under a member's tag (its class name, or the ``op``
    of a discriminated union): that member; else the member whose ``op`` the data
    names; else the first.
    """
    members = _members(schema)
    for member in members:
        op = member.model_fields.get("op")
        ops = get_args(op.annotation) if op is not None and get_origin(op.annotation) is Literal else ()
        if loc and (loc[0] == member.__name__ or loc[0] in ops):
            return member, tuple(loc[1:])
    for member in members:
        op = member.model_fields.get("op")
        if isinstance(data, dict) and op is not None and data.get("op") in get_args(op.annotation):
            return member, tuple(loc)
    return (members[0] if members else BaseModel), tuple(loc)


def _field_spec(annotation: Any) -> Any:
    """Return a :func:`~fsreg_ros.contract.codec.describe` spec for a schema field's annotation."""
    origin, args = get_origin(annotation), get_args(annotation)
    if origin is Annotated:
        return _field_spec(args[0])
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
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return dict  # a nested model is an object on the wire
    return annotation if isinstance(annotation, type) and annotation is not Any else object


_UNION_TAGS = {"str", "int", "float", "bool", "none"}


def _is_tag(part: Any) -> bool:
    """Return True for a pydantic location part that names a union member, not a key."""
    return isinstance(part, str) and (part in _UNION_TAGS or "[" in part)


def _inner(annotation: Any, part: Any) -> Any:
    """Return the annotation of item or field ``part`` of a value of ``annotation`` (``object``: unknown)."""
    origin, args = get_origin(annotation), get_args(annotation)
    if origin is Annotated:
        return _inner(args[0], part)
    if origin is Union:
        inner = [_inner(a, part) for a in args if a is not type(None)]
        known = [a for a in inner if a is not object]
        return known[0] if known else object
    if origin in (list, dict) and args:
        return args[-1]
    if isinstance(annotation, type) and issubclass(annotation, BaseModel) and part in annotation.model_fields:
        return annotation.model_fields[part].annotation
    return object


def _first_problem(schema: Any, data: Any, err: ValidationError) -> str:
    first = err.errors(include_url=False)[0]
    model, loc = _model_of(schema, data, tuple(first.get("loc", ())))
    message = str(first.get("msg", "invalid")).removeprefix("Value error, ")
    field = loc[0] if loc and isinstance(loc[0], str) and loc[0] in model.model_fields else None
    if field is None:  # a check of the whole message (e.g. "exactly one of text and description")
        return printable(message, 200)
    keys = [p for p in loc[1:] if not _is_tag(p) and p != "[key]"]
    if first.get("type") == "missing":  # of the message, or of an object inside it (a batch's fact)
        return f"missing field '{field}'" + "".join(f"[{printable(repr(p), 40)}]" for p in keys)
    is_key = "[key]" in loc  # the problem is a key of a mapping, not its value
    path = keys[:-1] if is_key else keys
    where = f"field '{field}'" + "".join(f"[{printable(repr(p), 40)}]" for p in path)
    annotation = model.model_fields[field].annotation
    for part in path:
        annotation = _inner(annotation, part)
    spec = _field_spec(annotation)
    if is_key:
        where, spec = f"{where} key {printable(repr(keys[-1]), 40)}", str
    got = printable(_show(first.get("input")), 60)
    if first.get("type") == "value_error":  # the project's own check: its message says what it got
        return printable(f"{where}: {message}", 300)
    if first.get("type") == "literal_error" or spec is object:
        return printable(f"{where}: {message}, got {got}", 300)
    return printable(f"{where}: expected {describe(spec)}, got {got}", 300)


def _show(value: Any) -> str:
    """``repr`` of an offending value; an integer too long to print is described (``repr`` raises on it)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 1000:
        return f"an integer of {value.bit_length()} bits"
    return repr(value)
