"""Reference resolution (docs/semantics.md section 3) and its encodings (docs/semantics.md section 2, rules 1, 2, 4)."""

from __future__ import annotations

import pytest

from fsreg_ros.core.consultant.consultant import Consultant
from fsreg_ros.core.consultant.local_port import LocalPort
from fsreg_ros.core.algorithms.port import run_sync
from fsreg_ros.core.forgetting.policies import ForgettingPolicy
from fsreg_ros.core.forgetting.wm_manager import WMManager
from fsreg_ros.core.algorithms.resolution import AMBIGUOUS, NO_MATCH, RESOLVED, Resolution, ResolutionError, resolve

FACES = {
    "f1": {"light-hair": 1.0, "male": 1.0, "glasses": 1.0},
    "f2": {"light-hair": 1.0, "female": 1.0},
    "f3": {"dark-hair": 1.0, "male": 1.0, "glasses": 0.4},  # below threshold
    "f4": {"light-hair": 0.8, "male": 1.0, "hoodie": 1.0},
}
FACE_PREF = ["light-hair", "dark-hair", "male", "female", "glasses", "hoodie"]
OBJECTS = {"o1": {"cup": 1.0, "red": 1.0}, "o2": {"glasses": 1.0}, "o3": {"cup": 1.0}}
OBJECT_PREF = ["cup", "glasses", "red"]


def keys(events):
    return [(e.op, e.entity, e.property, e.cause, e.time, e.turn) for e in events]


def world(policy=None):
    events: list = []
    faces = Consultant("faces", FACES, FACE_PREF, sink=events.append)
    objects = Consultant("objects", OBJECTS, OBJECT_PREF, sink=events.append)
    manager = WMManager()
    policy = policy or ForgettingPolicy.parse("displacement", capacity=10)
    manager.manage(faces.wm, policy)
    manager.manage(objects.wm, policy)
    ports = {"faces": LocalPort(faces), "objects": LocalPort(objects)}
    return ports, faces, objects, events


def rr(description, ports, **kw):
    return run_sync(resolve(description, ports, **kw))


# ---------------------------------------------------------------- results
def test_resolved_with_rule_2_then_rule_1_encodings():
    ports, faces, _, events = world()
    result = rr(["light-hair", "glasses"], ports, time=8.0, turn=3)
    assert result.status == RESOLVED and result.resolved == "f1" and result.candidates == ["f1"]
    assert result.domain == "faces" and result.description == ["light-hair", "glasses"]
    assert keys(events) == [
        # rule 2: light-hair affirmed for every candidate it holds for (entity order) ...
        ("encode", "f1", "light-hair", "rr", 8.0, 3),
        ("encode", "f2", "light-hair", "rr", 8.0, 3),
        ("encode", "f4", "light-hair", "rr", 8.0, 3),
        # ... glasses only checked against the candidates still in play
        ("encode", "f1", "glasses", "rr", 8.0, 3),
        # rule 1: the whole description for the referent, in utterance order
        ("encode", "f1", "light-hair", "speaker", 8.0, 3),
        ("encode", "f1", "glasses", "speaker", 8.0, 3),
    ]
    # Candidates ruled out later keep what was affirmed for them.
    assert faces.wm.snapshot() == {"f1": ["light-hair", "glasses"], "f2": ["light-hair"], "f4": ["light-hair"]}
    assert result.to_json() == {
        "status": "resolved",
        "resolved": "f1",
        "candidates": ["f1"],
        "description": ["light-hair", "glasses"],
        "domain": "faces",
    }


def test_utterance_order_drives_the_encodings():
    ports, faces, _, events = world()
    result = rr(["glasses", "male"], ports, time=1.0)
    assert result.resolved == "f1"
    assert [(k[1], k[2], k[3]) for k in keys(events)] == [
        ("f1", "glasses", "rr"),  # f3's 0.4 is below the threshold: not affirmed
        ("f1", "male", "rr"),
        ("f1", "glasses", "speaker"),
        ("f1", "male", "speaker"),
    ]
    assert faces.wm.queue("f1") == ("glasses", "male")


