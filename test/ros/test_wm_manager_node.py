"""The ``wm_manager`` node: configuration, decay on the clock, the sync barrier and
live parameter changes, against real consultant nodes (in-process, sim time)."""

from __future__ import annotations

import pytest
from rclpy.parameter import Parameter

from fsreg_ros import contract
from fsreg_ros.contract import EVENTS_QOS
from fsreg_ros.ros.node_base import StartupError
from fsreg_ros.nodes.consultant import ConsultantNode
from fsreg_ros.nodes.wm_manager import WMManagerNode
from rosutil import KB, RosSession

pytestmark = pytest.mark.graph

SYNC = contract.SYNC.name
STATUS = contract.STATUS.name


def consultant(graph: RosSession, domain: str = "faces"):
    return graph.add(ConsultantNode, use_sim_time=True, domain=domain, kb=KB, name=f"consultant_{domain}", debug=True)


def manager(graph: RosSession, domains=("faces",), **params):
    return graph.add(WMManagerNode, use_sim_time=True, domains=list(domains), **params)


def encode(graph: RosSession, entity: str, props: list[str], t: float, domain: str = "faces") -> None:
    request = {"op": "encode", "entity": entity, "properties": props, "cause": "speaker", "time": t}
    graph.call(f"/consultant/{domain}/debug", request)


def queues(graph: RosSession, domain: str = "faces") -> dict:
    return graph.call(f"/consultant/{domain}/debug", {"op": "snapshot"})["queues"]


def memory(graph: RosSession, domain: str = "faces") -> dict:
    return graph.call(f"/consultant/{domain}", {"op": "info"})["memory"]


def configured(graph: RosSession) -> None:
    graph.wait_service(STATUS)
    graph.spin_until(lambda: all(graph.call(STATUS, {})["configured"].values()), what="consultants configured")


def heard_all(graph: RosSession, events, domain: str = "faces") -> None:
    """Wait until ``events`` holds every event the consultant has published so far (its own count)."""
    published = graph.call(f"/consultant/{domain}", {"op": "info"})["events"]
    graph.spin_until(lambda: len([e for e in events if e["domain"] == domain]) >= published,
                     what=f"the {published} events of '{domain}'")


def forgets(events, cause: str) -> list[tuple]:
    return [(e["entity"], e["property"], e["time"]) for e in events if e["op"] == "forget" and e["cause"] == cause]


def test_configures_consultants_when_they_come_up(graph: RosSession):
    manager(graph, ("faces", "objects"), policy="decay+displacement", decay_period=10.0, capacity=3,
            service_timeout=0.5, **{"objects.policy": "displacement", "objects.capacity": 1})
    consultant(graph, "faces")
    graph.wait_service(SYNC)
    # objects has no consultant yet: the barrier waits up to service_timeout, then says so
    err = graph.call_error(SYNC, {"time": 0.0})
    assert err.kind == "not-ready" and "objects" in err.error and "faces," not in err.error
    consultant(graph, "objects")  # a late consultant is configured when it appears
    # (waited for here, not by sync within its 0.5 s: discovery and the configure may take longer under load)
    graph.spin_until(lambda: graph.call(STATUS, {})["configured"] == {"faces": True, "objects": True},
                     what="the late consultant configured")
    reply = graph.call(SYNC, {"time": 0.0})
    assert reply == {
        "time": 0.0,
        "memory": {
            "faces": {"policy": "decay+displacement", "decay_period": 10.0, "capacity": 3},
            "objects": {"policy": "displacement", "capacity": 1},
        },
        "applied": {"faces": 0, "objects": 0},
    }
    assert memory(graph, "faces") == reply["memory"]["faces"]
    assert memory(graph, "objects") == reply["memory"]["objects"]
    status = graph.call(STATUS, {})
    assert status["configured"] == {"faces": True, "objects": True}
    assert status["next_tick"] == {"faces": 10.0, "objects": None}
    assert status["domains"] == ["faces", "objects"]


