"""The JSON carrier: String topics and AddDiagnostics services (docs/semantics.md §7)."""

from __future__ import annotations

import os

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"

import time  # noqa: E402
from typing import Optional, Union  # noqa: E402

import pytest  # noqa: E402
from diagnostic_msgs.srv import AddDiagnostics  # noqa: E402
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup  # noqa: E402
from rclpy.node import Node  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from fsreg_ros.ros.carrier import (CarrierError, ServiceCaller, from_msg, qos_profile, to_msg,  # noqa: E402
                                   wait_until)
from fsreg_ros.ros.serving import serve  # noqa: E402
from fsreg_ros.contract.codec import MessageError  # noqa: E402
from fsreg_ros.contract import SERVICE_QOS, STATE_QOS, Message, check  # noqa: E402
from fsreg_ros.ros.node_base import error_reply  # noqa: E402
from rosutil import RosSession, call  # noqa: E402

pytestmark = pytest.mark.graph


# ------------------------------------------------------------------ pure JSON
def test_round_trip_keeps_the_object():
    obj = {"domain": "faces", "queues": {"face1": ["male", "glasses"]}, "time": 1.5, "turn": None}
    msg = to_msg(obj)
    assert isinstance(msg, String)
    assert from_msg(msg) == obj


@pytest.mark.parametrize(
    "text, expected",
    [
        ("not json", "not JSON"),
        ('{"a": NaN}', "not JSON"),
        ('{"a": Infinity}', "not JSON"),
        ('{"a": [1, {"b": -1e999}]}', "field 'a'[1]['b']: -1e999 is too large for a number (not finite)"),
        ("[1, 2]", "expected a JSON object, got a list"),
        ('"text"', "expected a JSON object, got a string"),
        ('{"a": ' + "9" * 5000 + "}", "not JSON"),
    ],
)
def test_what_is_not_a_json_object_is_reported_clearly(text, expected):
    with pytest.raises(MessageError) as info:
        from_msg(String(data=text))
    assert expected in str(info.value)


class Shape(Message):
    """A schema with one field of each kind, for the contract's error messages."""

    entity: str
    turn: Optional[int] = None
    time: Optional[Union[int, float]] = None
    entities: list[str] = []
    p: dict[str, float] = {}


@pytest.mark.parametrize(
    "data, expected",
    [
        ({}, "missing field 'entity'"),
        ({"entity": 3}, "field 'entity': expected a string, got 3"),
        ({"entity": "e", "turn": True}, "field 'turn': expected a whole number or null, got True"),
        ({"entity": "e", "time": True}, "field 'time': expected a number or null, got True"),
        ({"entity": "e", "time": "1"}, "field 'time': expected a number or null, got '1'"),
        ({"entity": "e", "entities": ["a", 2]}, "field 'entities'[1]: expected a string, got 2"),
        ({"entity": "e", "entities": "a"}, "field 'entities': expected a list of strings, got 'a'"),
        ({"entity": "e", "p": {"red": "high"}}, "field 'p'['red']: expected a number, got 'high'"),
        ({"entity": "e", "turn": 2.5}, "field 'turn': expected a whole number or null, got 2.5"),
    ],
)
def test_fields_against_the_schema_are_reported_in_one_line(data, expected):
    with pytest.raises(MessageError) as info:
        check(Shape, data)
    assert str(info.value) == expected


def test_numbers_ints_and_nulls():
    data = from_msg(String(data='{"entity": "e", "time": 3, "turn": null, "x": 1}'))
    assert check(Shape, data) == {"entity": "e", "time": 3, "turn": None, "x": 1}  # unknown fields are kept
    with pytest.raises(ValueError):
        to_msg({"x": float("nan")})  # never put non-JSON on the wire


def test_error_reply_keeps_the_id():
    assert error_reply(String(data='{"id": 7, "x": 1}'), "bad") == {"error": "bad", "id": 7}
    assert error_reply(String(data="garbage"), "bad") == {"error": "bad"}
    assert error_reply({"id": "a"}, "bad") == {"error": "bad", "id": "a"}


