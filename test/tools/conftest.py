"""Fixtures of the tools' tests (test/tools): the one place each is defined.

``live``: a live graph of Table 1's scenario as ``fsreg-up`` runs it (one process per
node, decay every 10 s of sim time) in a namespace of its own; yields ``(namespace,
graph)`` (:class:`~fsreg_ros.testing.LiveGraph`) and stops it after the test, so each
test starts from a fresh graph.
"""

from __future__ import annotations

import secrets

import pytest


@pytest.fixture
def live(table1_path):
    """Yield ``(namespace, LiveGraph)``: Table 1's graph of node processes, decay every 10 s, stopped after."""
    from fsreg_ros.testing import LiveGraph  # loads rclpy only when a test asks for a graph

    ns = f"probe_{secrets.token_hex(4)}"
    with LiveGraph(table1_path, namespace=ns, processes=True, policy="decay", decay_period=10.0) as graph:
        yield ns, graph
