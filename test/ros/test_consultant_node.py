"""The ``consultant`` node: its services, /wm/state, /wm/events and /ltm/assert."""

from __future__ import annotations

import os

import signal
import subprocess
import sys

import pytest
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.exceptions import InvalidParameterValueException
from rclpy.parameter import Parameter

from fsreg_ros import contract
from fsreg_ros.contract import EVENTS_QOS, STATE_QOS
from fsreg_ros.core.consultant.consultant import KnowledgeError
from fsreg_ros.core.consultant.local_port import LocalPort
from fsreg_ros.core.forgetting.policies import ForgettingPolicy
from fsreg_ros.core.algorithms.generation import generate
from fsreg_ros.core.forgetting.wm_manager import configure_buffer
from fsreg_ros.core.algorithms.resolution import resolve
from fsreg_ros.core.scenario import load_scenario
from fsreg_ros.ros.node_base import StartupError
from fsreg_ros.nodes.consultant import ConsultantNode
from fsreg_ros.ros.remote import RemotePort
from rosutil import DATA, KB, RosSession

pytestmark = pytest.mark.graph

Q = contract.consultant_service("faces")
M = contract.manage_service("faces")
D = contract.debug_service("faces")
#: What a consultant that found no stored state reports it restored.
FRESH = {"fresh": True, "runtime_entities": 0, "runtime_facts": 0, "queues": 0, "run": None, "clock": None,
         "latest": None}


def start(graph: RosSession, domain: str = "faces", debug: bool = True, **params):
    node = graph.add(ConsultantNode, domain=domain, kb=KB, name=f"consultant_{domain}", debug=debug, **params)
    graph.wait_service(contract.consultant_service(domain))
    graph.wait_service(contract.manage_service(domain))
    if debug:
        graph.wait_service(contract.debug_service(domain))
    return node


def plain(events: list[dict]) -> list[dict]:
    """Events without their numbering (``seq``, ``incarnation``)."""
    return [{k: v for k, v in e.items() if k not in ("seq", "incarnation")} for e in events]


def configure(graph: RosSession, policy: str = "displacement", domain: str = "faces", **params) -> dict:
    return graph.call(contract.manage_service(domain), {"op": "configure", "policy": {"policy": policy, **params},
                                                        "time": 0.0})


def test_info_and_latched_start_state(graph: RosSession):
    start(graph)
    info = graph.call(Q, {"op": "info"})
    version = info.pop("version")
    assert version.endswith(":3")  # "<incarnation>:<entities>"
    assert info == {
        "domain": "faces",
        "entities": ["face1", "face2", "face3"],
        "entity_count": 3,
        "preference": ["light-hair", "dark-hair", "male", "female", "glasses", "lab-coat"],
        "threshold": 0.5,
        "policy": "none",
        "memory": {"policy": "none"},
        "events": 0,
        "wm_version": 0,
        "event_listeners": 0,
        "state": {"wm": "empty", "persisted": True, "restored": FRESH},
    }
    events = graph.listen(contract.WM_EVENTS.name, EVENTS_QOS)
    graph.spin_until(lambda: graph.call(Q, {"op": "info"})["event_listeners"] == 1, what="a matched event listener")
    # entities are only ever appended: a caller that knows some asks for the rest
    assert graph.call(Q, {"op": "info", "entities_from": 2})["entities"] == ["face3"]
    # A late joiner gets the start state (transient local).
    states = graph.listen(contract.WM_STATE.name, STATE_QOS)
    graph.spin_until(lambda: states, what="latched /wm/state")
    assert states[0]["domain"] == "faces" and states[0]["queues"] == {}
    # Unconfigured (in this incarnation), the consultant refuses query ops but info, and changes nothing.
    for service, request in ((D, {"op": "encode", "entity": "face1", "properties": ["male"], "cause": "speaker",
                                  "time": 1.0}), (Q, {"op": "open", "first": {"property": "male", "cause": "rr"}})):
        err = graph.call_error(service, request)
        assert err.kind == "not-ready" and "not configured by the WM Manager" in err.error
    # Configured, the first change's events are numbered from 1 in this incarnation.
    configure(graph, "displacement", capacity=2)
    graph.call(D, {"op": "encode", "entity": "face2", "properties": ["female"], "cause": "speaker", "time": 2.0})
    graph.spin_until(lambda: events, what="the first event")
    assert events == [{"op": "encode", "domain": "faces", "entity": "face2", "property": "female",
                       "cause": "speaker", "time": 2.0, "turn": None, "seq": 1, "incarnation": 1}]
    graph.spin_until(lambda: states[-1]["wm_version"] == 2, what="the first change's state (configure 1, encode 2)")
    assert states[-1]["queues"] == {"face2": ["female"]}  # nothing the refused requests did


def test_query_ops_round_trip(graph: RosSession):
    start(graph)
    states = graph.listen(contract.WM_STATE.name, STATE_QOS)
    events = graph.listen(contract.WM_EVENTS.name, EVENTS_QOS)
    graph.spin_until(lambda: states, what="start state")
    assert configure(graph, "displacement", capacity=3) == {
        "memory": {"policy": "displacement", "capacity": 3},
        "queues_changed": 0,
        "incarnation": 1,
        "state": {"wm": "empty", "persisted": True, "restored": FRESH},
    }
    assert graph.call(Q, {"op": "info"})["policy"] == "displacement"

    # holds: no encoding
    assert graph.call(D, {"op": "holds", "property": "glasses", "entities": ["face3", "face2", "face1"]}) == {
        "holds": ["face2", "face1"]
    }
    # affirm: encodes for each holder, in the given order, with cause/time/turn
    assert graph.call(
        D, {"op": "affirm", "property": "male", "entities": ["face1", "face2", "face3"], "cause": "rr", "time": 2.0,
            "turn": 4}
    ) == {"holds": ["face1", "face3"]}
    graph.spin_until(lambda: len(events) == 2, what="affirm events")
    assert events == [
        {"op": "encode", "domain": "faces", "entity": e, "property": "male", "cause": "rr", "time": 2.0, "turn": 4,
         "seq": seq, "incarnation": 1}
        for seq, e in ((1, "face1"), (2, "face3"))
    ]
    # states count calls that changed WM (wm_version): configure 1, affirm 2 (configure's may be merged in)
    graph.spin_until(lambda: states[-1]["wm_version"] == 2, what="state after affirm")
    assert states[-1] == {"domain": "faces", "time": 2.0, "queues": {"face1": ["male"], "face3": ["male"]}, "events": 2,
                          "incarnation": 1, "wm_version": 2}

    # encode (Algorithm 1: re-encoding moves to the back); displacement at capacity 3
    graph.call(D, {"op": "encode", "entity": "face1", "properties": ["glasses", "male", "lab-coat", "light-hair"],
                   "cause": "speaker", "time": 3.0})
    assert graph.call(D, {"op": "wm", "entity": "face1"}) == {"queue": ["male", "lab-coat", "light-hair"]}
    graph.spin_until(lambda: states[-1]["wm_version"] == 3 and len(events) == 7, what="state and events after encode")
    assert states[-1]["queues"]["face1"] == ["male", "lab-coat", "light-hair"] and states[-1]["time"] == 3.0
    assert [e["cause"] for e in events[2:]] == ["speaker", "speaker", "speaker", "speaker", "displacement"]
    assert events[-1]["property"] == "glasses" and events[-1]["turn"] is None
    assert graph.call(D, {"op": "snapshot"}) == {
        "queues": {"face1": ["male", "lab-coat", "light-hair"], "face3": ["male"]},
        "events": 7,  # every event published so far: a trace listener waits for this many
    }
    assert graph.call(Q, {"op": "info"})["events"] == len(events) == states[-1]["events"]

    # reads publish nothing: the next change's event and state come right after the last ones
    n_states, n_events = len(states), len(events)
    graph.call(D, {"op": "wm", "entity": "face2"})
    graph.call(D, {"op": "holds", "property": "male", "entities": ["face1"]})
    graph.call(D, {"op": "snapshot"})
    graph.call(D, {"op": "encode", "entity": "face2", "properties": ["female"], "cause": "speaker", "time": 4.0})
    graph.spin_until(lambda: len(events) > n_events and len(states) > n_states, what="the change after the reads")
    assert events[n_events]["seq"] == events[n_events - 1]["seq"] + 1 and events[n_events]["property"] == "female"
    assert states[n_states]["time"] == 4.0 and states[n_states]["events"] == events[n_events]["seq"]
    assert states[n_states]["wm_version"] == 4


