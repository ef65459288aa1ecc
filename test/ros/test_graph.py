"""The whole node graph in one process and one executor, on sim time.

Every node of ``fsreg-graph`` (consultants, WM Manager, parser, RR, REG, player) is
built with the very parameters the runner passes (``graph.graph_nodes``) and spun in
one ``SingleThreadedExecutor``; the player drives ``/clock``.  The results must equal
the core simulator's, record for record.
"""

from __future__ import annotations

import random
from pathlib import Path

import pytest
import yaml

from rosutil import RosSession

from fsreg_ros import contract
from fsreg_ros.core.forgetting.policies import ForgettingPolicy
from fsreg_ros.core.scenario import load_scenario
from fsreg_ros.core.simulation.simulator import Options, Simulation, dumps, simulate
from fsreg_ros.tools.graph import graph_nodes
from fsreg_ros.nodes.consultant import ConsultantNode
from fsreg_ros.nodes.dialogue_player import DialoguePlayer
from fsreg_ros.nodes.parser import ParserNode
from fsreg_ros.nodes.reference_resolution import ReferenceResolutionNode
from fsreg_ros.nodes.reg import RegNode
from fsreg_ros.nodes.wm_manager import WMManagerNode

pytestmark = pytest.mark.graph

NODE_CLASSES = {
    "consultant": ConsultantNode,
    "wm_manager": WMManagerNode,
    "parser": ParserNode,
    "reference_resolution": ReferenceResolutionNode,
    "reg": RegNode,
    "dialogue_player": DialoguePlayer,
}
DATA = Path(__file__).resolve().parents[1] / "support" / "data" / "dialogues"


def start_graph(g: RosSession, scenario_path: Path, options: Options, tmp_path: Path) -> DialoguePlayer:
    """Add every node of the runner's graph to ``g``; return the player."""
    scenario = load_scenario(scenario_path)
    player = None
    for spec in graph_nodes(scenario, scenario_path, options, tmp_path / "result.json"):
        params = dict(spec.parameters)
        sim_time = params.pop("use_sim_time", False)
        node = g.add(NODE_CLASSES[spec.executable], use_sim_time=sim_time, name=spec.name, **params)
        if spec.executable == "dialogue_player":
            player = node
    assert player is not None
    return player


def play(scenario_path: Path, options: Options, tmp_path: Path) -> dict:
    with RosSession() as g:
        player = start_graph(g, scenario_path, options, tmp_path)
        return g.run(player.play(), timeout=60.0)


@pytest.mark.parametrize("policy", ["decay", "displacement", "none"])
def test_table1_through_the_graph(table1_path, paper_table1, tmp_path, policy):
    options = Options(memory={"policy": policy})
    result = play(table1_path, options, tmp_path)
    robot = [t for t in result["turns"] if t["speaker"] == "robot"]
    assert [set(t["description"]) for t in robot] == [set(d) for d in paper_table1[policy]]
    if policy == "decay":
        assert robot[5]["wm_before"] == ["lab-coat", "short-hair", "glasses"]
    if policy == "displacement":
        assert robot[5]["wm_before"] == ["short-hair", "glasses"]
    assert dumps(result) == dumps(simulate(load_scenario(table1_path), options))


def test_text_dialogue_goes_through_the_parser(table1_text_path, tmp_path):
    options = Options(memory={"policy": "decay"})
    result = play(table1_text_path, options, tmp_path)
    assert result["turns"][8]["unknown_words"] == ["he"]
    assert result["turns"][8]["description"] == ["dark-hair", "short-hair", "t-shirt", "male"]
    assert dumps(result) == dumps(simulate(load_scenario(table1_text_path), options))


def test_two_domains_each_keep_their_own_pool(tmp_path):
    path = DATA / "two_domains.yaml"
    result = play(path, Options(), tmp_path)
    assert result["memory"] == {
        "faces": {"policy": "displacement", "capacity": 1},
        "objects": {"policy": "decay", "decay_period": 5.0},
    }
    assert dumps(result) == dumps(simulate(load_scenario(path), Options()))
    robot = {t["turn"]: t for t in result["turns"] if t["speaker"] == "robot"}
    assert robot[2]["wm_before"] == ["light-hair"]  # faces: capacity 1
    assert robot[3]["wm_before"] == ["large", "red"]  # objects: nothing decayed by t=4
    assert robot[5]["wm_before"] == ["red"]  # objects: one tick at t=5 popped 'large'
    assert robot[5]["domain"] == "objects"


