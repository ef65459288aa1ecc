"""The JSON carrier: String topics and AddDiagnostics services (docs/semantics.md §7)."""

from __future__ import annotations

import os

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"

import time  # noqa: E402

import pytest  # noqa: E402
from diagnostic_msgs.srv import AddDiagnostics  # noqa: E402
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup  # noqa: E402
from rclpy.node import Node  # noqa: E402
from std_msgs.msg import String  # noqa: E402

from fsreg_ros.carrier import CarrierError, JsonClient, from_msg, serve, to_msg, wait_until  # noqa: E402
from fsreg_ros.codec import NUMBER, MessageError  # noqa: E402
from fsreg_ros.contract import STATE_QOS  # noqa: E402
from fsreg_ros.nodes.common import error_reply  # noqa: E402
from rosutil import Graph, call, ros_graph  # noqa: E402

pytestmark = pytest.mark.graph


@pytest.fixture
def graph():
    yield from ros_graph()


# ------------------------------------------------------------------ pure JSON
def test_round_trip_keeps_the_object():
    obj = {"domain": "faces", "queues": {"face1": ["male", "glasses"]}, "time": 1.5, "turn": None}
    msg = to_msg(obj)
    assert isinstance(msg, String)
    assert from_msg(msg, {"domain": str, "queues": dict[str, list[str]], "time": float}) == obj


@pytest.mark.parametrize(
    "text, required, optional, expected",
    [
        ("not json", {}, None, "not JSON"),
        ('{"a": NaN}', {}, None, "not JSON"),
        ('{"a": Infinity}', {}, None, "not JSON"),
        ("[1, 2]", {}, None, "expected a JSON object, got a list"),
        ('"text"', {}, None, "expected a JSON object, got a string"),
        ("{}", {"entity": str}, None, "missing field 'entity' (expected a string)"),
        ('{"entity": 3}', {"entity": str}, None, "field 'entity': expected a string, got a number (3)"),
        ('{"turn": true}', {"turn": int}, None, "field 'turn': expected a whole number, got a boolean"),
        ('{"time": true}', {"time": NUMBER}, None, "field 'time'"),
        ('{"time": "1"}', {"time": float}, None, "field 'time': expected a number, got a string"),
        ('{"entities": ["a", 2]}', {"entities": list[str]}, None,
         "field 'entities'[1]: expected a string, got a number (2)"),
        ('{"entities": "a"}', {"entities": list[str]}, None, "field 'entities': expected a list of strings"),
        ('{"p": {"red": "high"}}', {"p": dict[str, float]}, None, "field 'p'['red']: expected a number"),
        ('{"turn": "x"}', {}, {"turn": (int, None)}, "field 'turn': expected a whole number or null"),
    ],
)
def test_bad_messages_are_reported_clearly(text, required, optional, expected):
    with pytest.raises(MessageError) as info:
        from_msg(String(data=text), required, optional)
    assert expected in str(info.value)


def test_numbers_ints_and_nulls():
    data = from_msg(String(data='{"time": 3, "turn": null, "x": 1}'), {"time": float}, {"turn": (int, None)})
    assert data == {"time": 3, "turn": None, "x": 1}  # unknown fields are kept
    assert from_msg(String(data='{"n": 2}'), {"n": int}) == {"n": 2}
    with pytest.raises(MessageError):
        from_msg(String(data='{"n": 2.5}'), {"n": int})
    with pytest.raises(ValueError):
        to_msg({"x": float("nan")})  # never put non-JSON on the wire


def test_error_reply_keeps_the_id():
    assert error_reply(String(data='{"id": 7, "x": 1}'), "bad") == {"error": "bad", "id": 7}
    assert error_reply(String(data="garbage"), "bad") == {"error": "bad"}
    assert error_reply({"id": "a"}, "bad") == {"error": "bad", "id": "a"}


def test_a_late_reader_of_wm_state_gets_every_writers_latest_state(graph: Graph):
    """wm/state is latched per writer (depth 1) and read with a deeper history, so a
    reader that joins late hears the latest state of each of several consultants."""
    from fsreg_ros import contract
    from fsreg_ros.carrier import publisher

    writers = [publisher(graph.probe, contract.WM_STATE) for _ in range(3)]
    for i, writer in enumerate(writers):
        writer.publish(to_msg({"domain": f"d{i}", "time": 0.0, "queues": {}, "events": 0}))
        writer.publish(to_msg({"domain": f"d{i}", "time": 1.0, "queues": {}, "events": 1}))
    late = graph.listen(contract.WM_STATE.name, contract.WM_STATE.subscriber_qos)
    graph.spin_until(lambda: len(late) >= 3, 5.0, what="three latched states")
    graph.spin_for(0.2)
    assert sorted((m["domain"], m["time"]) for m in late) == [("d0", 1.0), ("d1", 1.0), ("d2", 1.0)]
    assert STATE_QOS.depth >= len(writers)