def test_configure_trims_and_decay_ticks(graph: RosSession):
    start(graph)
    states = graph.listen(contract.WM_STATE.name, STATE_QOS)
    events = graph.listen(contract.WM_EVENTS.name, EVENTS_QOS)

    def new_events(n: int, what: str) -> list[dict]:
        """Wait for the next ``n`` events; they must be numbered right after the last ones (nothing between)."""
        graph.spin_until(lambda: len(events) >= seen[0] + n, what=what)
        got = events[seen[0]:seen[0] + n]
        assert [e["seq"] for e in got] == list(range(seen[0] + 1, seen[0] + n + 1)), got
        seen[0] += n
        return got

    seen = [0]
    configure(graph, "decay+displacement", decay_period=10.0, capacity=3)
    graph.call(D, {"op": "encode", "entity": "face2", "properties": ["female"], "cause": "speaker", "time": 1.0})
    graph.call(D, {"op": "encode", "entity": "face1", "properties": ["male", "glasses", "lab-coat"],
                   "cause": "speaker", "time": 1.0})
    new_events(4, "encode events")
    # two ticks at once: both applied now, with their own times, in time order and
    # within a tick in entity order (face1 before face2, though face2 filled first)
    ticks = {"origin": 0.0, "period": 10.0, "first": 1, "count": 2}
    assert graph.call(M, {"op": "decay", "ticks": ticks}) == {"queues_changed": 2, "policy": "decay+displacement"}
    assert [(e["entity"], e["property"], e["cause"], e["time"]) for e in new_events(3, "decay events")] == [
        ("face1", "male", "decay", 10.0),
        ("face2", "female", "decay", 10.0),
        ("face1", "glasses", "decay", 20.0),
    ]
    graph.spin_until(lambda: states.latest(time=20.0), what="state after decay")
    assert states.latest(time=20.0)["queues"] == {"face1": ["lab-coat"]}
    n_states = len(states)

    # a lower capacity trims at once
    graph.call(D, {"op": "encode", "entity": "face1", "properties": ["male", "glasses"], "cause": "speaker",
                   "time": 21.0})
    new_events(2, "encode events")
    assert configure(graph, "displacement", capacity=1)["queues_changed"] == 1
    assert graph.call(D, {"op": "wm", "entity": "face1"}) == {"queue": ["glasses"]}
    assert [(e["property"], e["cause"]) for e in new_events(2, "displacement events")] == [
        ("lab-coat", "displacement"), ("male", "displacement")
    ]
    # global-capacity victims: the oldest front across queues
    configure(graph, "global-capacity", global_capacity=2)
    graph.call(D, {"op": "encode", "entity": "face2", "properties": ["female", "dark-hair"], "cause": "speaker",
                   "time": 22.0})
    assert graph.call(D, {"op": "snapshot"})["queues"] == {"face2": ["female", "dark-hair"]}
    assert [(e["entity"], e["property"], e["cause"]) for e in new_events(3, "global-capacity events")] == [
        ("face2", "female", "speaker"), ("face2", "dark-hair", "speaker"), ("face1", "glasses", "global-capacity")
    ]
    # none empties WM, cause reset
    configure(graph, "none")
    assert graph.call(D, {"op": "snapshot"})["queues"] == {}
    assert {e["cause"] for e in new_events(2, "reset events")} == {"reset"}
    graph.spin_until(lambda: states[-1]["queues"] == {}, what="empty state")
    assert len(states) > n_states


