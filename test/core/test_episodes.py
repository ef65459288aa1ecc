"""Reference episodes: counters, the episodes each entry was used in, rule ``episodes``, strength, persistence.

Small hand-made dialogues with exact WM contents, exact episode counters and exact
strengths (docs/semantics.md section 2, "Reference episodes").
"""

from __future__ import annotations

import math

import pytest

from fsreg_ros.contract.consultant_codec import view_of
from fsreg_ros.ros.consultant_ops import apply
from fsreg_ros.core.algorithms.generation import GenerationError, generate, phase1_order
from fsreg_ros.core.algorithms.port import run_sync
from fsreg_ros.core.algorithms.resolution import resolve
from fsreg_ros.core.consultant.consultant import Consultant
from fsreg_ros.core.consultant.local_port import LocalPort
from fsreg_ros.core.consultant.service import ConsultantService
from fsreg_ros.core.consultant.views import ViewTable
from fsreg_ros.core.forgetting.policies import ForgettingPolicy, PolicyError
from fsreg_ros.core.memory import Strength, WMBuffer
from fsreg_ros.core.state import journal
from fsreg_ros.core.state.store import DomainStore, StateDamaged
from test_consultant_service import ENTITIES, KB, PREF  # three faces, one of them with glasses at 0.7


def buffer(policy: str = "none", events=None, **settings) -> WMBuffer:
    wm = WMBuffer("faces", sink=events.append if events is not None else None)
    if policy != "none":
        wm.set_limits(ForgettingPolicy.parse(policy, **settings).limits(), 0.0)
    return wm


def forgets(events) -> list[tuple]:
    return [(e.entity, e.property, e.cause, e.time, e.turn) for e in events if e.op == "forget"]


# ------------------------------------------------------------------ the buffer
def test_episode_counters_and_what_each_entry_was_used_in():
    wm = buffer("displacement", capacity=10)
    wm.encode("f1", ["a", "b"], "rr", 0.0, 0)  # episode 0 (before any)
    assert wm.episode("f1") == 0 and wm.episode("f2") == 0
    assert wm.strength("f1") == [Strength(0, 1), Strength(0, 1)]
    assert wm.begin_episode("f1", 1.0, 1) == 1
    assert wm.strength("f1") == [Strength(1, 1), Strength(1, 1)]  # nothing used in episode 1 yet
    wm.encode("f1", ["b", "c"], "speaker", 1.0, 1)
    assert wm.queue("f1") == ("a", "b", "c")
    assert wm.strength("f1") == [Strength(1, 1), Strength(0, 2), Strength(0, 1)]
    wm.encode("f1", ["b"], "reg-distractor", 1.5, 2)  # again in episode 1: still two episodes
    assert wm.begin_episode("f1", 2.0, 3) == 2
    wm.encode("f1", ["c"], "speaker", 2.0, 3)
    assert wm.queue("f1") == ("a", "b", "c")
    assert wm.strength("f1") == [Strength(2, 1), Strength(1, 2), Strength(0, 2)]
    assert wm.episode("f1") == 2 and wm.episode("f2") == 0  # each entity counts its own


def test_an_entry_forgotten_and_encoded_again_counts_its_episodes_afresh():
    wm = buffer("displacement", capacity=1)
    wm.encode("f1", ["a"], "speaker", 0.0, 0)
    wm.begin_episode("f1", 1.0, 1)
    wm.encode("f1", ["a"], "speaker", 1.0, 1)
    assert wm.strength("f1") == [Strength(0, 2)]
    wm.encode("f1", ["b", "a"], "speaker", 1.0, 1)  # b displaces a, a displaces b: a enters again
    assert wm.queue("f1") == ("a",) and wm.strength("f1") == [Strength(0, 1)]
    wm.begin_episode("f1", 2.0, 2)
    wm.encode("f1", ["a"], "speaker", 2.0, 2)
    assert wm.strength("f1") == [Strength(0, 2)]


def test_strength_carries_activation_under_rule_activation():
    wm = buffer("activation", activation_decay=0.5, activation_threshold=-5.0)
    wm.encode("f1", ["a"], "speaker", 1.0, 0)
    wm.encode("f1", ["b"], "speaker", 2.0, 1)
    assert wm.strength("f1") == [Strength(0, 1, math.log(1.0 ** -0.5)), Strength(0, 1, math.inf)]
    wm.advance(5.0)
    assert wm.strength("f1") == [Strength(0, 1, math.log(4.0 ** -0.5)), Strength(0, 1, math.log(3.0 ** -0.5))]
    assert Strength(0, 1, math.inf).to_json() == {"age": 0, "episodes": 1, "activation": "inf"}
    assert Strength.from_json({"age": 2, "episodes": 3, "activation": "inf"}) == Strength(2, 3, math.inf)


