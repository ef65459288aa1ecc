"""Rule ``activation`` on an entity's own clock (``activation_clock`` = ``episodes`` or ``words``).

Hand-made sequences with exact WM contents, forgettings and strengths
(docs/semantics.md, "Activation on an entity's own clock"): ages count from 1, each
entity ages on its own clock only, the clocks survive a restart.
"""

from __future__ import annotations

import math

import pytest

from fsreg_ros.core.forgetting.policies import ForgettingPolicy
from fsreg_ros.core.memory import Strength, WMBuffer
from fsreg_ros.ros.consultant_ops import apply
from fsreg_ros.core.state.store import DomainStore
from test_consultant_service import ENTITIES, KB
from test_episodes import describe, make

#: d = 0.5, tau = -0.6: one encoding stays while its age is below exp(1.2) = 3.32 (ages 1, 2, 3).
D, TAU = 0.5, -0.6


def buffer(clock: str, events=None, **more) -> WMBuffer:
    wm = WMBuffer("faces", sink=events.append if events is not None else None)
    wm.set_limits(ForgettingPolicy.parse(more.pop("policy", "activation"), activation_decay=D,
                                         activation_threshold=TAU, activation_clock=clock, **more).limits(), 0.0)
    return wm


def act(*ages: int) -> float:
    """ACT-R's activation of encodings of these ages (the entity's clock less each encoding's, plus 1)."""
    return math.log(sum(a ** -D for a in ages))


def forgets(events) -> list[tuple]:
    return [(e.entity, e.property, e.cause, e.time) for e in events if e.op == "forget"]


def test_on_the_episodes_clock_an_entry_ages_by_its_entitys_episodes_from_one():
    events: list = []
    wm = buffer("episodes", events)
    wm.begin_episode("a", 1.0)
    wm.encode("a", ["x", "y"], "speaker", 1.0)
    assert wm.queue("a") == ("x", "y") and wm.strength("a") == [Strength(0, 1, 0.0), Strength(0, 1, 0.0)]
    wm.begin_episode("a", 2.0)
    wm.encode("a", ["y"], "speaker", 2.0)
    wm.encode_each(["a", "b"], "y", "reg-distractor", 2.5)  # used in an episode once, however many encodings
    assert wm.strength("a") == [Strength(1, 1, act(2)), Strength(0, 2, act(2, 1))]
    for time in (3.0, 4.0, 5.0, 6.0, 7.0):  # another entity's episodes and encodings age nothing of a's
        wm.begin_episode("b", time)
        wm.encode("b", ["z"], "speaker", time)
    assert wm.queue("a") == ("x", "y") and wm.episode("a") == 2
    assert wm.queue("b") == ("z",) and wm.strength("b") == [Strength(0, 5, act(5, 4, 3, 2, 1))]
    wm.begin_episode("a", 8.0)
    assert wm.strength("a") == [Strength(2, 1, act(3)), Strength(1, 2, act(3, 2))]
    wm.begin_episode("a", 9.0)  # x is of age 4 >= 3.32: forgotten as the episode begins, stamped then
    assert forgets(events) == [("b", "y", "activation", 5.0), ("a", "x", "activation", 9.0)]
    assert wm.queue("a") == ("y",) and wm.strength("a") == [Strength(2, 2, act(4, 3))]
    wm.advance(1e9)  # seconds age nothing
    assert wm.queue("a") == ("y",)


def test_on_the_words_clock_each_encoding_for_the_entity_moves_its_clock_by_one():
    events: list = []
    wm = buffer("words", events)
    wm.encode("a", ["x", "y", "z"], "speaker", 1.0)  # the clock at 3: x of age 3, y 2, z 1
    assert wm.strength("a") == [Strength(0, 1, act(3)), Strength(0, 1, act(2)), Strength(0, 1, act(1))]
    wm.encode_each(["b", "c"], "q", "reg-distractor", 2.0)  # other entities' encodings: a's clock stays
    wm.encode_each(["b"], "r", "reg-distractor", 2.5)
    assert wm.queue("a") == ("x", "y", "z") and wm.strength("b") == [Strength(0, 1, act(2)), Strength(0, 1, act(1))]
    wm.encode("a", ["z"], "speaker", 3.0)  # a refresh moves the clock too: x of age 4 >= 3.32 goes
    assert wm.queue("a") == ("y", "z") and wm.strength("a") == [Strength(0, 1, act(3)), Strength(0, 1, act(2, 1))]
    assert forgets(events) == [("a", "x", "activation", 3.0)]  # stamped with the encoding that aged it
    wm.encode("a", ["w"], "speaker", 4.0)
    assert wm.queue("a") == ("z", "w") and forgets(events)[1:] == [("a", "y", "activation", 4.0)]
    assert wm.strength("a") == [Strength(0, 1, act(3, 2)), Strength(0, 1, act(1))]
    wm.advance(1e9)  # seconds age nothing
    assert wm.queue("a") == ("z", "w")