BAD_REQUESTS = [
    # (service, request, error kind, text in the error)
    (Q, "not json at all", "MessageError", "not JSON"),
    (Q, "[1, 2]", "MessageError", "JSON object"),
    (Q, {}, "MessageError", "missing field 'op'"),
    (Q, {"op": 3}, "MessageError", "field 'op'"),
    (Q, {"op": "fly"}, "MessageError",
     "field 'op': expected one of info, open, narrow, walk, rule_out, close, got 'fly'"),
    (D, {"op": "holds", "entities": ["face1"]}, "MessageError", "missing field 'property'"),
    (D, {"op": "holds", "property": "wings", "entities": ["face1"]}, "KnowledgeError", "no property 'wings'"),
    (D, {"op": "holds", "property": "male", "entities": ["face1", "face9"]}, "KnowledgeError", "no entity 'face9'"),
    (D, {"op": "holds", "property": "male", "entities": "face1"}, "MessageError", "list of strings"),
    (D, {"op": "holds", "property": "male", "entities": ["face1", 2]}, "MessageError", "field 'entities'[1]"),
    (D, {"op": "affirm", "property": "wings", "entities": ["face1"], "cause": "rr"}, "KnowledgeError", "wings"),
    (D, {"op": "affirm", "property": "male", "entities": ["face1", "face9"], "cause": "rr"}, "KnowledgeError", "face9"),
    (D, {"op": "affirm", "property": "male", "entities": ["face1"], "cause": "decay"}, "MessageError", "field 'cause'"),
    (D, {"op": "affirm", "property": "male", "entities": ["face1"]}, "MessageError", "missing field 'cause'"),
    (D, {"op": "affirm", "property": "male", "entities": ["face1"], "cause": "rr", "time": "now"}, "MessageError",
     "field 'time'"),
    (D, {"op": "affirm", "property": "male", "entities": ["face1"], "cause": "rr", "turn": True}, "MessageError",
     "field 'turn'"),
    (D, {"op": "wm"}, "MessageError", "missing field 'entity'"),
    (D, {"op": "wm", "entity": "face9"}, "KnowledgeError", "no entity 'face9'"),
    (D, {"op": "encode", "entity": "face9", "properties": ["male"], "cause": "speaker"}, "KnowledgeError", "face9"),
    (D, {"op": "encode", "entity": "face1", "properties": ["male", "wings"], "cause": "speaker"}, "KnowledgeError",
     "wings"),
    (D, {"op": "encode", "entity": "face1", "properties": ["male"], "cause": "retract"}, "MessageError",
     "field 'cause'"),
    (D, {"op": "encode", "entity": "face1", "properties": "male", "cause": "speaker"}, "MessageError",
     "field 'properties'"),
    (D, {"op": "encode", "entity": "face1", "properties": ["male"], "cause": "speaker", "turn": "1"}, "MessageError",
     "field 'turn'"),
    (Q, {"op": "configure", "policy": {"policy": "none"}}, "MessageError", "got 'configure'"),
    (M, {"op": "snapshot"}, "MessageError", "got 'snapshot'"),
    (M, {"op": "configure"}, "MessageError", "missing field 'policy'"),
    (M, {"op": "configure", "policy": "none"}, "MessageError", "field 'policy': expected an object"),
    # the policy object is the contract's (generated from the settings table): refused when it is validated
    (M, {"op": "configure", "policy": {"policy": "forget-all"}}, "MessageError",
     "unknown forgetting rule 'forget-all'"),
    (M, {"op": "configure", "policy": {"policy": "decay"}}, "MessageError", "needs 'decay_period'"),
    (M, {"op": "configure", "policy": {"policy": "displacement", "capacity": 0}}, "MessageError",
     "capacity must be >= 1"),
    (M, {"op": "configure", "policy": {"policy": "displacement", "capacity": "2"}}, "MessageError", "['capacity']"),
    (M, {"op": "configure", "policy": {"policy": "decay", "decay_period": -1}}, "MessageError",
     "decay_period must be > 0"),
    (M, {"op": "decay", "ticks": 10}, "MessageError", "field 'ticks'"),
    (M, {"op": "decay", "ticks": [10.0, 20.0]}, "MessageError", "field 'ticks'"),
    (M, {"op": "decay", "ticks": {"origin": 0.0, "period": 1.0, "first": 1, "count": 0}}, "MessageError",
     "count must be >= 1"),
    (M, {"op": "decay", "ticks": {"origin": 1e308, "period": 1.0, "first": 1, "count": 1}}, "MessageError",
     "out of range"),
]


def test_bad_requests_get_json_errors_and_change_nothing(graph: RosSession):
    start(graph)
    configure(graph, "decay+displacement", decay_period=10.0, capacity=3)
    graph.call(D, {"op": "encode", "entity": "face1", "properties": ["male", "glasses"], "cause": "speaker",
                   "time": 1.0})
    before = graph.call(D, {"op": "snapshot"})
    info = graph.call(Q, {"op": "info"})
    states = graph.listen(contract.WM_STATE.name, STATE_QOS)
    # the state of the encode above went out once someone subscribed (within state_period)
    graph.spin_until(lambda: states and states[-1]["queues"] == before["queues"], what="current state")
    n_states = len(states)
    events = graph.listen(contract.WM_EVENTS.name, EVENTS_QOS)
    for service, request, kind, text in BAD_REQUESTS:
        err = graph.call_error(service, request)
        assert err.kind == kind, (request, err)
        assert text in err.error, (request, err.error)
        assert err.reply["error"] == err.error
        assert graph.call(D, {"op": "snapshot"}) == before, request
    assert {**graph.call(Q, {"op": "info"}), "event_listeners": 0} == {**info, "event_listeners": 0}
    # A last good change: its state and events arrive after any stray ones would have.
    graph.call(D, {"op": "encode", "entity": "face2", "properties": ["female"], "cause": "speaker", "time": 5.0})
    graph.spin_until(lambda: len(states) > n_states, what="state of the good request")
    assert len(states) == n_states + 1 and states[-1]["time"] == 5.0
    graph.spin_until(lambda: events, what="event of the good request")
    assert [e["property"] for e in events] == ["female"]


def test_ltm_assert_adds_updates_and_retracts(graph: RosSession):
    start(graph)
    configure(graph, "displacement", capacity=4)
    results = graph.listen(contract.LTM_ASSERT_RESULT.name)
    events = graph.listen(contract.WM_EVENTS.name, EVENTS_QOS)
    states = graph.listen(contract.WM_STATE.name, STATE_QOS)
    graph.call(D, {"op": "encode", "entity": "face1", "properties": ["glasses", "male"], "cause": "speaker",
                   "time": 1.0})
    graph.spin_until(lambda: len(events) == 2, what="encode events")

    # a new entity joins the domain, last in entity order
    face4 = {"domain": "faces", "entity": "face4", "properties": {"light-hair": 1, "female": 0.8}, "id": "a1"}
    graph.publish(contract.LTM_ASSERT.name, face4)
    graph.spin_until(lambda: results, what="assert result")
    assert results[-1] == {
        "domain": "faces", "entity": "face4", "id": "a1", "ok": True, "new_entity": True,
        "updated": {"light-hair": 1.0, "female": 0.8}, "retracted": [],
    }
    assert graph.call(Q, {"op": "info"})["entities"] == ["face1", "face2", "face3", "face4"]
    assert graph.call(D, {"op": "holds", "property": "light-hair", "entities": ["face1",
                                                                                "face4"]})["holds"] == ["face1",
                                                                                                        "face4"]

    # certainty 0 retracts; a retracted property in WM is forgotten (cause retract)
    now = graph.call(Q, {"op": "info"})["wm_version"]  # a state still due may follow the one already heard
    graph.spin_until(lambda: states and states[-1]["wm_version"] == now, what="the state as of now")
    n_states = len(states)
    events.clear_all()
    graph.publish(contract.LTM_ASSERT.name, {"domain": "faces", "entity": "face1", "properties": {"glasses": 0,
                                                                                                  "dark-hair": 0.2}})
    graph.spin_until(lambda: len(results) == 2, what="second result")
    assert results[-1]["ok"] is True and results[-1]["new_entity"] is False and results[-1]["retracted"] == ["glasses"]
    graph.spin_until(lambda: events, what="retract event")
    assert events == [{"op": "forget", "domain": "faces", "entity": "face1", "property": "glasses", "cause": "retract",
                       "time": events[0]["time"], "turn": None, "seq": 3, "incarnation": 1}]
    graph.spin_until(lambda: len(states) > n_states, what="state after retraction")
    assert states[-1]["queues"]["face1"] == ["male"]
    assert graph.call(D, {"op": "holds", "property": "glasses", "entities": ["face1"]})["holds"] == []

    # another domain's message is not ours: silence
    graph.publish(contract.LTM_ASSERT.name, {"domain": "objects", "entity": "obj9", "properties": {"red": 1.0}})
    # bad ones: error result, no change
    bad = [
        ("garbage", "not JSON"),
        ({"entity": "face1", "properties": {"male": 1}}, "missing field 'domain'"),
        ({"domain": "faces", "properties": {"male": 1}}, "missing field 'entity'"),
        ({"domain": "faces", "entity": "face1", "properties": {"wings": 1.0}}, "unknown property 'wings'"),
        ({"domain": "faces", "entity": "face1", "properties": {"male": 1.5}}, "must be in [0, 1]"),
        ({"domain": "faces", "entity": "face1", "properties": {"male": "yes"}}, "field 'properties'['male']"),
        ({"domain": "faces", "entity": "face1", "properties": {}}, "non-empty"),
        ({"domain": "faces", "entity": "face5", "properties": {"male": 1.0, "wings": 1.0}}, "wings"),
    ]
    snapshot = graph.call(D, {"op": "snapshot"})
    info = graph.call(Q, {"op": "info"})
    n_events = len(events)
    for message, text in bad:
        count = len(results)
        graph.publish(contract.LTM_ASSERT.name, message)
        graph.spin_until(lambda: len(results) > count, what=f"error result for {message}")
        assert results[-1]["ok"] is False and text in results[-1]["error"], (message, results[-1])
    assert all(r.get("entity") != "obj9" for r in results)
    assert graph.call(D, {"op": "snapshot"}) == snapshot
    assert graph.call(Q, {"op": "info"}) == info  # face5 did not join
    assert len(events) == n_events


