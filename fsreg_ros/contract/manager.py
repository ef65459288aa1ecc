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
    """``wm_manager/status`` reply: effective memory settings per domain."""

    memory: Optional[dict[str, Any]] = None
