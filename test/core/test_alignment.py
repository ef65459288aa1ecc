"""Alignment measured on played games (core/algorithms/alignment.py), from the result records alone."""

import pytest

from fsreg_ros.core.algorithms.alignment import (
    dice, entrainment_gain, explain, gain, length_matched, origin_name, summarise, turn_alignment,
)
from fsreg_ros.core.scenario import load_scenario
from fsreg_ros.core.simulation.simulator import Options, Simulation
from fsreg_ros.research.games import make_game, play, scenario_of


def play_file(path, memory, trace=False):
    simulation = Simulation(load_scenario(path), Options(memory=memory), trace=trace)
    result = simulation.run()
    return result, simulation.trace() if trace else None


@pytest.mark.parametrize(
    "memory, aligned, properties",
    [
        ({"policy": "none"}, 13, 15),
        ({"policy": "decay", "decay_period": 10}, 11, 14),
        ({"policy": "displacement", "capacity": 2}, 12, 15),
        ({"policy": "decay", "decay_period": 40}, 14, 16),
    ],
)
def test_table1_alignment(table1_path, memory, aligned, properties):
    summary = summarise(play_file(table1_path, memory)[0])
    assert (summary.aligned, summary.properties, summary.robot_turns) == (aligned, properties, 6)


def test_table1_origins_and_gains(table1_path):
    none = summarise(play_file(table1_path, {"policy": "none"})[0])
    displacement = summarise(play_file(table1_path, {"policy": "displacement", "capacity": 2})[0])
    assert none.from_wm == 0
    assert displacement.origins == {"human-speech": 5, "rr": 4, "robot-speech": 1}
    last = displacement.turns[-1]
    assert (last.turn, last.description) == (11, ["short-hair", "glasses", "lab-coat"])
    assert last.origins == {"short-hair": "rr", "glasses": "robot-speech"}
    assert last.aligned == ["glasses", "lab-coat"]
    # The human last described face1 at turn 0: light-hair, male, lab-coat, glasses (Table 1).
    assert last.human_last_turn == 0 and set(last.human_last) == {"light-hair", "male", "lab-coat", "glasses"}
    assert last.recall == pytest.approx(2 / 4) and last.dice == pytest.approx(2 * 2 / (3 + 4))
    assert gain(displacement, none) == pytest.approx(12 / 15 - 13 / 15)
    # Turn 3 (face5) has no earlier human description: it counts for neither entrainment nor recall.
    assert [t.turn for t in displacement.described] == [1, 5, 7, 9, 11]
    delta, paired = entrainment_gain(displacement, none)
    assert paired == 5
    assert delta == pytest.approx(sum(a.dice - b.dice for a, b in zip(displacement.described, none.described)) / 5)
    assert length_matched(displacement, none) == (pytest.approx(-1 / 6), 6)
    sentences = explain(displacement, none)
    assert len(sentences) == 5 and all(s.endswith(".") and "\n" not in s for s in sentences)
    assert sentences[0].startswith("Entrainment 0.82: the mean Dice of the robot's 5 descriptions")
    assert sentences[3].startswith("Entrainment gain -0.06 over 5 paired turns")


def test_dice_recall_share_by_hand():
    result = {"turns": [
        {"turn": 0, "time": 1.0, "speaker": "human", "target": "a", "description": ["p", "q", "r"]},
        {"turn": 1, "time": 2.0, "speaker": "human", "target": "a", "description": ["p", "s"]},
        {"turn": 2, "time": 3.0, "speaker": "robot", "target": "a", "domain": "d", "description": ["p", "q", "t"],
         "sources": ["ltm", "ltm", "ltm"]},
        {"turn": 3, "time": 4.0, "speaker": "robot", "target": "b", "domain": "d", "description": ["p"],
         "sources": ["ltm"]},
    ]}
    first, second = turn_alignment(result)
    assert first.human_used == ["p", "q", "r", "s"] and first.aligned == ["p", "q"]
    assert first.share == pytest.approx(2 / 3)
    assert first.human_last == ["p", "s"] and first.human_last_turn == 1  # the most recent, not the union
    assert first.recall == pytest.approx(1 / 2) and first.dice == pytest.approx(2 * 1 / (3 + 2))
    assert (second.human_last, second.recall, second.dice, second.share) == (None, None, None, 0.0)
    summary = summarise(result)
    assert summary.entrainment == pytest.approx(0.4) and len(summary.described) == 1
    assert dice([], []) == 1.0 and dice(["a"], ["b"]) == 0.0