def test_threshold_parameter(graph: RosSession):
    node = start(graph)
    configure(graph, "none")
    holds = {"op": "holds", "property": "glasses", "entities": ["face1", "face2"]}
    assert graph.call(D, holds)["holds"] == ["face1", "face2"]  # face2: 0.7
    assert node.set_parameters([Parameter("threshold", value=0.8)])[0].successful
    assert graph.call(D, holds)["holds"] == ["face1"]
    assert graph.call(Q, {"op": "info"})["threshold"] == 0.8
    for value in (1.5, -0.1):
        result = node.set_parameters([Parameter("threshold", value=value)])[0]
        assert not result.successful and "threshold" in result.reason and "range" in result.reason
    for value in ("high", 1):  # type changes are refused (the descriptor is statically typed)
        result = node.set_parameters([Parameter("threshold", value=value)])[0]
        assert not result.successful and "Wrong parameter type" in result.reason
    result = node.set_parameters([Parameter("threshold", Parameter.Type.NOT_SET)])[0]
    assert not result.successful and "cannot be undeclared" in result.reason
    assert node.get_parameter("threshold").value == 0.8
    described = node.describe_parameter("threshold")
    assert (described.floating_point_range[0].from_value, described.floating_point_range[0].to_value) == (0.0, 1.0)
    assert node.set_parameters([Parameter("threshold", value=1.0)])[0].successful  # the bound itself is in range
    assert graph.call(D, holds)["holds"] == ["face1"]


def test_remote_port_matches_the_local_consultant(graph: RosSession):
    start(graph)
    configure(graph, "displacement", capacity=2)
    group = ReentrantCallbackGroup()
    port = RemotePort(graph.probe, "faces", group)
    info = graph.run(port.wait_ready(5.0))
    assert info["domain"] == "faces"
    remote = graph.run(resolve(["male", "lab-coat"], {"faces": port}, time=3.0, turn=1))

    local = load_scenario(KB).consultants()["faces"]
    configure_buffer(local.wm, ForgettingPolicy.parse("displacement", capacity=2), 0.0)
    expected = graph.run(resolve(["male", "lab-coat"], {"faces": LocalPort(local)}, time=3.0, turn=1))
    assert remote.to_json() == expected.to_json()
    assert graph.call(D, {"op": "snapshot"})["queues"] == local.wm.snapshot()
    assert graph.call(D, {"op": "wm", "entity": "face1"})["queue"] == list(local.wm.queue("face1"))
    assert graph.run(port.preference()) == list(local.preference)
    with pytest.raises(KnowledgeError, match="no entity 'face9'"):
        graph.run(port.open("face9"))
    with pytest.raises(KnowledgeError, match="wings"):
        view = graph.run(port.open())
        graph.run(port.narrow(view, "wings", "rr", 4.0, None))
    for algorithm in ("sd-pia", "dist-pia", "full-brevity", "greedy"):
        remote = graph.run(generate("face1", port, algorithm, time=5.0, turn=2))
        expected = graph.run(generate("face1", LocalPort(local), algorithm, time=5.0, turn=2))
        assert remote.to_json() == expected.to_json(), algorithm
        assert graph.call(D, {"op": "snapshot"})["queues"] == local.wm.snapshot()


def test_a_session_unused_for_session_timeout_expires(graph: RosSession):
    """The node's session_timeout (steady clock) reaches its session table.  Alone in its test: a short
    timeout beside other session steps makes them race the wall clock (a pause under load expires them)."""
    start(graph, max_sessions=2, max_sessions_per_client=2, session_timeout=0.05)
    configure(graph, "displacement", capacity=3)
    session = graph.call(Q, {"op": "open"})["session"]
    graph.spin_for(0.1)  # at least this long unused (more time, as under load, cannot keep it open)
    err = graph.call_error(Q, {"op": "close", "session": session})
    assert err.kind == "SessionError"
    assert err.error == (f"no open session '{session}' (closed, expired after 0.05 s unused, or dropped: at most 2 "
                         "per client and 2 in all are open)")


def test_a_reg_open_begins_its_targets_episode_once_and_a_hostile_refer_changes_nothing(graph: RosSession):
    """REG's open carries ``refer``: the target's episode begins before the view reads WM, once per id."""
    start(graph)
    configure(graph, "episodes", episode_window=1)
    graph.call(D, {"op": "encode", "entity": "face2", "properties": ["female", "glasses"], "cause": "speaker",
                   "time": 1.0})
    refer = {"id": "reg/1", "time": 2.0, "turn": 1}
    first = graph.call(Q, {"op": "open", "target": "face2", "refer": refer})
    again = graph.call(Q, {"op": "open", "target": "face2", "refer": refer})  # the message repeated
    held = [{"age": 1, "episodes": 1, "activation": None}] * 2  # read in episode 1, which the open began
    assert first["queue"] == again["queue"] == ["female", "glasses"] and first["strength"] == again["strength"] == held
    before, version = graph.call(D, {"op": "snapshot"}), graph.call(Q, {"op": "info"})["wm_version"]
    for request, kind, text in [
        ({"op": "open", "refer": refer}, "MessageError",
         "open: 'refer' needs a 'target' (RR's referent is known only when its view closes, so its episode begins "
         "there)"),
        ({"op": "open", "target": "face2", "refer": {"id": "reg/2", "time": 1e300}}, "MessageError",
         "field 'refer.time': time is out of range: |1e+300| > "),
        ({"op": "open", "target": "face2", "refer": {"id": "reg/2", "turn": True}}, "MessageError",
         "field 'refer'['turn']: expected a whole number or null, got True"),
        ({"op": "open", "target": "face9", "refer": {"id": "reg/2"}}, "KnowledgeError",
         "domain 'faces' has no entity 'face9'"),
    ]:
        err = graph.call_error(Q, request)
        assert err.kind == kind and err.error.startswith(text) and "\n" not in err.error, (request, err.error)
    assert graph.call(D, {"op": "snapshot"}) == before
    assert graph.call(Q, {"op": "info"})["wm_version"] == version
    # Still episode 1 (an open without refer begins nothing); another id begins episode 2, forgetting episode 0's.
    assert graph.call(Q, {"op": "open", "target": "face2"})["strength"] == held
    assert graph.call(Q, {"op": "open", "target": "face2", "refer": {"id": "reg/2", "time": 3.0}})["queue"] == []


