"""Schemas of the working-memory topics: ``wm/state`` and ``wm/events``."""

from __future__ import annotations

from typing import Literal, Optional, Union

from .base import Message, Number


class Origin(Message):
    """What made a property enter a WM queue: the encoding's cause and dialogue turn."""

    cause: str
    turn: Optional[int] = None


class EntryStrength(Message):
    """How strongly a WM entry is held (``WMBuffer.strength``): episode age, episodes used in, activation.

    ``activation`` is null without rule ``activation``, ``"inf"`` at an encoding's very time.
    """

    age: int
    episodes: int
    activation: Union[Number, Literal["inf"], None] = None


class WMState(Message):
    """``wm/state``: one domain's non-empty WM queues (LRU first) and its event count.

    ``incarnation`` and ``wm_version`` say which state it is: the consultant's
    incarnation and how many of its calls had changed WM (``info`` reports the count
    now; a state with the same incarnation and at least that count is current).
    """

    domain: str
    time: Number
    queues: dict[str, list[str]]
    events: int
    incarnation: int
    wm_version: int


class WMEventMessage(Message):
    """``wm/events``: one encode or forget event (docs/semantics.md section 2).

    ``seq`` numbers a consultant's event messages 1, 2, 3, ... per ``incarnation``,
    consecutively: a listener that sees a gap missed events (a consultant publishes
    only while its publisher is matched with a subscription: ``info``'s
    ``event_listeners``).
    """

    op: str
    domain: str
    entity: str
    property: str
    cause: str
    time: Number
    turn: Optional[int] = None
    seq: int
    incarnation: int
