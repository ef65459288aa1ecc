"""Schemas of the WM Manager's services: ``wm_manager/sync`` and ``wm_manager/status``."""

from __future__ import annotations

from typing import Any, Optional

from .base import Message, Number
from .policy import PolicySettings
from .consultant import RestoredState


class SyncRequest(Message):
    """``wm_manager/sync``: apply every decay tick due at or before ``time`` (robot-clock seconds)."""

    time: Number


class SyncReply(Message):
    """``wm_manager/sync`` reply, once every consultant acknowledged everything due.

    ``memory``: each domain's effective setting; ``applied``: the decay ticks this call
    applied per domain.
    """

    time: Number
    memory: dict[str, PolicySettings]
    applied: dict[str, int]


class StatusRequest(Message):
    """``wm_manager/status``: no fields."""


class StatusReply(Message):
    """``wm_manager/status`` reply, per managed domain.

    ``memory``: the setting the parameters give; ``running``: what its consultant last
    acknowledged or announced, as it reported it (null until known); ``configured``: the consultant's
    current incarnation acknowledged the current setting; ``incarnation``: the
    consultant's (null until known); ``next_tick``: the time of the next decay tick
    (null without decay); ``ready``: every domain configured (as on ``wm_manager/ready``);
    ``graph``: the WM Manager's graph identity; ``reachable``: each consultant's liveliness
    (``consultant/<domain>/alive``; null until heard of; false while it lapsed, and then
    the domain is not configured either, under every policy); ``restored``: what each
    consultant's current incarnation took up from its state database at start
    (:class:`~fsreg_ros.contract.consultant.RestoredState`; null until it announced itself).
    """

    time: Number
    domains: list[str]
    memory: dict[str, PolicySettings]
    configured: dict[str, bool]
    running: dict[str, Optional[dict[str, Any]]]
    incarnation: dict[str, Optional[int]]
    next_tick: dict[str, Optional[Number]]
    ready: Optional[bool] = None
    graph: Optional[str] = None
    reachable: Optional[dict[str, Optional[bool]]] = None
    restored: Optional[dict[str, Optional[RestoredState]]] = None


class DomainReadiness(Message):
    """One domain on ``wm_manager/ready``: is its consultant's current incarnation configured (and reachable)."""

    configured: bool
    incarnation: Optional[int] = None
    running: Optional[dict[str, Any]] = None
    reachable: Optional[bool] = None


class ManagerReady(Message):
    """``wm_manager/ready`` (latched): whether the graph serves requests now.

    ``ready`` is true once every managed domain's consultant (its current incarnation)
    has been configured by the WM Manager, so a query is answered instead of refused
    with kind ``not-ready``; it turns false while a restarted consultant waits for its
    configuration.  Published at start and at every change.  ``graph``, ``pid`` and
    ``host`` say whose WM Manager it is (two on one name are a clash).  ``recorders``:
    the recorders (fully-qualified node names) the WM Manager has discovered reading the
    graph's ``dialogue/human``, so that a sender reaches them before it publishes.
    """

    ready: bool
    domains: dict[str, DomainReadiness]
    time: Number
    graph: Optional[str] = None
    pid: Optional[int] = None
    host: Optional[str] = None
    recorders: Optional[list[str]] = None
