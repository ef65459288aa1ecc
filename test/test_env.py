"""The test environment keeps ROS 2 traffic on this machine."""

import os


def test_discovery_range_is_localhost():
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"


def test_domain_id_and_log_dir_are_set():
    assert 0 <= int(os.environ["ROS_DOMAIN_ID"]) <= 232
    assert os.path.isdir(os.environ["ROS_LOG_DIR"]) or not os.path.exists(os.environ["ROS_LOG_DIR"])