def test_a_late_reader_of_wm_state_gets_every_writers_latest_state(graph: RosSession):
    """wm/state is latched per writer (depth 1) and read with a deeper history, so a
    reader that joins late hears the latest state of each of several consultants."""
    from fsreg_ros import contract
    from fsreg_ros.ros.carrier import publisher

    writers = [publisher(graph.probe, contract.WM_STATE) for _ in range(3)]
    for i, writer in enumerate(writers):
        writer.publish(to_msg({"domain": f"d{i}", "time": 0.0, "queues": {}, "events": 0}))
        writer.publish(to_msg({"domain": f"d{i}", "time": 1.0, "queues": {}, "events": 1}))
    late = graph.listen(contract.WM_STATE.name, contract.WM_STATE.subscriber_qos)
    graph.spin_until(lambda: len(late) >= 3, 5.0, what="three latched states")
    # Each writer's next message arrives after whatever history it delivered: once all three
    # are here, the late reader has heard everything it will of the earlier states.
    graph.spin_until(lambda: all(w.get_subscription_count() for w in writers), 5.0, what="matched writers")
    for i, writer in enumerate(writers):
        writer.publish(to_msg({"domain": f"d{i}", "time": 2.0, "queues": {}, "events": 2}))
    graph.spin_until(lambda: len([m for m in late if m["time"] == 2.0]) == 3, 5.0, what="three new states")
    assert sorted((m["domain"], m["time"]) for m in late) == [("d0", 1.0), ("d0", 2.0), ("d1", 1.0), ("d1", 2.0),
                                                              ("d2", 1.0), ("d2", 2.0)]
    assert STATE_QOS.depth >= len(writers)


# ------------------------------------------------------------------ services
class Server(Node):
    """A JSON server with sync, async (awaiting another service) and failing ops."""

    def __init__(self, context) -> None:
        super().__init__("carrier_server", context=context)
        self.group = ReentrantCallbackGroup()
        self.backend = ServiceCaller(self, "/carrier/echo", self.group)
        # echo in a group of its own: relay (default group) awaits it on this same node
        serve(self, "/carrier/echo", self.echo, MutuallyExclusiveCallbackGroup())
        serve(self, "/carrier/relay", self.relay)
        serve(self, "/carrier/fail", self.fail)
        self.calls = 0

    def echo(self, request: dict) -> dict:
        self.calls += 1
        if request.get("raise") == "value":
            raise ValueError("no such thing")
        if request.get("raise") == "message":
            check(Shape, {"needed": "x"})
        return {"echo": request}

    async def relay(self, request: dict) -> dict:
        # An async handler awaiting another service of the same node: the client is in
        # its own reentrant group, so this must not deadlock (carrier's docstring, "Calling").
        reply = await self.backend.call({"relayed": request}, 2.0)
        return {"via": "relay", **reply}

    def fail(self, request: dict) -> dict:
        if request.get("mode") == "bug":
            raise KeyError("oops")
        return "not an object"  # type: ignore[return-value]


def test_serve_and_call_round_trip(graph: RosSession):
    server = Server(graph.context)
    graph.executor.add_node(server)
    graph.nodes.append(server)
    assert graph.call("/carrier/echo", {"x": [1, 2]}) == {"echo": {"x": [1, 2]}}
    assert graph.call("/carrier/relay", {"y": 1}) == {"via": "relay", "echo": {"relayed": {"y": 1}}}
    # module-level call() with a ServiceCaller and with a plain client plus its node
    assert graph.run(call(graph.client("/carrier/echo"), {"z": 0}, 2.0)) == {"echo": {"z": 0}}
    plain = graph.probe.create_client(AddDiagnostics, "/carrier/echo")
    assert graph.run(call(plain, {"w": 1}, 2.0, node=graph.probe)) == {"echo": {"w": 1}}
    assert graph.run(call(plain, {"w": 2}, 2.0)) == {"echo": {"w": 2}}


def test_errors_become_json_error_replies_and_the_server_survives(graph: RosSession):
    server = Server(graph.context)
    graph.executor.add_node(server)
    graph.nodes.append(server)
    err = graph.call_error("/carrier/echo", "this is not json")
    assert err.kind == "MessageError" and "not JSON" in err.error
    err = graph.call_error("/carrier/echo", "[1]")
    assert err.kind == "MessageError" and "JSON object" in err.error
    err = graph.call_error("/carrier/echo", {"raise": "value"})
    assert err.kind == "ValueError" and err.error == "no such thing"
    assert err.reply == {"error": "no such thing", "kind": "ValueError"}
    err = graph.call_error("/carrier/echo", {"raise": "message"})
    assert err.kind == "MessageError" and err.error == "missing field 'entity'"
    err = graph.call_error("/carrier/fail", {"mode": "bug"})
    assert err.kind == "internal" and "KeyError" in err.error
    err = graph.call_error("/carrier/fail", {})
    assert err.kind == "internal" and "not a JSON object" in err.error
    assert "/carrier/fail" in str(err)
    # still serving
    assert graph.call("/carrier/echo", {"ok": True}) == {"echo": {"ok": True}}