def test_sync_applies_ticks_at_k_delta(graph: RosSession):
    consultant(graph)
    manager(graph, policy="decay", decay_period=10.0)
    events = graph.listen("/wm/events", EVENTS_QOS)
    configured(graph)
    encode(graph, "face1", ["male", "glasses", "lab-coat", "light-hair"], 1.0)
    assert graph.call(SYNC, {"time": 9.99})["applied"] == {"faces": 0}
    assert queues(graph) == {"face1": ["male", "glasses", "lab-coat", "light-hair"]}
    reply = graph.call(SYNC, {"time": 10.0})
    assert reply["applied"] == {"faces": 1} and reply["memory"] == {"faces": {"policy": "decay", "decay_period": 10.0}}
    # the reply comes after the consultant applied the tick: no waiting needed
    assert queues(graph) == {"face1": ["glasses", "lab-coat", "light-hair"]}
    assert graph.call(SYNC, {"time": 35})["applied"] == {"faces": 2}
    assert queues(graph) == {"face1": ["light-hair"]}
    assert graph.call(SYNC, {"time": 35.0})["applied"] == {"faces": 0}  # idempotent
    assert graph.call(SYNC, {"time": 12.0})["applied"] == {"faces": 0}  # the past is done
    # the sim clock catching up finds nothing left for the timer to do
    graph.set_time(36.0)
    assert graph.call(STATUS, {})["next_tick"] == {"faces": 40.0}
    heard_all(graph, events)
    expected = [("face1", "male", 10.0), ("face1", "glasses", 20.0), ("face1", "lab-coat", 30.0)]
    assert forgets(events, "decay") == expected


def test_timer_decay_follows_the_clock(graph: RosSession):
    consultant(graph)
    manager(graph, policy="decay", decay_period=2.0)
    events = graph.listen("/wm/events", EVENTS_QOS)
    configured(graph)
    encode(graph, "face1", ["male", "glasses", "lab-coat", "light-hair", "dark-hair"], 0.5)
    encode(graph, "face2", ["female"], 0.5)
    for t in (0.5, 1.0, 1.5, 1.9):
        graph.set_time(t)
    assert graph.call(STATUS, {})["next_tick"] == {"faces": 2.0}  # no tick taken yet
    heard_all(graph, events)
    assert forgets(events, "decay") == []
    graph.set_time(2.0)  # the tick fires exactly on the clock
    graph.spin_until(lambda: len(forgets(events, "decay")) == 2, what="tick at 2.0")
    assert forgets(events, "decay") == [("face1", "male", 2.0), ("face2", "female", 2.0)]
    for t in (2.5, 3.0, 3.5, 4.0):
        graph.set_time(t)
    graph.spin_until(lambda: len(forgets(events, "decay")) == 3, what="tick at 4.0")
    assert forgets(events, "decay")[-1] == ("face1", "glasses", 4.0)
    # a jump over several periods: the timer fires once, every tick is still applied
    graph.set_time(9.0)
    graph.spin_until(lambda: len(forgets(events, "decay")) == 5, what="ticks at 6 and 8")
    assert forgets(events, "decay")[3:] == [("face1", "lab-coat", 6.0), ("face1", "light-hair", 8.0)]
    assert queues(graph) == {"face1": ["dark-hair"]}
    assert graph.call(SYNC, {"time": 9.0})["applied"] == {"faces": 0}
    assert graph.call(STATUS, {})["next_tick"] == {"faces": 10.0}


