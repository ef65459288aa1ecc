"""Alignment measured on played games (core/alignment.py)."""

import pytest

from fsreg_ros.core.alignment import explain, gain, summarise, turn_alignment
from fsreg_ros.core.scenario import load_scenario
from fsreg_ros.core.simulation import Options, Simulation


def play(path, memory):
    simulation = Simulation(load_scenario(path), Options(memory=memory), trace=True)
    result = simulation.run()
    return summarise(result, simulation.trace())


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
    summary = play(table1_path, memory)
    assert (summary.aligned, summary.properties, summary.robot_turns) == (aligned, properties, 6)


def test_table1_origins_and_gain(table1_path):
    none = play(table1_path, {"policy": "none"})
    displacement = play(table1_path, {"policy": "displacement", "capacity": 2})
    assert none.from_wm == 0
    assert displacement.origins == {"human-speech": 5, "rr": 4, "robot-speech": 1}
    last = displacement.turns[-1]
    assert (last.turn, last.description) == (11, ["short-hair", "glasses", "lab-coat"])
    assert last.origins == {"short-hair": "rr", "glasses": "robot-speech"}
    assert last.aligned == ["glasses", "lab-coat"]
    assert gain(displacement, none) == pytest.approx(12 / 15 - 13 / 15)
    sentences = explain(displacement, none)
    assert len(sentences) == 3 and all(s.endswith(".") and "\n" not in s for s in sentences)
    assert sentences[0].startswith("Alignment 80%: of the robot's 15 properties, 12 had already been used")
    assert sentences[2].startswith("Alignment gain -7 points")


def ev(op, entity, prop, cause, time, turn):
    return {"op": op, "domain": "d", "entity": entity, "property": prop, "cause": cause, "time": time, "turn": turn}


def test_origin_is_what_made_the_property_enter_wm():
    result = {"turns": [
        {"turn": 0, "time": 1.0, "speaker": "human", "target": "a", "description": ["p", "q"]},
        {"turn": 1, "time": 2.0, "speaker": "robot", "target": "a", "domain": "d",
         "description": ["p", "r"], "sources": ["wm", "ltm"]},
        {"turn": 2, "time": 9.0, "speaker": "robot", "target": "a", "domain": "d",
         "description": ["p", "r", "s", "u"], "sources": ["wm", "wm", "wm", "wm"]},
    ]}
    trace = [
        ev("encode", "a", "p", "rr", 1.0, 0),  # RR affirmed the human's p for a, the referent: human speech
        ev("encode", "a", "p", "speaker", 1.0, 0),  # refresh: does not change the origin
        ev("encode", "a", "u", "rr", 1.0, 0),  # RR affirmed u, which the human did not say: rr
        ev("encode", "b", "s", "reg-distractor", 2.0, 1),
        ev("encode", "a", "r", "speaker", 2.0, 1),  # the robot's own description
        ev("encode", "a", "s", "reg-distractor", 2.0, 1),
        ev("forget", "a", "p", "decay", 5.0, None),
        ev("encode", "a", "p", "speaker", 2.0, 1),  # (out of order on purpose: stamps decide)
    ]
    trace = sorted(trace, key=lambda e: e["time"])
    turns = turn_alignment(result, trace)
    assert turns[0].origins == {"p": "human-speech"} and turns[0].aligned == ["p"]
    assert turns[1].origins == {"p": "unknown", "r": "robot-speech", "s": "reg-distractor", "u": "rr"}
    assert turns[1].human_used == ["p", "q"] and turns[1].aligned == ["p"]
    summary = summarise(result, trace)
    assert (summary.aligned, summary.properties, summary.from_wm) == (2, 6, 5)
