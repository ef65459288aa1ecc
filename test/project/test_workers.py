"""The suite's parallel workers (test/support/workers.py): each on a ROS domain and a log dir of its own."""

from __future__ import annotations

import os

from workers import BASE, worker_environment, worker_index


def test_each_worker_gets_a_domain_and_a_log_dir_of_its_own():
    run = {"ROS_DOMAIN_ID": "61", "ROS_LOG_DIR": "/tmp/logs"}
    first = worker_environment({**run, "PYTEST_XDIST_WORKER": "gw0"})
    second = worker_environment({**run, "PYTEST_XDIST_WORKER": "gw1"})
    assert first == {BASE: "61", "ROS_DOMAIN_ID": "61", "ROS_LOG_DIR": "/tmp/logs/gw0"}
    assert second == {BASE: "61", "ROS_DOMAIN_ID": "62", "ROS_LOG_DIR": "/tmp/logs/gw1"}
    # a worker counts from the run's domain (its controller's BASE), not from one a worker already moved
    assert worker_environment({**run, **second, "PYTEST_XDIST_WORKER": "gw1"}) == {BASE: "61", "ROS_DOMAIN_ID": "62"}


def test_without_workers_the_run_keeps_its_domain_and_log_dir():
    alone = worker_environment({"ROS_DOMAIN_ID": "75", "ROS_LOG_DIR": "/tmp/logs"})
    assert alone == {BASE: "75", "ROS_DOMAIN_ID": "75"}
    assert worker_index({}) == 0 and worker_index({"PYTEST_XDIST_WORKER": "gw12"}) == 12


def test_this_test_process_runs_on_its_workers_domain():
    """test/conftest.py applied it before any test imported rclpy: worker gwN is on the run's domain + N."""
    assert int(os.environ["ROS_DOMAIN_ID"]) == int(os.environ[BASE]) + worker_index(os.environ)
    worker = os.environ.get("PYTEST_XDIST_WORKER")
    assert worker is None or os.path.basename(os.environ["ROS_LOG_DIR"]) == worker
    assert os.path.isdir(os.environ["ROS_LOG_DIR"])
