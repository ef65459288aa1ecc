"""The base of every fsreg message schema (pydantic; no ROS import).

Every topic carries ``std_msgs/msg/String`` whose ``data`` is one JSON object; every
service is ``diagnostic_msgs/srv/AddDiagnostics`` with the request JSON in
``load_namespace`` and the reply JSON in ``message`` (``success=false`` means the reply
is an :class:`ErrorReply`).  The models allow extra fields (a newer peer may add some)
but fix the type of every named one.
"""

from __future__ import annotations

from typing import Optional, Union

from pydantic import BaseModel, ConfigDict

Id = Union[str, int]
Number = Union[int, float]


class Message(BaseModel):
    """Base of every schema: strict types, no NaN/Infinity, extra fields allowed."""

    model_config = ConfigDict(strict=True, allow_inf_nan=False, extra="allow")


class ErrorReply(Message):
    """A failed service call (``success=false``) or an error on a reply topic."""

    error: str
    kind: Optional[str] = None
    id: Optional[Id] = None


class Stamp(Message):
    """When and in which turn something was said (robot-clock seconds; turn index)."""

    time: Optional[Number] = None
    turn: Optional[int] = None
