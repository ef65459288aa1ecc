"""Fixtures of the ROS tests (test/ros): the one place each is defined.

``graph``: a bare :class:`~fsreg_ros.testing.RosSession` (one context, executor and probe
node; the test adds the nodes it needs), closed after the test.  Function-scoped: every
test starts from no node at all, so nothing one test leaves behind reaches the next.
"""

from __future__ import annotations

import pytest

from rosutil import ros_graph


@pytest.fixture
def graph():
    """Yield an empty RosSession for one test and close it after."""
    yield from ros_graph()
