"""REG's reference episode begins when its view opens: the ``open`` op's ``refer`` (docs/semantics.md section 2).

A repeated open (the same reference id), an open whose view is then abandoned or
expires, a restart between the open and the close, and hostile ``refer`` fields, each
with the exact WM, episode counters and journal records they leave.
"""

from __future__ import annotations

import pytest

from fsreg_ros import contract
from fsreg_ros.contract.codec import MessageError
from fsreg_ros.core.algorithms.generation import generate
from fsreg_ros.core.algorithms.port import Walked, run_sync
from fsreg_ros.core.consultant.consultant import Consultant, KnowledgeError
from fsreg_ros.core.consultant.local_port import LocalPort
from fsreg_ros.core.consultant.service import ConsultantService, RequestError
from fsreg_ros.core.consultant.views import SessionError, ViewTable
from fsreg_ros.core.forgetting.policies import ForgettingPolicy
from fsreg_ros.core.state.store import DomainStore
from fsreg_ros.ros.consultant_ops import apply
from test_consultant_service import ENTITIES, KB, PREF  # three faces, one of them with glasses at 0.7

EPISODES = {"policy": "episodes", "episode_window": 1}


class Clock:
    """A steady clock the test moves (session expiry)."""

    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def served(tmp_path=None, clock=None) -> ConsultantService:
    """A consultant of the three faces under ``episodes`` k = 1, face2 said once (its episode 1: female, glasses)."""
    consultant = Consultant("faces", ENTITIES, PREF)
    store = DomainStore(tmp_path / "faces.sqlite3", KB) if tmp_path is not None else None
    service = ConsultantService(consultant, store=store, now=lambda: 50.0, steady=clock or Clock(),
                                sessions=ViewTable(capacity=8, per_client=4, timeout=30.0))
    if store is not None:
        service.restore(store.open())
    return service


def configure(service: ConsultantService) -> None:
    apply(service, "configure", {"op": "configure", "policy": EPISODES, "time": 0.0})
    apply(service, "open", {"op": "open", "target": "face2", "refer": {"id": "human", "time": 0.0, "turn": 0}})
    apply(service, "encode", {"op": "encode", "entity": "face2", "properties": ["female", "glasses"],
                              "cause": "speaker", "time": 0.0, "turn": 0})


def opened(service: ConsultantService, refer: dict, target: str = "face2") -> dict:
    return apply(service, "open", {"op": "open", "target": target, "refer": refer}).reply


def test_a_repeated_open_with_the_same_reference_id_begins_one_episode():
    service = served()
    configure(service)
    wm = service.buffer
    apply(service, "open", {"op": "open", "target": "face2", "refer": {"id": "reg/1", "time": 1.0, "turn": 1}})
    assert wm.episode("face2") == 2
    # Sent again (its answer lost): the same id begins no episode 3, and the view reads WM as the first did.
    again = opened(service, {"id": "reg/1", "time": 1.0, "turn": 1})
    assert wm.episode("face2") == 2 and again["queue"] == ["female", "glasses"]
    assert again["strength"] == [{"age": 1, "episodes": 1, "activation": None}] * 2
    # Its close encodes the description without beginning an episode either.
    apply(service, "close", {"op": "close", "session": again["session"], "encode": ["female"], "time": 1.0,
                             "turn": 1})
    assert wm.episode("face2") == 2 and wm.queue("face2") == ("glasses", "female")
    # Another id is another act of referring: episode 3 begins, forgetting glasses (last used in episode 1).
    third = opened(service, {"id": "reg/2", "time": 2.0, "turn": 2})
    assert wm.episode("face2") == 3 and third["queue"] == ["female"] and wm.queue("face2") == ("female",)