def test_the_seconds_clock_is_todays_rule():
    wm = buffer("seconds")
    wm.encode("a", ["x"], "speaker", 1.0)
    wm.advance(3.0)
    assert wm.strength("a") == [Strength(0, 1, act(2.0))]
    wm.advance(1.0 + math.exp(1.2))
    assert wm.queue("a") == ()


def test_the_episodes_clock_keeps_the_column_form_of_a_large_domain():
    entities = [f"e{i}" for i in range(300)]
    wm = buffer("episodes", policy="activation+displacement", capacity=3)
    wm.column_min = 100
    wm.encode_members((1 << 300) - 1, entities, "p", "reg-distractor", 0.0)  # episode 0 of every entity
    assert wm.columns.entities and wm.store.in_columns("e7")
    for time in (1.0, 2.0):
        wm.begin_episode("e7", time)
        wm.encode_members(1 << 7 | 1 << 8, entities, "q", "reg-distractor", time)
    assert wm.queue("e7") == ("p", "q") and wm.strength("e7") == [Strength(2, 1, act(3)), Strength(0, 2, act(2, 1))]
    wm.begin_episode("e7", 3.0)  # p of age 4 >= 3.32
    assert wm.queue("e7") == ("q",) and wm.queue("e8") == ("p", "q")
    assert wm.strength("e8") == [Strength(0, 1, act(1)), Strength(0, 1, act(1))]  # e8's episode 0 all along


def test_the_words_clock_keeps_the_column_form_of_a_large_domain():
    entities = [f"e{i}" for i in range(300)]
    wm = buffer("words", policy="activation+displacement", capacity=2)
    wm.column_min = 100
    for k, prop in enumerate(("p", "q", "r", "s")):
        wm.encode_members((1 << 300) - 1, entities, prop, "reg-distractor", float(k))
    assert len(wm.columns.entities) == 300 and wm.queue("e7") == ("r", "s")
    assert wm.strength("e7") == [Strength(0, 1, act(2)), Strength(0, 1, act(1))]


def state(service) -> tuple:
    wm = service.buffer
    return ({e: wm.queue(e) for e in ENTITIES}, {e: wm.strength(e) for e in ENTITIES}, wm.counters())


DIALOGUE = ["face1", "face2", "face1", "face3", "face1", "face2"]


def played(path, policy) -> object:
    path.mkdir(exist_ok=True)
    service = make(path)
    apply(service, "configure", {"op": "configure", "policy": policy, "time": 0.0})
    for turn, target in enumerate(DIALOGUE):
        describe(service, target, float(turn + 1), turn)
    return service


@pytest.mark.parametrize("clock", ["episodes", "words"])
def test_the_entity_clocks_survive_a_restart_from_the_journal_and_from_a_checkpoint(tmp_path, clock):
    policy = {"policy": "activation", "activation_decay": D, "activation_threshold": TAU, "activation_clock": clock}
    service = played(tmp_path / "restarted", policy)
    expected, clocks = state(service), service.buffer.export_episodes()
    service.store.close()  # abruptly: the journal replays
    again = make(tmp_path / "restarted")
    assert state(again) == expected and again.persistence.wm_state == "restored"
    again.shutdown()  # a checkpoint, the journal emptied
    stored = DomainStore(tmp_path / "restarted" / "faces.sqlite3", KB)
    assert stored.open().episodes == clocks and ("words" in clocks["face1"]) == (clock == "words")
    assert ("activation" in clocks["face1"]) == (clock == "episodes")
    stored.close()
    third = make(tmp_path / "restarted")
    assert third.store.journal_length() == 0 and state(third) == expected
    # ... and the clocks go on from where they were: the next turns as without a restart
    twin = played(tmp_path / "twin", policy)
    for service in (third, twin):
        apply(service, "configure", {"op": "configure", "policy": policy, "time": 6.0})
        for turn, target in enumerate(["face2", "face2", "face1", "face2"], start=len(DIALOGUE)):
            describe(service, target, float(turn + 1), turn)
    assert state(third) == state(twin)
    assert [third.buffer.episode(e) for e in ENTITIES] == [4, 5, 1]


