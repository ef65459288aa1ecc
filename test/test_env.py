"""The environment check every node runs: DDS discovery must stay on this machine."""

import pytest

from fsreg_ros.nodes.common import check_discovery_range


class Recorder:
    """A stand-in logger that keeps its warnings."""

    def __init__(self) -> None:
        self.warnings: list[str] = []

    def warning(self, text: str) -> None:
        self.warnings.append(text)


@pytest.mark.parametrize("value", [None, "", "SUBNET", "SYSTEM_DEFAULT", "localhost"])
def test_a_wider_or_unset_discovery_range_is_warned_about(monkeypatch, value):
    if value is None:
        monkeypatch.delenv("ROS_AUTOMATIC_DISCOVERY_RANGE", raising=False)
    else:
        monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", value)
    logger = Recorder()
    assert check_discovery_range(logger) is False
    assert len(logger.warnings) == 1 and "ROS_AUTOMATIC_DISCOVERY_RANGE" in logger.warnings[0]


def test_localhost_is_accepted_silently(monkeypatch):
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    logger = Recorder()
    assert check_discovery_range(logger) is True and logger.warnings == []