def test_call_times_out_without_a_server(graph: RosSession):
    client = graph.client("/carrier/nobody")
    started = time.monotonic()
    with pytest.raises(CarrierError) as info:
        graph.run(client.call({"x": 1}, 0.3), timeout=5.0)
    assert info.value.kind == "timeout"
    assert 0.25 < time.monotonic() - started < 3.0
    with pytest.raises(CarrierError) as info:
        graph.run(client.wait_ready({"x": 1}, 0.3), timeout=5.0)
    assert info.value.kind == "timeout" and "not ready" in str(info.value)


def test_wait_ready_does_one_real_round_trip(graph: RosSession):
    server = Server(graph.context)
    graph.executor.add_node(server)
    graph.nodes.append(server)
    before = server.calls
    assert graph.run(graph.client("/carrier/echo").wait_ready({"ping": 1}, 5.0)) == {"echo": {"ping": 1}}
    assert server.calls == before + 1


def test_wait_until(graph: RosSession):
    flag = {"set": False}
    timer = graph.probe.create_timer(0.05, lambda: flag.update(set=True))
    assert graph.run(wait_until(graph.probe, lambda: flag["set"], 2.0)) is True
    graph.probe.destroy_timer(timer)
    assert graph.run(wait_until(graph.probe, lambda: False, 0.1)) is False


# ------------------------------------------------------------------ error replies never throw
@pytest.mark.parametrize(
    "value",
    [float("nan"), float("inf"), 10**5000, "\ud800", "x" * 100_000, object(), {"k": [float("-inf")]}, b"bytes"],
    ids=["nan", "inf", "huge-int", "surrogate", "long", "object", "nested-inf", "bytes"],
)
def test_error_replies_are_json_whatever_they_carry(value):
    import json

    from fsreg_ros.contract.codec import error_json, printable, safe_dumps

    text = error_json(value, "MessageError", value if isinstance(value, (str, int)) else None, extra=value)
    reply = json.loads(text)
    assert reply["kind"] == "MessageError" and isinstance(reply["error"], str)
    assert len(reply["error"]) <= 500
    json.loads(safe_dumps({"id": 1, "v": value}))
    printable(value).encode("utf-8")  # a logger can always write it


def test_parse_refuses_oversized_text_before_parsing():
    from fsreg_ros.contract.codec import parse

    with pytest.raises(MessageError, match="over the limit of 1000"):
        parse('{"a": "' + "x" * 2000 + '"}', max_bytes=1000)
    assert parse('{"a": "x"}', max_bytes=1000) == {"a": "x"}


def test_a_service_answers_hostile_requests(graph: RosSession):
    server = Server(graph.context)
    graph.executor.add_node(server)
    graph.nodes.append(server)
    for text in ['{"id": "\\ud800", "raise": "value"}', '{"x": 1e999}', '{"n": ' + "9" * 5000 + "}"]:
        err = graph.call_error("/carrier/fail", text)
        assert err.kind in ("internal", "MessageError")
    assert graph.call("/carrier/echo", {"ok": 1}) == {"echo": {"ok": 1}}


