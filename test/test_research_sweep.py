"""fsreg-sweep: games, determinism independent of --jobs, outputs, bad input."""

import csv
import json

import pytest

from fsreg_ros.research import cli
from fsreg_ros.research.games import ATTRIBUTES, BOARD_SIZE, make_game, play, scenario_of
from fsreg_ros.research.sweep import COLUMNS, Setting, SweepConfig, settings

SMALL = ["--policies", "decay,displacement,none", "--decay-periods", "5,20", "--capacities", "1,3",
         "--seeds", "3", "--turns", "16", "--no-progress"]


def test_game_is_a_guess_who_board_and_deterministic():
    game = make_game(7, 20)
    assert game == make_game(7, 20)
    assert len(game.board) == BOARD_SIZE
    assert len({tuple(p) for p in game.board.values()}) == BOARD_SIZE  # distinct faces
    for props in game.board.values():
        assert [a for a, values in ATTRIBUTES.items() for p in props if p in values] == list(ATTRIBUTES)
    speakers = [t[0] for t in game.turns]
    assert speakers == ["human", "robot"] * 10
    times = [t[1] for t in game.turns]
    assert times == sorted(times) and times[0] > 0
    assert make_game(8, 20).board != game.board


def test_human_descriptions_resolve_and_policies_change_the_robot():
    game = make_game(3, 40)
    none = play(game, {"policy": "none"})
    humans = [t for t in none.result["turns"] if t["speaker"] == "human"]
    assert all(t["status"] == "resolved" and t["resolved"] == t["target"] for t in humans)
    robots = [t for t in none.result["turns"] if t["speaker"] == "robot"]
    assert all(t["algorithm"] == "dist-pia" and t["distinguishing"] for t in robots)
    decay = play(game, {"policy": "decay", "decay_period": 20})
    assert {t["algorithm"] for t in decay.result["turns"] if t["speaker"] == "robot"} == {"sd-pia"}
    assert decay.alignment.from_wm > 0 and none.alignment.from_wm == 0
    assert len(scenario_of(game).dialogue) == 40


def test_grid_runs_none_once():
    config = SweepConfig(("decay", "none"), (5.0, 10.0), (1, 2), (0,), 10)
    assert settings(config) == [Setting("decay", 5.0, 1), Setting("decay", 5.0, 2), Setting("decay", 10.0, 1),
                                Setting("decay", 10.0, 2), Setting("none")]


