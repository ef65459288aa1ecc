r"""The wire codec: one JSON object per ``std_msgs/String`` or service field (docs/semantics.md §7).

Decoding (:func:`parse`) is bounded (a text longer than
``max_bytes`` is refused before it is parsed) and checks fields against a small spec
(:func:`check_fields`: a type, a tuple of types with ``None`` for JSON ``null``, or
``list[T]`` / ``dict[str, T]``); a problem raises :class:`MessageError` naming the field
and what is wrong.  ``float`` accepts whole numbers; ``int`` never accepts
``true``/``false``; NaN and infinities are never valid JSON here.

Encoding (:func:`dumps`) refuses what is not JSON.  Error replies go
through :func:`error_json`/:func:`safe_dumps`, which never raise: non-finite numbers,
integers too long to print, lone surrogates (``"\ud800"``) and unserialisable values
become printable text, and long texts are clipped.  :func:`printable` makes any text
safe for a ROS logger (which raises on a lone surrogate).

This module imports no ROS package (the ``std_msgs/String`` glue is :mod:`fsreg_ros.carrier`'s).
"""

from __future__ import annotations

import json
import math
import types
from typing import Any, Mapping, Optional, Union

#: Field spec for "any JSON number" (whole numbers included, booleans excluded).
NUMBER = (int, float)
#: Longest error text put in a reply or a log line (characters).
MAX_ERROR_CHARS = 500


class MessageError(ValueError):
    """A message or request that is not what it must be.

    Not JSON, not an object, too big, a missing or wrong-typed field, an unknown op:
    the text says which field and why.
    """


# ----------------------------------------------------------------- encoding
def dumps(obj: Mapping[str, Any]) -> str:
    """Return the compact JSON text of one object (NaN/Infinity refused: they are not JSON)."""
    return json.dumps(obj, separators=(",", ":"), allow_nan=False)


def printable(text: Any, limit: int = MAX_ERROR_CHARS) -> str:
    """Return ``text`` clipped to ``limit`` characters, lone surrogates escaped (never raises)."""
    try:
        text = str(text)
    except Exception:  # noqa: BLE001 - a __str__ that fails
        text = f"<unprintable {type(text).__name__}>"
    text = text.encode("utf-8", "backslashreplace").decode("utf-8")
    return _clip(text, limit)


def _sanitise(value: Any, depth: int = 0) -> Any:
    """Return a JSON-safe copy of ``value``: what JSON cannot carry becomes text."""
    if depth > 20:
        return "..."
    if value is None or isinstance(value, bool):
        return value
    if isinstance(value, int):
        return value if abs(value) < 10**300 else printable(f"<integer of {value.bit_length()} bits>")
    if isinstance(value, float):
        return value if math.isfinite(value) else repr(value)
    if isinstance(value, str):
        return printable(value)
    if isinstance(value, (list, tuple)):
        return [_sanitise(v, depth + 1) for v in list(value)[:100]]
    if isinstance(value, Mapping):
        return {printable(k, 100): _sanitise(v, depth + 1) for k, v in list(value.items())[:100]}
    return printable(repr(value))


def safe_dumps(obj: Mapping[str, Any]) -> str:
    """Return JSON text for ``obj``, sanitised if it is not JSON as it stands; never raises."""
    try:
        return dumps(obj)
    except (TypeError, ValueError, RecursionError, OverflowError):
        pass
    try:
        return dumps(_sanitise(obj))
    except Exception as err:  # noqa: BLE001 - the last resort must not fail
        return dumps({"error": f"reply not serialisable: {type(err).__name__}", "kind": "internal"})


def error_json(error: Any, kind: Optional[str] = None, rid: Any = None, **fields: Any) -> str:
    """Return the JSON text of an error reply ``{"error", "kind"?, "id"?, ...}``; never raises."""
    reply: dict[str, Any] = {"error": printable(error)}
    if kind is not None:
        reply["kind"] = printable(kind, 100)
    if rid is not None:
        reply["id"] = rid
    reply.update(fields)
    return safe_dumps(reply)


def _reject_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def parse(
    text: str,
    required: Optional[Mapping[str, "FieldSpec"]] = None,
    optional: Optional[Mapping[str, "FieldSpec"]] = None,
    *,
    max_bytes: Optional[int] = None,
) -> dict:
    """Decode one JSON object from ``text`` and check its fields (see :func:`check_fields`).

    A text of more than ``max_bytes`` UTF-8 bytes is refused before it is parsed.
    """
    if not isinstance(text, str):
        raise MessageError(f"expected JSON text, got {type(text).__name__}")
    if max_bytes is not None and len(text) > max_bytes // 4:
        size = len(text.encode("utf-8", "surrogatepass"))
        if size > max_bytes:
            raise MessageError(f"message is {size} bytes, over the limit of {max_bytes}")
    try:
        obj = json.loads(text, parse_constant=_reject_constant)
    except (ValueError, RecursionError) as err:
        raise MessageError(f"not JSON ({printable(err, 120)}): {printable(text, 80)}") from None
    if not isinstance(obj, dict):
        raise MessageError(f"expected a JSON object, got {_json_kind(obj)}: {printable(text, 80)}")
    return check_fields(obj, required or {}, optional)


