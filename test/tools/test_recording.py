"""Recording as rosbag2 (MCAP) and replay through the simulator (issue 24.1, 24.2 and its standards).

The bag is written by ``rosbags`` (:mod:`fsreg_ros.core.io.recording`) and read back here,
independently, by the ``mcap`` package.  A live session (the public harness, in-process
graph, sim time) is recorded with exact message counts, replayed (equal), doctored (one
expression changed: exit 1 naming the turn), damaged (one line naming the file, exit 2),
and cut short by SIGKILL (the closed segments still open, and what was lost is said).  Two
recorders at once (one on a ROS context of its own) both hold the whole session.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from fsreg_ros.core.io.recording import (
    CLOCK, STRING, TOPICS_KEY, BagWriter, Channel, RecordingError, encode_clock, encode_string, open_recording,
)
from fsreg_ros.research.cli import plot_main
from fsreg_ros.tools.sim import sim_main

REPO = Path(__file__).resolve().parents[2]
SCENARIO = REPO / "scenarios" / "guess_who_table1.yaml"
BIN = Path(sys.executable).parent
CHANNELS = [Channel("/r/rr/result", STRING, 100), Channel("/r/wm/state", STRING, 1, latched=True),
            Channel("/r/clock", CLOCK, 10)]
ROLES = {TOPICS_KEY: json.dumps({"/r/rr/result": "rr", "/r/wm/state": "state", "/r/clock": "clock"})}


class Ticks:
    """A wall clock for the writer's segment timer that the test moves."""

    def __init__(self) -> None:
        self.ns = 0

    def __call__(self) -> int:
        return self.ns


def mcap_summary(path: Path) -> tuple[dict, dict, dict]:
    """Read an .mcap with the mcap package: topic -> (message count, schema name, channel metadata)."""
    counts: dict[str, int] = {}
    with path.open("rb") as handle:
        reader = make_reader(handle)
        summary = reader.get_summary()
        schemas = {c.topic: summary.schemas[c.schema_id].name for c in summary.channels.values()}
        metadata = {c.topic: dict(c.metadata) for c in summary.channels.values()}
        for _schema, channel, _message in reader.iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    return counts, schemas, metadata


def test_a_bag_written_by_rosbags_reads_back_with_the_mcap_package(tmp_path):
    ticks = Ticks()
    bag = BagWriter(tmp_path / "bag", CHANNELS, segment_seconds=1.0, now=ticks, custom=ROLES)
    for i in range(5):
        ticks.ns = i * 600_000_000  # segments close every second: three segments, merged at close
        bag.write("/r/rr/result", 10 + i, encode_string({"id": f"x{i}", "status": "resolved"}))
        bag.write("/r/clock", 10 + i, encode_clock(i + 0.5))
    assert len(bag.segments) == 2
    bag.close()
    assert sorted(p.name for p in (tmp_path / "bag").iterdir()) == ["bag.mcap", "metadata.yaml"]
    counts, schemas, metadata = mcap_summary(tmp_path / "bag" / "bag.mcap")
    assert counts == {"/r/rr/result": 5, "/r/clock": 5}
    assert schemas == {"/r/rr/result": STRING, "/r/wm/state": STRING, "/r/clock": CLOCK}
    assert "durability: transient_local" in metadata["/r/wm/state"]["offered_qos_profiles"]
    assert "depth: 100" in metadata["/r/rr/result"]["offered_qos_profiles"]
    recording = open_recording(tmp_path / "bag")
    assert recording.counts == {"/r/rr/result": 5, "/r/wm/state": 0, "/r/clock": 5}
    assert [m.data for m in recording.on("rr")][2] == {"id": "x2", "status": "resolved"}
    assert [m.data for m in recording.on("clock")] == [0.5, 1.5, 2.5, 3.5, 4.5]
    assert recording.lost is None
    with pytest.raises(RecordingError, match="exists already"):
        BagWriter(tmp_path / "bag", CHANNELS)