def test_sessions_one_call_per_property_and_state_once_per_request(graph: RosSession):
    start(graph, max_sessions=2)  # sessions kept 30 s: a loaded machine's pause between two calls keeps them
    configure(graph, "displacement", capacity=3)
    states = graph.listen(contract.WM_STATE.name, STATE_QOS)
    events = graph.listen(contract.WM_EVENTS.name, EVENTS_QOS)
    now = graph.call(Q, {"op": "info"})["wm_version"]  # the configure's state may follow the latched start state
    graph.spin_until(lambda: states and states[-1]["wm_version"] == now, what="the state as of now")
    n_states = len(states)
    opened = graph.call(Q, {"op": "open", "target": "face1"})
    assert {k: opened[k] for k in ("size", "queue", "retains")} == {"size": 2, "queue": [], "retains": True}
    session, version = opened["session"], opened["version"]
    # 'female' does not hold for face1: nothing encoded, nothing narrowed (rule 4)
    step = {"op": "narrow", "session": session, "cause": "reg-distractor", "time": 2.0, "turn": 1}
    assert graph.call(Q, {**step, "property": "female"}) == {"target_holds": False, "size": 2, "version": version}
    # 'glasses' holds for face1 and face2: encoded for face2 (rule 3), face3 ruled out
    assert graph.call(Q, {**step, "property": "glasses"}) == {"target_holds": True, "size": 1, "version": version}
    graph.spin_until(lambda: events, what="rule-3 event")
    assert [(e["entity"], e["property"], e["cause"]) for e in events] == [("face2", "glasses", "reg-distractor")]
    closed = graph.call(Q, {"op": "close", "session": session, "encode": ["glasses"], "time": 2.0, "turn": 1})
    assert closed == {"members": ["face2"], "version": version}
    graph.spin_until(lambda: len(states) > n_states, what="state at close")
    # the first state after the open is the close's (the session's steps published none)
    assert states[n_states]["queues"] == {"face2": ["glasses"], "face1": ["glasses"]}
    assert states[n_states]["events"] == 2
    # a closed session is gone
    err = graph.call_error(Q, {**step, "property": "male"})
    assert err.kind == "SessionError" and "no open session" in err.error
    # at most two open: a third drops the least recently used
    first, second, third = (graph.call(Q, {"op": "open"})["session"] for _ in range(3))
    assert graph.call_error(Q, {"op": "rule_out", "session": first}).kind == "SessionError"
    assert graph.call_error(Q, {"op": "rule_out", "session": second}).error == "rule-out sets need a target"
    # RR's open checks the first property at once (rule 2: encoded for face1 and face3)
    n_events = len(events)
    opened = graph.call(Q, {"op": "open", "first": {"property": "male", "cause": "rr", "time": 3.0, "turn": 2}})
    assert opened["first"] == {"target_holds": True, "size": 2} and opened["size"] == 3
    graph.spin_until(lambda: len(events) == n_events + 2, what="rule-2 events")
    assert [(e["entity"], e["cause"]) for e in events[n_events:]] == [("face1", "rr"), ("face3", "rr")]
    # a bad first step is refused and opens nothing, encodes nothing: the next event is numbered right after
    assert graph.call_error(Q, {"op": "open", "first": {"property": "wings", "cause": "rr"}}).kind == "KnowledgeError"
    assert graph.call_error(Q, {"op": "open", "first": {"property": "male", "cause": "decay"}}).kind == "MessageError"
    graph.call(D, {"op": "encode", "entity": "face2", "properties": ["female"], "cause": "speaker", "time": 4.0})
    graph.spin_until(lambda: len(events) > n_events + 2, what="the next event")
    assert events[n_events + 2]["seq"] == events[n_events + 1]["seq"] + 1
    assert events[n_events + 2]["property"] == "female"
    # an LTM change changes the version callers cache by
    graph.publish(contract.LTM_ASSERT.name, {"domain": "faces", "entity": "face4", "properties": {"male": 1.0}})
    graph.spin_until(lambda: graph.call(Q, {"op": "info", "entities_from": 3})["entities"] == ["face4"],
                     what="new entity")
    assert graph.call(Q, {"op": "open"})["version"] != version


def test_remote_port_refreshes_its_catalogue_when_ltm_changes(graph: RosSession):
    start(graph)
    port = RemotePort(graph.probe, "faces", ReentrantCallbackGroup())
    graph.run(port.wait_ready(5.0))
    assert graph.run(port.knows("face3")) and not graph.run(port.knows("face4"))
    graph.publish(contract.LTM_ASSERT.name, {"domain": "faces", "entity": "face4", "properties": {"male": 1.0}})
    graph.spin_until(lambda: graph.call(Q, {"op": "info", "entities_from": 3})["entities"], what="new entity")
    assert graph.run(port.knows("face4", refresh=True))
    assert graph.run(port.preference())[0] == "light-hair"


def test_the_catalogue_version_follows_the_entities_not_facts_about_known_ones(graph: RosSession):
    """A perception stream updating known entities must not make every RR turn and REG request
    ask ``info`` again: replies' ``version`` is ``<incarnation>:<entities>``."""
    start(graph)
    configure(graph, "displacement", capacity=4)
    port = RemotePort(graph.probe, "faces", ReentrantCallbackGroup())
    graph.run(port.wait_ready(5.0))
    results = graph.listen(contract.LTM_ASSERT_RESULT.name, contract.LTM_ASSERT_RESULT.qos)
    cached = graph.run(port.catalogue())
    assert cached.version == "1:3"
    graph.publish(contract.LTM_ASSERT.name, {"id": "k1", "domain": "faces", "entity": "face1",
                                             "properties": {"glasses": 0.9}}, contract.LTM_ASSERT.qos)
    graph.spin_until(lambda: results.latest(id="k1") is not None, what="the update's answer")
    assert results.latest(id="k1")["ok"]
    view = graph.run(port.open("face1"))  # a reply after the update: the same catalogue version
    graph.run(port.close(view))
    assert graph.run(port.catalogue()) is cached and cached.version == "1:3"  # not asked again
    graph.publish(contract.LTM_ASSERT.name, {"id": "k2", "domain": "faces", "entity": "face4",
                                             "properties": {"male": 1.0}}, contract.LTM_ASSERT.qos)
    graph.spin_until(lambda: results.latest(id="k2") is not None, what="the new entity's answer")
    graph.run(port.close(graph.run(port.open("face1"))))
    refreshed = graph.run(port.catalogue())
    assert refreshed.version == "1:4" and refreshed.entities == ["face1", "face2", "face3", "face4"]