def test_live_parameter_changes(graph: RosSession):
    consultant(graph)
    node = manager(graph, policy="displacement", capacity=3)
    events = graph.listen("/wm/events", EVENTS_QOS)
    configured(graph)
    encode(graph, "face1", ["male", "glasses", "lab-coat"], 1.0)
    encode(graph, "face2", ["female", "dark-hair"], 1.0)

    # lowering capacity trims every queue at once
    assert node.set_parameters([Parameter("capacity", value=1)])[0].successful
    graph.call(SYNC, {"time": 1.0})  # the barrier returns once the consultant applied it
    assert queues(graph) == {"face1": ["lab-coat"], "face2": ["dark-hair"]}
    graph.spin_until(lambda: len(forgets(events, "displacement")) == 3, what="displacement events")

    # invalid values are rejected with a reason, and nothing changes
    before_params = {p: node.get_parameter(p).value for p in ("policy", "capacity", "decay_period", "faces.capacity")}
    before_memory = memory(graph)
    for name, value, reason in [
        ("capacity", 0, "capacity out of range"),
        ("capacity", 10_001, "capacity out of range"),
        ("policy", "forget-everything", "unknown forgetting rule"),
        ("policy", "decay+decay", "twice"),
        ("policy", "displacement+displacement-lfu", "choose one displacement rule"),
        ("decay_period", -1.0, "decay_period out of range"),
        ("decay_period", 1e300, "decay_period out of range"),
        ("decay_period", 1e-6, "decay_period out of range"),
        ("decay_period", "soon", "Wrong parameter type"),  # refused by rclpy (static typing)
        ("decay_period", 10, "Wrong parameter type"),
        ("decay_period", None, "cannot be undeclared"),  # NOT_SET: refused by rclpy
        ("faces.capacity", -2, "faces.capacity: capacity must be >= 1, got -2 (0 inherits 'capacity')"),
        ("faces.decay_period", 0.001, "faces.decay_period: decay_period must be >= 0.01"),
        ("faces.policy", "sometimes", "faces.policy"),
        ("global_capacity", 0, "global_capacity out of range"),
        ("seed", -1, "seed out of range"),
        ("service_timeout", 0.0, "service_timeout out of range"),
    ]:
        result = node.set_parameters([Parameter(name, value=value)])[0]
        assert not result.successful, (name, value)
        assert reason in result.reason, (name, result.reason)
    # all-or-nothing: one bad value in a batch rejects the batch
    results = node.set_parameters_atomically([Parameter("capacity", value=2), Parameter("global_capacity", value=-1)])
    assert not results.successful
    assert {p: node.get_parameter(p).value for p in before_params} == before_params
    graph.call(SYNC, {"time": 2.0})
    assert memory(graph) == before_memory

    # switching to decay at t = 3: the schedule counts from t = 0, next tick at 10
    graph.set_time(3.0)
    change = [Parameter("policy", value="decay+displacement"), Parameter("decay_period", value=10.0)]
    assert node.set_parameters(change)[0].successful
    graph.call(SYNC, {"time": 3.0})
    assert memory(graph) == {"policy": "decay+displacement", "decay_period": 10.0, "capacity": 1}
    assert graph.call(STATUS, {})["next_tick"] == {"faces": 10.0}
    # a new decay_period restarts the schedule: next tick one new period after the change
    graph.set_time(5.0)
    assert node.set_parameters([Parameter("decay_period", value=4.0)])[0].successful
    assert graph.call(STATUS, {})["next_tick"] == {"faces": 9.0}
    assert graph.call(SYNC, {"time": 8.9})["applied"] == {"faces": 0}
    assert graph.call(SYNC, {"time": 9.0})["applied"] == {"faces": 1}
    assert queues(graph) == {}
    graph.spin_until(lambda: len(forgets(events, "decay")) == 2, what="decay events at 9")
    assert forgets(events, "decay") == [("face1", "lab-coat", 9.0), ("face2", "dark-hair", 9.0)]

    # switching to none empties WM (cause reset) and stops the schedule
    graph.set_time(9.5)
    encode(graph, "face3", ["male"], 9.5)
    assert node.set_parameters([Parameter("policy", value="none")])[0].successful
    graph.call(SYNC, {"time": 9.5})
    assert queues(graph) == {} and memory(graph) == {"policy": "none"}
    graph.spin_until(lambda: forgets(events, "reset"), what="reset event")
    assert forgets(events, "reset") == [("face3", "male", 9.5)]
    assert graph.call(STATUS, {})["next_tick"] == {"faces": None}
    assert graph.call(SYNC, {"time": 30.0})["applied"] == {"faces": 0}