# ------------------------------------------------------------------ rule episodes
def test_window_one_keeps_the_previous_episode_and_the_current_one():
    events: list = []
    wm = buffer("episodes", events, episode_window=1)
    wm.encode("f1", ["a", "b"], "rr", 0.0, 0)  # episode 0
    wm.begin_episode("f1", 1.0, 1)  # keeps what episode 0 used
    wm.encode("f1", ["c"], "speaker", 1.0, 1)
    assert wm.queue("f1") == ("a", "b", "c") and forgets(events) == []
    wm.begin_episode("f1", 2.0, 2)  # keeps what episode 1 used: c
    assert wm.queue("f1") == ("c",)
    assert forgets(events) == [("f1", "a", "episodes", 2.0, 2), ("f1", "b", "episodes", 2.0, 2)]
    wm.encode("f1", ["d"], "speaker", 2.0, 2)
    wm.encode("f2", ["x"], "rr", 2.5, 3)
    assert wm.queue("f1") == ("c", "d")  # the previous episode's and the current one's
    wm.begin_episode("f1", 3.0, 4)
    assert wm.queue("f1") == ("d",) and wm.queue("f2") == ("x",)  # only the entity whose episode begins
    assert wm.begin_episode("f1", 4.0, 5) == 4  # d was last used in episode 2
    assert wm.queue("f1") == () and forgets(events)[-1] == ("f1", "d", "episodes", 4.0, 5)


def test_window_two_and_a_refresh_keeps_an_entry():
    wm = buffer("episodes", episode_window=2)
    wm.encode("f1", ["a", "b"], "speaker", 0.0, 0)
    for n, props in ((1, ["c"]), (2, ["a"]), (3, ["d"])):
        wm.begin_episode("f1", float(n), n)
        wm.encode("f1", props, "speaker", float(n), n)
    # Episode 3 began forgetting what was last used before episode 1: b (a was used again in 2).
    assert wm.queue("f1") == ("c", "a", "d")
    assert wm.strength("f1") == [Strength(2, 1), Strength(1, 2), Strength(0, 1)]
    wm.begin_episode("f1", 4.0, 4)
    assert wm.queue("f1") == ("a", "d")


def test_the_window_combines_with_displacement_and_is_installed_without_forgetting():
    wm = buffer("displacement", capacity=2)
    wm.encode("f1", ["a"], "speaker", 0.0, 0)
    wm.begin_episode("f1", 1.0, 1)
    wm.begin_episode("f1", 2.0, 2)
    wm.set_limits(ForgettingPolicy.parse("episodes+displacement", episode_window=1, capacity=2).limits(), 2.5)
    assert wm.queue("f1") == ("a",)  # installing the window forgets nothing
    wm.encode("f1", ["b", "c"], "speaker", 2.5, 3)
    assert wm.queue("f1") == ("b", "c")  # displacement as usual
    wm.begin_episode("f1", 3.0, 4)
    assert wm.queue("f1") == ("b", "c")


def test_the_window_setting_is_a_row_of_the_table():
    policy = ForgettingPolicy.parse("episodes", episode_window=3)
    assert policy.limits().episode_window == 3 and policy.to_json() == {"policy": "episodes", "episode_window": 3}
    assert ForgettingPolicy.parse("decay+episodes+displacement", decay_period=5.0, capacity=2,
                                  episode_window=1).name == "decay+episodes+displacement"
    assert ForgettingPolicy.parse("episodes").to_json() == {"policy": "episodes", "episode_window": 1}  # its fallback
    with pytest.raises(PolicyError, match="^episode_window must be >= 1, got 0$"):
        ForgettingPolicy.parse("episodes", episode_window=0)
    assert ForgettingPolicy.parse("displacement", capacity=2).limits().episode_window is None


