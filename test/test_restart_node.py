"""The consultant node's recovery in-process: destroyed and created again on the same state database."""

from __future__ import annotations

import time

import pytest
from rclpy.callback_groups import ReentrantCallbackGroup

from fsreg_ros import contract
from fsreg_ros.carrier import CarrierError
from fsreg_ros.contract import STATE_QOS
from fsreg_ros.nodes.common import StartupError
from fsreg_ros.nodes.consultant import ConsultantNode
from fsreg_ros.remote import RESTART_GRACE, RemotePort
from rosutil import KB, Graph, ros_graph

pytestmark = pytest.mark.graph

Q = contract.consultant_service("faces")
M = contract.manage_service("faces")
POLICY = {"policy": "decay+displacement", "decay_period": 10.0, "capacity": 3}


@pytest.fixture
def graph():
    yield from ros_graph()


def start(graph: Graph, state_dir, **params) -> ConsultantNode:
    node = graph.add(ConsultantNode, domain="faces", kb=KB, name="consultant_faces", state_dir=str(state_dir),
                     **params)
    graph.wait_service(Q)
    graph.wait_service(M)
    return node


def encode(graph: Graph, entity: str, props: list[str], time: float) -> None:
    graph.call(Q, {"op": "encode", "entity": entity, "properties": props, "cause": "speaker", "time": time})


def test_a_recreated_consultant_resumes_ltm_wm_and_policy_and_serves_only_once_configured(graph: Graph, tmp_path):
    announces = graph.listen(contract.ANNOUNCE.name, STATE_QOS)
    node = start(graph, tmp_path)
    graph.spin_until(lambda: announces.latest(incarnation=1, ready=False), what="announce of incarnation 1")
    assert graph.call(M, {"op": "configure", "policy": POLICY, "time": 0.0})["incarnation"] == 1
    graph.spin_until(lambda: announces.latest(incarnation=1, ready=True), what="ready announce")
    results = graph.listen(contract.LTM_ASSERT_RESULT.name)
    graph.publish(contract.LTM_ASSERT.name, {"domain": "faces", "entity": "face9",
                                             "properties": {"glasses": 1.0, "male": 1.0}, "id": "a1"})
    graph.spin_until(lambda: results.latest(id="a1"), what="assert result")
    assert results.latest(id="a1")["ok"]
    encode(graph, "face1", ["male", "glasses", "lab-coat", "light-hair"], 1.0)  # capacity 3: male displaced
    encode(graph, "face9", ["glasses"], 2.0)
    tick = {"op": "decay", "ticks": {"origin": 0.0, "period": 10.0, "first": 1, "count": 1}}
    graph.call(M, tick)  # tick at 10: pops face1's glasses and face9's glasses
    before = graph.call(Q, {"op": "snapshot"})["queues"]
    assert before == {"face1": ["lab-coat", "light-hair"]}
    encode(graph, "face9", ["male"], 12.0)
    before = graph.call(Q, {"op": "snapshot"})["queues"]
    graph.remove(node)  # as good as SIGKILL for the database: every change was committed before its reply

    announces.clear()
    start(graph, tmp_path)
    graph.spin_until(lambda: announces.latest(incarnation=2), what="announce of incarnation 2")
    assert announces.latest(incarnation=2) == {"domain": "faces", "incarnation": 2, "ready": False,
                                               "memory": {"policy": "decay+displacement", "decay_period": 10.0,
                                                          "capacity": 3}}
    err = graph.call_error(Q, {"op": "holds", "property": "glasses", "entities": ["face9"]})
    assert err.kind == "not-ready" and "incarnation 2" in err.error
    info = graph.call(Q, {"op": "info"})  # info answers (readiness probes), and shows the asserted face
    assert info["entities"][-1] == "face9" and info["policy"] == "decay+displacement"
    # The manager re-sends the tick at 10 (its reply was lost, say), then configures.
    assert graph.call(M, tick)["queues_changed"] == 0  # applied before the restart: not again
    reply = graph.call(M, {"op": "configure", "policy": POLICY, "time": 12.0})
    assert reply == {"memory": POLICY, "queues_changed": 0, "incarnation": 2}
    assert graph.call(Q, {"op": "snapshot"})["queues"] == before
    assert graph.call(Q, {"op": "holds", "property": "glasses", "entities": ["face9", "face2"]}) == {
        "holds": ["face9", "face2"]}
    encode(graph, "face1", ["glasses"], 13.0)
    assert graph.call(Q, {"op": "wm", "entity": "face1"}) == {"queue": ["lab-coat", "light-hair", "glasses"]}


def test_without_persist_wm_ltm_facts_survive_but_wm_starts_empty(graph: Graph, tmp_path):
    node = start(graph, tmp_path, persist_wm=False)
    graph.call(M, {"op": "configure", "policy": POLICY, "time": 0.0})
    results = graph.listen(contract.LTM_ASSERT_RESULT.name)
    graph.publish(contract.LTM_ASSERT.name, {"domain": "faces", "entity": "face9", "properties": {"male": 1.0},
                                             "id": "a2"})
    graph.spin_until(lambda: results.latest(id="a2"), what="assert result")
    encode(graph, "face1", ["male"], 1.0)
    graph.remove(node)
    start(graph, tmp_path, persist_wm=False)
    info = graph.call(Q, {"op": "info"})
    assert info["entities"][-1] == "face9" and info["memory"] == POLICY
    graph.call(M, {"op": "configure", "policy": POLICY, "time": 2.0})
    assert graph.call(Q, {"op": "snapshot"})["queues"] == {}


def test_an_unusable_state_dir_stops_the_node_with_one_line(graph: Graph, tmp_path):
    (tmp_path / "file").write_text("not a directory")
    with pytest.raises(StartupError, match="state database .*file"):
        graph.add(ConsultantNode, domain="faces", kb=KB, name="consultant_faces", state_dir=str(tmp_path / "file"))


def test_a_new_incarnation_ends_the_fail_fast_pause_and_fails_calls_left_with_the_old_one(graph: Graph):
    """RR's and REG's port to a consultant that never answers: a new incarnation ends a stale call early.

    The call in flight fails after the grace, not after its own 30 s timeout.
    """
    port = RemotePort(graph.probe, "nobody", ReentrantCallbackGroup(), timeout=30.0)
    port.restarted(1)  # the first incarnation heard: nothing to do

    async def info():
        try:
            return await port.info()
        except CarrierError as err:
            return err

    task = graph.executor.create_task(info())
    graph.spin_for(0.2)
    assert not task.done()
    started = time.monotonic()
    port.restarted(2)
    graph.spin_until(task.done, RESTART_GRACE + 3.0, what="the stale call to fail")
    assert RESTART_GRACE - 0.1 <= time.monotonic() - started < RESTART_GRACE + 2.0
    err = task.result()
    assert isinstance(err, CarrierError) and err.kind == "restarted" and "incarnation 2" in err.error
    port._down_until = time.monotonic() + 30.0  # as after a timeout
    port.restarted(3)
    assert port._down_until == 0.0  # calls go out again at once
