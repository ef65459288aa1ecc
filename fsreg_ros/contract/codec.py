r"""The wire codec: one JSON object per ``std_msgs/String`` or service field (docs/semantics.md §7).

Decoding is done in one place, :func:`_decode`, which every reader of wire text goes
through (:func:`parse`, and :func:`id_of`/:func:`leading_id`, which read a request's id
for an error reply): whatever the text, it returns a value or raises
:class:`MessageError`, never anything else.  It refuses nesting deeper than
:data:`MAX_DEPTH` (checked without recursion, so no ``RecursionError`` can leave it),
a lone surrogate (``"\ud800"``: not Unicode), and NaN and infinities (``NaN``, ``Infinity``, ``1e999``:
never valid JSON here, in any field; the error names the field).  :func:`parse` is
also bounded in size (a text longer than ``max_bytes`` is refused before it is parsed)
and returns one JSON object.  What the object's fields must be is the contract's
business (:func:`fsreg_ros.contract.check`, whose one-line errors use :func:`describe`
for the expected types).  Bytes that are not UTF-8 never get here: rclpy's generated
message code decodes a string field with U+FFFD for each invalid byte (measured on a
topic with this project's Jazzy wheels; a service request's field is the same code).

Encoding (:func:`dumps`) refuses what is not JSON.  Error replies go
through :func:`error_json`/:func:`safe_dumps`, which never raise: non-finite numbers,
integers too long to print, lone surrogates (``"\ud800"``) and unserialisable values
become printable text, and long texts are clipped.  :func:`printable` makes any text
safe for a ROS logger (which raises on a lone surrogate).

This module imports no ROS package (the ``std_msgs/String`` glue is :mod:`fsreg_ros.ros.carrier`'s).
"""

from __future__ import annotations

import json
import math
import re
import types
from typing import Any, Mapping, Optional, Union

#: Longest error text put in a reply or a log line (characters).
MAX_ERROR_CHARS = 500


class MessageError(ValueError):
    """A message or request that is not what it must be.

    Not JSON, not an object, too big, a missing or wrong-typed field, an unknown op:
    the text says which field and why.
    """


class TooLarge(MessageError):
    """A message over the receiver's ``max_message_bytes`` (error kind ``too-large``)."""

    kind = "too-large"


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


#: Deepest nesting of arrays and objects in a message (the top-level object is level 1).
#: The contract's deepest message nests 4 (a fact batch: object, ``facts``, a fact,
#: its ``properties``); 32 leaves room for extra fields and stays far below Python's
#: recursion limit, so nothing that walks a decoded message (validation, error
#: replies) can run out of stack.
MAX_DEPTH = 32


def _reject_constant(name: str) -> Any:
    raise ValueError(f"{name} is not a JSON number")


def _non_finite_path(value: Any, depth: int = 0) -> Optional[list]:
    """Return the path to the first non-finite float in a decoded value (None if there is none)."""
    if isinstance(value, float):
        return [] if not math.isfinite(value) else None
    if depth > MAX_DEPTH:
        return None
    items = value.items() if isinstance(value, dict) else enumerate(value) if isinstance(value, list) else ()
    for key, item in items:
        found = _non_finite_path(item, depth + 1)
        if found is not None:
            return [key, *found]
    return None


def _too_deep(value: Any, limit: int = MAX_DEPTH) -> bool:
    """Whether a decoded value nests arrays and objects deeper than ``limit`` (level by level, no recursion)."""
    level = [value] if type(value) in (dict, list) else []
    for _ in range(limit):
        below = []
        for node in level:
            for child in node.values() if type(node) is dict else node:
                kind = type(child)
                if kind is dict or kind is list:
                    below.append(child)
        if not below:
            return False
        level = below
    return True


#: An escaped UTF-16 surrogate in JSON text (``\ud800``); decoded alone it is no character.
_SURROGATE_ESCAPE = re.compile(r"\\u[dD][89a-fA-F]")


def _lone_surrogate(value: Any) -> bool:
    """Whether a decoded value holds a string (or key) with a lone surrogate."""
    try:
        json.dumps(value, ensure_ascii=False).encode("utf-8")
    except UnicodeEncodeError:
        return True
    return False


