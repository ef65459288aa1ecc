"""Every fsreg node's ``/diagnostics``: one ``diagnostic_msgs/DiagnosticArray`` a second (ROS 2 convention).

rqt_robot_monitor, Foxglove's diagnostics panel and fleet monitors read
``/diagnostics``.  Each node publishes one ``DiagnosticStatus`` there, once a second on
the steady clock (sim time or not):

* ``name``: ``fsreg: <the node's fully qualified name>`` (so two graphs on one ROS domain
  stay apart), ``hardware_id``: the host name;
* ``level``: OK, WARN or ERROR from the node's own judgement (a node that defines
  ``diagnostic_values()`` returns ``(level, message, values)``: the consultant reports its
  store's health and WM sizes, the WM Manager readiness, RR and REG their consultants);
* ``values``: the node's values, then the request figures every node shares
  (:class:`RequestStats`: requests and refusals since start, the rate over the last
  :data:`RATE_WINDOW` seconds and the 95th percentile of the handling time over the last
  :data:`LATENCY_SAMPLES` requests).

A request is a service call this node served or a message of a topic that is answered (a
subscription with a ``reject``); :mod:`fsreg_ros.ros.carrier` counts them.
``fsreg-ctl status`` reads the same statuses (:func:`read_statuses`).
"""

from __future__ import annotations

import math
import socket
import time
import weakref
from collections import deque
from typing import Any, Callable, Mapping, Optional

#: The topic (absolute, as every ROS tool expects it).
TOPIC = "/diagnostics"
#: Seconds between two statuses (steady clock).
PERIOD = 1.0
#: The request rate is counted over this many seconds.
RATE_WINDOW = 10.0
#: The latency percentile is taken over this many latest requests.
LATENCY_SAMPLES = 1000
#: DiagnosticStatus levels (diagnostic_msgs/DiagnosticStatus), named.
OK, WARN, ERROR, STALE = 0, 1, 2, 3
LEVEL_NAMES = {OK: "OK", WARN: "WARN", ERROR: "ERROR", STALE: "STALE"}
#: A status's name: this prefix, then the node's fully qualified name.
NAME_PREFIX = "fsreg: "


