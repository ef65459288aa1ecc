"""pytest plugin of fsreg (registered as ``fsreg`` by the package's ``pytest11`` entry point).

Fixture ``fsreg_graph``: a factory of live graphs, each stopped after the test::

    def test_the_robot_forgets(fsreg_graph):
        robot = fsreg_graph("scenarios/guess_who_table1.yaml", policy="decay", decay_period=10.0)
        ...

The factory takes :class:`~fsreg_ros.testing.LiveGraph`'s arguments and returns the
graph started and ready.  Graphs run under namespaces of their own, so tests (and
pytest-xdist workers) on one ROS domain do not mix.
"""

from __future__ import annotations

from typing import Any, Callable, Iterator

import pytest


@pytest.fixture
def fsreg_graph() -> Iterator[Callable[..., Any]]:
    """Return a factory of live graphs: each call starts a LiveGraph, stopped after the test."""
    from .live import LiveGraph  # loads rclpy only when a test asks for a graph

    graphs: list[LiveGraph] = []

    def start(scenario, **options: Any) -> LiveGraph:
        graph = LiveGraph(scenario, **options)
        graphs.append(graph)
        return graph.start()

    try:
        yield start
    finally:
        for graph in reversed(graphs):
            graph.close()