def test_startup_errors(graph: RosSession):
    with pytest.raises(StartupError, match="no domain 'shoes'"):
        graph.add(ConsultantNode, domain="shoes", kb=KB)
    with pytest.raises(StartupError, match="must be in"):
        graph.add(ConsultantNode, domain="faces", kb=str(DATA / "bad.yaml"))
    with pytest.raises(StartupError, match="'domain' is required"):
        graph.add(ConsultantNode, kb=KB)
    with pytest.raises(InvalidParameterValueException, match="threshold out of range"):
        graph.add(ConsultantNode, domain="faces", kb=KB, threshold=2.0)


def _consultant_process(*ros_args: str) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "fsreg_ros.nodes.consultant", "--ros-args", *ros_args],
        env=dict(os.environ),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


@pytest.mark.slow
def test_process_serves_and_exits_cleanly(graph: RosSession):
    """The real ``main()``: a bad domain exits 2 with one error line; a good one serves
    another process and exits 0 on Ctrl-C."""
    bad = _consultant_process("-p", "domain:=shoes", "-p", f"kb:={KB}")
    good = _consultant_process("-r", "__node:=consultant_proc", "-p", "domain:=procfaces", "-p",
                               f"kb:={DATA / 'proc.yaml'}")
    try:
        _, err = bad.communicate(timeout=20)
        assert bad.returncode == 2
        assert "no domain 'shoes'" in err and "Traceback" not in err
        info = graph.run(RemotePort(graph.probe, "procfaces").wait_ready(15.0), timeout=20.0)
        assert info["entities"] == ["p1", "p2"]
        good.send_signal(signal.SIGINT)
        _, err = good.communicate(timeout=10)
        assert good.returncode == 0, err
        assert "Traceback" not in err
    finally:
        for proc in (bad, good):
            if proc.poll() is None:
                proc.kill()
                proc.wait()


RUNNER_SCRIPT = r'''
import sys
from rclpy.node import Node
from fsreg_ros.ros.node_base import StartupError, run_node

class Job(Node):
    NODE_NAME = "job"
    def __init__(self):
        super().__init__("job")
        if "--bad" in sys.argv:
            raise StartupError("bad configuration")

class Failed(RuntimeError):
    pass

async def ok(node):
    return 42

async def fails(node):
    raise Failed("the job failed")

class Flaky(Node):
    NODE_NAME = "flaky"
    def __init__(self):
        super().__init__("flaky")
        from rclpy.task import Future
        from fsreg_ros import contract
        from fsreg_ros.ros.carrier import publisher, subscribe
        self.done = Future()
        subscribe(self, contract.REG_REQUEST, self.explode)
        self.pub = publisher(self, contract.REG_REQUEST)
        self.boom = self.create_timer(0.05, self.send)
        self.create_timer(0.5, lambda: self.done.done() or self.done.set_result("survived"))
    def send(self):
        self.boom.cancel()
        self.pub.publish(__import__("std_msgs.msg").msg.String(data='{"id": "r7", "target": "x"}'))
    def explode(self, data):
        raise RuntimeError("boom")

async def survive(node):
    return await node.done

done = []
codes = [
    run_node(Flaky, ["x"], job=survive, on_done=lambda node, result: done.append(result)),
    run_node(Job, ["x"], job=ok, on_done=lambda node, result: done.append(result)),
    run_node(Job, ["x"], job=fails, job_errors=(Failed,)),
]
sys.argv.append("--bad")
codes.append(run_node(Job, ["x"]))
print(codes, done)
'''


def test_run_node_exit_codes():
    proc = subprocess.run([sys.executable, "-c", RUNNER_SCRIPT], env=dict(os.environ), capture_output=True, text=True,
                          timeout=30)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[0, 0, 1, 2] ['survived', 42]"
    # logged with the topic and request id by the subscribe wrapper, and the node lived on
    assert "reg/request (id 'r7'): internal error: RuntimeError: boom" in proc.stderr
    assert "the job failed" in proc.stderr and "cannot start: bad configuration" in proc.stderr
    assert "Traceback" not in proc.stderr


STOPPED_SCRIPT = r'''
import os, signal, sys
import rclpy
from rclpy.node import Node
from fsreg_ros.ros.node_base import run_node

class Late(Node):  # ROS shut down (SIGTERM) between the executor's check and its next wait
    NODE_NAME = "late"
    def __init__(self):
        super().__init__("late")
        self.create_timer(0.05, self.tick)
    def tick(self):
        rclpy.try_shutdown()
        raise RuntimeError("the context is not valid")

class Starting(Node):  # ROS shut down while the node was still starting
    NODE_NAME = "starting"
    def __init__(self):
        super().__init__("starting")
        rclpy.try_shutdown()
        self.create_publisher(__import__("std_msgs.msg").msg.String, "x", 1)

class Idle(Node):
    NODE_NAME = "idle"
    def __init__(self):
        super().__init__("idle")
        from rclpy.task import Future
        self.never = Future()

async def interrupted(node):  # Ctrl-C while the job waits: rclpy stops it, no KeyboardInterrupt
    os.kill(os.getpid(), signal.SIGINT)
    return await node.never

codes = [run_node(Late, ["x"]), run_node(Starting, ["x"])]
kept = signal.getsignal(signal.SIGINT) is signal.default_int_handler
codes.append(run_node(Idle, ["x"], job=interrupted))
ignored = [signal.getsignal(s) is signal.SIG_IGN for s in (signal.SIGINT, signal.SIGTERM)]
print(codes, kept, *ignored)
'''


def test_run_node_stopped_by_ros_shutdown_or_ctrl_c_exits_0_quietly():
    """Ctrl-C or SIGTERM shuts ROS down at any moment: in a callback, while starting, while a job waits.

    Exit 0 with nothing logged, no traceback: the first Ctrl-C leaves the stopping to
    rclpy (no ``KeyboardInterrupt`` raised half-way through rclpy's own code, whose
    ``Task.__del__`` then printed one), and an error from a ROS already shut down is
    the shutdown, not a failure.  The Ctrl-C handler in place before is put back, unless
    a signal stopped the run: then SIGINT and SIGTERM stay ignored while the process exits.
    """
    proc = subprocess.run([sys.executable, "-c", STOPPED_SCRIPT], env=dict(os.environ), capture_output=True,
                          text=True, timeout=30)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "[0, 0, 0] True True True"
    assert "Traceback" not in proc.stderr and "ERROR" not in proc.stderr, proc.stderr