# ------------------------------------------------------------------ services
class Server(Node):
    """A JSON server with sync, async (awaiting another service) and failing ops."""

    def __init__(self, context) -> None:
        super().__init__("carrier_server", context=context)
        self.group = ReentrantCallbackGroup()
        self.backend = JsonClient(self, "/carrier/echo", self.group)
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
            from_msg(String(data="{}"), {"needed": str})
        return {"echo": request}

    async def relay(self, request: dict) -> dict:
        # An async handler awaiting another service of the same node: the client is in
        # its own reentrant group, so this must not deadlock (ROS-NOTES).
        reply = await self.backend.call({"relayed": request}, 2.0)
        return {"via": "relay", **reply}

    def fail(self, request: dict) -> dict:
        if request.get("mode") == "bug":
            raise KeyError("oops")
        return "not an object"  # type: ignore[return-value]


def test_serve_and_call_round_trip(graph: Graph):
    server = Server(graph.context)
    graph.executor.add_node(server)
    graph.nodes.append(server)
    assert graph.call("/carrier/echo", {"x": [1, 2]}) == {"echo": {"x": [1, 2]}}
    assert graph.call("/carrier/relay", {"y": 1}) == {"via": "relay", "echo": {"relayed": {"y": 1}}}
    # module-level call() with a JsonClient and with a plain client plus its node
    assert graph.run(call(graph.client("/carrier/echo"), {"z": 0}, 2.0)) == {"echo": {"z": 0}}
    plain = graph.probe.create_client(AddDiagnostics, "/carrier/echo")
    assert graph.run(call(plain, {"w": 1}, 2.0, node=graph.probe)) == {"echo": {"w": 1}}
    assert graph.run(call(plain, {"w": 2}, 2.0)) == {"echo": {"w": 2}}


def test_errors_become_json_error_replies_and_the_server_survives(graph: Graph):
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
    assert err.kind == "MessageError" and "missing field 'needed'" in err.error
    err = graph.call_error("/carrier/fail", {"mode": "bug"})
    assert err.kind == "internal" and "KeyError" in err.error
    err = graph.call_error("/carrier/fail", {})
    assert err.kind == "internal" and "not a JSON object" in err.error
    assert "/carrier/fail" in str(err)
    # still serving
    assert graph.call("/carrier/echo", {"ok": True}) == {"echo": {"ok": True}}


def test_call_times_out_without_a_server(graph: Graph):
    client = graph.client("/carrier/nobody")
    started = time.monotonic()
    with pytest.raises(CarrierError) as info:
        graph.run(client.call({"x": 1}, 0.3), timeout=5.0)
    assert info.value.kind == "timeout"
    assert 0.25 < time.monotonic() - started < 3.0
    with pytest.raises(CarrierError) as info:
        graph.run(client.wait_ready({"x": 1}, 0.3), timeout=5.0)
    assert info.value.kind == "timeout" and "not ready" in str(info.value)


def test_wait_ready_does_one_real_round_trip(graph: Graph):
    server = Server(graph.context)
    graph.executor.add_node(server)
    graph.nodes.append(server)
    before = server.calls
    assert graph.run(graph.client("/carrier/echo").wait_ready({"ping": 1}, 5.0)) == {"echo": {"ping": 1}}
    assert server.calls == before + 1


def test_wait_until(graph: Graph):
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

    from fsreg_ros.codec import error_json, printable, safe_dumps

    text = error_json(value, "MessageError", value if isinstance(value, (str, int)) else None, extra=value)
    reply = json.loads(text)
    assert reply["kind"] == "MessageError" and isinstance(reply["error"], str)
    assert len(reply["error"]) <= 500
    json.loads(safe_dumps({"id": 1, "v": value}))
    printable(value).encode("utf-8")  # a logger can always write it


def test_parse_refuses_oversized_text_before_parsing():
    from fsreg_ros.codec import parse

    with pytest.raises(MessageError, match="over the limit of 1000"):
        parse('{"a": "' + "x" * 2000 + '"}', max_bytes=1000)
    assert parse('{"a": "x"}', max_bytes=1000) == {"a": "x"}


def test_a_service_answers_hostile_requests(graph: Graph):
    server = Server(graph.context)
    graph.executor.add_node(server)
    graph.nodes.append(server)
    for text in ['{"id": "\\ud800", "raise": "value"}', '{"x": 1e999}', '{"n": ' + "9" * 5000 + "}"]:
        err = graph.call_error("/carrier/fail", text)
        assert err.kind in ("internal", "MessageError")
    assert graph.call("/carrier/echo", {"ok": 1}) == {"echo": {"ok": 1}}
