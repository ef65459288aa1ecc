"""Test-wide setup: keep ROS 2 on this machine, in a private domain, with a temp log dir.

Each pytest-xdist worker (scripts/test.sh runs two) gets a ROS domain and a log dir of its
own (test/support/workers.py), so the graphs of two workers never meet.

This runs before any test module imports rclpy.  Discovery must stay on localhost
(nothing may send traffic off this machine) and Fast DDS is bound to loopback by
fsreg_ros.ros.network; an environment that would widen it stops the run at once (exit 2).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

from fsreg_ros.ros.network import NetworkRefused, ros_environment  # imports no rclpy

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "test" / "support"))  # test helpers (rosutil, naive_wm, naive_sim, fuzzgraph)

from workers import worker_environment  # noqa: E402  (test/support)

try:  # the tests never widen the network, whatever FSREG_ALLOW_NETWORK says
    os.environ.update(ros_environment(allow_network=False))  # in an xdist worker: as the controller set it
    os.environ.update(worker_environment(os.environ))  # an xdist worker: a ROS domain and log dir of its own
    Path(os.environ["ROS_LOG_DIR"]).mkdir(parents=True, exist_ok=True)
except NetworkRefused as err:
    pytest.exit(f"fsreg tests: {err}", returncode=2)
assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"


def pytest_collection_modifyitems(items: list) -> None:
    """Run the modules holding slow tests first, test/tools' first (the longest), each module whole and in order.

    With ``--dist loadfile`` (scripts/test.sh) the two workers start on the long modules and end
    on the many short ones, so neither is left alone at the end with a long one.
    """
    def module(item) -> str:
        return item.nodeid.split("::")[0]

    first: dict[str, int] = {}
    for index, item in enumerate(items):
        first.setdefault(module(item), index)
    slow = {module(item) for item in items if item.get_closest_marker("slow")}
    items.sort(key=lambda item: (0, -first[module(item)]) if module(item) in slow else (1, first[module(item)]))


@pytest.fixture(autouse=True)
def _private_state_dir(tmp_path_factory, monkeypatch) -> None:
    """Give every test its own consultant state directory (XDG_STATE_HOME), so no test restores another's."""
    monkeypatch.setenv("XDG_STATE_HOME", str(tmp_path_factory.mktemp("state")))


#: The Guess-Who case study (Table 1 of the paper): the repository's own scenarios.
SCENARIOS = REPO / "scenarios"


@pytest.fixture(scope="session")
def table1_path() -> Path:
    return SCENARIOS / "guess_who_table1.yaml"


@pytest.fixture(scope="session")
def table1_text_path() -> Path:
    return SCENARIOS / "guess_who_table1_text.yaml"


@pytest.fixture(scope="session")
def tuna_dir() -> Path:
    """Return the TUNA corpus directory (not shipped: its licence), from ``$FSREG_TUNA_DIR``."""
    if not os.environ.get("FSREG_TUNA_DIR"):
        pytest.skip("TUNA corpus not given: set FSREG_TUNA_DIR to the directory holding furniture/ and people/")
    path = Path(os.environ["FSREG_TUNA_DIR"])
    if not (path / "furniture").is_dir():
        pytest.fail(f"FSREG_TUNA_DIR={path} has no furniture/ directory")
    return path


@pytest.fixture(scope="session")
def paper_table1() -> dict:
    """Return the paper's Table 1 robot descriptions per policy (config/paper_table1.yaml)."""
    import yaml

    return yaml.safe_load((REPO / "config" / "paper_table1.yaml").read_text())["robot_descriptions"]