def test_each_domain_keeps_its_own_pool(graph: RosSession):
    consultant(graph, "faces")
    consultant(graph, "objects")
    node = manager(graph, ("faces", "objects"), policy="displacement", capacity=2, global_capacity=3,
                   **{"objects.capacity": 1, "faces.policy": "displacement+global-capacity"})
    configured(graph)
    assert graph.call(SYNC, {"time": 0.0})["memory"] == {
        "faces": {"policy": "displacement+global-capacity", "capacity": 2, "global_capacity": 3},
        "objects": {"policy": "displacement", "capacity": 1},
    }
    encode(graph, "face1", ["male", "glasses", "lab-coat"], 1.0)
    encode(graph, "face2", ["female", "dark-hair"], 1.0)
    encode(graph, "obj1", ["red", "ball"], 1.0, "objects")
    encode(graph, "obj2", ["blue", "ball"], 1.0, "objects")
    # faces: alpha = 2 per entity and 3 in all; objects: alpha = 1, no global limit
    assert queues(graph, "faces") == {"face1": ["lab-coat"], "face2": ["female", "dark-hair"]}
    assert queues(graph, "objects") == {"obj1": ["ball"], "obj2": ["ball"]}
    # one domain's setting changes only that domain
    assert node.set_parameters([Parameter("objects.capacity", value=0)])[0].successful  # inherit: 2
    assert node.set_parameters([Parameter("faces.capacity", value=1)])[0].successful
    reply = graph.call(SYNC, {"time": 2.0})
    assert reply["memory"]["objects"] == {"policy": "displacement", "capacity": 2}
    assert reply["memory"]["faces"]["capacity"] == 1
    assert queues(graph, "faces") == {"face1": ["lab-coat"], "face2": ["dark-hair"]}
    encode(graph, "obj1", ["red"], 3.0, "objects")
    assert queues(graph, "objects") == {"obj1": ["ball", "red"], "obj2": ["ball"]}
    # a node-wide setting that a domain overrides would not apply there: refused with the reason, nothing changes
    result = node.set_parameters([Parameter("policy", value="none")])[0]
    assert not result.successful and result.reason == (
        "policy: not changed: faces.policy='displacement+global-capacity' overrides the node-wide value (which "
        "applies only to domains that inherit it); set faces.policy instead, or faces.policy='' to inherit")
    assert graph.call(SYNC, {"time": 3.0})["memory"]["objects"] == {"policy": "displacement", "capacity": 2}
    # once every domain inherits it, the default changes every domain
    assert node.set_parameters([Parameter("faces.policy", value="")])[0].successful
    assert node.set_parameters([Parameter("policy", value="none")])[0].successful
    reply = graph.call(SYNC, {"time": 3.0})
    assert reply["memory"] == {"faces": {"policy": "none"}, "objects": {"policy": "none"}}
    assert queues(graph, "objects") == {} and queues(graph, "faces") == {}


def test_a_restarted_consultant_is_configured_again(graph: RosSession):
    old = consultant(graph)
    manager(graph, policy="decay", decay_period=5.0)
    configured(graph)
    graph.remove(old)
    consultant(graph)  # a fresh process would start with policy none
    graph.wait_service("/consultant/faces/manage")
    graph.call(SYNC, {"time": 5.0})  # the decay reply reveals the lost setting
    graph.spin_until(lambda: memory(graph) == {"policy": "decay", "decay_period": 5.0}, what="reconfiguration")
    assert graph.call(SYNC, {"time": 6.0})["applied"] == {"faces": 0}


def test_bad_sync_requests(graph: RosSession):
    consultant(graph)
    manager(graph)
    configured(graph)
    for request, text in [
        ("no json", "not JSON"),
        ({}, "missing field 'time'"),
        ({"time": "later"}, "field 'time'"),
        ({"time": True}, "field 'time'"),
    ]:
        err = graph.call_error(SYNC, request)
        assert err.kind == "MessageError" and text in err.error
    assert graph.call(SYNC, {"time": 1})["applied"] == {"faces": 0}


