"""A replay rebuilds the requests its recording lacks from what the graph's nodes forwarded (issue 38.4).

A short-lived sender (``fsreg-ctl``) can leave before a recorder discovers it; the graph's
long-lived nodes, which the recorder always hears, forward what they applied: the parser's
``dialogue/semantics``, RR's ``rr/result``, REG's ``reg/expression``, a consultant's
``ltm/assert/result``.  A recording holding only those replays the same turns, and says
how many requests it rebuilt.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fsreg_ros.core.io.recording import STRING, TOPICS_KEY, BagWriter, Channel, encode_string, open_recording
from fsreg_ros.core.simulation.replay import ReplayError, session_of
from fsreg_ros.tools.sim import sim_main

REPO = Path(__file__).resolve().parents[2]
SCENARIO = REPO / "scenarios" / "guess_who_table1.yaml"
ROLES = {"/r/dialogue/human": "human", "/r/dialogue/semantics": "semantics", "/r/rr/result": "rr",
         "/r/reg/request": "request", "/r/reg/expression": "expression", "/r/ltm/assert": "assert",
         "/r/ltm/assert/result": "assert_result"}


def test_requests_missing_from_a_recording_are_rebuilt_from_what_the_graph_forwarded(tmp_path):
    path = tmp_path / "bag"
    writer = BagWriter(path, [Channel(t, STRING) for t in ROLES], custom={TOPICS_KEY: json.dumps(ROLES)})
    writer.attach("scenario", SCENARIO)
    messages = [
        ("/r/dialogue/human", {"id": "u1", "text": "male, glasses", "time": 1.0}),  # heard: kept as sent
        ("/r/dialogue/semantics", {"id": "u1", "description": ["male", "glasses"], "text": "male, glasses",
                                   "time": 1.0}),
        ("/r/rr/result", {"id": "u1", "status": "ambiguous", "time": 1.0, "text": "male, glasses"}),
        # not heard: the sender had left; the parser's forward and RR's answer remain
        ("/r/dialogue/semantics", {"id": "u2", "description": ["female", "glasses"], "domain": "faces",
                                   "time": 2.0}),
        ("/r/rr/result", {"id": "u2", "status": "resolved", "resolved": "face2", "time": 2.0,
                          "description": ["female", "glasses"]}),
        ("/r/reg/expression", {"id": "d1", "target": "face1", "time": 3.0, "text": "the man"}),
        ("/r/ltm/assert/result", {"id": "a1", "ok": True, "domain": "faces", "entity": "face17",
                                  "updated": {"female": 1.0}}),
        ("/r/ltm/assert/result", {"id": "a2", "ok": True, "domain": "faces", "applied": 2, "results": []}),
    ]
    for stamp, (topic, data) in enumerate(messages, 1):
        writer.write(topic, stamp, encode_string(data))
    writer.close()
    session = session_of(open_recording(path))
    assert [(s.kind, s.request, s.time) for s in session.steps] == [
        ("human", {"id": "u1", "text": "male, glasses", "time": 1.0}, 1.0),
        ("human", {"id": "u2", "time": 2.0, "description": ["female", "glasses"], "domain": "faces"}, 2.0),
        ("robot", {"id": "d1", "time": 3.0, "target": "face1"}, 3.0),
        ("assert", {"id": "a1", "domain": "faces", "entity": "face17", "properties": {"female": 1.0}}, 0.0),
    ]  # a batch's result (a2) does not say its facts: not rebuilt
    assert session.notes == [f"{path}: 3 request(s) not in the recording were rebuilt from what the graph's nodes "
                             "forwarded (dialogue/semantics, rr/result, reg/expression, ltm/assert/result): their "
                             "sender left before the recorder heard them"]


def test_a_recording_without_a_turn_is_refused_not_called_equal(tmp_path, capsys):
    """A graph that failed before its first turn leaves a recording with facts at most: nothing was compared."""
    path = tmp_path / "bag"
    writer = BagWriter(path, [Channel(t, STRING) for t in ROLES], custom={TOPICS_KEY: json.dumps(ROLES)})
    writer.attach("scenario", SCENARIO)
    writer.write("/r/ltm/assert", 1, encode_string({"id": "a1", "domain": "faces", "entity": "face17",
                                                    "properties": {"female": 1.0}}))
    writer.write("/r/ltm/assert/result", 2, encode_string({"id": "a1", "ok": True, "domain": "faces",
                                                           "entity": "face17", "updated": {"female": 1.0}}))
    writer.close()
    with pytest.raises(ReplayError) as caught:
        session_of(open_recording(path))
    assert str(caught.value) == (f"{path}: the recording holds no human utterance or REG request with its graph "
                                 "(nothing to replay: did the graph fail before its first turn?)")
    assert sim_main(["--replay", str(path)]) == 2
    assert capsys.readouterr().err == f"fsreg-sim: error: {caught.value}\n"