def test_a_recording_never_closed_keeps_its_closed_segments_and_says_what_is_lost(tmp_path):
    ticks = Ticks()
    bag = BagWriter(tmp_path / "cut", CHANNELS, segment_seconds=1.0, now=ticks, custom=ROLES)
    for i in range(4):
        ticks.ns = i * 700_000_000
        bag.write("/r/rr/result", 1_700_000_000_000_000_000 + i, encode_string({"id": f"m{i}"}))
    # the process dies here: no close, the open segment has no index
    recording = open_recording(tmp_path / "cut")
    assert [m.data["id"] for m in recording.on("rr")] == ["m0", "m1"]  # the closed segment (0 to 1.4 s)
    assert "cut short" in recording.lost and "in 000001" in recording.lost
    assert "1 closed segment(s) with 2 messages" in recording.lost
    assert plot_main([str(tmp_path / "cut"), "-o", str(tmp_path / "cut.png")]) == 0


def test_a_damaged_recording_gets_one_line_naming_the_file(tmp_path, capsys):
    bag = BagWriter(tmp_path / "bad", CHANNELS, custom=ROLES)
    bag.write("/r/rr/result", 1, encode_string({"id": "a"}))
    bag.close()
    mcap = tmp_path / "bad" / "bad.mcap"
    mcap.write_bytes(mcap.read_bytes()[:-20])  # the footer damaged
    assert sim_main(["--replay", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith(f"fsreg-sim: error: {mcap}: not a readable recording (")
    (tmp_path / "bad" / "metadata.yaml").write_text("rosbag2_bagfile_information: [")
    assert sim_main(["--replay", str(tmp_path / "bad")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"{tmp_path / 'bad' / 'metadata.yaml'}: not a readable recording" in err
    assert sim_main(["--replay", str(tmp_path / "nothing")]) == 2
    assert capsys.readouterr().err.strip() == f"fsreg-sim: error: {tmp_path / 'nothing'}: no such file or folder"


def test_plot_accepts_watch_output_with_states_between_the_events(tmp_path, capsys):
    lines = [{"domain": "faces", "time": 0.0, "queues": {}, "events": 0, "incarnation": 1, "wm_version": 0},
             {"op": "encode", "domain": "faces", "entity": "face1", "property": "male", "cause": "speaker",
              "time": 1.0, "turn": None, "seq": 1, "incarnation": 1},
             {"domain": "faces", "time": 1.0, "queues": {"face1": ["male"]}, "events": 1, "incarnation": 1,
              "wm_version": 1},
             {"op": "forget", "domain": "faces", "entity": "face1", "property": "male", "cause": "decay",
              "time": 10.0, "turn": None, "seq": 2, "incarnation": 1}]
    trace = tmp_path / "f.jsonl"
    trace.write_text("".join(json.dumps(line) + "\n" for line in lines))
    assert plot_main([str(trace), "-o", str(tmp_path / "f.png")]) == 0
    assert capsys.readouterr().out.strip() == f"fsreg-plot: 1 WM stays from 2 events drawn to {tmp_path / 'f.png'}"
    trace.write_text(json.dumps({"op": "refresh"}) + "\n")
    assert plot_main([str(trace), "-o", str(tmp_path / "g.png")]) == 2
    assert "f.jsonl: line 1: not a WM event (an object with op encode|forget)" in capsys.readouterr().err


# ------------------------------------------------------------------ a live session
def record_live_session(path: Path, second: Path) -> dict:
    """Record a scripted session of the in-process graph (sim time); return what was sent and the graph's counts.

    Two recorders at once: one on the harness's node, one on a node and ROS context of its
    own (``second``, as ``fsreg-graph --record`` runs it).
    """
    from fsreg_ros import contract
    from fsreg_ros.ros.recorder import Recorder, RecorderThread
    from fsreg_ros.testing import LiveGraph

    with LiveGraph(SCENARIO, policy="decay", decay_period=10.0) as robot:
        recorder = Recorder(robot.session.probe, path, segment_seconds=0.5, attach={"scenario": SCENARIO},
                            custom={"fsreg.graph": robot.identity})
        other = RecorderThread(second, robot.namespace, attach={"scenario": SCENARIO})
        both = (recorder, other.recorder)
        robot.session.spin_until(lambda: all(r.matched()[f"{robot.namespace}/rr/result"] >= 1
                                             and r.matched()[f"{robot.namespace}/wm/events"] >= 1
                                             and r.counts[f"{robot.namespace}/wm/state"] >= 1 for r in both), 10.0,
                                 what="both recorders matched with the graph and hold its latched state")
        robot.client.wait_matched("say", 10.0)
        said = robot.say("male, lab-coat, light-hair, glasses", time=1.0)
        assert said["resolved"] == "face1"
        robot.set_clock(2.0)
        robot.describe("face1", time=2.0)
        robot.set_clock(4.0)
        robot.say(description=["female", "glasses"], time=4.0)
        robot.set_clock(11.0)  # a decay tick at 10
        robot.describe("face5", time=11.0)
        assert robot.assert_facts("face17", {"female": 1.0, "light-hair": 1.0})["ok"]
        robot.set_clock(12.0)
        robot.describe("face17", time=12.0)
        robot.set_clock(21.0)
        robot.describe("face1", time=21.0)
        info = robot.client.call(contract.consultant_service("faces"), {"op": "info"})
        ns = robot.namespace
        wanted = {f"{ns}/rr/result": 2, f"{ns}/reg/expression": 4, f"{ns}/wm/events": info["events"],
                  f"{ns}/ltm/assert/result": 1}
        robot.session.spin_until(lambda: all(r.counts[t] >= n for t, n in wanted.items() for r in both), 10.0,
                                 what="every answer and event in both recordings")
        recorder.close()
        other.close()
        return {"namespace": ns, "events": info["events"], "hash": str(
            robot.session.probe.get_publishers_info_by_topic(f"{ns}/rr/result")[0].topic_type_hash)}


@pytest.mark.graph
def test_a_write_that_fails_stops_the_recorder_and_is_kept_for_its_owner(tmp_path):
    from fsreg_ros import contract
    from fsreg_ros.ros.recorder import Recorder
    from fsreg_ros.testing.ros_session import RosSession

    with RosSession("/full") as session:
        recorder = Recorder(session.probe, tmp_path / "bag")

        def full(*_args) -> None:
            raise OSError(28, "No space left on device")

        recorder.bag.write = full  # the disk fills up
        answer = {"id": "r1", "resolved": "face1"}
        session.publish("/full/rr/result", answer, contract.PIPELINE_QOS)  # the writer (matched or not yet)
        session.spin_until(lambda: recorder.matched()["/full/rr/result"] >= 1, 10.0, what="the recorder matched")
        session.publish("/full/rr/result", answer, contract.PIPELINE_QOS)
        session.spin_until(lambda: recorder.error is not None, 10.0, what="the recorder's thread to stop")
        assert isinstance(recorder.error, OSError) and recorder.error.errno == 28
        assert not recorder._thread.is_alive()


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    folder = tmp_path_factory.mktemp("live")
    path = folder / "session"
    sent = record_live_session(path, folder / "second")
    return path, sent


@pytest.mark.graph
@pytest.mark.slow
def test_a_live_session_is_recorded_with_nothing_dropped(recorded):
    path, sent = recorded
    ns = sent["namespace"]
    counts, schemas, metadata = mcap_summary(path / f"{path.name}.mcap")
    # exactly what was sent: 2 utterances, 4 REG requests (each sent once), 1 assertion, every WM event
    for topic, n in (("dialogue/human", 2), ("dialogue/semantics", 2), ("rr/result", 2), ("reg/request", 4),
                     ("reg/expression", 4), ("ltm/assert", 1), ("ltm/assert/result", 1),
                     ("wm/events", sent["events"])):
        assert counts[f"{ns}/{topic}"] == n, topic
    assert counts[f"{ns}/wm_manager/ready"] >= 1 and counts[f"{ns}/consultant/announce"] >= 1
    assert counts[f"{ns}/clock"] == 5  # set_clock 2, 4, 11, 12, 21
    assert schemas[f"{ns}/clock"] == CLOCK
    assert metadata[f"{ns}/rr/result"]["offered_qos_profiles"].count("reliability: reliable") == 1
    recording = open_recording(path)
    seqs = [m.data["seq"] for m in recording.on("events")]
    assert seqs == list(range(1, sent["events"] + 1))  # no gap, nothing twice
    # the type hash in the bag is the one the live publisher announces
    meta = (path / "metadata.yaml").read_text()
    assert sent["hash"].startswith("RIHS01_") and f"type_description_hash: {sent['hash']}" in " ".join(meta.split())


@pytest.mark.graph
@pytest.mark.slow
def test_two_recorders_at_once_both_hold_the_whole_session(recorded):
    path, sent = recorded
    second = path.parent / "second"
    ns = sent["namespace"]
    first_counts, _, _ = mcap_summary(path / f"{path.name}.mcap")
    second_counts, _, _ = mcap_summary(second / f"{second.name}.mcap")
    for topic, n in (("dialogue/human", 2), ("dialogue/semantics", 2), ("rr/result", 2), ("reg/request", 4),
                     ("reg/expression", 4), ("ltm/assert", 1), ("ltm/assert/result", 1),
                     ("wm/events", sent["events"]), ("clock", 5)):
        assert first_counts[f"{ns}/{topic}"] == second_counts[f"{ns}/{topic}"] == n, topic
    first, other = open_recording(path), open_recording(second)
    for role in ("human", "rr", "request", "expression", "events", "assert", "assert_result"):
        assert [m.data for m in first.on(role)] == [m.data for m in other.on(role)], role
    assert [m.data["seq"] for m in other.on("events")] == list(range(1, sent["events"] + 1))


@pytest.mark.graph
@pytest.mark.slow
def test_the_recorded_session_replays_equal_and_a_doctored_one_names_the_turn(recorded, tmp_path, capsys):
    path, _ = recorded
    assert sim_main(["--replay", str(path)]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[-1] == "replay: all 6 turns equal the live graph (answers and WM)"
    assert "   3     11.00  robot    face5 -> the man with dark hair: equal" in out
    # one expression changed: turn 3's text and description
    recording = open_recording(path)
    doctored = tmp_path / "doctored"
    writer = BagWriter(doctored, [Channel(t, m) for t, m in recording.topics.items()],
                       custom=recording.custom)
    writer.attach("scenario", recording.attached("scenario"))
    changed = 0
    for message in recording.messages:
        data = message.data
        if message.topic.endswith("/reg/expression") and data.get("target") == "face5":
            data = {**data, "description": ["male"], "text": "the man"}
            changed += 1
        raw = encode_clock(data) if message.msgtype == CLOCK else encode_string(data)
        writer.write(message.topic, message.timestamp, raw)
    writer.close()
    assert changed == 1
    assert sim_main(["--replay", str(doctored)]) == 1
    lines = capsys.readouterr().out.splitlines()
    assert "   3     11.00  robot    face5 -> the man: DIFF" in lines
    assert lines[lines.index("   3     11.00  robot    face5 -> the man: DIFF") + 1:][:2] == [
        "      description: live ['male'], replay ['male', 'dark-hair']",
        "      text: live 'the man', replay 'the man with dark hair'"]
    assert lines[-1] == "replay: 1 of 6 turns differ from the live graph (first: turn 3 at t=11)"
    assert plot_main([str(path), "-o", str(tmp_path / "wm.png")]) == 0
    assert capsys.readouterr().out.startswith("fsreg-plot: ")


@pytest.mark.graph
@pytest.mark.slow
def test_a_recorder_killed_mid_write_leaves_a_recording_that_opens(tmp_path, capsys):
    from fsreg_ros.testing import LiveGraph

    with LiveGraph(SCENARIO, policy="decay", decay_period=10.0) as robot:
        out = tmp_path / "killed"
        proc = subprocess.Popen([str(BIN / "fsreg-ctl"), "--namespace", robot.namespace, "record", str(out),
                                 "--segment", "0.3"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=os.environ)
        try:
            deadline = time.monotonic() + 30
            while not (out / "segments").is_dir() or not any((out / "segments").iterdir()):
                assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read().decode()
                robot.session.spin_for(0.1)
            # the recorder is subscribed once a graph message reached it: talk until a segment is closed
            turn = 0
            while not list((out / "segments").glob("*/metadata.yaml")):
                assert time.monotonic() < deadline, "no segment closed"
                turn += 1
                robot.set_clock(float(turn))
                robot.say("male, glasses", time=float(turn))
            robot.describe("face1")
        finally:
            proc.send_signal(signal.SIGKILL)
            proc.wait()
    recording = open_recording(out)
    assert recording.lost is not None and "cut short" in recording.lost
    assert recording.messages and not (out / "metadata.yaml").exists()
    assert plot_main([str(out), "-o", str(tmp_path / "killed.png")]) == 0
    assert "fsreg-plot: note: " in capsys.readouterr().err


@pytest.mark.graph
def test_a_recorder_waits_until_it_matched_the_writers_it_is_told_of(tmp_path):
    from std_msgs.msg import String

    from fsreg_ros import contract
    from fsreg_ros.ros.carrier import qos_profile
    from fsreg_ros.ros.recorder import Recorder
    from fsreg_ros.testing.ros_session import RosSession

    with RosSession("/told") as session:
        recorder = Recorder(session.probe, tmp_path / "bag")
        try:
            writers = {contract.WM_STATE.name: 1}
            assert recorder.wait_matched(0.2, writers) == (
                "not yet matched on /told/wm/state after 0.2 s; their first messages may be missing from the recording")
            session.probe.create_publisher(String, "/told/wm/state", qos_profile(contract.STATE_PUB_QOS))
            assert recorder.wait_matched(10.0, writers, between=lambda: session.executor.spin_once(0.05)) is None
            assert recorder.matched()["/told/wm/state"] == 1
        finally:
            recorder.close()


def test_fsreg_graph_starts_its_player_once_the_recording_matched_the_graph(tmp_path, monkeypatch):
    """The race of ``fsreg-graph --record``: a latched ``wm/state`` matched after turn 1 lost the first state."""
    from fsreg_ros.tools import graph as graph_tool
    from fsreg_ros.core.simulation.simulator import Options

    spawned: list[str] = []
    waits: list[tuple[list[str], dict]] = []

    class Recorder:
        def wait_matched(self, timeout=15.0, writers=None, between=None):
            waits.append((list(spawned), dict(writers or {})))
            return None

    class Thread:
        recorder = Recorder()

        def close(self):
            return tmp_path / "bag"

    class Done:
        returncode = 0

        def poll(self):
            return 0

    def spawn(self, spec, log_name):
        spawned.append(spec.name)
        if spec.name == "dialogue_player":
            Path(spec.parameters["output"]).write_text("{}")
        return Done()

    monkeypatch.setattr(graph_tool, "start_recorder", lambda *args: Thread())
    monkeypatch.setattr(graph_tool, "check_recording", lambda *args: None)
    monkeypatch.setattr(graph_tool.Graph, "_spawn", spawn)
    monkeypatch.setattr(graph_tool.Graph, "stop", lambda self: None)
    graph_tool.run_graph(SCENARIO, Options(), namespace="/order", record=tmp_path / "bag")
    assert spawned[-1] == "dialogue_player" and spawned.count("dialogue_player") == 1
    assert waits == [(spawned[:-1], {"dialogue/semantics": 1, "rr/result": 2, "reg/expression": 1, "wm/state": 1,
                                     "wm/events": 1, "consultant/announce": 1, "wm_manager/ready": 1})]