@pytest.mark.slow  # the same sweep in one process and in several
def test_same_arguments_same_runs_csv_whatever_jobs(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    assert cli.sweep_main([*SMALL, "--out", str(a), "--jobs", "1"]) == 0
    assert cli.sweep_main([*SMALL, "--out", str(b), "--jobs", "2", "--no-plots"]) == 0
    assert (a / "runs.csv").read_bytes() == (b / "runs.csv").read_bytes()
    assert (a / "divergence.csv").read_bytes() == (b / "divergence.csv").read_bytes()
    rows = list(csv.DictReader((a / "runs.csv").open()))
    assert tuple(rows[0]) == COLUMNS
    assert len(rows) == 3 * (2 * 4 + 1)
    none = [r for r in rows if r["policy"] == "none"]
    assert all(float(r["alignment_gain"]) == 0 and float(r["divergence"]) == 0 for r in none)
    assert all(r["decay_period"] == "" and r["capacity"] == "" for r in none)
    for r in rows:
        assert 0 <= float(r["alignment"]) <= 1 and float(r["overspecification"]) >= 0
        assert r["robot_turns"] == "8" and r["divergence_k10"] == ""
    manifest = json.loads((a / "manifest.json").read_text())
    assert manifest["seeds"] == [0, 1, 2] and set(manifest["kb_sha256"]) == {"0", "1", "2"}
    assert manifest["parameters"]["policies"] == ["decay", "displacement", "none"]
    assert manifest["parameters"]["turns"] == 16 and "version" in manifest and "git_commit" in manifest
    for name in ("alignment.png", "divergence.png", "mean_wm_occupancy.png"):
        assert name in manifest["files"] and (a / name).stat().st_size > 1000


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--capacities", "0"], "--capacities: 0 is out of range"),
        (["--decay-periods", "x"], "--decay-periods: 'x' is not a number"),
        (["--policies", "forget-all"], "forget-all"),
        (["--turns", "1"], "--turns must be in [2, 10000]"),
        (["--jobs", "0"], "--jobs must be in [1, 256]"),
        (["--human-memory", "policy=bogus"], "bogus"),
        (["--human-memory", "decay"], "--human-memory 'decay': expected KEY=VALUE"),
    ],
)
def test_bad_sweep_input_is_one_line(tmp_path, capsys, extra, message):
    assert cli.sweep_main([*SMALL, "--out", str(tmp_path / "o"), *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1
    assert not (tmp_path / "o" / "runs.csv").exists()


def test_human_with_its_own_wm_hears_the_robot(tmp_path):
    game = make_game(5, 30)
    plain = play(game, {"policy": "displacement", "capacity": 2})
    human_wm = {"policy": "decay", "decay_period": 30}
    played = play(game, {"policy": "displacement", "capacity": 2}, human_memory=human_wm)
    humans = [t for t in played.result["turns"] if t["speaker"] == "human"]
    assert all(t["status"] == "resolved" and t["resolved"] == t["target"] for t in humans)
    assert [t["description"] for t in humans] != [t["description"] for t in plain.result["turns"]
                                                  if t["speaker"] == "human"]
    assert played.result == play(game, {"policy": "displacement", "capacity": 2}, human_memory=human_wm).result
    out = tmp_path / "h"
    assert cli.sweep_main([*SMALL, "--out", str(out), "--no-plots", "--human-memory", "policy=decay",
                           "--human-memory", "decay_period=10"]) == 0
    assert json.loads((out / "manifest.json").read_text())["parameters"]["human_memory"] == {
        "policy": "decay", "decay_period": 10}


def test_new_forgetting_rules_get_their_settings_from_the_grid_and_the_game():
    setting = Setting("displacement-random+shared-capacity", 10.0, 2)
    assert setting.memory({}, seed=5) == {"policy": "displacement-random+shared-capacity", "decay_period": 10.0,
                                          "capacity": 2, "shared_capacity": 2, "seed": 5}
    assert setting.memory({"seed": 9, "shared_capacity": 7}, seed=5)["seed"] == 9
    assert scenario_of(make_game(1, 4)).domains["faces"].attributes["hoodie"] == "clothing"


def test_sweep_runs_the_new_rules_reproducibly(tmp_path):
    args = ["--policies", "none,displacement-lfu,displacement-random,similarity,shared-capacity",
            "--decay-periods", "10", "--capacities", "2", "--seeds", "3", "--turns", "30", "--no-progress",
            "--no-plots"]
    a, b = tmp_path / "a", tmp_path / "b"
    assert cli.sweep_main([*args, "--out", str(a)]) == 0
    assert cli.sweep_main([*args, "--out", str(b), "--jobs", "2"]) == 0
    assert (a / "runs.csv").read_bytes() == (b / "runs.csv").read_bytes()
    rows = list(csv.DictReader((a / "runs.csv").open()))
    assert sorted({r["policy"] for r in rows}) == ["displacement-lfu", "displacement-random", "none",
                                                   "shared-capacity", "similarity"]
    lfu = [float(r["mean_wm_occupancy"]) for r in rows if r["policy"] == "displacement-lfu"]
    pooled = [float(r["mean_wm_occupancy"]) for r in rows if r["policy"] == "shared-capacity"]
    assert all(x <= 2 for x in pooled) and max(lfu) > 2  # one pool of 2 vs 2 per face
