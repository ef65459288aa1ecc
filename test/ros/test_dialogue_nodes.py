"""Parser, reference resolution and REG nodes: their contracts and their bad input.

Bad input on a topic (not JSON, wrong fields, unknown entity or property) gets an
error on the reply topic, never a crash, and never a change to WM (checked through
the consultant's snapshot); the node keeps serving afterwards.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from rosutil import RosSession

from fsreg_ros import contract
from fsreg_ros.nodes.consultant import ConsultantNode
from fsreg_ros.nodes.parser import ParserNode
from fsreg_ros.nodes.reference_resolution import ReferenceResolutionNode
from fsreg_ros.nodes.reg import RegNode
from fsreg_ros.nodes.wm_manager import WMManagerNode

pytestmark = pytest.mark.graph


@pytest.fixture
def pipeline(table1_path: Path):
    """Consultant (displacement, capacity 2), WM Manager, parser, RR and REG."""
    with RosSession() as g:
        kb = str(table1_path)
        g.add(ConsultantNode, name="consultant_faces", domain="faces", kb=kb, debug=True)
        g.add(WMManagerNode, domains=["faces"], policy="displacement", capacity=2)
        g.add(ParserNode, kb=kb)
        g.add(ReferenceResolutionNode, domains=["faces"])
        g.add(RegNode, domains=["faces"])
        g.results = g.listen(contract.RR_RESULT.name)
        g.expressions = g.listen(contract.REG_EXPRESSION.name)
        g.call(contract.SYNC.name, {"time": 0.0}, timeout=15.0)
        yield g


def snapshot(g: RosSession) -> dict:
    return g.call(contract.debug_service("faces"), {"op": "snapshot"})["queues"]


def ask(g: RosSession, topic: str, inbox, message, key=None, timeout: float = 10.0) -> dict:
    """Publish and wait for the reply on ``inbox`` with id ``key``."""
    g.publish(topic, message)
    g.spin_until(lambda: inbox.latest(id=key) is not None, timeout, what=f"a reply with id {key!r}")
    return inbox.latest(id=key)


def error_naming(g: RosSession, inbox, fragment: str) -> dict:
    """Wait for an error reply on ``inbox`` whose error names ``fragment``; return the first."""
    def naming(reply: dict) -> bool:
        return fragment in (reply.get("error") or "")

    g.spin_until(lambda: any(naming(r) for r in inbox), 10.0, what=f"error {fragment!r}")
    return next(r for r in inbox if naming(r))


def test_text_is_parsed_resolved_and_encoded(pipeline):
    reply = ask(pipeline, contract.HUMAN.name, pipeline.results, {"id": "u1", "time": 1.0,
                                                                  "text": "the woman with glasses, says he"}, "u1")
    assert reply["status"] == "resolved" and reply["resolved"] == "face2"
    assert reply["description"] == ["female", "glasses"]
    assert reply["unknown_words"] == ["says", "he"]
    assert snapshot(pipeline)["face2"] == ["female", "glasses"]


def test_an_utterance_whose_reading_would_be_too_large_is_refused_in_one_line_naming_it(pipeline):
    """~1,000 long unknown words fit ``dialogue/human`` but not their reading (text and unknown words, twice)."""
    words = " ".join(f"w{i:04d}" + "x" * 35 for i in range(1000))
    before = snapshot(pipeline)
    reply = ask(pipeline, contract.HUMAN.name, pipeline.results, {"id": "long", "time": 1.0, "text": words}, "long")
    assert reply["status"] == "error" and reply["kind"] == "too-large", reply
    size = re.fullmatch(r"dialogue/human: its reading on dialogue/semantics \(the text and its 1000 unknown words\) "
                        r"would be (\d+) bytes, over the limit of 65536 \(max_message_bytes\); say less at once",
                        reply["error"])
    assert size and int(size.group(1)) > 80_000, reply["error"]
    assert snapshot(pipeline) == before


def test_ambiguous_and_no_match(pipeline):
    reply = ask(pipeline, contract.HUMAN.name, pipeline.results, {"id": 7, "description": ["light-hair", "glasses"]}, 7)
    assert reply["status"] == "ambiguous"
    assert reply["resolved"] is None
    assert reply["candidates"] == ["face1", "face6", "face10", "face11", "face13"]
    reply = ask(pipeline, contract.HUMAN.name, pipeline.results, {"id": 8, "text": "the purple giraffe"}, 8)
    assert reply["status"] == "no-match" and reply["candidates"] == []
    assert reply["unknown_words"] == ["purple", "giraffe"]


def test_reg_expression_fields(pipeline):
    reply = ask(pipeline, contract.REG_REQUEST.name, pipeline.expressions,
                {"id": "r1", "target": "face5", "time": 2.0}, "r1")
    assert reply["description"] == ["male", "dark-hair"] and reply["sources"] == ["ltm", "ltm"]
    assert reply["text"] == "the man with dark hair"
    assert reply["distinguishing"] is True and reply["distractors_left"] == []
    assert reply["wm_before"] == [] and reply["algorithm"] == "sd-pia" and reply["domain"] == "faces"
    assert snapshot(pipeline)["face5"] == ["male", "dark-hair"]


def test_repeated_id_is_answered_from_cache_without_encoding_twice(pipeline):
    first = ask(pipeline, contract.REG_REQUEST.name, pipeline.expressions, {"id": "dup", "target": "face3"}, "dup")
    before = snapshot(pipeline)
    pipeline.expressions.clear_all()
    again = ask(pipeline, contract.REG_REQUEST.name, pipeline.expressions, {"id": "dup", "target": "face3"}, "dup")
    assert again == first
    assert snapshot(pipeline) == before


HUMAN_KINDS = {"b5": "unknown-property", "b6": "unknown-domain", "b8": "too-large"}


@pytest.mark.parametrize(
    "message, fragment",
    [
        ("not json at all", "not JSON"),
        ('["a", "list"]', "object"),
        ({"time": 1.0, "text": "the man"}, "id"),
        ({"id": "b1", "text": "the man", "description": ["male"]}, "exactly one"),
        ({"id": "b2"}, "exactly one"),
        ({"id": "b3", "text": 42}, "text"),
        ({"id": "b4", "description": "male"}, "description"),
        ({"id": "b5", "description": ["purple-hair"]}, "purple-hair"),
        ({"id": "b6", "description": ["male"], "domain": "kitchen"}, "kitchen"),
        ({"id": "b8", "text": "the man " + "x" * 70_000}, "over the limit of 65536"),
        ({"id": "b7", "description": [3]}, "description"),
    ],
)
def test_bad_human_turns_get_an_error_and_change_nothing(pipeline, message, fragment):
    before = snapshot(pipeline)
    pipeline.publish(contract.HUMAN.name, message if isinstance(message, (dict, str)) else message)
    key = message.get("id") if isinstance(message, dict) else None
    error = error_naming(pipeline, pipeline.results, fragment)
    assert error.get("id") == key  # an oversized message too: its id is read off its head
    assert error["status"] == "error"
    assert error["kind"] == HUMAN_KINDS.get(key, "bad-request"), error  # every error reply carries a kind
    assert snapshot(pipeline) == before
    # still serving
    ok = ask(pipeline, contract.HUMAN.name, pipeline.results,
             {"id": "after", "description": ["female", "hoodie"]}, "after")
    assert ok["resolved"] == "face3"


@pytest.mark.parametrize(
    "message, fragment",
    [
        ("{broken", "not JSON"),
        ({"target": "face1"}, "id"),
        ({"id": "x1"}, "target"),
        ({"id": "x2", "target": 5}, "target"),
        ({"id": "x3", "target": "face99"}, "face99"),
        ({"id": "x4", "target": "face1", "context": ["face2", "face77"]}, "face77"),
        ({"id": "x5", "target": "face1", "context": "face2"}, "context"),
    ],
)
def test_bad_reg_requests_get_an_error_and_change_nothing(pipeline, message, fragment):
    before = snapshot(pipeline)
    pipeline.publish(contract.REG_REQUEST.name, message)
    error = error_naming(pipeline, pipeline.expressions, fragment)
    assert error.get("id") == (message.get("id") if isinstance(message, dict) else None)
    # Every error reply carries a kind (REG's unknown-entity error had none).
    assert error["kind"] == {"x3": "unknown-entity", "x4": "unknown-entity"}.get(error.get("id"), "bad-request"), error
    assert snapshot(pipeline) == before
    ok = ask(pipeline, contract.REG_REQUEST.name, pipeline.expressions, {"id": "fine", "target": "face2"}, "fine")
    assert ok["description"] == ["glasses", "female"]


@pytest.mark.parametrize(
    "message, fragment",
    [
        ("[1, 2", "not JSON"),
        ({"id": "s1"}, "description"),
        ({"id": "s2", "description": "male"}, "description"),
        ({"description": ["male"]}, "id"),
    ],
)
def test_bad_semantics_get_an_error_and_change_nothing(pipeline, message, fragment):
    before = snapshot(pipeline)
    pipeline.publish(contract.SEMANTICS.name, message)
    error = error_naming(pipeline, pipeline.results, fragment)
    assert error["status"] == "error"
    assert error.get("id") == (message.get("id") if isinstance(message, dict) else None)
    assert snapshot(pipeline) == before


def test_context_set_limits_distractors(pipeline):
    reply = ask(pipeline, contract.REG_REQUEST.name, pipeline.expressions,
                {"id": "c", "target": "face1", "context": ["face1", "face2", "face3"]}, "c")
    assert reply["description"] == ["light-hair"]
    assert reply["text"] == "the person with light hair"


def test_reg_parameters_are_validated(pipeline):
    from rclpy.parameter import Parameter

    reg = next(n for n in pipeline.nodes if isinstance(n, RegNode))
    bad = reg.set_parameters([Parameter("algorithm", value="telepathy")])[0]
    assert not bad.successful and "telepathy" in bad.reason
    bad = reg.set_parameters([Parameter("wm_order", value="random")])[0]
    assert not bad.successful and "wm_order" in bad.reason
    good = reg.set_parameters([Parameter("algorithm", value="full-brevity")])[0]
    assert good.successful
    reply = ask(pipeline, contract.REG_REQUEST.name, pipeline.expressions, {"id": "fb", "target": "face1"}, "fb")
    assert reply["algorithm"] == "full-brevity"
    assert reply["description"] == ["lab-coat", "glasses"]  # shortest distinguishing set


@pytest.mark.parametrize(
    "seconds, expected",
    [(0.0, (0, 0)), (8.0, (8, 0)), (0.5, (0, 500_000_000)), (2.9999999999, (3, 0)), (86.000000001, (86, 1))],
)
def test_clock_message_keeps_nanoseconds_below_one_second(seconds, expected):
    from fsreg_ros.nodes.dialogue_player import clock_message

    stamp = clock_message(seconds).clock
    assert (stamp.sec, stamp.nanosec) == expected


# ------------------------------------------------------------------ request ids (issue 10 item 2)
def test_a_reused_id_for_another_request_is_an_error_never_the_other_answer(pipeline):
    first = ask(pipeline, contract.REG_REQUEST.name, pipeline.expressions, {"id": 1, "target": "face1"}, 1)
    assert first["target"] == "face1" and "error" not in first
    before = snapshot(pipeline)
    pipeline.expressions.clear_all()
    other = ask(pipeline, contract.REG_REQUEST.name, pipeline.expressions, {"id": 1, "target": "face2"}, 1)
    assert other["kind"] == "IdConflict" and "already used for a different request" in other["error"]
    assert "description" not in other
    assert snapshot(pipeline) == before  # nothing ran
    pipeline.expressions.clear_all()
    again = ask(pipeline, contract.REG_REQUEST.name, pipeline.expressions, {"id": 1, "target": "face1"}, 1)
    assert again == first  # the cache kept the first answer
    # the same for RR, where the id 1 and the string "1" are different ids
    rr = ask(pipeline, contract.HUMAN.name, pipeline.results, {"id": 1, "description": ["female", "hoodie"]}, 1)
    assert rr["resolved"] == "face3"
    pipeline.results.clear_all()
    clash = ask(pipeline, contract.HUMAN.name, pipeline.results, {"id": 1, "description": ["male"]}, 1)
    assert clash["status"] == "error" and clash["kind"] == "IdConflict"
    fresh = ask(pipeline, contract.HUMAN.name, pipeline.results, {"id": "1", "description": ["female", "hoodie"]}, "1")
    assert fresh["resolved"] == "face3"


class Client:
    """A requester of its own (a node publishing requests and hearing every answer on the topic)."""

    def __init__(self, pipeline: RosSession, name: str, topic: str, answers: str) -> None:
        from rclpy.node import Node
        from std_msgs.msg import String

        from fsreg_ros.ros.carrier import qos_profile

        self.node = Node(name, context=pipeline.context)
        pipeline.executor.add_node(self.node)
        pipeline.nodes.append(self.node)
        self.heard: list[dict] = []
        self.pub = self.node.create_publisher(String, topic, qos_profile(contract.PIPELINE_QOS))
        self.node.create_subscription(String, answers, lambda m: self.heard.append(json.loads(m.data)),
                                      qos_profile(contract.PIPELINE_QOS))
        pipeline.spin_until(lambda: self.pub.get_subscription_count() > 0
                            and self.node.count_publishers(answers) > 0, what=f"{name}'s peers")
        self.sent: list[dict] = []

    def send(self, request: dict) -> str:
        from fsreg_ros.ros.carrier import to_msg

        self.sent.append(request)
        self.pub.publish(to_msg(request))
        return contract.fingerprint(request)

    def mine(self, fingerprint: str) -> list[dict]:
        return [a for a in self.heard if a.get("request") == fingerprint]


@pytest.mark.parametrize("topic, answers, a, b", [
    (contract.REG_REQUEST.name, contract.REG_EXPRESSION.name, {"target": "face1"}, {"target": "face2"}),
    (contract.HUMAN.name, contract.RR_RESULT.name, {"description": ["female", "hoodie"]}, {"description": ["male"]}),
])
def test_two_clients_sending_one_id_at_once_can_each_tell_their_reply(pipeline, topic, answers, a, b):
    """Both hear every answer on the shared topic.  Without a client name, one request
    runs and the other gets IdConflict naming it; each tells its own reply by the
    request fingerprint it echoes.  With client names, the ids are theirs: both run."""
    first, second = Client(pipeline, "client_a", topic, answers), Client(pipeline, "client_b", topic, answers)
    fa, fb = first.send({"id": 5, **a}), second.send({"id": 5, **b})  # at once: nothing spun in between
    pipeline.spin_until(lambda: first.mine(fa) and second.mine(fb) and len(first.heard) >= 2, what="both answers")
    (mine_a,), (mine_b,) = first.mine(fa), second.mine(fb)
    winner, loser = (mine_a, mine_b) if "kind" not in mine_a else (mine_b, mine_a)
    assert "error" not in winner and loser["kind"] == "IdConflict" and loser["id"] == 5
    assert loser["conflicts_with"] == {"client": None, "request": winner["request"]}
    assert winner["request"] in loser["error"] and loser["request"] in loser["error"]
    assert {mine_a["request"], mine_b["request"]} == {fa, fb} and fa != fb
    # The same id from two named clients is two requests: both answered, each echoing its client.
    fa, fb = first.send({"id": 6, "client": "a", **a}), second.send({"id": 6, "client": "b", **b})
    pipeline.spin_until(lambda: first.mine(fa) and second.mine(fb), what="both named answers")
    (mine_a,), (mine_b,) = first.mine(fa), second.mine(fb)
    assert "error" not in mine_a and "error" not in mine_b
    assert (mine_a["client"], mine_b["client"]) == ("a", "b")
    # A resend is answered from the cache, with the same attribution; a reuse names the holder.
    fa_again = first.send({"id": 6, "client": "a", **a})
    clash = first.send({"id": 6, "client": "a", **b})
    pipeline.spin_until(lambda: len(first.mine(fa)) == 2 and first.mine(clash), what="the resend and the reuse")
    assert first.mine(fa)[1] == mine_a and fa_again == fa
    (conflict,) = first.mine(clash)
    assert conflict["kind"] == "IdConflict" and conflict["conflicts_with"] == {"client": "a", "request": fa}


def test_a_failed_answer_is_not_cached_and_a_retry_runs_again(table1_path):
    """REG with no consultant: the request fails (not ready); once the consultant is up,
    the same id is executed for real instead of getting the cached failure."""
    with RosSession() as g:
        reg = g.add(RegNode, domains=["faces"], ready_timeout=0.3, service_timeout=0.3)
        inbox = g.listen(contract.REG_EXPRESSION.name)
        failed = ask(g, contract.REG_REQUEST.name, inbox, {"id": "r", "target": "face5"}, "r")
        assert "not ready" in failed["error"]
        reg.ready_timeout = 30.0  # the retry must not race discovery and a call in 0.3 s (a loaded machine)
        for port in reg.ports.values():
            port.timeout = 10.0
        g.add(ConsultantNode, name="consultant_faces", domain="faces", kb=str(table1_path))
        g.add(WMManagerNode, domains=["faces"], policy="displacement", capacity=2)
        g.call(contract.SYNC.name, {"time": 0.0}, timeout=15.0)
        inbox.clear_all()
        ok = ask(g, contract.REG_REQUEST.name, inbox, {"id": "r", "target": "face5"}, "r")
        assert ok["description"] == ["male", "dark-hair"]


def test_a_dead_consultant_fails_fast_for_the_requests_queued_behind(pipeline):
    import time

    reg = next(n for n in pipeline.nodes if isinstance(n, RegNode))
    ask(pipeline, contract.REG_REQUEST.name, pipeline.expressions, {"id": "warm", "target": "face2"}, "warm")
    for port in reg.ports.values():
        port.timeout = 0.5
    pipeline.remove(next(n for n in pipeline.nodes if isinstance(n, ConsultantNode)))
    started = time.monotonic()
    for i in range(4):
        pipeline.publish(contract.REG_REQUEST.name, {"id": f"q{i}", "target": "face1"})
    pipeline.spin_until(lambda: all(pipeline.expressions.latest(id=f"q{i}") for i in range(4)), 10.0, what="4 answers")
    elapsed = time.monotonic() - started
    errors = [pipeline.expressions.latest(id=f"q{i}")["error"] for i in range(4)]
    assert all("is not running" in e for e in errors), errors  # its liveliness is gone: known at once
    assert elapsed < 1.5  # not one timeout each


# ------------------------------------------------------------------ hostile input (issue 10 items 5, 6)
@pytest.mark.parametrize(
    "text, fragment",
    [
        ('{"id": "h1", "target": "\\ud800"}', "a string with a lone surrogate (not Unicode)"),  # not Unicode
        ('{"id": "h2", "target": "face1", "time": 1e999}', "time"),  # not a finite number
        ('{"id": ' + "9" * 5000 + ', "target": "face1"}', "not JSON"),  # an integer too long to read
        ('{"id": "h4", "target": "' + "x" * 300 + '"}', "over the limit of 256"),
        ('{"id": "h5", "target": "face1", "context": [' + ",".join(['"face2"'] * 1001) + "]}", "1001 items"),
        ('{"id": "h6", "target": "' + "y" * 70000 + '"}', "over the limit of 65536"),
    ],
)
def test_hostile_reg_requests_are_answered_and_change_nothing(pipeline, text, fragment):
    before = snapshot(pipeline)
    pipeline.publish(contract.REG_REQUEST.name, text)
    error_naming(pipeline, pipeline.expressions, fragment)
    assert snapshot(pipeline) == before
    ok = ask(pipeline, contract.REG_REQUEST.name, pipeline.expressions, {"id": "fine", "target": "face2"}, "fine")
    assert ok["description"] == ["glasses", "female"]


def test_answer_cache_is_bounded_in_bytes():
    from fsreg_ros.contract import cache_key, fingerprint
    from fsreg_ros.ros.asking import AnswerCache

    cache = AnswerCache(max_entries=1000, max_bytes=10_000)
    for i in range(100):
        cache.put({"id": i}, fingerprint({"id": i}), "x" * 500)
    per_entry = 500 + len(str(cache_key({"id": 99}))) + AnswerCache.OVERHEAD
    assert cache.bytes <= 10_000 and len(cache) == 10_000 // per_entry
    assert cache.get({"id": 99}, fingerprint({"id": 99})) == ("x" * 500, None)
    assert cache.get({"id": 0}, fingerprint({"id": 0})) == (None, None)  # dropped, oldest first
    cached, holder = cache.get({"id": 99, "target": "other"}, "f" * 16)
    assert cached is None and holder.model_dump() == {"client": None, "request": fingerprint({"id": 99})}
    assert cache.get({"id": 99, "client": "b"}, "f" * 16) == (None, None)  # ids are per client
    cache.put({"id": "big"}, "0" * 16, "y" * 20_000)  # larger than the whole budget: not kept
    assert cache.get({"id": "big"}, "0" * 16) == (None, None) and cache.bytes <= 10_000


@pytest.mark.slow  # starts a node process
def test_reference_resolution_without_domains_exits_2_in_one_line():
    import os
    import subprocess
    import sys

    proc = subprocess.run([sys.executable, "-m", "fsreg_ros.nodes.reference_resolution"], env=dict(os.environ),
                          capture_output=True, text=True, timeout=30)
    assert proc.returncode == 2
    assert "cannot start: parameter 'domains' must name at least one consultant domain" in proc.stderr
    assert "Traceback" not in proc.stderr and len(proc.stderr.strip().splitlines()) == 1


def test_a_sim_time_node_without_clock_warns_once_naming_the_topic(capfd):
    from fsreg_ros.ros.node_base import watch_clock

    with RosSession(namespace="quiet") as g:
        node = g.add(ParserNode, use_sim_time=True, name="quiet_parser")
        timer = watch_clock(node, silence=0.3)
        checks = []
        check = timer.callback
        timer.callback = lambda: (check(), checks.append(1))  # count the watchdog's own checks
        seen = []
        g.spin_until(lambda: seen.append(capfd.readouterr().err) or "nothing has moved" in "".join(seen),
                     what="the warning")
        after = len(checks)
        g.spin_until(lambda: len(checks) >= after + 10, what="ten more checks of a still clock")
        seen.append(capfd.readouterr().err)
    assert "".join(seen).count("nothing has moved /quiet/clock for 0.3 s") == 1


def test_a_whole_number_for_a_real_parameter_is_taken_and_a_wrong_type_refused():
    """``-p service_timeout:=2`` means 2.0 s; a text is refused by rclpy's static typing.

    declare_number reads the given value with public rclpy API only (no private state)."""
    import inspect

    from rclpy.exceptions import InvalidParameterTypeException

    from fsreg_ros.ros import node_base as common

    with RosSession() as g:
        reg = g.add(RegNode, domains=["faces"], service_timeout=2, ready_timeout=3)
        assert reg.get_parameter("service_timeout").value == 2.0
        assert reg.describe_parameter("service_timeout").type == 3  # DOUBLE, statically typed
        with pytest.raises(InvalidParameterTypeException, match="ready_timeout"):
            g.add(RegNode, domains=["faces"], ready_timeout="soon", name="reg2")
    assert "_parameter_overrides" not in inspect.getsource(common)


def test_an_assert_for_a_domain_no_consultant_serves_is_answered_by_the_wm_manager(pipeline):
    """Issue 28.3: ``ltm/assert`` for an unknown domain went unanswered (the client waited its full timeout)."""
    results = pipeline.listen(contract.LTM_ASSERT_RESULT.name)
    pipeline.publish(contract.LTM_ASSERT.name, {"id": "p1", "domain": "planets", "entity": "face1",
                                                "properties": {"male": 1.0}})
    pipeline.spin_until(lambda: results.latest(id="p1") is not None, 10.0, what="the unknown-domain reply")
    reply = results.latest(id="p1")
    assert reply["ok"] is False and reply["kind"] == "unknown-domain" and reply["domain"] == "planets"
    assert "no consultant serves domain 'planets' (this graph's domains: faces)" in reply["error"]
    pipeline.spin_for(0.3)
    assert len(results.where(id="p1")) == 1  # answered once: by the WM Manager, not by any consultant
    # Refusals of the consultant carry a kind too; a known domain is not answered by the WM Manager.
    pipeline.publish(contract.LTM_ASSERT.name, {"id": "p2", "domain": "faces", "entity": "face1",
                                                "properties": {"wings": 1.0}})
    pipeline.spin_until(lambda: results.latest(id="p2") is not None, 10.0, what="the unknown-property reply")
    assert results.latest(id="p2")["kind"] == "unknown-property"
    pipeline.publish(contract.LTM_ASSERT.name, {"id": "p3", "domain": "faces", "entity": "face1",
                                                "properties": {"male": 1.0}, "x": "y" * 70_000})
    pipeline.spin_until(lambda: results.latest(id="p3") is not None, 10.0, what="the too-large reply")
    pipeline.spin_for(0.3)
    assert [r["kind"] for r in results.where(id="p3")] == ["too-large"]
    # several waiting at once are taken together (drained), and each is answered once
    for key, domain in (("p4", "planets"), ("p5", "moons"), ("p6", "faces"), ("p7", "stars")):
        pipeline.publish(contract.LTM_ASSERT.name, {"id": key, "domain": domain, "entity": "face1",
                                                    "properties": {"wings": 1.0}}, contract.LTM_ASSERT.qos)
    pipeline.spin_until(lambda: all(results.latest(id=k) for k in ("p4", "p5", "p6", "p7")), 10.0, what="4 replies")
    pipeline.spin_for(0.3)
    assert [(r["id"], r["domain"], r["kind"]) for r in results if r["id"] in ("p4", "p5", "p7")] == [
        ("p4", "planets", "unknown-domain"), ("p5", "moons", "unknown-domain"), ("p7", "stars", "unknown-domain")]
    assert [r["kind"] for r in results.where(id="p6")] == ["unknown-property"]
    assert snapshot(pipeline) == {}