def test_sync_far_from_the_clock_is_rejected_and_changes_nothing(graph: RosSession):
    consultant(graph)
    manager(graph, policy="decay", decay_period=10.0)
    configured(graph)
    encode(graph, "face1", ["male", "glasses"], 1.0)
    for request, text in [
        ({"time": 1e6}, "more than 86400 s ahead"),
        ({"time": 1e308}, "out of range"),
    ]:
        err = graph.call_error(SYNC, request)
        assert err.kind == "TickError" and text in err.error, err.error
    for text in ('{"time": 1e999}', '{"time": Infinity}', '{"time": NaN}', '{"time": -1e400}'):
        err = graph.call_error(SYNC, text)  # answered with a reason, never a raise in the node
        assert err.kind in ("TickError", "MessageError") and err.error, text
    assert queues(graph) == {"face1": ["male", "glasses"]}
    assert graph.call(STATUS, {})["next_tick"] == {"faces": 10.0}
    # a big but plausible jump empties WM in O(1), and decay goes on afterwards
    assert graph.call(SYNC, {"time": 80_000.0})["applied"] == {"faces": 8000}
    assert queues(graph) == {}
    graph.set_time(80_000.0)
    encode(graph, "face1", ["male", "glasses"], 80_001.0)
    assert graph.call(SYNC, {"time": 80_010.0})["applied"] == {"faces": 1}
    assert queues(graph) == {"face1": ["glasses"]}
    # backwards: nothing undone or applied again
    assert graph.call(SYNC, {"time": 5.0})["applied"] == {"faces": 0}
    assert queues(graph) == {"face1": ["glasses"]}


def test_numeric_parameters_declare_their_ranges(graph: RosSession):
    node = manager(graph, ("faces",))
    ranges = {}
    for name in ("decay_period", "service_timeout"):
        (r,) = node.describe_parameter(name).floating_point_range
        ranges[name] = (r.from_value, r.to_value)
    for name in ("capacity", "global_capacity", "seed"):
        (r,) = node.describe_parameter(name).integer_range
        ranges[name] = (r.from_value, r.to_value)
    assert ranges == {
        "decay_period": (0.01, 1e6),
        "service_timeout": (0.01, 3600.0),
        "capacity": (1, 10_000),
        "global_capacity": (1, 1_000_000),
        "seed": (0, 2**31 - 1),
    }
    # per domain: the rule in words, no range (a range reaching down to the inherit marker read "Min: 0")
    capacity = node.describe_parameter("faces.capacity")
    assert not capacity.integer_range
    assert capacity.additional_constraints == "0 (inherit) or a whole number in [1, 10000]"
    refused = node.set_parameters([Parameter("faces.capacity", value=-1)])[0]
    assert not refused.successful and "capacity must be >= 1, got -1" in refused.reason and "Min" not in refused.reason


def test_startup_errors(graph: RosSession):
    with pytest.raises(StartupError, match="'domains'"):
        graph.add(WMManagerNode, domains=[""])
    with pytest.raises(StartupError, match="unknown forgetting rule"):
        graph.add(WMManagerNode, domains=["faces"], policy="amnesia")
    with pytest.raises(StartupError, match="faces.capacity"):
        graph.add(WMManagerNode, domains=["faces"], **{"faces.capacity": -1})
    with pytest.raises(StartupError, match="twice"):
        graph.add(WMManagerNode, domains=["faces", "faces"])
    with pytest.raises(StartupError, match="service_timeout"):
        graph.add(WMManagerNode, domains=["faces"], service_timeout=-1.0)
    with pytest.raises(StartupError, match="service name"):
        graph.add(WMManagerNode, domains=["two words"])


