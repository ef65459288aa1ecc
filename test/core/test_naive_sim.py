"""The simulator equals the naive eager reference (test/support/naive_sim.py), turn by turn.

On Table 1 under each policy, and on small random worlds (fsreg_ros.tools.worlds) drawn by
hypothesis under every policy: the robot's descriptions, their sources, WM before
each robot turn and the RR results are the same.  Also: the world generator makes
what it promises; the naive command prints what ``fsreg-sim --json`` prints (alignment and
the none baseline included); and scripts/bench_sim.py runs and compares (no timing asserted).
"""

from __future__ import annotations

import contextlib
import io
import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from naive_sim import dumps_naive, load_naive, run_command, simulate_naive

from fsreg_ros.core.algorithms.generation import WM_ORDERS
from fsreg_ros.core.scenario import load_scenario, parse_scenario
from fsreg_ros.core.simulation.simulator import Options, simulate
from fsreg_ros.tools.worlds import DOMAIN, WorldShape, dump_world, random_world

COMPARED = (
    "description", "sources", "wm_before", "distinguishing", "distractors_left", "status", "resolved", "candidates"
)
POLICIES = (
    "none", "decay", "displacement", "decay+displacement", "global-capacity", "decay+displacement+global-capacity"
)
BENCH = Path(__file__).resolve().parents[2] / "scripts" / "bench_sim.py"


def assert_same_turns(ours: list[dict], naive: list[dict]) -> None:
    assert len(ours) == len(naive)
    for mine, ref in zip(ours, naive):
        assert mine["speaker"] == ref["speaker"]
        for key in COMPARED:
            if key in ref:
                assert mine[key] == ref[key], (ref["turn"], key)


@pytest.mark.parametrize("policy", ["none", "decay", "displacement", "decay+displacement"])
def test_table1_equals_naive_reference(table1_path, policy):
    memory = {"policy": policy, "decay_period": 10.0, "capacity": 2}
    ours = simulate(load_scenario(table1_path), Options(memory=memory))["turns"]
    naive = simulate_naive(load_naive(table1_path), memory=memory)
    assert_same_turns(ours, naive)
    robot = [t["description"] for t in naive if t["speaker"] == "robot"]
    assert len(robot) == 6 and all(robot)


def test_table1_decay_turn6_is_the_papers(table1_path):
    """The naive reference itself reproduces Table 1's last decay description."""
    naive = simulate_naive(load_naive(table1_path), memory={"policy": "decay", "decay_period": 10.0})
    last = [t for t in naive if t["speaker"] == "robot"][-1]
    assert sorted(last["description"]) == ["glasses", "lab-coat"]
    assert last["wm_before"] == ["lab-coat", "short-hair", "glasses"]


@st.composite
def worlds(draw):
    policy = draw(st.sampled_from(POLICIES))
    return WorldShape(
        entities=draw(st.integers(1, 30)),
        attributes=draw(st.integers(1, 5)),
        values=draw(st.integers(1, 4)),
        human_turns=draw(st.integers(0, 8)),
        robot_turns=draw(st.integers(0, 8)),
        policy=policy,
        decay_period=draw(st.sampled_from((0.5, 1.0, 2.5, 10.0))),
        capacity=draw(st.integers(1, 4)),
        global_capacity=draw(st.integers(1, 12)) if "global" in policy else None,
        distinguishing_share=draw(st.sampled_from((0.0, 0.5, 1.0))),
        follow_share=draw(st.sampled_from((0.0, 0.5, 1.0))),
        seed=draw(st.integers(0, 2**32 - 1)),
    )