def test_ambiguous_lists_candidates_and_gets_no_speaker_encoding():
    ports, faces, _, events = world()
    result = rr(["male", "light-hair"], ports, time=2.0, turn=1)
    assert result.status == AMBIGUOUS and result.resolved is None
    assert result.candidates == ["f1", "f4"]  # entity order
    assert [k[3] for k in keys(events)] == ["rr"] * 5
    assert [(k[1], k[2]) for k in keys(events)] == [
        ("f1", "male"),
        ("f3", "male"),
        ("f4", "male"),
        ("f1", "light-hair"),
        ("f4", "light-hair"),
    ]
    assert faces.wm.snapshot() == {"f1": ["male", "light-hair"], "f3": ["male"], "f4": ["male", "light-hair"]}
    assert result.to_json()["resolved"] is None


def test_no_match_keeps_rule_2_encodings_and_stops_checking():
    ports, faces, _, events = world()
    result = rr(["female", "glasses", "light-hair"], ports)
    assert result.status == NO_MATCH and result.candidates == [] and result.resolved is None
    # female holds for f2 only; glasses fails for f2; light-hair is never checked.
    assert [(k[1], k[2], k[3]) for k in keys(events)] == [("f2", "female", "rr")]
    assert faces.wm.snapshot() == {"f2": ["female"]}


def test_single_property_single_holder():
    ports, _, objects, events = world()
    result = rr(["red"], ports)
    assert result.status == RESOLVED and result.resolved == "o1" and result.domain == "objects"
    assert [(k[1], k[3]) for k in keys(events)] == [("o1", "rr"), ("o1", "speaker")]
    assert objects.wm.queue("o1") == ("red",)


def test_policy_none_resolves_but_stores_nothing():
    ports, faces, objects, events = world(ForgettingPolicy.parse("none"))
    result = rr(["light-hair", "glasses"], ports)
    assert result.status == RESOLVED and result.resolved == "f1"
    assert events == [] and faces.wm.snapshot() == {} and objects.wm.snapshot() == {}


def test_resolution_object_defaults():
    r = Resolution(NO_MATCH, "faces", ["male"])
    assert r.candidates == [] and r.resolved is None


# ----------------------------------------------------------------- domains
def test_domain_from_preference_orders():
    ports, *_ = world()
    assert rr(["cup"], ports).domain == "objects"
    assert rr(["hoodie"], ports).domain == "faces"
    # glasses is known to both, but only faces also knows male.
    assert rr(["glasses", "male"], ports).domain == "faces"
    assert rr(["glasses", "cup"], ports).domain == "objects"


def test_explicit_domain():
    ports, _, _, events = world()
    result = rr(["glasses"], ports, domain="objects")
    assert result.status == RESOLVED and result.resolved == "o2" and result.domain == "objects"
    result = rr(["glasses"], ports, domain="faces")
    assert result.status == RESOLVED and result.resolved == "f1"


@pytest.mark.parametrize(
    "description, domain, message",
    [
        (["glasses"], None, r"several domains \(faces, objects\)"),
        (["beard"], None, "no consultant knows property 'beard'"),
        (["male", "beard"], None, "no consultant knows property 'beard'"),
        (["male", "cup"], None, "no domain"),
        ([], None, "empty"),
        ([], "faces", "empty"),
        (["male"], "vehicles", "unknown domain 'vehicles'"),
        (["male", "cup"], "faces", "domain 'faces' knows no property 'cup'"),
        (["beard"], "faces", "knows no property 'beard'"),
    ],
)
def test_resolution_errors_change_nothing(description, domain, message):
    ports, faces, objects, events = world()
    with pytest.raises(ResolutionError, match=message):
        rr(description, ports, domain=domain)
    assert events == []
    assert faces.wm.snapshot() == {} and objects.wm.snapshot() == {}


def test_resolution_error_is_a_value_error():
    assert issubclass(ResolutionError, ValueError)