def test_wall_clock_manager(graph: RosSession):
    consultant(graph)
    graph.add(WMManagerNode, domains=["faces"], policy="decay", decay_period=10.0)  # no sim time
    configured(graph)
    status = graph.call(STATUS, {})
    assert status["time"] > 1e9  # the wall clock
    assert status["time"] < status["next_tick"]["faces"] <= status["time"] + 10.0
    assert graph.call(SYNC, {"time": status["time"]})["applied"] == {"faces": 0}


def test_shared_pool_ops_of_the_consultant(graph: RosSession):
    consultant(graph)
    manage = "/consultant/faces/manage"
    graph.wait_service(manage)
    graph.call(manage, {"op": "configure", "policy": {"policy": "displacement", "capacity": 3}, "time": 0.0})
    encode(graph, "face1", ["male", "glasses"], 1.0)
    encode(graph, "face2", ["female"], 2.0)
    assert graph.call(manage, {"op": "size"}) == {"size": 3}
    assert graph.call(manage, {"op": "evict", "count": 2, "time": 3.0}) == {"queues_changed": 1, "size": 1}
    assert queues(graph) == {"face2": ["female"]}
    for request, text in [
        ({"op": "evict"}, "missing field 'count'"),
        ({"op": "evict", "count": -1}, "field 'count'"),
        ({"op": "evict", "count": "2"}, "field 'count'"),
    ]:
        err = graph.call_error(manage, request)
        assert err.kind == "MessageError" and text in err.error, err.error
    assert queues(graph) == {"face2": ["female"]}


@pytest.mark.parametrize("policy", [{"policy": "none"}, {"policy": "decay", "decay_period": 5.0},
                                    {"policy": "displacement", "capacity": 2},
                                    {"policy": "decay+displacement", "decay_period": 5.0, "capacity": 2}])
def test_readiness_is_false_while_a_consultant_is_unreachable_under_every_policy(graph: RosSession, policy):
    """Issue 28.5: under displacement (which sends the consultant nothing on its own) status said ready and
    configured seconds into an outage; the manager now follows each consultant's liveliness."""
    ready = graph.listen(contract.READY.name, contract.STATE_QOS)
    node = consultant(graph)
    manager(graph, **policy)
    configured(graph)
    status = graph.call(STATUS, {})
    assert status["ready"] is True and status["configured"] == {"faces": True}
    assert status["reachable"] == {"faces": True}
    graph.remove(node)  # the consultant goes away; nothing is sent to it under displacement or none
    graph.spin_until(lambda: graph.call(STATUS, {})["ready"] is False, what="readiness lost")
    status = graph.call(STATUS, {})
    assert status["configured"] == {"faces": False} and status["reachable"] == {"faces": False}
    assert ready.latest(ready=False)["domains"]["faces"]["reachable"] is False
    consultant(graph)  # back (a new process would have a new incarnation; here the same one)
    graph.spin_until(lambda: graph.call(STATUS, {})["ready"] is True, what="readiness back")
    assert memory(graph) == policy
    status = graph.call(STATUS, {})
    assert status["configured"] == {"faces": True} and status["reachable"] == {"faces": True}


def test_ready_names_the_recorders_running_now(graph: RosSession, tmp_path):
    """Issue 38.4: ``wm_manager/ready`` names each recorder while it runs and not after it stopped."""
    from fsreg_ros.ros.recorder import Recorder

    manager(graph)
    ready = graph.listen(contract.READY.name, contract.STATE_QOS)
    graph.spin_until(lambda: ready.latest() is not None, what="readiness")
    assert ready.latest()["recorders"] == []
    with RosSession() as other:  # a participant of its own, as fsreg-ctl record's process
        recorder = Recorder(other.probe, tmp_path / "bag")
        try:
            graph.spin_until(lambda: ready.latest()["recorders"] == ["/probe_recorder"], 10.0,
                             what="the recorder named")
        finally:
            recorder.close()
        graph.spin_until(lambda: ready.latest()["recorders"] == [], 10.0, what="the stopped recorder no longer named")