@pytest.mark.slow  # 120 generated worlds
@settings(max_examples=120, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(shape=worlds(), wm_order=st.sampled_from(WM_ORDERS), algorithm=st.sampled_from((None, "sd-pia", "dist-pia")))
def test_random_worlds_equal_naive_reference(shape, wm_order, algorithm):
    text = dump_world(random_world(shape))
    ours = simulate(parse_scenario(text), Options(algorithm=algorithm, wm_order=wm_order))["turns"]
    naive = simulate_naive(yaml.safe_load(text), algorithm=algorithm, wm_order=wm_order)
    assert_same_turns(ours, naive)


def test_random_world_shape_and_determinism():
    shape = WorldShape(entities=200, attributes=6, values=3, human_turns=12, robot_turns=9, seed=7)
    document = random_world(shape)
    assert dump_world(document) == dump_world(random_world(shape))
    assert dump_world(document) != dump_world(random_world(WorldShape(**{**shape.__dict__, "seed": 8})))
    domain = document["domains"][DOMAIN]
    assert len(domain["entities"]) == 200 and len(domain["preference"]) == 18
    for facts in domain["entities"].values():  # exactly one value of every attribute
        assert sorted(p.split("=")[0] for p in facts) == [f"a{a}" for a in range(6)]
    assert document["memory"] == {"policy": "decay+displacement", "decay_period": 10.0, "capacity": 3}
    turns = document["dialogue"]
    assert [t["speaker"] for t in turns].count("human") == 12 and len(turns) == 21
    times = [t["time"] for t in turns]
    assert times == sorted(times)
    scenario = parse_scenario(dump_world(document))
    assert len(scenario.dialogue) == 21
    for turn in turns:
        if turn["speaker"] == "human":
            assert set(turn["description"]) <= set(domain["entities"][turn["target"]])


def test_distinguishing_descriptions_resolve_to_their_target():
    shape = WorldShape(entities=300, attributes=8, values=4, human_turns=20, robot_turns=0, distinguishing_share=1.0)
    document = random_world(shape)
    naive = simulate_naive(document, memory={"policy": "none"})
    for turn, result in zip(document["dialogue"], naive):
        assert result["status"] == "resolved" and result["resolved"] == turn["target"]


@pytest.mark.parametrize("field,value", [("entities", 0), ("values", 0), ("human_turns", -1), ("follow_share", 2.0)])
def test_world_shape_rejects_bad_sizes(field, value):
    with pytest.raises(ValueError, match=field):
        WorldShape(**{field: value}).check()


@pytest.mark.slow  # runs the benchmark script as processes
def test_bench_sim_small_worlds_run_and_agree(tmp_path):
    """bench_sim times both commands on both presets and finds their outputs byte-identical (no timing asserted)."""
    out = tmp_path / "bench.json"
    proc = subprocess.run(
        [sys.executable, str(BENCH), "--entities", "200", "--human", "6", "--robot", "6", "--seed", "3",
         "--json", str(out)],
        capture_output=True,
        text=True,
        timeout=240,
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.count("output: byte-identical") == 2
    for line in ("world sparse: 200 entities, 200 properties", "world dense: 200 entities, 6 properties",
                 "fsreg-sim WORLD --json", "python test/support/naive_sim.py WORLD --json", "none game + alignment"):
        assert line in proc.stdout
    data = json.loads(out.read_text())
    assert [w["world"] for w in data["worlds"]] == ["sparse", "dense"]
    for world in data["worlds"]:
        assert world["differences"] == [] and world["turns"] == 12
        for side in ("fsreg", "naive"):
            figures = world["end_to_end"][side]
            assert figures["wall_s"] > 0 and figures["cpu_s"] > 0 and figures["peak_rss_mb"] > 5
            assert all(world["split"][side][key] > 0 for key in ("start_s", "load_s", "play_s", "output_s"))
        assert world["ratio_total"] == world["end_to_end"]["naive"]["wall_s"] / world["end_to_end"]["fsreg"]["wall_s"]


def test_bench_sim_reports_different_outputs(tmp_path, monkeypatch):
    """A naive reference that disagrees is reported, turn and key, and fails the run."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("bench_sim_module", BENCH)
    bench = importlib.util.module_from_spec(spec)
    monkeypatch.syspath_prepend(str(BENCH.parent))
    spec.loader.exec_module(bench)
    ours = {"scenario": "s", "turns": [{"speaker": "robot", "description": ["a"], "text": "x"}]}
    theirs = {"scenario": "s", "turns": [{"speaker": "robot", "description": ["b"], "text": "x"}]}
    assert bench.differences(json.dumps(ours), json.dumps(ours)) == []
    assert bench.differences(json.dumps(ours), json.dumps(theirs)) == [
        "turn 0 (robot): description: fsreg ['a'] != naive ['b']"
    ]
    assert bench.differences(json.dumps(ours), json.dumps(ours, indent=1)) == [
        "the texts differ but parse to equal objects (formatting)"
    ]


@pytest.mark.parametrize("policy", ["none", "decay", "displacement", "decay+displacement"])
def test_naive_command_prints_what_fsreg_sim_prints(table1_path, policy, tmp_path):
    """The naive reference computes the whole printed result: alignment, the none baseline, the text."""
    from fsreg_ros.tools.sim import sim_main

    scenario = tmp_path / "table1.yaml"
    document = yaml.safe_load(Path(table1_path).read_text(encoding="utf-8"))
    document["memory"] = {"policy": policy, "decay_period": 10.0, "capacity": 2}
    scenario.write_text(yaml.safe_dump(document, sort_keys=False), encoding="utf-8")
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert sim_main([str(scenario), "--json"]) == 0
    assert printed.getvalue() == dumps_naive(run_command(str(scenario)))
    assert '"none_baseline": "' in printed.getvalue() and '"wm_origins": {' in printed.getvalue()


@settings(max_examples=40, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(shape=worlds())
def test_random_worlds_print_what_the_naive_command_prints(shape, tmp_path_factory):
    """``fsreg-sim WORLD --json``'s whole output equals the naive reference's, byte for byte."""
    from fsreg_ros.tools.sim import sim_main

    path = tmp_path_factory.mktemp("world") / "world.yaml"
    path.write_text(dump_world(random_world(shape)), encoding="utf-8")
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert sim_main([str(path), "--json"]) == 0
    assert printed.getvalue() == dumps_naive(run_command(str(path)))


@pytest.mark.parametrize(
    "changes,message",
    [({"policy": "forget-all"}, "unknown forgetting rule"), ({"policy": "global-capacity"}, "global_capacity")],
)
def test_world_shape_rejects_bad_policies(changes, message):
    with pytest.raises(ValueError, match=message):
        WorldShape(**changes).check()
