"""The WM Manager in the graph equals the simulator where the decay schedule's
boundary test matters (issue 9): turns on tick boundaries at large times."""

from __future__ import annotations

import pytest
import yaml

from fsreg_ros.core.scenario import load_scenario
from fsreg_ros.core.simulation.simulator import Options, Simulation, dumps, simulate
from test_graph import DATA, play

pytestmark = pytest.mark.graph

PROPS = ["p0", "p1", "p2", "p3"]


def boundary_scenario(period: float, boundary: float) -> dict:
    """A human turn one period before ``boundary``, robot turns at ``boundary``: the tick
    k with k * period <= boundary + 1e-9 (although floor((boundary + 1e-9) / period)
    is k - 1) pops one property before the robot speaks."""
    return {
        "name": f"boundary-{period}",
        "domains": {"things": {"preference": PROPS, "entities": {"e0": PROPS, "e1": ["p0", "p1", "p2"], "e2": ["p3"]}}},
        "memory": {"policy": "decay", "decay_period": period},
        "dialogue": [
            {"time": 0.0, "speaker": "human", "description": ["p3"]},
            {"time": round(boundary - period, 6), "speaker": "human", "description": ["p0", "p1", "p2"]},
            {"time": boundary, "speaker": "robot", "target": "e1"},
            {"time": boundary, "speaker": "robot", "target": "e0"},
        ],
    }


@pytest.mark.parametrize("period, boundary", [(0.1, 567.899999999), (0.3, 9253.199999998998)])
def test_tick_boundaries_at_large_times_graph_equals_simulator(tmp_path, period, boundary):
    path = tmp_path / "boundary.yaml"
    path.write_text(yaml.safe_dump(boundary_scenario(period, boundary), sort_keys=False))
    expected = simulate(load_scenario(path), Options())
    robot = [t for t in expected["turns"] if t["speaker"] == "robot"]
    assert robot[0]["wm_before"] == ["p1", "p2"]  # the boundary tick popped p0
    result = play(path, Options(), tmp_path)
    assert dumps(result) == dumps(expected)


@pytest.mark.parametrize(
    "memory, cause",
    [
        ({"policy": "displacement+shared-capacity", "capacity": 2, "shared_capacity": 3}, "shared-capacity"),
        ({"policy": "displacement-random+similarity", "capacity": 1, "seed": 3}, "displacement"),
        ({"policy": "decay+displacement-lfu", "decay_period": 5.0, "capacity": 1}, "displacement"),
    ],
)
def test_new_forgetting_rules_graph_equals_simulator(tmp_path, memory, cause):
    path = DATA / "two_domains.yaml"
    options = Options(memory=memory)
    sim = Simulation(load_scenario(path), options, trace=True)
    expected = sim.run()
    assert expected["memory"]["faces"]["policy"] == memory["policy"]
    assert cause in {e["cause"] for e in sim.trace()}  # the rule did forget something
    result = play(path, options, tmp_path)
    assert dumps(result) == dumps(expected)


def test_similarity_uses_the_declared_attributes_in_graph_and_simulator(tmp_path):
    scenario = {
        "name": "similarity",
        "domains": {
            "faces": {
                "preference": ["light-hair", "dark-hair", "glasses", "hat"],
                "attributes": {"hair": ["light-hair", "dark-hair"]},
                "entities": {"f1": ["light-hair", "dark-hair", "glasses"], "f2": ["dark-hair", "hat"]},
            }
        },
        "memory": {"policy": "similarity"},
        "dialogue": [
            {"time": 1.0, "speaker": "human", "description": ["light-hair", "glasses"]},
            {"time": 2.0, "speaker": "human", "description": ["dark-hair", "glasses"]},
            {"time": 3.0, "speaker": "robot", "target": "f1"},
        ],
    }
    path = tmp_path / "similarity.yaml"
    path.write_text(yaml.safe_dump(scenario, sort_keys=False))
    expected = simulate(load_scenario(path), Options())
    # dark-hair displaced light-hair (same attribute): WM holds one hair colour.
    assert expected["turns"][2]["wm_before"] == ["dark-hair", "glasses"]  # no light-hair
    assert dumps(play(path, Options(), tmp_path)) == dumps(expected)


def episodes_scenario() -> dict:
    """Three human references to f1, then the robot's: rule ``episodes`` (k = 1) forgets at each episode."""
    return {
        "name": "episodes",
        "domains": {"faces": {
            "preference": ["light-hair", "dark-hair", "male", "female", "glasses", "lab-coat"],
            "entities": {"f1": ["light-hair", "male", "glasses", "lab-coat"], "f2": ["dark-hair", "female", "glasses"],
                         "f3": ["dark-hair", "male"]}}},
        "memory": {"policy": "episodes", "episode_window": 1},
        "dialogue": [
            {"time": 1.0, "speaker": "human", "description": ["male", "glasses"]},
            {"time": 2.0, "speaker": "human", "description": ["lab-coat"]},
            {"time": 3.0, "speaker": "human", "description": ["light-hair"]},
            {"time": 4.0, "speaker": "robot", "target": "f1"},
            {"time": 5.0, "speaker": "robot", "target": "f1"},
        ],
    }


@pytest.mark.parametrize("wm_order", ["lru-first", "strength"])
def test_reference_episodes_graph_equals_simulator(tmp_path, wm_order):
    path = tmp_path / "episodes.yaml"
    path.write_text(yaml.safe_dump(episodes_scenario(), sort_keys=False))
    options = Options(wm_order=wm_order)
    sim = Simulation(load_scenario(path), options, trace=True)
    expected = sim.run()
    robot = [t for t in expected["turns"] if t["speaker"] == "robot"]
    # f1's episode 3 (the third reference) forgot male and glasses, used in its episode 1 only; episode 4, begun
    # when REG's view opened, forgot lab-coat (episode 2) before Phase 1 read WM: both orders read light-hair alone.
    assert [t["wm_before"] for t in robot] == [["light-hair"], ["light-hair"]]
    assert [t["description"] for t in robot] == [["light-hair"], ["light-hair"]]
    assert [(e["property"], e["time"]) for e in sim.trace() if e["cause"] == "episodes"] == [
        ("male", 3.0), ("glasses", 3.0), ("lab-coat", 4.0)]
    assert dumps(play(path, options, tmp_path)) == dumps(expected)