class RequestStats:
    """Requests handled by one node: counts, recent rate and latency (steady clock)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self.clock = clock
        self.total = 0
        self.refused = 0
        self._recent: deque = deque()  # times of the requests within RATE_WINDOW
        self._latencies: deque = deque(maxlen=LATENCY_SAMPLES)

    def record(self, seconds: float, refused: bool = False) -> None:
        """One request handled in ``seconds`` (refused: answered with an error)."""
        now = self.clock()
        self.total += 1
        self.refused += int(refused)
        self._recent.append(now)
        self._latencies.append(seconds)
        self._trim(now)

    def _trim(self, now: float) -> None:
        while self._recent and self._recent[0] < now - RATE_WINDOW:
            self._recent.popleft()

    def rate(self) -> float:
        """Return the requests per second over the last :data:`RATE_WINDOW` seconds."""
        self._trim(self.clock())
        return len(self._recent) / RATE_WINDOW

    def p95_ms(self) -> Optional[float]:
        """Return the 95th percentile of the latest handling times in ms (nearest rank); None before any."""
        if not self._latencies:
            return None
        ordered = sorted(self._latencies)
        return 1000.0 * ordered[max(0, math.ceil(0.95 * len(ordered)) - 1)]

    def values(self) -> dict[str, Any]:
        p95 = self.p95_ms()
        return {"requests": self.total, "refused": self.refused, "request_rate_hz": round(self.rate(), 3),
                "latency_p95_ms": None if p95 is None else round(p95, 3)}


_STATS: "weakref.WeakKeyDictionary[Any, RequestStats]" = weakref.WeakKeyDictionary()


def request_stats(node) -> RequestStats:
    """Return the request figures of ``node`` (made on first use)."""
    stats = _STATS.get(node)
    if stats is None:
        stats = _STATS[node] = RequestStats()
    return stats


def node_status(node) -> tuple[int, str, dict[str, Any]]:
    """``(level, message, values)`` of one node: its own ``diagnostic_values()`` plus the request figures."""
    own = getattr(node, "diagnostic_values", None)
    level, message, values = own() if own is not None else (OK, "running", {})
    return level, message, {**values, **request_stats(node).values()}


def status_message(node):
    """Return the ``DiagnosticStatus`` of ``node`` now."""
    from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

    level, message, values = node_status(node)
    return DiagnosticStatus(level=bytes([level]), name=NAME_PREFIX + node.get_fully_qualified_name(),
                            message=message, hardware_id=socket.gethostname(),
                            values=[KeyValue(key=str(k), value=_text(v)) for k, v in values.items()])


def _text(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


class Diagnostics:
    """Publish ``node``'s status on ``/diagnostics`` once a second (steady clock) until the node goes."""

    def __init__(self, node) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.clock import Clock, ClockType

        self.node = node
        self._array = DiagnosticArray
        self.publisher = node.create_publisher(DiagnosticArray, TOPIC, 10)
        self.timer = node.create_timer(PERIOD, self.publish, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def publish(self) -> None:
        try:
            status = status_message(self.node)
        except Exception as err:  # noqa: BLE001 - a node's health report must not stop the node
            from diagnostic_msgs.msg import DiagnosticStatus

            status = DiagnosticStatus(level=bytes([ERROR]), name=NAME_PREFIX + self.node.get_fully_qualified_name(),
                                      message=f"cannot report: {type(err).__name__}: {err}",
                                      hardware_id=socket.gethostname())
        array = self._array(status=[status])
        array.header.stamp = self.node.get_clock().now().to_msg()
        self.publisher.publish(array)


def as_dict(status) -> dict[str, Any]:
    """Return a received ``DiagnosticStatus`` as plain data (the level by name)."""
    level = status.level[0] if isinstance(status.level, (bytes, bytearray)) else int(status.level)
    return {"name": status.name, "level": LEVEL_NAMES.get(level, str(level)), "message": status.message,
            "hardware_id": status.hardware_id, "values": {kv.key: kv.value for kv in status.values}}


def read_statuses(node, spin: Callable[[float], None], namespace: str, wait: float = 1.5) -> dict[str, dict]:
    """Listen to ``/diagnostics`` for ``wait`` seconds; return the latest status of each fsreg node of ``namespace``."""
    from diagnostic_msgs.msg import DiagnosticArray

    prefix = NAME_PREFIX + (namespace.rstrip("/") or "") + "/"
    heard: dict[str, dict] = {}

    def on_array(array) -> None:
        for status in array.status:
            if status.name.startswith(prefix) and "/" not in status.name[len(prefix):]:
                heard[status.name[len(NAME_PREFIX):]] = as_dict(status)

    subscription = node.create_subscription(DiagnosticArray, TOPIC, on_array, 10)
    try:
        spin(wait)
    finally:
        node.destroy_subscription(subscription)
    return dict(sorted(heard.items()))


def summary(statuses: Mapping[str, Mapping[str, Any]]) -> list[str]:
    """One line per node: its level, message and request figures."""
    lines = []
    for name, status in statuses.items():
        v = status["values"]
        figures = ", ".join(f"{k} {v[k]}" for k in ("requests", "refused", "request_rate_hz", "latency_p95_ms")
                            if v.get(k) not in (None, ""))
        own = ", ".join(f"{k} {value}" for k, value in v.items()
                        if k not in ("requests", "refused", "request_rate_hz", "latency_p95_ms"))
        lines.append(f"{name}: {status['level']} {status['message']}" + (f"; {own}" if own else "")
                     + (f"; {figures}" if figures else ""))
    return lines