def request_id(data: Any) -> Any:
    """Return the ``id`` of a decoded request if it is a usable id (a string or an integer), else None."""
    if not isinstance(data, Mapping):
        return None
    value = data.get("id")
    if isinstance(value, str) or (isinstance(value, int) and not isinstance(value, bool)):
        return value
    return None


def id_of(text: Any) -> Any:
    """Return the usable ``id`` of raw JSON text (or a String message), None if there is none."""
    try:
        return request_id(json.loads(getattr(text, "data", text)))
    except (TypeError, ValueError, RecursionError):
        return None


FieldSpec = Union[type, tuple, types.GenericAlias, None]


def check_fields(
    obj: Mapping[str, Any],
    required: Mapping[str, FieldSpec],
    optional: Optional[Mapping[str, FieldSpec]] = None,
) -> dict:
    """Check the fields of an already decoded object; return it as a dict."""
    for name, spec in required.items():
        if name not in obj:
            raise MessageError(f"missing field '{name}' (expected {describe(spec)})")
        _check_value(name, obj[name], spec)
    for name, spec in (optional or {}).items():
        if name in obj:
            _check_value(name, obj[name], spec)
    return dict(obj)


def describe(spec: FieldSpec) -> str:
    """English for a field spec: ``list[str]`` -> ``"a list of strings"``."""
    if spec is None or spec is type(None):
        return "null"
    if isinstance(spec, tuple):
        return " or ".join(describe(s) for s in spec)
    if isinstance(spec, types.GenericAlias):
        origin, args = spec.__origin__, spec.__args__
        if origin is list:
            return f"a list of {_plural(args[0])}"
        if origin is dict:
            return f"an object of {_plural(args[0]).replace('strings', 'names')} to {_plural(args[1])}"
    return {
        str: "a string",
        int: "a whole number",
        float: "a number",
        bool: "true or false",
        list: "a list",
        dict: "an object",
    }.get(spec, getattr(spec, "__name__", str(spec)))


def _plural(spec: FieldSpec) -> str:
    if spec == NUMBER or spec is float:
        return "numbers"
    return {str: "strings", int: "whole numbers", bool: "booleans", dict: "objects", list: "lists"}.get(
        spec, describe(spec)
    )


def _matches(value: Any, spec: FieldSpec) -> bool:
    if spec is None or spec is type(None):
        return value is None
    if isinstance(spec, tuple):
        return any(_matches(value, s) for s in spec)
    if isinstance(spec, types.GenericAlias):
        origin, args = spec.__origin__, spec.__args__
        if origin is list:
            return isinstance(value, list) and all(_matches(v, args[0]) for v in value)
        if origin is dict:
            return isinstance(value, dict) and all(
                _matches(k, args[0]) and _matches(v, args[1]) for k, v in value.items()
            )
        raise TypeError(f"unsupported field spec {spec!r}")
    if spec is bool:
        return isinstance(value, bool)
    if isinstance(value, bool):
        return False  # JSON true/false is not a number
    if spec is float:
        return isinstance(value, (int, float)) and math.isfinite(value)
    return isinstance(value, spec)


def _check_value(name: str, value: Any, spec: FieldSpec) -> None:
    if _matches(value, spec):
        return
    where = f"field '{name}'"
    if isinstance(spec, types.GenericAlias) and spec.__origin__ is list and isinstance(value, list):
        for i, item in enumerate(value):
            if not _matches(item, spec.__args__[0]):
                raise MessageError(
                    f"{where}[{i}]: expected {describe(spec.__args__[0])}, got {_show(item)}"
                )
    if isinstance(spec, types.GenericAlias) and spec.__origin__ is dict and isinstance(value, dict):
        for key, item in value.items():
            if not _matches(item, spec.__args__[1]):
                raise MessageError(f"{where}['{key}']: expected {describe(spec.__args__[1])}, got {_show(item)}")
    raise MessageError(f"{where}: expected {describe(spec)}, got {_show(value)}")


def _json_kind(value: Any) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, (int, float)):
        return "a number"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "a list"
    return "an object"


def _show(value: Any) -> str:
    try:
        text = json.dumps(value)
    except (TypeError, ValueError, RecursionError):
        text = printable(value, 80)
    return f"{_json_kind(value)} ({printable(text, 80)})"


def _clip(text: str, limit: int = 80) -> str:
    text = str(text)
    return text if len(text) <= limit else text[: limit - 3] + "..."