def test_a_retried_reg_request_begins_its_targets_episode_once():
    class LosesTheFirstWalk(LocalPort):
        lost = 1

        async def walk(self, view, steps, cause, time, turn, size=None) -> Walked:
            if self.lost:
                self.lost -= 1
                raise TimeoutError("the walk's reply was lost")
            return await super().walk(view, steps, cause, time, turn, size)

    for reference, episodes, read, said in (("reg/7", 2, ["female", "glasses"], ["female"]),
                                            (None, 3, [], ["dark-hair", "female"])):
        consultant = Consultant("faces", ENTITIES, PREF)
        consultant.wm.set_limits(ForgettingPolicy.parse("episodes", episode_window=1).limits(), 0.0)
        consultant.wm.begin_episode("face2", 0.0, 0)
        consultant.wm.encode("face2", ["female", "glasses"], "speaker", 0.0, 0)
        port = LosesTheFirstWalk(consultant)
        with pytest.raises(TimeoutError):
            run_sync(generate("face2", port, "sd-pia", time=1.0, turn=1, reference=reference))
        expression = run_sync(generate("face2", port, "sd-pia", time=1.0, turn=1, reference=reference))
        # With the request's id the retry is the same act (episode 2, reading episode 1's WM); without one it is
        # episode 3, which forgets all of episode 1 before the robot said anything of face2.
        assert consultant.wm.episode("face2") == episodes, reference
        assert expression.wm_before == read and expression.description == said


def test_an_abandoned_or_expired_view_leaves_its_episode_begun(tmp_path):
    clock = Clock()
    service = served(tmp_path, clock)
    configure(service)
    wm = service.buffer
    first = opened(service, {"id": "reg/1", "time": 1.0, "turn": 1})
    assert wm.episode("face2") == 2 and first["queue"] == ["female", "glasses"]
    # reg/1 is abandoned (never closed): episode 2 said nothing, so episode 3 keeps nothing of episode 1.
    second = opened(service, {"id": "reg/2", "time": 2.0, "turn": 2})
    assert wm.episode("face2") == 3 and second["queue"] == [] and wm.queue("face2") == ()
    clock.now += 31.0  # both sessions expire unused
    with pytest.raises(SessionError, match="^no open session"):
        apply(service, "close", {"op": "close", "session": second["session"], "encode": ["female"], "time": 3.0})
    # The episodes stand, and what episode 3's beginning forgot stays forgotten.
    assert wm.episode("face2") == 3 and wm.queue("face2") == ()
    service.store.close()
    journal = DomainStore(tmp_path / "faces.sqlite3", KB).open().journal
    refers = [["refer", "face2", [], 0.0, 0], ["refer", "face2", [], 1.0, 1], ["refer", "face2", [], 2.0, 2]]
    assert [r for r in journal if r[0] == "refer"] == refers


def state(service: ConsultantService) -> tuple:
    wm = service.buffer
    return ({e: wm.queue(e) for e in ENTITIES}, {e: wm.episode(e) for e in ENTITIES},
            {e: wm.strength(e) for e in ENTITIES}, wm.counters())


def test_an_episode_begun_at_open_survives_a_restart_from_the_journal_and_a_checkpoint(tmp_path):
    service = served(tmp_path)
    configure(service)
    session = opened(service, {"id": "reg/1", "time": 1.0, "turn": 1})["session"]
    apply(service, "close", {"op": "close", "session": session, "encode": ["female"], "time": 1.0, "turn": 1})
    opened(service, {"id": "reg/2", "time": 2.0, "turn": 2})  # the robot began describing face2 ... and stopped
    expected = state(service)
    assert expected[1]["face2"] == 3 and expected[0]["face2"] == ("female",)
    service.store.close()  # abruptly: the journal replays
    peek = DomainStore(tmp_path / "faces.sqlite3", KB)
    assert peek.open().journal[-3:] == [["refer", "face2", [], 1.0, 1],
                                        ["encode", "face2", ["female"], "speaker", 1.0, 1],
                                        ["refer", "face2", [], 2.0, 2]]
    peek.close()
    again = served(tmp_path)
    assert state(again) == expected and again.persistence.wm_state == "restored"
    again.shutdown()  # a checkpoint, the journal emptied
    third = served(tmp_path)
    assert third.store.journal_length() == 0 and state(third) == expected
    # Its session did not survive; the reference ids are not stored, so the same id after a restart begins
    # another episode (docs/semantics.md section 2).
    apply(third, "configure", {"op": "configure", "policy": EPISODES, "time": 2.0})
    assert opened(third, {"id": "reg/2", "time": 2.0, "turn": 2})["queue"] == []  # female: last used in episode 2
    assert third.buffer.episode("face2") == 4