# ------------------------------------------------------------------ callbacks survive every input
def test_a_warning_then_an_internal_error_on_one_topic_keeps_the_node_alive(graph: RosSession):
    """rclpy raises if one logging call site changes severity: a malformed message (a
    warning) followed by one whose handler fails unexpectedly (an error) once killed
    REG, RR and the consultant.  Both are logged and answered, and the node serves on."""
    from fsreg_ros import contract
    from fsreg_ros.ros.carrier import subscribe

    node = Node("survivor", context=graph.context)
    graph.executor.add_node(node)
    graph.nodes.append(node)
    handled, rejected = [], []

    def handler(data: dict) -> None:
        float(data["time"])  # OverflowError for 10**400: not a ValueError, so "internal"
        handled.append(data["time"])

    # A topic whose schema takes any object, so the handler sees the hostile number.
    topic = contract.Topic("carrier/any", contract.Message, contract.DEFAULT_QOS, "test", "test")
    subscribe(node, topic, handler, reject=lambda rid, error, kind: rejected.append((rid, error)))
    huge = "1" + "0" * 400
    for text in ["not json", '{"id": 1, "time": ' + huge + "}", "{", '{"id": 2, "time": -' + huge + "}",
                 '{"id": 3, "time": 1.5}']:
        graph.publish("/carrier/any", text, topic.qos)
    graph.spin_until(lambda: handled == [1.5], what="the last, valid message")
    assert [rid for rid, _ in rejected] == [None, 1, None, 2]
    assert "not JSON" in rejected[0][1] and rejected[1][1].startswith("internal error: OverflowError")


def test_a_contract_topic_refuses_a_number_no_float_holds_before_the_handler(graph: RosSession):
    from fsreg_ros import contract
    from fsreg_ros.ros.carrier import subscribe

    node = Node("strict", context=graph.context)
    graph.executor.add_node(node)
    graph.nodes.append(node)
    handled, rejected = [], []
    subscribe(node, contract.REG_REQUEST, handled.append, reject=lambda rid, error, kind: rejected.append((rid, error)),
              limits=contract.Limits(max_name_chars=8))
    huge = "1" + "0" * 400
    for text in ['{"id": 1, "target": "f", "time": ' + huge + "}", '{"id": 2, "target": "far-too-long"}',
                 '{"id": 3, "target": "face1", "time": 2}']:
        graph.publish("/" + contract.REG_REQUEST.name, text, contract.REG_REQUEST.qos)
    graph.spin_until(lambda: len(handled) == 1, what="the valid request")
    assert handled == [{"id": 3, "target": "face1", "time": 2}]
    assert rejected == [(1, "field 'time': a number too large (1329 bits; at most about 1e308)"),
                        (2, "field 'target': a name of 12 characters, over the limit of 8")]


def test_a_service_logging_a_warning_then_an_error_keeps_serving(graph: RosSession):
    server = Server(graph.context)
    graph.executor.add_node(server)
    graph.nodes.append(server)
    for _ in range(2):
        assert graph.call_error("/carrier/fail", "not json").kind == "MessageError"
        assert graph.call_error("/carrier/fail", {"mode": "bug"}).kind == "internal"
    assert graph.call("/carrier/echo", {"ok": 2}) == {"echo": {"ok": 2}}


def test_log_lines_never_raise():
    from fsreg_ros.ros.carrier import log_error, log_warning

    class Refusing:
        def warning(self, text):
            raise ValueError("Logger severity cannot be changed between calls.")

        error = warning

    log_warning(Refusing(), "x\ud800")
    log_error(Refusing(), object())


def test_serve_validates_once_against_the_contract_and_dispatches_by_op(graph: RosSession):
    """A contract service with ops: the op chooses the handler, the request is validated
    against that op's schema (names within the limits) before any handler runs, and a
    handler may return a contract model."""
    from typing import Literal, Union

    from fsreg_ros import contract
    from fsreg_ros.ros.serving import serve

    class Look(contract.Message):
        op: Literal["look"]
        entity: contract.Name

    class Count(contract.Message):
        op: Literal["count"]
        entities: contract.Names

    class Counted(contract.Message):
        count: int
        note: str = "unset"

    service = contract.Service("carrier/<domain>/ops", Union[Look, Count], Union[contract.Message, Counted],
                               "test", "test")
    node = Node("ops", context=graph.context)
    graph.executor.add_node(node)
    graph.nodes.append(node)
    ran = []
    serve(node, service, {"look": lambda r: ran.append(r) or {"seen": r["entity"]},
                          "count": lambda r: ran.append(r) or Counted(count=len(r["entities"]))},
          limits=contract.Limits(max_name_chars=5, max_list_items=3), domain="faces")
    name = "/carrier/faces/ops"
    assert graph.call(name, {"op": "look", "entity": "face1"}) == {"seen": "face1"}
    assert graph.call(name, {"op": "count", "entities": ["a", "b"]}) == {"count": 2}  # fields set only
    for request, error in [
        ({"op": "jump"}, "field 'op': expected one of look, count, got 'jump'"),
        ({"entity": "face1"}, "missing field 'op' (one of look, count)"),
        ({"op": "count", "entities": "a"}, "field 'entities': expected a list of strings, got 'a'"),
        ({"op": "count", "entities": ["a"] * 4}, "field 'entities': 4 items, over the limit of 3"),
        ({"op": "look", "entity": "face10"}, "field 'entity': a name of 6 characters, over the limit of 5"),
        ({"op": "look"}, "missing field 'entity'"),
    ]:
        err = graph.call_error(name, request)
        assert (err.kind, err.error) == ("MessageError", error)
    assert len(ran) == 2  # no handler saw a refused request