def test_switching_clocks_counts_what_wm_holds_as_presented_once_now():
    wm = buffer("seconds")
    wm.begin_episode("a", 1.0)
    wm.encode("a", ["x"], "speaker", 1.0)
    wm.encode("a", ["x"], "speaker", 2.0)
    policy = ForgettingPolicy.parse("activation", activation_decay=D, activation_threshold=TAU,
                                    activation_clock="episodes")
    wm.set_limits(policy.limits(), 3.0)  # on the episodes clock x counts as used once, in episode 1
    assert wm.strength("a") == [Strength(0, 1, act(1))]
    wm.begin_episode("a", 4.0)
    wm.begin_episode("a", 5.0)
    assert wm.strength("a") == [Strength(2, 1, act(3))]
    wm.set_limits(policy.with_changes(activation_clock="words").limits(), 6.0)  # words: once, now
    assert wm.strength("a") == [Strength(2, 1, act(1))]
    wm.encode("a", ["y", "z", "w"], "speaker", 7.0)  # x of age 4 goes
    assert wm.queue("a") == ("y", "z", "w")


def test_an_entry_that_came_back_in_the_current_episode_starts_afresh_after_a_restore():
    wm = buffer("episodes", policy="activation+displacement", capacity=1)
    for time in (1.0, 2.0):
        wm.begin_episode("a", time)
        wm.encode("a", ["x"], "speaker", time)
    wm.encode("a", ["y", "x"], "speaker", 2.5)  # x displaced by y, then back: one use, episode 2
    assert wm.strength("a") == [Strength(0, 1, act(1))]
    again = WMBuffer("faces")
    again.restore({"a": wm.export_queue("a")}, *wm.counters(), wm.limits)
    again.restore_episodes(wm.export_episodes())
    for buf in (wm, again):
        buf.begin_episode("a", 3.0)
    assert again.strength("a") == wm.strength("a") == [Strength(1, 1, act(2))]


@pytest.mark.parametrize("column_min", [10**9, 1])
def test_new_limits_on_the_words_clock_keep_each_entitys_clock(column_min):
    """New limits on the same clock keep the clocks: the entries' presentations stay in their units."""
    entities = ["a", "b"]
    wm = buffer("words", policy="activation+displacement", capacity=3)
    wm.column_min = column_min  # dict queues, or column queues (each row keeps its entity's clock)
    wm.encode_members(0b11, entities, "x", "reg-distractor", 1.0)
    wm.encode_members(0b01, entities, "y", "reg-distractor", 2.0)  # a's clock at 2: x of age 2, y 1
    assert bool(wm.columns.entities) == (column_min == 1)
    wm.set_limits(ForgettingPolicy.parse("activation+displacement", activation_decay=D, activation_threshold=TAU,
                                         activation_clock="words", capacity=2).limits(), 3.0)
    assert wm.strength("a") == [Strength(0, 1, act(2)), Strength(0, 1, act(1))]
    assert wm.export_episodes() == {"a": {"starts": [], "counts": {}, "words": 2},
                                    "b": {"starts": [], "counts": {}, "words": 1}}
    wm.encode("a", ["z"], "speaker", 4.0)  # a's clock at 3: x of age 3, y 2, z 1 (capacity 2: x displaced)
    assert wm.queue("a") == ("y", "z") and wm.strength("a") == [Strength(0, 1, act(2)), Strength(0, 1, act(1))]
    wm.encode("a", ["z"], "speaker", 5.0)  # at 4: y of age 3, below; z of ages 2 and 1
    assert wm.queue("a") == ("y", "z") and wm.strength("a") == [Strength(0, 1, act(3)), Strength(0, 1, act(2, 1))]
    wm.encode("a", ["z"], "speaker", 6.0)  # at 5: y of age 4 >= 3.32 goes
    assert wm.queue("a") == ("z",)
