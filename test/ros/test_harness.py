"""The public test harness, ``fsreg_ros.testing``: as a robot builder's test uses it, and what it guarantees.

The integration test of docs/testing.md is run as it stands, by pytest in a subprocess (so the
``fsreg_graph`` fixture comes from the installed plugin, as for any user).  Then: a graph
of processes that survives a consultant restart, a graph on a private ROS domain, an
answer stamped by another graph rejected, two graphs on one namespace refused (by the
client and by ``fsreg-ctl``), and node classes that take a name and a namespace.
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from fsreg_ros import contract
from fsreg_ros.ros.client import ClientError, GraphClient
from fsreg_ros.testing import LiveGraph, RosSession

pytestmark = pytest.mark.graph

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent


def docs_block(marker: str) -> str:
    """Return docs/testing.md's python block that contains ``marker``."""
    blocks = re.findall(r"```python\n(.*?)```", (REPO / "docs" / "testing.md").read_text(), re.S)
    (block,) = [b for b in blocks if marker in b]
    return block


def test_the_documented_integration_test_runs_as_it_stands(tmp_path):
    test = tmp_path / "test_robot.py"
    test.write_text(docs_block("from fsreg_ros.testing import LiveGraph"))
    assert len(test.read_text().splitlines()) <= 20  # "a dozen lines" per test
    proc = subprocess.run([sys.executable, "-m", "pytest", str(test), "-q", "-p", "no:cacheprovider"], cwd=REPO,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "2 passed" in proc.stdout


@pytest.mark.slow  # a pytest process of its own
def test_the_fixture_comes_from_the_installed_plugin():
    proc = subprocess.run([sys.executable, "-m", "pytest", "--fixtures", "-q", "-p", "no:cacheprovider",
                           str(REPO / "test" / "project" / "test_lint.py")],
                          capture_output=True, text=True, timeout=120)
    assert "fsreg_graph" in proc.stdout and "fsreg_ros/testing/plugin.py" in proc.stdout


@pytest.mark.slow
def test_a_graph_of_processes_keeps_its_facts_across_a_consultant_restart(table1_path, tmp_path):
    with LiveGraph(table1_path, processes=True, policy="displacement", capacity=3, state_dir=tmp_path) as robot:
        assert robot.status()["incarnation"] == {"faces": 1}
        assert robot.assert_facts("face17", {"female": 1.0, "light-hair": 0.9})["ok"]
        robot.set_clock(2.0)
        assert robot.say(description=["female", "light-hair"])["resolved"] == "face17"
        assert robot.wm("face17") == ["female", "light-hair"]
        robot.restart("consultant_faces")  # SIGKILLed and started again on its state database
        status = robot.status()
        assert status["incarnation"] == {"faces": 2} and status["ready"] is True
        assert robot.wm("face17") == ["female", "light-hair"]  # WM persisted
        described = robot.describe("face17")  # the runtime facts too, and WM first (SD-PIA); first send succeeds
        assert described["description"] == ["female", "light-hair"] and described["sources"] == ["wm", "wm"]
        assert robot.say(description=["female", "light-hair"])["resolved"] == "face17"  # RR's first, too
        with pytest.raises(ValueError, match=r"no node 'faces' in this graph \(its nodes: consultant_faces, "
                                             r"wm_manager, parser, reference_resolution, reg\)"):
            robot.restart("faces")  # the node's name, not the domain's: said, not a StopIteration


def test_a_graph_on_a_ros_domain_of_its_own(table1_path):
    with LiveGraph(table1_path, domain_id=43, namespace="") as robot:
        assert robot.session.context.get_domain_id() == 43 and robot.namespace == ""
        assert robot.status()["graph"] == robot.identity
        robot.set_clock(1.0)
        assert robot.say("female, glasses")["resolved"] == "face2"


def test_the_client_asserts_a_batch_in_one_message(table1_path):
    with LiveGraph(table1_path) as robot:
        answer = robot.assert_facts({"face17": ["female", "light-hair"], "face2": {"glasses": 0.0},
                                     "face3": {"wings": 1.0}})
        assert answer["ok"] is False and (answer["applied"], answer["refused"]) == (2, 1)
        assert [(r["entity"], r["ok"], r.get("kind")) for r in answer["results"]] == [
            ("face17", True, None), ("face2", True, None), ("face3", False, "unknown-property")]
        assert answer["results"][0]["new_entity"] is True
        robot.set_clock(1.0)
        assert robot.say(description=["female", "light-hair"])["resolved"] == "face17"
        with pytest.raises(ClientError, match="not both") as usage:
            robot.assert_facts({"face17": ["male"]}, ["male"])
        assert usage.value.kind == "usage"


def test_an_answer_from_another_graph_is_rejected(table1_path):
    with LiveGraph(table1_path) as robot:
        client = robot.client
        key = client.new_id("say")
        client.answers[key] = []
        fake = {"id": key, "status": "resolved", "resolved": "face1", "candidates": ["face1"], "graph": "someone-else"}
        robot.session.publish(contract.RR_RESULT.name, fake, contract.PIPELINE_QOS)
        client.spin_until(lambda: client.answers[key], 10.0, "the injected answer")
        with pytest.raises(ClientError) as err:
            client.answer_of(key)
        assert err.value.kind == "foreign"
        assert str(err.value).startswith(f"the answer to {key!r} came from another graph ('someone-else', expected "
                                         f"'{robot.identity}')")


def test_two_graphs_on_one_namespace_are_refused(table1_path):
    from fsreg_ros.nodes.wm_manager import WMManagerNode

    with LiveGraph(table1_path) as robot:
        with RosSession(robot.namespace) as intruder:
            intruder.add(WMManagerNode, name="wm_manager", domains=["faces"], graph="intruder-0001")
            fresh = GraphClient(robot.session.probe, robot.session.executor)

            def both() -> bool:  # the intruder's executor serves its node too (it publishes as it runs)
                intruder.executor.spin_once(timeout_sec=0.0)
                return len(fresh.ready_messages) >= 2

            fresh.spin_until(both, 20.0, "both WM Managers' readiness")
            with pytest.raises(ClientError) as err:
                fresh.wait_ready(10.0)
            assert err.value.kind == "clash"
            assert f"two graphs in namespace {robot.namespace} on ROS domain" in str(err.value)
            assert "'intruder-0001'" in str(err.value) and repr(robot.identity) in str(err.value)
            # fsreg-ctl, a new process, while both graphs serve: it refuses the namespace once discovery has shown
            # it both WM Managers, rejects an answer from the graph it did not choose, and otherwise answers for
            # the one graph it chose, all of it that graph's (never a mix).
            for _ in range(3):
                proc = subprocess.Popen([str(BIN / "fsreg-ctl"), "--namespace", robot.namespace, "status", "--json"],
                                        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                while proc.poll() is None:
                    robot.session.executor.spin_once(timeout_sec=0.005)
                    intruder.executor.spin_once(timeout_sec=0.005)
                out, err = proc.communicate()
                if proc.returncode == 0:
                    reply = json.loads(out)
                    assert reply["graph"] in (robot.identity, "intruder-0001") and err == ""
                else:
                    assert proc.returncode == 3 and out == "" and err.count("\n") == 1, err
                    assert err.startswith("fsreg-ctl: error: two graphs in namespace") or "another graph" in err, err


def test_node_classes_take_a_name_and_a_namespace(tmp_path):
    from fsreg_ros.nodes.dialogue_player import DialoguePlayer
    from fsreg_ros.nodes.consultant import ConsultantNode
    from fsreg_ros.nodes.parser import ParserNode
    from fsreg_ros.nodes.reference_resolution import ReferenceResolutionNode
    from fsreg_ros.nodes.reg import RegNode
    from fsreg_ros.nodes.wm_manager import WMManagerNode
    from rclpy.parameter import Parameter

    with RosSession() as ros:
        params = {ReferenceResolutionNode: {"domains": ["faces"]}, RegNode: {"domains": ["faces"]},
                  WMManagerNode: {"domains": ["faces"]}, ParserNode: {},
                  ConsultantNode: {"domain": "faces", "kb": str(REPO / "scenarios" / "guess_who_table1.yaml"),
                                   "persist_wm": False, "state_dir": str(tmp_path)},
                  DialoguePlayer: {"scenario": str(REPO / "scenarios" / "guess_who_table1.yaml")}}
        for cls, values in params.items():
            node = cls(node_name="mine", namespace="/robot7", context=ros.context,
                       parameter_overrides=[Parameter(k, value=v) for k, v in values.items()])
            try:
                assert node.get_fully_qualified_name() == "/robot7/mine", cls
            finally:
                node.destroy_node()


def test_a_message_stamped_before_the_clock_counts_at_the_clock_under_activation(table1_path):
    """A say stamped 3 s before the graph's clock (a client whose clock jumped back) under rule activation.

    tau = -1, d = 0.5: n encodings at one time stay (n e)^2 seconds.  Each say encodes
    "female" and "glasses" twice into face2's WM (the speaker's words, and reference
    resolution affirming them for the candidates).  The late say is answered and counts
    at the clock, 10: four encodings at 10 stay until 10 + 16 e^2 = 128.22 (the first
    say's two alone would have gone at 10 + 4 e^2 = 39.56).  The previous release noted
    it at 7, before the entry's last encoding: a history out of order.
    """
    with LiveGraph(table1_path, policy="activation", activation_threshold=-1.0) as robot:
        robot.set_clock(10.0)
        assert robot.say(description=["female", "glasses"])["resolved"] == "face2"
        late = robot.say(description=["female", "glasses"], time=7.0)
        assert late["resolved"] == "face2"
        robot.set_clock(128.0)
        assert robot.wm("face2") == ["female", "glasses"]
        robot.set_clock(128.5)
        assert robot.wm("face2") == []
