"""Parallel test workers (pytest-xdist): each on a ROS domain and a ROS log directory of its own.

``scripts/test.sh`` runs the suite on pytest-xdist workers.  Graphs of two workers must
never discover each other (some tests start a graph without a namespace, or count what
a whole domain holds), so worker ``gwN`` runs on domain ``base + N``, ``base`` being the
run's ``ROS_DOMAIN_ID`` (scripts/test.sh and .ci/run choose it), and writes its ROS logs
to ``gwN/`` under the run's ``ROS_LOG_DIR``.  ``test/conftest.py`` applies it before any
test imports rclpy.
"""

from __future__ import annotations

from pathlib import Path

#: Where the run's own ROS domain is kept, so a test can check its worker's domain against it.
BASE = "FSREG_TEST_DOMAIN_BASE"


def worker_index(env: dict) -> int:
    """Return the pytest-xdist worker's number (``gw3`` -> 3), 0 outside xdist."""
    worker = env.get("PYTEST_XDIST_WORKER", "")
    return int(worker.removeprefix("gw")) if worker else 0


def worker_environment(env: dict) -> dict:
    """Return what this test process changes in ``env`` (holding ``ROS_DOMAIN_ID``): its domain and log dir."""
    base = int(env.get(BASE, env["ROS_DOMAIN_ID"]))  # a worker inherits the controller's BASE
    changed = {BASE: str(base), "ROS_DOMAIN_ID": str(base + worker_index(env))}
    worker = env.get("PYTEST_XDIST_WORKER")
    if worker and env.get("ROS_LOG_DIR") and Path(env["ROS_LOG_DIR"]).name != worker:
        changed["ROS_LOG_DIR"] = str(Path(env["ROS_LOG_DIR"]) / worker)
    return changed