def test_length_cannot_buy_entrainment():
    """Dropping an unaligned property raises the share a lot; Dice moves less, and adding one lowers both."""
    human = ["p", "q", "r"]

    def one(description):
        result = {"turns": [
            {"turn": 0, "time": 0.0, "speaker": "human", "target": "a", "description": human},
            {"turn": 1, "time": 1.0, "speaker": "robot", "target": "a", "description": description,
             "sources": ["ltm"] * len(description)}]}
        return turn_alignment(result)[0]

    short, long_ = one(["p"]), one(["p", "x", "y"])
    assert short.share == 1.0 and long_.share == pytest.approx(1 / 3)  # the share rewards saying less
    assert short.dice == pytest.approx(0.5) and long_.dice == pytest.approx(1 / 3)
    assert one(["p", "q", "r"]).dice == 1.0 > one(["p", "q", "r", "x"]).dice


def test_origin_names_from_the_records():
    turns = {
        0: {"turn": 0, "speaker": "human", "target": "a", "description": ["p", "q"]},
        1: {"turn": 1, "speaker": "robot", "target": "b"},
        2: {"turn": 2, "speaker": "human", "resolved": "c", "description": ["p"]},
    }
    assert origin_name({"cause": "speaker", "turn": 0}, "p", "a", turns) == "human-speech"
    assert origin_name({"cause": "speaker", "turn": 1}, "p", "b", turns) == "robot-speech"
    # RR affirming the human's own word for the referent: the human's description put it there.
    assert origin_name({"cause": "rr", "turn": 0}, "p", "a", turns) == "human-speech"
    assert origin_name({"cause": "rr", "turn": 0}, "p", "z", turns) == "rr"  # another candidate
    assert origin_name({"cause": "rr", "turn": 0}, "u", "a", turns) == "rr"  # not a word the human said
    assert origin_name({"cause": "rr", "turn": 2}, "p", "c", turns) == "human-speech"  # referent from RR
    assert origin_name({"cause": "reg-distractor", "turn": 1}, "p", "a", turns) == "reg-distractor"


# --------------------------------------------------------------------------------------------------
# The records' origins equal what the full event trace says (the way alignment was measured before).
def trace_origins(result, trace):
    """For each robot turn, what made each WM-sourced property enter Q[target], replayed from the trace."""
    speaker_of = {t["turn"]: t["speaker"] for t in result["turns"]}
    said = {t["turn"]: (t.get("target") or t.get("resolved"), set(t.get("description") or ()))
            for t in result["turns"] if t["speaker"] == "human"}
    entered, out, events = {}, {}, iter(trace)
    pending = next(events, None)
    for record in result["turns"]:
        while pending is not None and (
            pending["turn"] < record["turn"] if pending["turn"] is not None else pending["time"] <= record["time"]
        ):
            key = (pending["domain"], pending["entity"], pending["property"])
            if pending["op"] == "forget":
                entered.pop(key, None)
            elif key not in entered:
                cause = pending["cause"]
                if cause == "speaker":
                    cause = "robot-speech" if speaker_of.get(pending["turn"]) == "robot" else "human-speech"
                elif cause == "rr" and pending["turn"] in said:
                    referent, words = said[pending["turn"]]
                    if pending["entity"] == referent and pending["property"] in words:
                        cause = "human-speech"
                entered[key] = cause
            pending = next(events, None)
        if record["speaker"] == "robot":
            out[record["turn"]] = {p: entered.get((record["domain"], record["target"], p), "unknown")
                                   for p, s in zip(record["description"], record["sources"]) if s == "wm"}
    return out


POLICIES = [
    {"policy": "decay", "decay_period": 10},
    {"policy": "displacement", "capacity": 2},
    {"policy": "decay+displacement", "decay_period": 7, "capacity": 3},
    {"policy": "displacement-lfu", "capacity": 2},
    {"policy": "displacement-random", "capacity": 2, "seed": 4},
    {"policy": "similarity+decay", "decay_period": 20},
    {"policy": "global-capacity", "global_capacity": 6},
    {"policy": "shared-capacity", "shared_capacity": 5},
]


@pytest.mark.parametrize("memory", POLICIES, ids=lambda m: m["policy"])
def test_record_origins_equal_the_trace_replay(table1_path, memory):
    result, trace = play_file(table1_path, memory, trace=True)
    assert {t.turn: t.origins for t in turn_alignment(result)} == trace_origins(result, trace)
    for seed in range(4):
        game = make_game(seed, 60, world="faces+objects", changes=10 if seed % 2 else 0)
        played = play(game, memory, trace=True, retract=seed != 3)
        assert {t.turn: t.origins for t in played.alignment.turns} == trace_origins(played.result, played.trace)
        assert sum(played.alignment.origins.values()) == played.alignment.from_wm
        assert "unknown" not in played.alignment.origins


def test_games_are_played_identically_with_and_without_a_trace():
    game = make_game(2, 40, world="faces+objects", changes=20)
    memory = {"policy": "decay+displacement", "decay_period": 10, "capacity": 2}
    assert play(game, memory, trace=True).result == play(game, memory).result
    assert scenario_of(game).name == "guess-who-2"
