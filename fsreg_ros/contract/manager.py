"""Schemas of the WM Manager's services: ``wm_manager/sync`` and ``wm_manager/status``."""

from __future__ import annotations

from typing import Any, Optional

from .base import Message, Number


class SyncRequest(Message):
    """``wm_manager/sync``: apply every decay tick due at or before ``time``."""

    time: Number


class SyncReply(Message):
    """``wm_manager/sync`` reply: the effective memory settings once all is applied."""

    time: Optional[Number] = None
    memory: Optional[dict[str, Any]] = None


class StatusRequest(Message):
    """``wm_manager/status``: no fields."""


class StatusReply(Message):
    """``wm_manager/status`` reply: effective memory settings per domain; ``ready`` as on ``wm_manager/ready``."""

    memory: Optional[dict[str, Any]] = None
    ready: Optional[bool] = None
    graph: Optional[str] = None


class DomainReadiness(Message):
    """One domain on ``wm_manager/ready``: is its consultant's current incarnation configured, and with what."""

    configured: bool
    incarnation: Optional[int] = None
    running: Optional[dict[str, Any]] = None


class ManagerReady(Message):
    """``wm_manager/ready`` (latched): whether the graph serves requests now.

    ``ready`` is true once every managed domain's consultant (its current incarnation)
    has been configured by the WM Manager, so a query is answered instead of refused
    with kind ``not-ready``; it turns false while a restarted consultant waits for its
    configuration.  Published at start and at every change.  ``graph``, ``pid`` and
    ``host`` say whose WM Manager it is (two on one name are a clash).
    """

    ready: bool
    domains: dict[str, DomainReadiness]
    time: Number
    graph: Optional[str] = None
    pid: Optional[int] = None
    host: Optional[str] = None