def test_subscribe_ignores_what_accept_refuses_before_validating_it(graph: RosSession):
    """Several consultants share ltm/assert: a message for another domain is that one's to
    refuse; this node neither handles nor rejects it, however malformed."""
    from fsreg_ros import contract
    from fsreg_ros.ros.carrier import subscribe

    node = Node("faces_only", context=graph.context)
    graph.executor.add_node(node)
    graph.nodes.append(node)
    handled, rejected = [], []
    subscribe(node, contract.LTM_ASSERT, lambda data: handled.append(data["id"]),
              reject=lambda rid, error, kind: rejected.append(rid),
              accept=lambda data: not isinstance(data.get("domain"), str) or data["domain"] == "faces")
    for text in ['{"domain": "objects", "id": 1, "properties": "bad"}', '{"domain": 7, "id": 2}',
                 '{"domain": "faces", "id": 3, "properties": "bad"}',
                 '{"domain": "faces", "id": 4, "entity": "e", "properties": {"p": 1}}']:
        graph.publish("/" + contract.LTM_ASSERT.name, text, contract.LTM_ASSERT.qos)
    graph.spin_until(lambda: handled == [4], what="the one valid assertion for faces")
    assert rejected == [2, 3]  # the objects message was not this node's to refuse


def test_a_draining_service_answers_every_waiting_request_in_order_and_once(graph: RosSession):
    server = Node("drained", context=graph.context)
    seen: list[int] = []

    def handler(request: dict) -> dict:
        seen.append(request["n"])
        if request["n"] == 7:
            raise MessageError("seven is refused")
        return {"n": request["n"]}

    serve(server, "/carrier/drained", handler, drain=4)  # 20 waiting: answered four at a time, ahead of the round
    graph.executor.add_node(server)
    graph.nodes.append(server)
    graph.wait_service("/carrier/drained")
    # a client as deep as the contract's (a reader of depth 10 taking one answer a round would lose some)
    plain = graph.probe.create_client(AddDiagnostics, "/carrier/drained", qos_profile=qos_profile(SERVICE_QOS))
    futures = [plain.call_async(AddDiagnostics.Request(load_namespace=f'{{"n": {n}}}')) for n in range(20)]
    graph.spin_until(lambda: all(f.done() for f in futures), 10.0, what="20 answers")
    replies = [(f.result().success, from_msg(String(data=f.result().message))) for f in futures]
    refused = {"error": "seven is refused", "kind": "MessageError", "detail": "bad-request"}
    assert replies == [(n != 7, {"n": n} if n != 7 else refused)
                       for n in range(20)]
    assert seen == list(range(20))  # each once, in the order sent


def _gathering_node(graph: RosSession, name: str, **options):
    """A node with a gathered ltm/assert subscription; the batches handled and the ids rejected."""
    from fsreg_ros import contract
    from fsreg_ros.ros.batches import subscribe_batches

    node = Node(name, context=graph.context)
    graph.executor.add_node(node)
    graph.nodes.append(node)
    batches: list[list] = []
    rejected: list = []
    subscription = subscribe_batches(node, contract.LTM_ASSERT, lambda batch: batches.append([d["id"] for d in batch]),
                                     reject=lambda rid, error, kind: rejected.append((rid, kind)),
                                     limits=contract.Limits(), **options)
    return subscription, batches, rejected


def _fact(n: int) -> dict:
    return {"domain": "faces", "id": n, "entity": f"e{n}", "properties": {"glasses": 1.0}}