# ------------------------------------------------------------------ hostile input (issue 10 items 5, 6)
@pytest.mark.parametrize(
    "request_text, kind, fragment",
    [
        ('{"op": "affirm", "property": "male", "cause": "rr", "entities": ['
         + ",".join(f'"e{i}"' for i in range(5000)) + "]}", "MessageError", "5000 items"),
        ('{"op": "wm", "entity": "' + "z" * 1000 + '"}', "MessageError", "1000 characters"),
        ('{"op": "wm", "entity": "\\ud800"}', "MessageError", "a string with a lone surrogate (not Unicode)"),
        ('{"op": "encode", "entity": "face1", "properties": ["male", "wings"], "cause": "speaker"}',
         "KnowledgeError", "wings"),
        ('{"op": "affirm", "property": "male", "entities": ["face1"], "cause": "rr", "time": 1e999}',
         "MessageError", "time"),
        ('{"op": "holds", "property": "male", "entities": [' + "9" * 5000 + "]}", "MessageError", "not JSON"),
        ('{"op": "' + "q" * 100_000 + '"}', "too-large", "over the limit of 65536"),
    ],
    ids=["long-list", "long-name", "surrogate", "unknown-property", "infinite-time", "huge-int", "huge-message"],
)
def test_hostile_requests_are_answered_and_change_nothing(graph: RosSession, request_text, kind, fragment):
    start(graph)
    configure(graph, "displacement", capacity=2)
    graph.call(D, {"op": "encode", "entity": "face2", "properties": ["female"], "cause": "speaker", "time": 1.0})
    before = graph.call(D, {"op": "snapshot"})
    err = graph.call_error(D, request_text)
    assert err.kind == kind and fragment in err.error, err.error
    assert graph.call(D, {"op": "snapshot"}) == before


def test_hostile_ltm_assertions_are_rejected_with_a_reason(graph: RosSession):
    start(graph)
    results = graph.listen(contract.LTM_ASSERT_RESULT.name)
    big = {"domain": "faces", "entity": "x" * 300, "properties": {"male": 1.0}, "id": "a1"}
    many = {"domain": "faces", "entity": "face9", "properties": {f"p{i}": 1.0 for i in range(1001)}, "id": "a2"}
    graph.publish(contract.LTM_ASSERT.name, big)
    graph.publish(contract.LTM_ASSERT.name, many)
    graph.spin_until(lambda: results.latest(id="a1") and results.latest(id="a2"), 5.0, what="two rejections")
    assert "300 characters" in results.latest(id="a1")["error"] and not results.latest(id="a1")["ok"]
    assert "1001 items" in results.latest(id="a2")["error"]
    assert graph.call(Q, {"op": "info"})["entities"] == ["face1", "face2", "face3"]


# ------------------------------------------------------------------ facts at robot rates (issue 28.10)
def test_a_batch_on_ltm_assert_is_one_commit_with_a_result_per_fact(graph: RosSession):
    node = start(graph)
    configure(graph, "displacement", capacity=4)
    graph.call(D, {"op": "encode", "entity": "face1", "properties": ["glasses"], "cause": "speaker", "time": 1.0})
    results = graph.listen(contract.LTM_ASSERT_RESULT.name, contract.LTM_ASSERT_RESULT.qos)
    commits = node.service.store.durable_commits
    graph.publish(contract.LTM_ASSERT.name, {"id": "b1", "domain": "faces", "facts": [
        {"entity": "face7", "properties": {"female": 1.0}},
        {"entity": "face2", "properties": {"wings": 1.0}},
        {"entity": "face1", "properties": {"glasses": 0.0}},
    ]}, contract.LTM_ASSERT.qos)
    graph.spin_until(lambda: results.latest(id="b1"), what="the batch's result")
    per_fact = [
        {"entity": "face7", "ok": True, "new_entity": True, "updated": {"female": 1.0}, "retracted": []},
        {"entity": "face2", "ok": False, "kind": "unknown-property",
         "error": "domain 'faces', entity 'face2': unknown property 'wings' (not in the domain's preference order)"},
        {"entity": "face1", "ok": True, "new_entity": False, "updated": {"glasses": 0.0}, "retracted": ["glasses"]},
    ]
    assert results.latest(id="b1") == {"domain": "faces", "id": "b1", "ok": False, "applied": 2, "refused": 1,
                                       "results": per_fact}
    assert node.service.store.durable_commits == commits + 1
    assert graph.call(Q, {"op": "info"})["entities"] == ["face1", "face2", "face3", "face7"]
    assert graph.call(D, {"op": "wm", "entity": "face1"})["queue"] == []
    # a malformed batch is refused whole, naming the fact
    graph.publish(contract.LTM_ASSERT.name, {"id": "b2", "domain": "faces", "facts": [
        {"entity": "face8", "properties": {"male": 1.0}}, {"entity": "face9"}]}, contract.LTM_ASSERT.qos)
    graph.spin_until(lambda: results.latest(id="b2"), what="the malformed batch's result")
    assert results.latest(id="b2") == {"domain": None, "consultant": "faces", "entity": None, "ok": False,
                                       "id": "b2", "kind": "bad-request",
                                       "error": "missing field 'facts'[1]['properties']"}
    assert graph.call(Q, {"op": "info"})["entity_count"] == 4


def test_a_burst_of_single_asserts_far_deeper_than_10_is_all_applied_and_answered(graph: RosSession):
    node = start(graph)
    configure(graph, "displacement", capacity=4)
    results = graph.listen(contract.LTM_ASSERT_RESULT.name, contract.LTM_ASSERT_RESULT.qos)
    commits = node.service.store.durable_commits
    burst = 500
    for i in range(burst):  # published without spinning: the consultant takes none until all are sent
        graph.publish(contract.LTM_ASSERT.name, {"id": f"f{i}", "domain": "faces", "entity": f"new{i}",
                                                 "properties": {"male": 1.0}}, contract.LTM_ASSERT.qos)
    graph.spin_until(lambda: len(results) >= burst, 30.0, what=f"{burst} results")
    graph.spin_for(0.2)  # no duplicates after
    assert sorted(r["id"] for r in results) == sorted(f"f{i}" for i in range(burst))
    assert all(r["ok"] and r["new_entity"] for r in results)
    info = graph.call(Q, {"op": "info"})
    assert info["entity_count"] == 3 + burst and info["entities"][3:] == [f"new{i}" for i in range(burst)]
    assert node.service.store.durable_commits - commits <= burst // 10  # drained: many facts per commit