# ------------------------------------------------------------------ the consultant's dialogue
def test_rr_begins_its_referents_episode_at_close_and_reg_its_targets_at_open():
    consultant = Consultant("faces", ENTITIES, PREF)
    consultant.wm.set_limits(ForgettingPolicy.parse("episodes", episode_window=1).limits(), 0.0)
    port = LocalPort(consultant)
    wm = consultant.wm
    # The human: "the woman with dark hair" -> face2 (rule 2 for the candidates, rule 1 for face2).
    resolution = run_sync(resolve(["dark-hair", "female"], {"faces": port}, time=1.0, turn=0))
    assert resolution.status == "resolved" and resolution.candidates == ["face2"]
    assert [wm.episode(e) for e in ENTITIES] == [0, 1, 0]
    assert wm.queue("face2") == ("dark-hair", "female") and wm.queue("face3") == ("dark-hair",)
    # An ambiguous description begins no episode.
    run_sync(resolve(["dark-hair"], {"faces": port}, time=2.0, turn=1))
    assert [wm.episode(e) for e in ENTITIES] == [0, 1, 0]
    # The robot describes face3: its episode 1 begins when REG's view opens, then Phase 1 reads Q[face3].
    expression = run_sync(generate("face3", port, "sd-pia", time=3.0, turn=2))
    assert expression.description == ["dark-hair", "male"] and expression.wm_before == ["dark-hair"]
    assert expression.strengths == [{"age": 1, "episodes": 1, "activation": None}, None]  # read in episode 1
    assert [wm.episode(e) for e in ENTITIES] == [0, 1, 1]
    assert wm.queue("face3") == ("dark-hair", "male")
    assert wm.strength("face3") == [Strength(0, 2), Strength(0, 1)]  # dark-hair: rule 2 in episode 0, rule 1 in 1
    # face2's dark-hair was refreshed in its episode 1 by the ambiguous RR and by face3's REG (rule 3).
    assert wm.queue("face2") == ("female", "dark-hair")
    expression = run_sync(generate("face2", port, "sd-pia", time=4.0, turn=3))
    assert expression.description == ["female"] and wm.episode("face2") == 2
    assert wm.queue("face2") == ("dark-hair", "female")
    assert wm.strength("face2") == [Strength(1, 2), Strength(0, 3)]  # dark-hair: episodes 0, 1; female: 0, 1, 2
    events: list = []
    wm.sink = events.append
    expression = run_sync(generate("face2", port, "sd-pia", time=5.0, turn=4))
    # Episode 3 began at the open, forgetting dark-hair (last used in episode 1) before Phase 1 read WM.
    assert forgets(events) == [("face2", "dark-hair", "episodes", 5.0, 4)]
    assert expression.wm_before == ["female"] and expression.description == ["female"]
    assert wm.episode("face2") == 3 and wm.queue("face2") == ("female",)
    assert wm.strength("face2") == [Strength(0, 4)]


def test_reg_reads_under_k_1_only_its_targets_last_episode_across_three_descriptions():
    """The corpus's k = 1: while describing, Q[target] holds what its last episode used (and nothing older)."""
    consultant = Consultant("faces", ENTITIES, PREF)
    consultant.wm.set_limits(ForgettingPolicy.parse("episodes", episode_window=1).limits(), 0.0)
    port = LocalPort(consultant)
    wm = consultant.wm
    # The human: "the woman with glasses" -> face2, its episode 1 (female, glasses).
    assert run_sync(resolve(["female", "glasses"], {"faces": port}, time=0.0, turn=0)).candidates == ["face2"]
    assert wm.queue("face2") == ("female", "glasses") and wm.episode("face2") == 1
    read, said = [], []
    for turn in (1, 2, 3):
        expression = run_sync(generate("face2", port, "sd-pia", time=float(turn), turn=turn))
        read.append(expression.wm_before)
        said.append(expression.description)
        assert wm.episode("face2") == turn + 1
    # Episode 2 reads episode 1's female and glasses; episode 3 reads episode 2's female only (glasses, last
    # used in episode 1, went when episode 3 began); so does episode 4.
    assert read == [["female", "glasses"], ["female"], ["female"]]
    assert said == [["female"], ["female"], ["female"]]
    assert wm.queue("face2") == ("female",) and wm.strength("face2") == [Strength(0, 5)]  # episodes 0-4