def test_a_gathered_stream_is_taken_a_period_at_a_time_and_a_quiet_reader_at_once(graph: RosSession):
    """subscribe_batches(gather=): the first message of a stream is handled at once; while the
    stream lasts the executor does not wait on the reader (the group holds it) and the timer takes
    what came in each period in one batch; a period with nothing hands the reader back."""
    from fsreg_ros import contract

    topic = "/" + contract.LTM_ASSERT.name
    subscription, batches, rejected = _gathering_node(graph, "gathering", gather=0.2, max_seconds=30.0)
    group = subscription.callback_group
    graph.publish(topic, _fact(0), contract.LTM_ASSERT.qos)
    graph.spin_until(lambda: batches == [[0]], what="the first message, handled at once")
    assert group.holding and not group.timer.is_canceled()  # a stream may be starting: gather it
    for n in range(1, 21):  # 20 more, one a message, while nothing spins: they wait in the reader
        graph.publish(topic, _fact(n), contract.LTM_ASSERT.qos)
    graph.publish(topic, '{"domain": "faces", "id": 21, "entity": "e21", "properties": "bad"}', contract.LTM_ASSERT.qos)
    time.sleep(0.5)  # delivered to the reader meanwhile (no spinning: nothing is taken)
    graph.spin_until(lambda: len(batches) == 2, what="the period's batch")
    assert batches == [[0], list(range(1, 21))]  # the 20 valid ones in one batch, in order
    assert rejected == [(21, "bad-request")]  # the bad one refused alone, with its id
    graph.spin_until(lambda: not group.holding and group.timer.is_canceled(),  # an idle node pays nothing
                     what="the reader handed back and the timer stopped after a quiet period")
    graph.publish(topic, _fact(30), contract.LTM_ASSERT.qos)
    graph.spin_until(lambda: len(batches) == 3, what="a message into the quiet reader")
    assert batches[2] == [30]


def test_a_gathered_stream_over_the_budget_is_handed_back_at_once_and_nothing_is_lost(graph: RosSession):
    """A period's drain stops at max_size; what is left is taken at once (the executor waits on
    the reader again), in batches within the budget, each message once and in order."""
    from fsreg_ros import contract

    topic = "/" + contract.LTM_ASSERT.name
    subscription, batches, rejected = _gathering_node(graph, "gathering_budget", gather=0.2, max_size=5,
                                                      max_seconds=30.0)
    graph.publish(topic, _fact(0), contract.LTM_ASSERT.qos)
    graph.spin_until(lambda: batches == [[0]], what="the first message")
    for n in range(1, 18):
        graph.publish(topic, _fact(n), contract.LTM_ASSERT.qos)
    time.sleep(0.5)
    graph.spin_until(lambda: sum(map(len, batches)) == 18, what="all 18")
    assert [n for batch in batches for n in batch] == list(range(18))
    assert [len(batch) for batch in batches] == [1, 5, 5, 5, 2]  # the budget, not the period, sets the rest
    assert rejected == []


def test_releasing_a_held_reader_takes_what_waits_at_once_and_hands_it_back(graph: RosSession):
    """GatheringGroup.release (a client blocked on its own answer): what waits is taken now, not
    at the period's end, and the executor waits on the reader again."""
    from fsreg_ros import contract

    topic = "/" + contract.LTM_ASSERT.name
    # a period never reached
    subscription, batches, rejected = _gathering_node(graph, "releasing", gather=30.0, max_seconds=30.0)
    group = subscription.callback_group
    group.release()  # not held: nothing happens
    assert batches == [] and not group.holding
    graph.publish(topic, _fact(0), contract.LTM_ASSERT.qos)
    graph.spin_until(lambda: batches == [[0]], what="the first message")
    assert group.holding
    for n in (1, 2, 3):
        graph.publish(topic, _fact(n), contract.LTM_ASSERT.qos)
    time.sleep(0.5)
    graph.spin_for(0.2)
    assert batches == [[0]]  # held: the executor does not take them
    group.release()
    assert batches == [[0], [1, 2, 3]] and not group.holding  # taken at the call, without spinning
    graph.publish(topic, _fact(4), contract.LTM_ASSERT.qos)
    graph.spin_until(lambda: len(batches) == 3, what="the next message, taken as it arrives")
    assert batches[2] == [4] and rejected == []
