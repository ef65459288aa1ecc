"""A session recorded by ``fsreg-up --record`` and driven only by ``fsreg-ctl`` replays equal (issue 38.4).

Each ``fsreg-ctl`` is a process that lives a second or two: its request must reach the
recorder (every reader it has matched holds what it sent before it leaves:
``GraphClient.delivered``), and a request the recorder still did not hear -- its sender
left before the recorder discovered it -- is rebuilt by the replay from what the graph's
long-lived nodes forwarded (``dialogue/semantics``, ``rr/result``, ``reg/expression``).
"""

from __future__ import annotations

import signal
import sys
from pathlib import Path

import pytest
from test_live import Up, ctl, namespace

from fsreg_ros.core.io.recording import open_recording
from fsreg_ros.tools.sim import sim_main

pytestmark = [pytest.mark.graph, pytest.mark.slow]

BIN = Path(sys.executable).parent


def test_a_session_driven_only_by_fsreg_ctl_replays_equal(table1_path, tmp_path, capsys):
    ns, bag = namespace(), tmp_path / "session"
    up = Up(str(table1_path), "--namespace", ns, "--policy", "decay", "--decay-period", "10",
            "--state-dir", str(tmp_path / "state"), "--record", str(bag))
    try:
        for t in (5, 10, 15):
            said = ctl(ns, "say", "male,", "glasses")
            assert said.returncode == 0 and said.stdout.startswith("ambiguous: face1, face6"), said
            described = ctl(ns, "describe", "face1")
            assert described.returncode == 0 and described.stdout.startswith('"the man with'), described
            clocked = ctl(ns, "clock", str(t))
            assert clocked.returncode == 0, clocked
            assert [p.stderr for p in (said, described, clocked)] == ["", "", ""]  # every recorder was reached
    finally:
        assert up.stop(signal.SIGINT) == 0
    recording = open_recording(bag)
    # The bag itself holds every message fsreg-ctl sent (the graph names its recorder: ``ros/recorders.py``).
    humans, requests = recording.on("human"), recording.on("request")
    assert len({m.data["id"] for m in humans}) == 3 and {m.data["text"] for m in humans} == {"male, glasses"}
    assert len({m.data["id"] for m in requests}) == 3 and {m.data["target"] for m in requests} == {"face1"}
    assert {m.data for m in recording.on("clock")} >= {5.0, 10.0, 15.0}
    assert len({m.data["id"] for m in recording.on("rr")}) == 3
    assert len({m.data["id"] for m in recording.on("expression")}) == 3
    assert sim_main(["--replay", str(bag)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[-1] == "replay: all 6 turns equal the live graph (answers and WM)"
    assert [line.split()[2] for line in out if line[:4].strip().isdigit()] == ["human", "robot"] * 3


def test_a_reader_matched_after_the_send_gets_the_message_before_the_client_leaves():
    """A recorder discovered only after ``fsreg-ctl`` sent its request still holds it (``GraphClient.delivered``)."""
    from fsreg_ros import contract
    from fsreg_ros.ros.client import GraphClient
    from fsreg_ros.testing.ros_session import RosSession

    with RosSession("/late") as sender:
        client = GraphClient(sender.probe, sender.executor)
        client.send("say", {"id": "late-1", "text": "male, glasses"})  # no reader yet: it reaches no one
        with RosSession("/late") as recorder:  # a participant of its own, as a recorder in another process
            heard = recorder.listen("/late/dialogue/human", contract.HUMAN.qos)
            sender.spin_until(lambda: sender.probe.count_subscribers("/late/dialogue/human") >= 1, 10.0,
                              what="the sender discovered the late reader")
            assert client.delivered(10.0)
            recorder.spin_until(lambda: heard.latest(id="late-1") is not None, 10.0, what="the late reader heard it")
            assert heard.latest(id="late-1") == {"id": "late-1", "text": "male, glasses"}


def test_a_recorder_the_graph_names_but_the_sender_cannot_reach_costs_one_line_once():
    """A stale ``recorders`` entry (a recorder killed, not yet expired by DDS) holds a command once, and says so."""
    from fsreg_ros import contract
    from fsreg_ros.ros.client import GraphClient
    from fsreg_ros.testing.ros_session import RosSession

    with RosSession("/ghost") as session:
        client = GraphClient(session.probe, session.executor)
        client.recorder_wait = 0.2
        session.publish("/ghost/wm_manager/ready", {"ready": True, "domains": {}, "time": 0.0, "graph": "g",
                                                    "recorders": ["/ghost/dead_recorder"]}, contract.READY.qos)
        session.spin_until(lambda: client.readiness() is not None, 10.0, what="the graph's readiness")
        assert client.unheard() is None
        client.send("say", {"id": "ghost-1", "text": "male, glasses"})  # sent after the bound, not refused
        client.send("say", {"id": "ghost-2", "text": "male, glasses"})
        client.publish_clock(5.0)  # a recorder missed once is not waited for again (not on /clock either)
        assert client.unheard() == (
            "recorder /ghost/dead_recorder (named by the graph's WM Manager) did not match this command's writer "
            "of /ghost/dialogue/human within 0.2 s: the recording may lack what it sent there")