def test_wm_order_strength_walks_the_strongest_entry_first():
    assert phase1_order(["a", "b", "c", "d"], "strength", [],
                        [Strength(2, 1), Strength(0, 1), Strength(0, 3), Strength(0, 1)]) == ["c", "b", "d", "a"]
    with pytest.raises(GenerationError, match="^wm_order 'strength' needs the strength of each WM entry, which the "
                                              "consultant did not report \\(0 for 1 entries\\)$"):
        phase1_order(["a"], "strength", [], [])

    def described(order: str) -> tuple[list[str], list[str]]:
        consultant = Consultant("faces", ENTITIES, PREF)
        consultant.wm.set_limits(ForgettingPolicy.parse("displacement", capacity=10).limits(), 0.0)
        port = LocalPort(consultant)
        wm = consultant.wm
        wm.encode("face1", ["male"], "speaker", 0.0, 0)  # episode 0
        wm.begin_episode("face1", 1.0, 1)
        wm.encode("face1", ["glasses"], "speaker", 1.0, 1)
        wm.begin_episode("face1", 2.0, 2)
        wm.encode("face1", ["lab-coat", "male"], "speaker", 2.0, 2)
        # Q[face1] = glasses (age 1, 1 episode), lab-coat (age 0, 1), male (age 0, 2 episodes)
        assert wm.strength("face1") == [Strength(1, 1), Strength(0, 1), Strength(0, 2)]
        expression = run_sync(generate("face1", port, "sd-pia", wm_order=order, time=3.0, turn=3))
        assert expression.wm_before == ["glasses", "lab-coat", "male"]
        return expression.description, expression.sources

    # glasses rules out face3, lab-coat face2 (LRU); male rules out face2, lab-coat face3 (strength).
    assert described("lru-first") == (["glasses", "lab-coat"], ["wm", "wm"])
    assert described("strength") == (["male", "lab-coat"], ["wm", "wm"])


def test_the_open_reply_carries_strength_and_decodes_to_the_view():
    consultant = Consultant("faces", ENTITIES, PREF)
    service = ConsultantService(consultant, ready=True)
    consultant.wm.encode("face1", ["male", "glasses"], "speaker", 0.0, 0)
    consultant.wm.begin_episode("face1", 1.0, 1)
    consultant.wm.encode("face1", ["glasses"], "speaker", 1.0, 1)
    reply = apply(service, "open", {"op": "open", "target": "face1"}).reply
    assert reply["queue"] == ["male", "glasses"]
    assert reply["strength"] == [{"age": 1, "episodes": 1, "activation": None},
                                 {"age": 0, "episodes": 2, "activation": None}]
    assert view_of(reply, False).strength == [Strength(1, 1), Strength(0, 2)]


# ------------------------------------------------------------------ persistence
def make(tmp_path):
    consultant = Consultant("faces", ENTITIES, PREF)
    store = DomainStore(tmp_path / "faces.sqlite3", KB)
    service = ConsultantService(consultant, store=store, clock="system", now=lambda: 50.0, steady=lambda: 100.0,
                                sessions=ViewTable(capacity=8, per_client=2))
    service.restore(store.open())
    return service


def describe(service, target: str, time: float, turn: int) -> list[str]:
    session = apply(service, "open", {"op": "open", "target": target}).reply["session"]
    walked = apply(service, "walk", {"op": "walk", "session": session, "cause": "reg-distractor", "time": time,
                                     "turn": turn, "steps": [{"property": p} for p in PREF]}).reply
    taken = [PREF[i] for i in walked["taken"]]
    apply(service, "close", {"op": "close", "session": session, "encode": taken, "time": time, "turn": turn})
    return taken


def state(service) -> tuple:
    wm = service.buffer
    return ({e: wm.queue(e) for e in ENTITIES}, {e: wm.episode(e) for e in ENTITIES},
            {e: wm.strength(e) for e in ENTITIES}, wm.counters())


