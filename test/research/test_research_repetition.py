"""The sweep runs rule episodes over k and REG's WM orders, and measures description length by repetition."""

import pytest

from fsreg_ros.research import cli
from fsreg_ros.research.repetition import METRICS, lengths_by_repetition
from fsreg_ros.research.sweep import COLUMNS, Setting, SweepConfig, columns, settings, setting_of


def _robot(target, *description):
    return {"speaker": "robot", "target": target, "description": list(description)}


def test_length_of_the_kth_description_of_a_referent_averages_over_referents():
    turns = [_robot("a", "x", "y", "z"), {"speaker": "human", "target": "a", "description": ["q"]},
             _robot("b", "x"), _robot("a", "x"), _robot("b", "x", "y", "z", "w", "v"), _robot("a", "y"),
             {"speaker": "robot", "target": "c", "description": None}]  # no description: length 0
    assert METRICS == ("length_rep1", "length_rep2", "length_rep3", "length_rep4", "length_rep5", "length_rep6")
    assert lengths_by_repetition(turns) == {"length_rep1": 4 / 3, "length_rep2": 3.0, "length_rep3": 1.0,
                                            "length_rep4": None, "length_rep5": None, "length_rep6": None}


def test_episodes_runs_over_its_windows_and_every_policy_under_each_wm_order():
    config = SweepConfig(("decay+displacement", "episodes", "none"), (10.0,), (2,), (0,), 10,
                         episode_windows=(1, 2), wm_orders=("lru-first", "strength"))
    grid = settings(config)
    assert grid == [
        Setting("decay+displacement", 10.0, 2), Setting("decay+displacement", 10.0, 2, wm_order="strength"),
        Setting("episodes", episode_window=1), Setting("episodes", episode_window=1, wm_order="strength"),
        Setting("episodes", episode_window=2), Setting("episodes", episode_window=2, wm_order="strength"),
        Setting("none"),
    ]
    assert [s.label() for s in grid] == [
        "decay+displacement delta=10, alpha=2", "decay+displacement delta=10, alpha=2, strength order",
        "episodes k=1", "episodes k=1, strength order", "episodes k=2", "episodes k=2, strength order", "none"]
    assert grid[3].memory({}) == {"policy": "episodes", "episode_window": 1}
    grid_columns = columns(config)[2:COLUMNS.index("retraction") + 2]
    assert grid_columns == ("decay_period", "capacity", "global_capacity", "shared_capacity",
                            "activation_threshold", "episode_window", "wm_order")
    row = {"policy": "episodes", "decay_period": None, "capacity": None, "global_capacity": None,
           "shared_capacity": None, "activation_threshold": None, "episode_window": 2, "wm_order": "strength",
           "retraction": "on"}
    assert setting_of(row) == grid[5]


def test_a_sweep_without_the_new_axes_keeps_its_columns():
    config = SweepConfig(("decay", "none"), (10.0,), (2,), (0,), 10)
    assert columns(config) == COLUMNS
    assert "episode_window" not in COLUMNS and "wm_order" not in COLUMNS and "length_rep6" in COLUMNS
    assert columns(SweepConfig(("episodes",), (10.0,), (2,), (0,), 10))[:8] == (
        "policy", "wm", "decay_period", "capacity", "global_capacity", "shared_capacity", "activation_threshold",
        "episode_window")


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--wm-orders", "loudest"], "fsreg-sweep: error: --wm-orders: expected one or more of lru-first, "
                                     "mru-first, preference, strength, got 'loudest'\n"),
        (["--wm-orders", ","], "fsreg-sweep: error: --wm-orders: expected one or more of lru-first, "
                               "mru-first, preference, strength, got ','\n"),
        (["--episode-windows", "0"], "fsreg-sweep: error: --episode-windows: 0 is out of range [1, 1000000]\n"),
    ],
)
def test_bad_episode_windows_or_wm_orders_are_one_line(tmp_path, capsys, extra, message):
    assert cli.sweep_main(["--seeds", "1", "--turns", "4", "--policies", "episodes", "--no-progress", "--no-plots",
                           "--out", str(tmp_path / "o"), *extra]) == 2
    assert capsys.readouterr().err == message
    assert not (tmp_path / "o").exists()


def test_plots_group_a_setting_by_its_policy_and_a_wm_order_other_than_the_papers():
    from fsreg_ros.research.plot import _group

    assert [_group(s) for s in (Setting("episodes", episode_window=1),
                                Setting("episodes", episode_window=1, wm_order="strength"), Setting("none"))] == [
        "episodes", "episodes (strength order)", "none"]