def _decode(text: str, start: int = 0, *, whole: bool = True) -> tuple[Any, int]:
    """Decode the JSON value at ``text[start:]``: (value, end); :class:`MessageError` whatever is wrong.

    The one place wire text is decoded.  ``whole``: the value must be all of the text
    (but whitespace).  Refused: not JSON, ``NaN``/``Infinity``/``1e999``, nesting deeper than
    :data:`MAX_DEPTH`, a lone surrogate.  Never raises anything else.  A key given twice in
    one object: the last counts, as for every JSON reader of fsreg's (refusing it cost
    about half again the decoding time of a fact batch).
    """
    too_large: list[str] = []

    def parse_float(number: str) -> float:
        value = float(number)
        if not math.isfinite(value):  # 1e999: JSON syntax, but no number; located below
            too_large.append(number)
        return value

    decoder = json.JSONDecoder(parse_constant=_reject_constant, parse_float=parse_float)
    try:
        if whole:
            value, end = decoder.decode(text), len(text)
        else:
            value, end = decoder.raw_decode(text, start)
    except RecursionError:
        raise MessageError(f"nested deeper than {MAX_DEPTH} levels: {printable(text[start:], 80)}") from None
    except (ValueError, TypeError) as err:  # json's errors, and int() of a number over its digit limit
        raise MessageError(f"not JSON ({printable(err, 120)}): {printable(text[start:], 80)}") from None
    piece = text if whole and not start else text[start:end]
    if piece.count("[") + piece.count("{") > MAX_DEPTH and _too_deep(value):
        raise MessageError(f"nested deeper than {MAX_DEPTH} levels: {printable(piece, 80)}")
    if (_SURROGATE_ESCAPE.search(piece) and _lone_surrogate(value)) or (not piece.isascii() and _lone_surrogate(piece)):
        raise MessageError(f"a string with a lone surrogate (not Unicode): {printable(piece, 80)}")
    if too_large:
        path = _non_finite_path(value) or ["?"]
        where = f"field '{printable(path[0], 60)}'" + "".join(f"[{printable(repr(p), 40)}]" for p in path[1:])
        raise MessageError(f"{where}: {_clip(too_large[0], 40)} is too large for a number (not finite)")
    return value, end


def parse(text: str, *, max_bytes: Optional[int] = None) -> dict:
    """Decode one JSON object from ``text``; MessageError if it is not one.

    A text of more than ``max_bytes`` UTF-8 bytes is refused before it is parsed.
    """
    if not isinstance(text, str):
        raise MessageError(f"expected JSON text, got {type(text).__name__}")
    if max_bytes is not None and len(text) > max_bytes // 4:
        size = len(text.encode("utf-8", "surrogatepass"))
        if size > max_bytes:
            raise TooLarge(f"message is {size} bytes, over the limit of {max_bytes}")
    obj, _ = _decode(text)
    if not isinstance(obj, dict):
        raise MessageError(f"expected a JSON object, got {_json_kind(obj)}: {printable(text, 80)}")
    return obj


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
    text = getattr(text, "data", text)
    if not isinstance(text, str):
        return None
    try:
        return request_id(_decode(text)[0])
    except MessageError:
        return None


#: Characters of an oversized message searched for its top-level ``id`` (it is never parsed whole).
ID_SCAN_CHARS = 65_536


def leading_id(text: Any, limit: int = ID_SCAN_CHARS) -> Any:
    """Return the top-level ``id`` of JSON object text found within its first ``limit`` characters, else None.

    For a message refused as too large: its answer can still name the request (a
    client writes ``id`` before the bulk), without parsing the whole text.  The key
    and its value are decoded by :func:`_decode`, so no text makes this raise.
    """
    if not isinstance(text, str) or not text.lstrip().startswith("{"):
        return None
    head, depth, i, n = text[:limit], 0, 0, min(len(text), limit)
    while i < n:
        ch = head[i]
        if ch == '"':
            try:
                key, end = _decode(head, i, whole=False)
            except MessageError:
                return None
            j = end
            while j < n and head[j] in " \t\r\n":
                j += 1
            if depth == 1 and key == "id" and j < n and head[j] == ":":
                j += 1
                while j < n and head[j] in " \t\r\n":
                    j += 1
                try:
                    value, _ = _decode(head, j, whole=False)
                except MessageError:
                    return None
                return request_id({"id": value})
            i = end
            continue
        if ch in "{[":
            depth += 1
        elif ch in "}]":
            depth -= 1
        i += 1
    return None


#: A type in the words of :func:`describe`: a type, a tuple of them (``None`` for JSON
#: ``null``), or ``list[T]`` / ``dict[str, T]``.
FieldSpec = Union[type, tuple, types.GenericAlias, None]


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
    if spec == (int, float) or spec is float:
        return "numbers"
    return {str: "strings", int: "whole numbers", bool: "booleans", dict: "objects", list: "lists"}.get(
        spec, describe(spec)
    )


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


def _clip(text: str, limit: int = 80) -> str:
    text = str(text)
    return text if len(text) <= limit else text[: limit - 3] + "..."
