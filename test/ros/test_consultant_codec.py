"""The consultant protocol's codec (``contract.consultant_codec``): every op through one codec, both ways.

Issue 35.4: the contract is names, schemas and codecs only.  Each op a caller sends is
encoded by the codec (never a raw dict in ``ros/``), validates against its schema, and
decodes on the consultant's side to the typed call's arguments; each reply the
consultant encodes validates against its reply schema and decodes on the caller's side
to what was encoded.  What the service would refuse of a field (ticks, counts) the schema
refuses first, with the same one-line error, so the codec re-checks nothing.  ROS-free.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

from fsreg_ros import contract
from fsreg_ros.contract import check
from fsreg_ros.contract import consultant_codec as codec
from fsreg_ros.contract.codec import MessageError
from fsreg_ros.core.algorithms.port import Narrowed, Reference, Step, View, Walked, WalkStep
from fsreg_ros.core.consultant.ops import Configured, Info, Opened
from fsreg_ros.core.forgetting.policies import ForgettingPolicy
from fsreg_ros.core.memory.ticks import TickRun

PACKAGE = Path(__file__).resolve().parents[2] / "fsreg_ros"
POLICY = ForgettingPolicy.from_settings({"policy": "decay+displacement", "decay_period": 10.0, "capacity": 3})
STATE = {"wm": "empty", "persisted": True}

#: (op, the request the caller encodes, the arguments the consultant decodes from it).
REQUESTS = [
    ("info", codec.info_request(), (0,)),
    ("info", codec.info_request(3), (3,)),
    ("open", codec.open_request("face1", ["face2", "face3"], Step("male", "rr", 2.0, 4), "reg#1"),
     ("face1", ["face2", "face3"], Step("male", "rr", 2.0, 4), "reg#1", None)),
    ("open", codec.open_request(None, None, None, "rr#2"), (None, None, None, "rr#2", None)),
    ("open", codec.open_request("face1", None, None, "reg#1", Reference(3.0, 5, "reg#1/0123")),
     ("face1", None, None, "reg#1", Reference(3.0, 5, "reg#1/0123"))),
    ("narrow", codec.narrow_request("s1", "male", None, 1.5, None), ("s1", "male", None, 1.5, None)),
    ("walk", codec.walk_request("s1", [WalkStep("glasses"), WalkStep("dark-hair", "hair")], "reg-distractor", 2.0, 7),
     ("s1", [WalkStep("glasses"), WalkStep("dark-hair", "hair")], "reg-distractor", 2.0, 7)),
    ("rule_out", codec.rule_out_request("s1"), ("s1",)),
    ("close", codec.close_request("s1", ["male"], 3.0, 2), ("s1", ["male"], 3.0, 2)),
    ("close", codec.close_request("s1", (), 3.0, None), ("s1", (), 3.0, None)),
    ("holds", codec.holds_request("male", ["face1", "face2"]), ("male", ["face1", "face2"])),
    ("affirm", codec.affirm_request("male", ["face1"], "rr", 1.0, 3), ("male", ["face1"], "rr", 1.0, 3)),
    ("wm", codec.wm_request("face1"), ("face1",)),
    ("encode", codec.encode_request("face1", ["male"], "speaker", None, None),
     ("face1", ["male"], "speaker", None, None)),
    ("snapshot", codec.snapshot_request(), ()),
    ("configure", codec.configure_request(POLICY, 4.0), (POLICY, 4.0)),
    ("decay", codec.decay_request(TickRun(0.0, 10.0, 3, 2)), (TickRun(0.0, 10.0, 3, 2),)),
    ("advance", codec.advance_request(5.0), (5.0,)),
    ("evict", codec.evict_request(2, 6.0), (2, 6.0)),
    ("size", codec.size_request(), ()),
    ("reset", codec.reset_request("/fsreg_ctl"), ("/fsreg_ctl",)),
]


@pytest.mark.parametrize("op, request_, args", REQUESTS, ids=[r[0] for r in REQUESTS])
def test_every_request_a_caller_sends_is_the_codecs_and_decodes_to_what_it_encoded(op, request_, args):
    assert {op for op, _, _ in REQUESTS} == set(codec.ALL_OPS)  # every op: query, debug and manage
    assert request_["op"] == op
    check(codec.ALL_OPS[op][0], request_)  # the schema admits it
    decode = codec.reset_args if op == "reset" else codec.SERVED[op][0]
    assert decode(request_) == args


VIEW = View(None, 3, ["male", "glasses"], True, frozenset({"male", "glasses"}), first=Narrowed(True, 2),
            origins=[("rr", 1), ("speaker", None)])
#: (op, the typed call's result, the reply the caller decodes, what it decodes it to).
REPLIES = [
    ("open", Opened("s1", VIEW, ["glasses", "male"]), lambda r: codec.view_of(r, True),
     View("s1", 3, ["male", "glasses"], True, frozenset({"male", "glasses"}), first=Narrowed(True, 2),
          origins=[("rr", 1), ("speaker", None)])),
    ("narrow", Narrowed(False, 2), codec.narrowed_of, Narrowed(False, 2)),
    ("walk", Walked((0, 2), 0, 3), lambda r: codec.walked_of(r, 3), Walked((0, 2), 0, 3)),
    ("rule_out", (["male", "glasses"], [0x5, 0x10]), codec.rule_out_of, (["male", "glasses"], [0x5, 0x10])),
    ("close", ["face2"], codec.members_of, ["face2"]),
    ("holds", ["face1"], codec.held_of, ["face1"]),
    ("affirm", [], codec.held_of, []),
    ("wm", ["male"], codec.queue_of, ["male"]),
    ("encode", None, lambda r: r, {}),
    ("snapshot", ({"face1": ["male"]}, 7), codec.snapshot_of, {"face1": ["male"]}),
    ("configure", Configured(POLICY.to_json(), 2, {**STATE, "restored": {"fresh": True, "runtime_entities": 0,
                                                                         "runtime_facts": 0, "queues": 0}}),
     codec.configured_of, (POLICY.to_json(), 2, {"fresh": True, "runtime_entities": 0, "runtime_facts": 0,
                                                 "queues": 0})),
    ("decay", "decay", codec.policy_of, "decay"),
    ("advance", "activation", codec.policy_of, "activation"),
    ("size", 4, codec.size_of, 4),
    ("evict", 1, codec.size_of, 1),
    ("info", Info("faces", ["face2"], 2, ["male"], 0.5, "none", {"policy": "none"}, 3, 1, STATE),
     codec.catalogue_of, ("1:2", ["male"], ["face2"])),
]


@pytest.mark.parametrize("op, result, decode, decoded", REPLIES, ids=[r[0] for r in REPLIES])
def test_every_reply_the_consultant_encodes_fits_its_schema_and_decodes_to_what_it_encoded(op, result, decode, decoded):
    assert {op for op, _, _, _ in REPLIES} == set(codec.SERVED)  # every op the service runs
    reply = codec.completed(op, codec.SERVED[op][1](result), 0, lambda: "1:2")
    if op == "info":
        codec.with_listeners(reply, 0)
    check(codec.ALL_OPS[op][1], reply)
    assert decode(reply) == decoded


def test_the_reset_reply_fits_its_schema():
    check(contract.ResetReply, codec.reset_reply(3, "/tmp/x.sqlite3", {"runtime_facts": 1, "queues": 2}, STATE))


@pytest.mark.parametrize("request_, error", [
    ({"op": "decay", "ticks": {"origin": 0.0, "period": -1.0, "first": 1, "count": 1}},
     "field 'ticks': ticks.period must be > 0, got -1.0"),
    ({"op": "decay", "ticks": {"origin": 0.0, "period": 1.0, "first": 1, "count": 0}},
     "field 'ticks': ticks.count must be >= 1"),
    ({"op": "decay", "ticks": {"origin": 0.0, "period": 1.0, "first": 1, "count": 1, "extra": 1}},
     "field 'ticks': ticks must be an object with exactly origin, period, first and count"),
    ({"op": "evict", "count": -1}, "field 'count': expected a whole number >= 0, got -1"),
    ({"op": "info", "entities_from": -1}, "field 'entities_from': expected a whole number >= 0, got -1"),
])
def test_the_schemas_refuse_what_the_service_cannot_take_so_the_codec_rechecks_nothing(request_, error):
    with pytest.raises(MessageError) as refused:
        check(codec.ALL_OPS[request_["op"]][0], request_)
    assert str(refused.value) == error


def test_one_tick_run_the_cores():
    assert not hasattr(contract, "TickRun")  # the contract's schema field is the core's TickRun, checked by it
    ticks = {"origin": 0, "period": 2.5, "first": 4, "count": 3}
    assert codec.decay_args(check(contract.DecayRequest, {"op": "decay", "ticks": ticks})) == (TickRun(0.0, 2.5, 4, 3),)


def test_no_request_is_spelled_outside_the_codec():
    # The callers' side in ros/ and the contract: every request built by the codec's <op>_request,
    # never a dict literal naming an op of the consultant protocol.
    def ops_spelled(path: Path) -> list[str]:
        return [f"{path.relative_to(PACKAGE)}:{node.lineno}" for node in ast.walk(ast.parse(path.read_text()))
                if isinstance(node, ast.Dict) and any(
                    isinstance(k, ast.Constant) and k.value == "op" and isinstance(v, ast.Constant)
                    and v.value in codec.ALL_OPS for k, v in zip(node.keys, node.values))]

    found = [where for folder in ("ros", "contract") for path in sorted((PACKAGE / folder).rglob("*.py"))
             if path.name != "consultant_codec.py" for where in ops_spelled(path)]
    assert found == []
    assert ops_spelled(PACKAGE / "contract" / "consultant_codec.py")  # the check sees a spelled op
