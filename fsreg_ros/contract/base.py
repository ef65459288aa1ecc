"""The base of every fsreg message schema (pydantic; no ROS import).

Every topic carries ``std_msgs/msg/String`` whose ``data`` is one JSON object; every
service is ``diagnostic_msgs/srv/AddDiagnostics`` with the request JSON in
``load_namespace`` and the reply JSON in ``message`` (``success=false`` means the reply
is an :class:`ErrorReply`).  The models allow extra fields (a newer peer may add some)
but fix the type of every named one.

Field types shared by the schemas: :data:`Number` (a JSON number a float can hold:
``1e400`` and a 400-digit integer are refused), :data:`Whole` and :data:`Count` (a whole
number so bounded; a count is >= 0), :data:`Name` and :data:`Names` (an
entity, property, domain or target name, and a list of them: bounded by the receiving
node's :class:`~fsreg_ros.contract.limits.Limits`, given as the validation context
``{"limits": limits}``; without it only their types are checked), and
:data:`NameNumbers` (a mapping of names to numbers, bounded alike).
"""

from __future__ import annotations

import math
from typing import Annotated, Any, Optional, Union

from pydantic import AfterValidator, BaseModel, BeforeValidator, ConfigDict, ValidationInfo

Id = Union[str, int]


def _representable(value: Union[int, float]) -> Union[int, float]:
    """Refuse an integer no float can hold (JSON allows any length; every consumer computes in floats)."""
    if isinstance(value, int) and not isinstance(value, bool):
        try:
            math.isfinite(value)
        except OverflowError:
            raise ValueError(f"a number too large ({value.bit_length()} bits; at most about 1e308)") from None
    return value


Number = Annotated[Union[int, float], AfterValidator(_representable)]
#: A whole number a float can hold.
Whole = Annotated[int, AfterValidator(_representable)]


def _not_negative(value: int) -> int:
    if value < 0:
        raise ValueError(f"expected a whole number >= 0, got {value!r}")
    return value


#: A whole number >= 0 a float can hold (a count, an index).
Count = Annotated[Whole, AfterValidator(_not_negative)]


def _limits(info: ValidationInfo) -> Any:
    return (info.context or {}).get("limits") if isinstance(info.context, dict) else None


def _name_within_limits(value: str, info: ValidationInfo) -> str:
    limits = _limits(info)
    if limits is not None and len(value) > limits.max_name_chars:
        raise ValueError(f"a name of {len(value)} characters, over the limit of {limits.max_name_chars}")
    return value


def _list_within_limits(value: Any, info: ValidationInfo) -> Any:
    limits = _limits(info)
    if limits is not None and isinstance(value, (list, dict)) and len(value) > limits.max_list_items:
        raise ValueError(f"{len(value)} items, over the limit of {limits.max_list_items}")
    return value


#: One name (entity, property, domain, target), bounded by ``max_name_chars``.
Name = Annotated[str, AfterValidator(_name_within_limits)]
#: A list of names, bounded by ``max_list_items`` (checked before its items).
Names = Annotated[list[Name], BeforeValidator(_list_within_limits)]
#: A mapping name -> number (facts: property -> certainty), bounded like a list of names.
NameNumbers = Annotated[dict[Name, Number], BeforeValidator(_list_within_limits)]


def bounded_list(item: Any) -> Any:
    """Return the type of a list of ``item`` bounded by ``max_list_items`` (checked before its items)."""
    return Annotated[list[item], BeforeValidator(_list_within_limits)]


class Message(BaseModel):
    """Base of every schema: strict types, no NaN/Infinity, extra fields allowed."""

    model_config = ConfigDict(strict=True, allow_inf_nan=False, extra="allow")


class RequestRef(Message):
    """Which request an id is already taken by: its ``client`` (null if it gave none) and fingerprint."""

    client: Optional[str] = None
    request: str


class ErrorReply(Message):
    """A failed service call (``success=false``) or an error on a reply topic.

    ``kind`` names the error (every error reply carries one; docs/semantics.md §7 lists
    them); on a service reply it is the server's exception class (``KnowledgeError``) or
    a carrier kind (``not-ready``, ``too-large``), and ``detail`` the specific kind
    (``unknown-entity``, ``unknown-property``) when there is one.
    """

    error: str
    kind: Optional[str] = None
    id: Optional[Id] = None
    detail: Optional[str] = None


class Stamp(Message):
    """When and in which turn something was said (robot-clock seconds; turn index)."""

    time: Optional[Number] = None
    turn: Optional[int] = None