@pytest.mark.parametrize("request_, error, text", [
    ({"op": "open", "refer": {"id": "reg/1", "time": 1.0}}, RequestError,
     "open: 'refer' needs a 'target' (RR's referent is known only when its view closes, so its episode begins there)"),
    ({"op": "open", "target": "face2", "refer": {"time": 1e300}}, RequestError,
     "field 'refer.time': time is out of range: |1e+300| > "),
    ({"op": "open", "target": "face9", "refer": {"time": 1.0}}, KnowledgeError, "domain 'faces' has no entity 'face9'"),
], ids=["no-target", "time-out-of-range", "unknown-target"])
def test_a_hostile_refer_is_refused_in_one_line_and_changes_nothing(tmp_path, request_, error, text):
    service = served(tmp_path)
    configure(service)
    before = state(service), service.wm_version, len(service.sessions), service.store.journal_length()
    with pytest.raises(error) as refused:
        apply(service, "open", request_)
    assert str(refused.value).startswith(text) and "\n" not in str(refused.value)
    assert (state(service), service.wm_version, len(service.sessions), service.store.journal_length()) == before


@pytest.mark.parametrize("refer, text", [
    ({"time": "now"}, "field 'refer'['time']"),
    ({"time": 1.0, "turn": 1.5}, "field 'refer'['turn']"),
    ({"time": 1.0, "turn": True}, "field 'refer'['turn']"),
    ({"id": 7}, "field 'refer'['id']"),
    ("yes", "field 'refer'"),
], ids=["time-text", "turn-float", "turn-bool", "id-number", "not-an-object"])
def test_the_refer_schema_refuses_bad_fields_in_one_line(refer, text):
    with pytest.raises(MessageError) as refused:
        contract.check(contract.OpenRequest, {"op": "open", "target": "face2", "refer": refer})
    assert text in str(refused.value) and "\n" not in str(refused.value)


def test_an_open_without_refer_is_the_older_protocol_its_episode_begins_at_close():
    service = served()
    configure(service)
    wm = service.buffer
    session = apply(service, "open", {"op": "open", "target": "face2"}).reply
    assert wm.episode("face2") == 1 and session["queue"] == ["female", "glasses"]
    apply(service, "close", {"op": "close", "session": session["session"], "encode": ["female"], "time": 1.0})
    assert wm.episode("face2") == 2 and wm.queue("face2") == ("glasses", "female")
    # The port's Reference is what the wire's refer carries.
    from fsreg_ros.core.algorithms.port import Reference
    assert contract.consultant_codec.open_args(
        {"op": "open", "target": "face2", "refer": {"id": "r", "time": 1.0, "turn": 2}})[4] == Reference(1.0, 2, "r")


def test_the_reg_node_names_each_request_as_one_act_of_referring():
    one = contract.reference_id({"id": 7, "client": "ui", "target": "face2"}, "/reg#ab12cd")
    assert one == contract.reference_id({"id": 7, "client": "ui", "target": "face2", "time": 3.0}, "/reg#ab12cd")
    assert one.startswith("/reg#ab12cd/") and len(one) == len("/reg#ab12cd/") + 16
    assert len({one, contract.reference_id({"id": "7", "client": "ui"}, "/reg#ab12cd"),
                contract.reference_id({"id": 7}, "/reg#ab12cd"),
                contract.reference_id({"id": 7, "client": "ui"}, "/reg#ff0000")}) == 4
