"""fsreg's public test harness: run a live graph in a test and talk to it (no rosbag, no launch).

Layer: may import everything below it (core, contract, ros, nodes, tools).

* :class:`LiveGraph` (:mod:`.live`): a scenario's graph in this process or as one
  process per node, under a namespace (or ROS domain) of its own, ready when returned;
  ``say``, ``describe``, ``assert_facts``, ``wm``, ``status``, ``set_clock``,
  ``set_memory``, ``restart``.
* :class:`RosSession` (:mod:`.ros_session`): the low level, one context and executor with a
  probe node (``add`` a node, ``call`` a service, ``publish``, ``listen``, ``set_clock``),
  every wait bounded.
* A pytest plugin (:mod:`.plugin`, registered on install): the fixture ``fsreg_graph``
  starts a :class:`LiveGraph` and stops it after the test.

Importing this package does not load rclpy; the names below are imported on first use.
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

_EXPORTS = {
    "LiveGraph": ".live",
    "RosSession": ".ros_session",
    "Inbox": ".ros_session",
    "Timeout": ".ros_session",
    "ClientError": "..ros.client",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    """Import an exported name when it is first used (PEP 562): the pytest plugin must not load rclpy early."""
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(import_module(module, __name__), name)
