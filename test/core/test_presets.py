"""Named presets (core/forgetting/presets.py): the table, explicit settings over a preset, and the tools' --preset."""

import json

import pytest

from fsreg_ros.core.algorithms.generation import WM_ORDERS
from fsreg_ros.core.forgetting import presets
from fsreg_ros.core.forgetting.policies import ForgettingPolicy, PolicyError, check_setting
from fsreg_ros.tools import graph, sim, up

TABLE1 = "scenarios/guess_who_table1.yaml"


def test_the_table_holds_valid_settings_and_orders():
    assert presets.names() == ("paper", "human-like")
    for row in presets.PRESETS:
        for name, value in row.memory.items():
            check_setting(name, value)
        ForgettingPolicy.from_settings(dict(row.memory))
        assert row.wm_order in WM_ORDERS
    assert dict(presets.preset("human-like").memory) == {"policy": "episodes", "episode_window": 1}
    assert presets.preset("human-like").wm_order == "strength"
    assert dict(presets.preset("paper").memory) == {"policy": "decay+displacement", "decay_period": 10.0,
                                                    "capacity": 2}


def test_explicit_settings_override_the_preset():
    assert presets.apply("human-like", {}, None) == ({"policy": "episodes", "episode_window": 1}, "strength")
    assert presets.apply("human-like", {"episode_window": 3, "capacity": 2}, "lru-first") == (
        {"policy": "episodes", "episode_window": 3, "capacity": 2}, "lru-first")
    assert presets.apply(None, {"capacity": 2}, None) == ({"capacity": 2}, None)
    with pytest.raises(PolicyError) as err:
        presets.apply("humane", {}, None)
    assert str(err.value) == "unknown preset 'humane' (known: paper, human-like)"


def _robot(capsys, *argv):
    assert sim.sim_main([TABLE1, "--json", *argv]) == 0
    result = json.loads(capsys.readouterr().out)
    return result["memory"], [t["description"] for t in result["turns"] if t["speaker"] == "robot"]


def test_fsreg_sim_runs_a_preset_as_its_settings_and_an_explicit_order_overrides_it(capsys):
    memory, said = _robot(capsys, "--preset", "human-like")
    assert memory == {"faces": {"policy": "episodes", "episode_window": 1}}
    assert said == [["male", "lab-coat", "glasses"], ["male", "dark-hair"], ["female", "glasses"],
                    ["glasses", "male", "lab-coat"], ["hoodie", "no-glasses", "female"],
                    ["male", "lab-coat", "glasses"]]
    assert _robot(capsys, "--policy", "episodes", "--episode-window", "1", "--wm-order", "strength") == (memory, said)
    # Under k = 1 REG reads only its target's last episode, where LRU and strength walk this dialogue alike.
    mru = _robot(capsys, "--preset", "human-like", "--wm-order", "mru-first")
    assert mru == _robot(capsys, "--policy", "episodes", "--episode-window", "1", "--wm-order", "mru-first")
    assert mru[1] != said
    memory, _ = _robot(capsys, "--preset", "human-like", "--policy", "decay", "--decay-period", "5")
    assert memory == {"faces": {"policy": "decay", "decay_period": 5.0}}  # the preset's k: unread by decay


@pytest.mark.parametrize("main, tool", [(sim.sim_main, "fsreg-sim"), (graph.main, "fsreg-graph"),
                                        (up.main, "fsreg-up")])
def test_an_unknown_preset_is_one_line_and_exit_2(main, tool, capsys):
    assert main([TABLE1, "--preset", "humane"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err == f"{tool}: error: unknown preset 'humane' (known: paper, human-like)\n"
