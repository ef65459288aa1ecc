"""How a new client waits before its first request (``DialogueExchange.wait_matched``), with stand-ins for rclpy.

The graph's own reader must match first; then every other reader this client has
discovered (a recorder, a view) gets a bounded moment to match as well, so that a
one-shot ``fsreg-ctl describe`` is in a recording of the session too.
"""

from __future__ import annotations

import time

from fsreg_ros.ros import exchange
from fsreg_ros.ros.exchange import DialogueExchange


class Endpoint:
    """A publisher (or subscription) whose match count grows as the executor spins."""

    def __init__(self, schedule: list[int]) -> None:
        self.schedule, self.spins = schedule, 0
        self.topic_name = "/robot/reg/request"

    def count(self) -> int:
        return self.schedule[min(self.spins, len(self.schedule) - 1)]

    get_subscription_count = get_publisher_count = count


class Executor:
    def __init__(self, *endpoints: Endpoint) -> None:
        self.endpoints = endpoints

    def spin_once(self, timeout_sec: float) -> None:
        for endpoint in self.endpoints:
            endpoint.spins += 1


class Node:
    def __init__(self, readers: int) -> None:
        self.readers = readers
        self.context = type("Context", (), {"get_domain_id": lambda self: 0})()

    def get_namespace(self) -> str:
        return "/robot"

    def count_subscribers(self, topic: str) -> int:
        assert topic == "/robot/reg/request"
        return self.readers


def client(pub: Endpoint, sub: Endpoint, readers: int) -> DialogueExchange:
    c = DialogueExchange()
    c.node, c.executor = Node(readers), Executor(pub, sub)
    c._publishers, c._reply_subs = {"describe": pub}, {"describe": sub}
    c.domains = lambda: ["faces"]
    return c


def test_a_new_client_waits_for_every_reader_it_has_discovered(monkeypatch):
    monkeypatch.setattr(exchange, "MATCH_SETTLE", 0.0)
    pub = Endpoint([0, 1, 1, 1, 1, 1, 2])  # REG's reader first, the recorder's six spins later
    sub = Endpoint([1])
    client(pub, sub, readers=2).wait_matched("describe", 5.0)
    assert pub.count() == 2  # it did not send before the recorder's reader matched


def test_a_reader_that_never_matches_is_not_waited_for_long(monkeypatch):
    monkeypatch.setattr(exchange, "MATCH_SETTLE", 0.0)
    monkeypatch.setattr(exchange, "MATCH_EVERY", 0.2)
    pub, sub = Endpoint([0, 1]), Endpoint([1])  # a second reader is known but never matches (incompatible QoS)
    started = time.monotonic()
    client(pub, sub, readers=2).wait_matched("describe", 5.0)
    assert pub.spins > 2 and 0.2 <= time.monotonic() - started < 2.0  # it waited MATCH_EVERY, then sent