@pytest.mark.parametrize("sim_time", [False, True], ids=["wall-clock", "sim-time-stopped"])
def test_a_stream_of_single_asserts_is_gathered_while_queries_are_answered_between(graph: RosSession, sim_time):
    """The first fact of a stream is answered at once; while the stream lasts the consultant takes its
    ltm/assert every FACTS_GATHER seconds (the reader held from the executor), still answering queries
    between; a quiet period hands the reader back.  The gathering timer is steady: under sim time
    with no /clock at all the stream is taken just the same."""
    node = start(graph, use_sim_time=sim_time)
    assert node.get_parameter("use_sim_time").value is sim_time
    configure(graph, "displacement", capacity=4)
    results = graph.listen(contract.LTM_ASSERT_RESULT.name, contract.LTM_ASSERT_RESULT.qos)
    group = next(sub for sub in node.subscriptions if sub.topic_name.endswith(contract.LTM_ASSERT.name)).callback_group

    def fact(i: int) -> dict:
        return {"id": f"s{i}", "domain": "faces", "entity": f"seen{i}", "properties": {"male": 1.0}}

    graph.publish(contract.LTM_ASSERT.name, fact(0), contract.LTM_ASSERT.qos)
    graph.spin_until(lambda: len(results) == 1, what="the first fact's answer")
    # A stream may be starting: the reader is gathered, not waited on.  Counted, not read from group.holding:
    # FACTS_GATHER (10 ms) of wall time may pass before this line under load, and the empty period ends the hold.
    assert group.holds == 1
    counts = []
    for round_ in range(5):
        for i in range(1 + 10 * round_, 11 + 10 * round_):
            graph.publish(contract.LTM_ASSERT.name, fact(i), contract.LTM_ASSERT.qos)
        counts.append(graph.call(Q, {"op": "info"})["entity_count"])  # served while the reader is held
    assert counts == sorted(counts) and 3 + 1 <= counts[0] and counts[-1] <= 3 + 51  # what was applied by then
    graph.spin_until(lambda: len(results) == 51, 10.0, what="51 answers")
    assert [r["id"] for r in results] == [f"s{i}" for i in range(51)]  # each once, in the order sent
    assert all(r["ok"] and r["new_entity"] for r in results)
    assert graph.call(Q, {"op": "info"})["entities"][3:] == [f"seen{i}" for i in range(51)]
    graph.spin_until(lambda: not group.holding, what="the reader handed back after the stream")


# ------------------------------------------------------------------ the production protocol
def test_the_debug_service_is_served_only_when_asked_for(graph: RosSession):
    # A name no other test of the module uses: the graph is shared by the module, and a node of
    # the same name that an earlier test destroyed may still be listed by discovery, which made
    # the lookup by node name below read the old node's (gone) services now and then.
    node = graph.add(ConsultantNode, domain="faces", kb=KB, name="consultant_faces_no_debug", debug=False)
    graph.wait_service(Q)
    graph.wait_service(M)
    assert node.get_parameter("debug").value is False

    def names() -> set[str]:
        return {name for name, _ in node.get_service_names_and_types_by_node(node.get_name(), node.get_namespace())}

    graph.spin_until(lambda: {"/" + Q, "/" + M} <= names(), what="the node's services in the ROS graph")
    assert "/" + D not in names()
    err = graph.call_error(Q, {"op": "snapshot"})  # nor are its ops on the production service
    assert err.kind == "MessageError"
    assert "field 'op': expected one of info, open, narrow, walk, rule_out, close, got 'snapshot'" in err.error


def test_sessions_are_counted_per_client_and_a_busy_client_drops_only_its_own(graph: RosSession):
    start(graph, max_sessions=8, max_sessions_per_client=2)
    configure(graph, "displacement", capacity=2)
    mine = graph.call(Q, {"op": "open", "target": "face1", "client": "reg"})["session"]
    hog = [graph.call(Q, {"op": "open", "client": "hog"})["session"] for _ in range(6)]
    assert graph.call(Q, {"op": "close", "session": mine})["members"] == ["face2", "face3"]
    assert graph.call_error(Q, {"op": "close", "session": hog[0]}).kind == "SessionError"
    assert graph.call(Q, {"op": "close", "session": hog[-1]})["members"] == ["face1", "face2", "face3"]


def test_info_counts_the_event_listeners_and_events_are_numbered_without_gaps(graph: RosSession):
    start(graph)
    configure(graph, "displacement", capacity=2)
    assert graph.call(Q, {"op": "info"})["event_listeners"] == 0
    graph.call(D, {"op": "encode", "entity": "face1", "properties": ["male"], "cause": "speaker", "time": 1.0})
    events = graph.listen(contract.WM_EVENTS.name, EVENTS_QOS)
    graph.spin_until(lambda: graph.call(Q, {"op": "info"})["event_listeners"] == 1, what="the listener matched")
    # nothing was published while nobody listened: numbering starts with the first event sent
    graph.call(D, {"op": "encode", "entity": "face1", "properties": ["glasses", "lab-coat"], "cause": "speaker",
                   "time": 2.0})
    graph.spin_until(lambda: len(events) == 3, what="three events")
    assert [(e["seq"], e["incarnation"], e["op"], e["property"]) for e in events] == [
        (1, 1, "encode", "glasses"), (2, 1, "encode", "lab-coat"), (3, 1, "forget", "male")]
    assert graph.call(Q, {"op": "info"})["events"] == 3


@pytest.mark.parametrize("period", [0.0, 0.1], ids=["each-change", "coalesced"])
def test_a_late_wm_state_subscriber_gets_the_state_as_of_now(graph: RosSession, period):
    """Issue 24.5: the latched wm/state is the current state even when nobody listened while WM changed."""
    node = start(graph, state_period=period)
    configure(graph, "displacement", capacity=2)
    assert node.outbox.state.get_subscription_count() == 0  # nobody reads wm/state while WM changes
    for t, (entity, props) in enumerate((("face1", ["male", "glasses"]), ("face2", ["female"]),
                                         ("face1", ["lab-coat"]), ("face3", ["dark-hair", "male"])), 1):
        graph.call(D, {"op": "encode", "entity": entity, "properties": props, "cause": "speaker", "time": float(t)})
    graph.spin_until(lambda: not node.outbox.state_due, what="the coalesced state published (nobody listening)")
    version = graph.call(Q, {"op": "info"})["wm_version"]
    states = graph.listen(contract.WM_STATE.name, STATE_QOS)  # joins after every change, like `ros2 topic echo --once`
    graph.spin_until(lambda: states, what="the latched wm/state")
    first = states[0]
    assert first["queues"] == {"face1": ["glasses", "lab-coat"], "face2": ["female"], "face3": ["dark-hair", "male"]}
    # events: 0, as nobody subscribed to wm/events either (events are numbered only while someone listens)
    assert (first["time"], first["wm_version"], first["events"]) == (4.0, version, 0)