@pytest.mark.slow  # two whole graphs
def test_two_namespaced_graphs_share_a_domain_without_hearing_each_other(table1_path, tmp_path):
    """Two whole graphs in one process and one executor, under /robot1 and /robot2 on the
    same ROS_DOMAIN_ID, each replaying a different dialogue with its own clock (the
    namespaced /clock remap): each result equals the simulator's for its own scenario."""
    second = DATA / "two_domains.yaml"
    options = Options(memory={"policy": "decay"})
    with RosSession(namespace="robot1") as g1:
        g2 = RosSession(namespace="robot2", context=g1.context, executor=g1.executor)
        try:
            (tmp_path / "r1").mkdir()
            (tmp_path / "r2").mkdir()
            p1 = start_graph(g1, table1_path, options, tmp_path / "r1")
            p2 = start_graph(g2, second, Options(), tmp_path / "r2")
            assert p1.get_fully_qualified_name() == "/robot1/dialogue_player"
            assert p1.resolve_topic_name("/clock") == "/robot1/clock"
            t1, t2 = g1.executor.create_task(p1.play()), g1.executor.create_task(p2.play())
            g1.spin_until(lambda: t1.done() and t2.done(), 90.0, what="both players")
            r1, r2 = t1.result(), t2.result()
            # Each graph's consultants saw only their own dialogue.
            faces1 = g1.call("consultant/faces", {"op": "info"})["entities"]
            objects2 = g2.call("consultant/objects", {"op": "info"})["entities"]
            assert g1.probe.count_publishers("/robot1/rr/result") == 2  # RR + parser (errors), not robot2's
        finally:
            g2.close()
    assert dumps(r1) == dumps(simulate(load_scenario(table1_path), options))
    assert dumps(r2) == dumps(simulate(load_scenario(second), Options()))
    assert faces1 == list(load_scenario(table1_path).domains["faces"].entities)
    assert objects2 == list(load_scenario(second).domains["objects"].entities)


def random_scenario(seed: int) -> dict:
    """A random scenario in the docs/semantics.md section 5 schema (valid by construction)."""
    rng = random.Random(seed)
    props = [f"p{i}" for i in range(8)]
    entities = {f"e{i}": sorted(rng.sample(props, rng.randint(1, 5))) for i in range(10)}
    dialogue, t = [], 0.0
    for _ in range(12):
        t += rng.choice([0.0, 0.5, 1.0, 2.5, 4.0])
        if rng.random() < 0.5:
            target = rng.choice(list(entities))
            desc = rng.sample(entities[target], rng.randint(1, len(entities[target])))
            dialogue.append({"time": t, "speaker": "human", "description": desc})
        else:
            dialogue.append({"time": t, "speaker": "robot", "target": rng.choice(list(entities))})
    policy = rng.choice(["decay", "displacement", "decay+displacement", "global-capacity", "decay+global-capacity"])
    return {
        "name": f"random-{seed}",
        "domains": {"things": {"preference": props, "entities": entities}},
        "memory": {"policy": policy, "decay_period": 3.0, "capacity": 2, "global_capacity": 5},
        "dialogue": dialogue,
    }


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_random_scenarios_equal_the_simulator(tmp_path, seed):
    path = tmp_path / f"random-{seed}.yaml"
    path.write_text(yaml.safe_dump(random_scenario(seed), sort_keys=False))
    result = play(path, Options(), tmp_path)
    assert dumps(result) == dumps(simulate(load_scenario(path), Options()))


