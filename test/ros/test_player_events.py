"""The dialogue player never builds a result from an incomplete or foreign event stream (issue 20).

:class:`EventAudit` is checked on its own (a gap, a repeat, a restart, a foreign or
unnumbered event); then live: a player whose consultant never sees its ``wm/events``
subscription does not start the dialogue, and a foreign event heard during a real
in-process run fails it with one line instead of writing a result.
"""

from __future__ import annotations

import pytest
from std_msgs.msg import String

from rosutil import RosSession

from fsreg_ros import contract
from fsreg_ros.ros.carrier import publisher
from fsreg_ros.ros.serving import serve
from fsreg_ros.core.scenario import load_scenario
from fsreg_ros.core.simulation.simulator import Options
from fsreg_ros.tools.graph import graph_nodes
from fsreg_ros.nodes.dialogue_player import DialoguePlayer, PlayerError
from fsreg_ros.ros.event_audit import EventAudit
from fsreg_ros.testing.live import node_classes

GRAPH = "test-1234abcd"


def event(seq: int, graph: str = GRAPH, incarnation: int = 1, domain: str = "faces", **extra) -> dict:
    data = {"op": "encode", "domain": domain, "entity": "face1", "property": f"p{seq}", "cause": "rr",
            "time": 1.0, "turn": 0, "seq": seq, "incarnation": incarnation, "graph": graph}
    data.update(extra)
    return {k: v for k, v in data.items() if v is not None}


def audit() -> EventAudit:
    book = EventAudit(GRAPH, ("faces",))
    book.start("faces", 1, 2)  # two events were published before the run
    return book


def test_a_complete_stream_gives_the_trace_without_transport_fields():
    book = audit()
    for seq in (1, 3, 4, 5):  # 1 is from before the run
        book.hear(event(seq))
    assert book.fault is None and book.check("faces", 5) is None
    assert [e["property"] for e in book.trace_events()] == ["p3", "p4", "p5"]
    assert set(book.trace_events()[0]) == {"op", "domain", "entity", "property", "cause", "time", "turn"}


@pytest.mark.parametrize("seqs, last, said", [
    ([3, 5], 5, "consultant 'faces': 1 of its 3 events missing (seq 4)"),
    ([3, 4], 6, "consultant 'faces': 2 of its 4 events missing (seq 5, 6)"),
    ([3, 3, 4], 4, "consultant 'faces': 1 unexpected or repeated"),
    ([4, 3], 4, "consultant 'faces': its events arrived out of order"),
    ([], 3, "consultant 'faces': 1 of its 1 events missing (seq 3)"),
])
def test_a_gap_a_repeat_or_disorder_is_named(seqs, last, said):
    book = audit()
    for seq in seqs:
        book.hear(event(seq))
    assert book.check("faces", last) == said


@pytest.mark.parametrize("message, said", [
    (event(3, graph="fsreg-graph-other"), "an event from another graph ('fsreg-graph-other', this run is "
                                          f"'{GRAPH}'): another graph publishes in this namespace"),
    (event(3, graph=None), f"an event from another graph (none (unstamped), this run is '{GRAPH}')"),
    (event(3, domain="objects"), "an event of domain 'objects', which this run does not have"),
    (event(3, incarnation=2), "consultant 'faces' restarted during the run (incarnation 1 -> 2)"),
    (event(None), "an event of 'faces' without 'seq' and 'incarnation'"),
])
def test_a_foreign_restarted_or_unnumbered_event_is_a_fault(message, said):
    book = audit()
    book.hear(message)
    assert said in book.fault
    book.hear(event(3))
    assert said in book.fault  # the first fault stands


@pytest.mark.graph
def test_the_player_does_not_start_until_its_event_subscription_is_matched(table1_path, tmp_path):
    """A graph whose consultant reports no wm/events listener: the player refuses to play (its events would be
    lost) instead of playing without them.  The graph here is a stand-in answering as a real one would."""
    with RosSession() as g:
        node = g.probe
        serve(node, contract.SYNC.name, lambda r: {"time": r["time"], "memory": {"faces": {"policy": "decay"}}})
        serve(node, contract.STATUS.name, lambda r: {"graph": "", "incarnation": {"faces": 1}})
        info = {"calls": 0}

        def consultant(request: dict) -> dict:
            info["calls"] += 1
            return {"events": 0, "event_listeners": 0}

        serve(node, contract.consultant_service("faces"), consultant)
        for topic in (contract.RR_RESULT, contract.REG_EXPRESSION):
            publisher(node, topic)
        for topic in (contract.HUMAN, contract.REG_REQUEST):
            node.create_subscription(String, topic.name, lambda m: None, 10)
        player = g.add(DialoguePlayer, scenario=str(table1_path), ready_timeout=1.5)
        with pytest.raises(PlayerError) as err:
            g.run(player.play(), timeout=30.0)
        assert str(err.value) == ("graph not ready: the wm/events publisher of faces is not matched with this player "
                                  "(its events would be lost)")
        assert info["calls"] >= 2  # it asked again until its deadline


@pytest.mark.graph
def _player_graph(g: RosSession, table1_path, tmp_path) -> DialoguePlayer:
    scenario = load_scenario(table1_path)
    classes = {**node_classes(), "dialogue_player": DialoguePlayer}
    player = None
    for spec in graph_nodes(scenario, table1_path, Options(memory={"policy": "decay"}), tmp_path / "r.json",
                            graph=GRAPH):
        params = dict(spec.parameters)
        node = g.add(classes[spec.executable], use_sim_time=params.pop("use_sim_time", False), name=spec.name,
                     **params)
        player = node if spec.executable == "dialogue_player" else player
    return player


def test_a_foreign_writer_on_the_event_topic_refuses_the_run(table1_path, tmp_path):
    """A publisher of wm/events beyond the run's consultants: the run stops before its first turn."""
    with RosSession() as g:
        player = _player_graph(g, table1_path, tmp_path)
        g.publish(contract.WM_EVENTS.name, event(1, graph="intruder"), contract.EVENTS_QOS)
        with pytest.raises(PlayerError) as err:
            g.run(player.play(), timeout=60.0)
        assert str(err.value) == ("wm/events has 2 publishers for this run's 1 consultant(s): another graph "
                                  "publishes in this namespace")
        assert player.audit.events == []


def test_a_foreign_event_heard_fails_the_run(table1_path, tmp_path):
    """An event stamped by another graph (as the subscription delivers it): the run fails, naming it."""
    with RosSession() as g:
        player = _player_graph(g, table1_path, tmp_path)
        player._on_event(event(1, graph="intruder"))
        with pytest.raises(PlayerError) as err:
            g.run(player.play(), timeout=60.0)
        assert str(err.value).startswith("wm/events: an event from another graph ('intruder', this run is "
                                         f"'{GRAPH}')")