def test_episodes_survive_a_restart_from_the_journal_and_from_a_checkpoint(tmp_path):
    service = make(tmp_path)
    apply(service, "configure", {"op": "configure", "policy": {"policy": "episodes", "episode_window": 1},
                                 "time": 0.0})
    assert describe(service, "face1", 1.0, 0) == ["light-hair"]
    assert describe(service, "face2", 2.0, 1) == ["dark-hair", "female"]
    assert describe(service, "face1", 3.0, 2) == ["light-hair"]
    assert describe(service, "face3", 4.0, 3) == ["dark-hair", "male"]
    assert describe(service, "face1", 5.0, 4) == ["light-hair"]
    expected = state(service)
    assert expected[1] == {"face1": 3, "face2": 1, "face3": 1}
    assert expected[2]["face1"] == [Strength(0, 3)]
    service.store.close()  # abruptly: the journal replays
    peek = DomainStore(tmp_path / "faces.sqlite3", KB)
    assert peek.open().journal[-1] == ["refer", "face1", ["light-hair"], 5.0, 4]
    peek.close()
    again = make(tmp_path)
    assert state(again) == expected and again.persistence.wm_state == "restored"
    again.shutdown()  # a checkpoint, the journal emptied
    third = make(tmp_path)
    assert third.store.journal_length() == 0
    assert state(third) == expected
    # The counters go on from where they were: face2's episode 2 keeps what episode 1 used.
    apply(third, "configure", {"op": "configure", "policy": {"policy": "episodes", "episode_window": 1},
                               "time": 5.0})
    assert describe(third, "face2", 6.0, 5) == ["dark-hair", "female"]
    assert third.buffer.episode("face2") == 2 and third.buffer.queue("face2") == ("dark-hair", "female")
    assert third.buffer.strength("face2") == [Strength(0, 2), Strength(0, 2)]
    assert third.buffer.strength("face3") == [Strength(0, 1), Strength(0, 2)]  # rule 3 refreshed dark-hair


def test_the_refer_record_is_checked_and_replays_an_episode():
    wm = buffer("episodes", episode_window=1)
    record = journal.refer("f1", ["a", "b"], 2.0, 3)
    assert record == ["refer", "f1", ["a", "b"], 2.0, 3]
    assert journal.check(record, lambda e: True, lambda p: True) == record
    assert journal.time_of(record) == 2.0
    journal.replay(wm, ["f1"], record)
    assert wm.episode("f1") == 1 and wm.queue("f1") == ("a", "b")
    with pytest.raises(journal.JournalError, match="^'refer' record names an unknown entity 'f9'$"):
        journal.check(["refer", "f9", ["a"], 1.0, None], lambda e: e == "f1", lambda p: True)
    with pytest.raises(journal.JournalError, match="^malformed 'refer' record"):
        journal.check(["refer", "f1", "a", 1.0, None], lambda e: True, lambda p: True)


def test_a_damaged_stored_episode_log_is_refused_with_one_line(tmp_path):
    service = make(tmp_path)
    apply(service, "configure", {"op": "configure", "policy": {"policy": "episodes", "episode_window": 1},
                                 "time": 0.0})
    describe(service, "face1", 1.0, 0)
    service.shutdown()
    store = DomainStore(tmp_path / "faces.sqlite3", KB)
    contents = store.open()
    store.execute("UPDATE meta SET value = json_set(value, '$.episodes.face1.starts', json('[5, 2]')) "
                  "WHERE key = 'checkpoint'")
    store.close()
    assert contents.episodes == {"face1": {"starts": [0], "counts": {}}}
    with pytest.raises(StateDamaged, match="stored checkpoint episodes of 'face1': starts \\[5, 2\\] are not stamps "
                                           "in order"):
        make(tmp_path)


def test_a_restored_entry_that_entered_in_the_current_episode_counts_from_one():
    wm = buffer("displacement", capacity=1)
    wm.encode("f1", ["a"], "speaker", 0.0, 0)
    wm.begin_episode("f1", 1.0, 1)
    wm.encode("f1", ["a"], "speaker", 1.0, 1)  # a: episodes 0 and 1
    wm.encode("f1", ["b", "a"], "speaker", 1.0, 1)  # a forgotten and back in episode 1: one episode
    saved = wm.export_episodes()
    assert saved == {"f1": {"starts": [1], "counts": {}}}
    again = buffer("displacement", capacity=1)
    stamp, ticks = wm.counters()
    again.restore({"f1": wm.export_queue("f1")}, stamp, ticks, wm.limits)
    assert again.restore_episodes(saved) == []
    for one in (wm, again):
        assert one.strength("f1") == [Strength(0, 1)]
        one.begin_episode("f1", 2.0, 2)
        one.encode("f1", ["a"], "speaker", 2.0, 2)
        assert one.strength("f1") == [Strength(0, 2)] and one.episode("f1") == 2
    assert again.export_episodes() == wm.export_episodes() == {"f1": {"starts": [1, 4], "counts": {"a": 1}}}