def test_live_policy_change_mid_dialogue(table1_path, tmp_path):
    """Switch decay -> displacement after the fourth turn, in the graph and in the
    core; the WM Manager's change takes effect at once and both agree exactly."""
    scenario = load_scenario(table1_path)
    options = Options(memory={"policy": "decay"})
    switch_after = 3
    with RosSession() as g:
        player = start_graph(g, table1_path, options, tmp_path)
        manager = next(n for n in g.nodes if isinstance(n, WMManagerNode))
        g.run(player.wait_ready(), timeout=30.0)
        records = []
        for turn in scenario.dialogue:
            records.append(g.run(player.play_turn(turn), timeout=30.0))
            if turn.index == switch_after:
                from rclpy.parameter import Parameter

                result = manager.set_parameters([Parameter("faces.policy", value="displacement")])
                assert result[0].successful, result[0].reason
        assert player.memory == {"faces": {"policy": "displacement", "capacity": 2}}

    sim = Simulation(scenario, options)
    expected = []
    for turn in scenario.dialogue:
        expected.append(sim.play(turn))
        if turn.index == switch_after:
            policy = ForgettingPolicy.parse("displacement", capacity=2, decay_period=10.0)
            sim.manager.set_policy("faces", policy, turn.time)
    assert records == expected
    # The switch changed behaviour: turn 11 now describes face1 as under displacement.
    assert records[11]["wm_before"] != simulate(scenario, options)["turns"][11]["wm_before"]


def test_invalid_live_parameter_is_rejected_and_changes_nothing(table1_path, tmp_path):
    with RosSession() as g:
        player = start_graph(g, table1_path, Options(memory={"policy": "decay"}), tmp_path)
        manager = next(n for n in g.nodes if isinstance(n, WMManagerNode))
        g.run(player.wait_ready(), timeout=30.0)
        from rclpy.parameter import Parameter

        for name, value, fragment in [
            ("faces.capacity", -1, "capacity"),
            ("faces.policy", "forget-everything", "unknown forgetting rule"),
            ("decay_period", 0.0, "decay_period"),
        ]:
            result = manager.set_parameters([Parameter(name, value=value)])
            assert not result[0].successful
            assert fragment in result[0].reason
        reply = g.call(contract.STATUS.name, {})
        assert reply["memory"] == {"faces": {"policy": "decay", "decay_period": 10.0}}


@pytest.mark.parametrize("policy", ["decay", "decay+global-capacity"])
def test_graph_trace_equals_simulator_trace(table1_path, tmp_path, policy):
    """Every encode/forget event heard on /wm/events, in canonical order, equals the
    simulator's trace: the graph encodes and forgets exactly what the core does."""
    options = Options(memory={"policy": policy, "global_capacity": 5})
    scenario = load_scenario(table1_path)
    with RosSession() as g:
        player = start_graph(g, table1_path, options, tmp_path)
        player.set_parameters([__import__("rclpy").parameter.Parameter("trace", value=str(tmp_path / "t.jsonl"))])
        g.run(player.play(), timeout=60.0)
        heard = player.trace()
    sim = Simulation(scenario, options, trace=True)
    sim.run()
    expected = sim.trace()
    assert heard == expected
    assert {e["cause"] for e in expected} >= {"rr", "speaker", "reg-distractor", "decay"}


@pytest.mark.slow  # a whole graph, twice the events of a decay run
def test_graph_under_activation_equals_the_simulator(table1_path, tmp_path):
    """ACT-R activation (issue 27): the WM Manager sends its clock (manage op ``advance``) and the
    consultant forgets lazily at crossing times; results and the canonical trace equal the core's."""
    options = Options(memory={"policy": "activation+displacement", "activation_threshold": -1.15, "capacity": 3})
    scenario = load_scenario(table1_path)
    with RosSession() as g:
        player = start_graph(g, table1_path, options, tmp_path)
        player.set_parameters([__import__("rclpy").parameter.Parameter("trace", value=str(tmp_path / "t.jsonl"))])
        result = g.run(player.play(), timeout=60.0)
        heard = player.trace()
    sim = Simulation(scenario, options, trace=True)
    assert dumps(result) == dumps(sim.run())
    expected = sim.trace()
    assert heard == expected
    assert sum(e["cause"] == "activation" for e in expected) >= 5
