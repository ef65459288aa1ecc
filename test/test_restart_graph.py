"""Recovery through the multi-process graph: a consultant SIGKILLed mid-replay and started again.

Table 1 is replayed by a player in this test process (sim time, the WM Manager's
``sync`` barrier, then the turn), with an ``ltm/assert`` of a new face after turn 2.
Once uninterrupted and once with the consultant SIGKILLed after turn 7: a turn sent
during the outage fails fast with an error; the consultant is started again on the
same state database; the WM Manager configures the new incarnation (and sends the
decay tick owed) before it serves; the failed turn is retried under the same id (the
error was not cached) and every answer after the restart, including a REG request for
the asserted face, equals the uninterrupted run's.
"""

from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import pytest
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from fsreg_ros import contract
from fsreg_ros.carrier import CarrierError, JsonClient, qos_profile, to_msg
from fsreg_ros.core.scenario import load_scenario
from fsreg_ros.core.simulation import Options
from fsreg_ros.graph import Graph, _die_with_parent, command, graph_nodes
from fsreg_ros.nodes.dialogue_player import clock_message

pytestmark = [pytest.mark.graph, pytest.mark.slow]

NEW_FACE = {"domain": "faces", "entity": "face17", "properties": {"light-hair": 1.0, "male": 1.0, "glasses": 1.0,
                                                                  "lab-coat": 1.0}, "id": "assert-face17"}
ASSERT_AFTER = 2  # turn index after which face17 is asserted
KILL_AFTER = 7  # turn index after which the consultant is SIGKILLed
TIMEOUT = 1.5  # service_timeout of the WM Manager, RR and REG (s)
#: What an error during the outage says (RR and REG pass the consultant's error text on).
OUTAGE_ERRORS = ("not configured by the WM Manager", "not answering", "no reply within", "restarted")


class Player:
    """A scripted player in this process: /clock, sync, the turn, its answer."""

    def __init__(self) -> None:
        self.context = rclpy.Context()
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node("restart_player", context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.clock = self.node.create_publisher(Clock, "/clock", 10)
        self.pubs = {name: self.node.create_publisher(String, "/" + topic.name, qos_profile(topic.qos))
                     for name, topic in (("human", contract.HUMAN), ("reg", contract.REG_REQUEST),
                                         ("ltm", contract.LTM_ASSERT))}
        self.sync = JsonClient(self.node, "/" + contract.SYNC.name)
        self.status = JsonClient(self.node, "/" + contract.STATUS.name)
        self.replies: dict[str, list[dict]] = {}
        for topic in (contract.RR_RESULT, contract.REG_EXPRESSION, contract.LTM_ASSERT_RESULT):
            self.node.create_subscription(String, "/" + topic.name, self._on_reply, qos_profile(topic.qos))

    def _on_reply(self, msg: String) -> None:
        data = json.loads(msg.data)
        self.replies.setdefault(str(data.get("id")), []).append(data)

    def spin_until(self, predicate, seconds: float) -> bool:
        deadline = time.monotonic() + seconds
        while not predicate():
            if time.monotonic() > deadline:
                return False
            self.executor.spin_once(timeout_sec=0.005)
        return True

    def call(self, client: JsonClient, payload: dict, timeout: float) -> dict:
        async def go():
            try:
                return await client.call(payload, timeout)
            except CarrierError as err:
                return {"error": err.error, "kind": err.kind}

        task = self.executor.create_task(go())
        assert self.spin_until(task.done, timeout + 5.0), f"no answer from {client.name}"
        return task.result()

    def sync_to(self, t: float, seconds: float = 60.0) -> dict:
        """Call sync(t) until it succeeds (the graph may still be coming up or reconfiguring)."""
        deadline = time.monotonic() + seconds
        while True:
            reply = self.call(self.sync, {"time": t}, 3 * TIMEOUT)
            if "error" not in reply:
                return reply
            assert time.monotonic() < deadline, f"sync({t}) kept failing: {reply}"
            self.spin_until(lambda: False, 0.2)

    def send(self, kind: str, message: dict, seconds: float = 30.0) -> dict:
        """Publish ``message`` (resending every 2 s) until it is answered; the first answer."""
        key = str(message["id"])
        self.replies.pop(key, None)
        deadline = time.monotonic() + seconds
        while not self.replies.get(key):
            assert time.monotonic() < deadline, f"no answer to {key}"
            self.pubs[kind].publish(to_msg(message))
            self.spin_until(lambda: self.replies.get(key), 2.0)
        return self.replies[key][0]

    def close(self) -> None:
        self.executor.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def turn_message(turn) -> tuple[str, dict]:
    message: dict = {"id": f"turn-{turn.index}", "time": turn.time, "turn": turn.index}
    if turn.speaker == "human":
        message["description"] = list(turn.description)
        return "human", message
    message["target"] = turn.target
    return "reg", message


def answer(reply: dict) -> dict:
    """What a reply says (its id aside)."""
    return {k: v for k, v in reply.items() if k != "id"}


def replay(table1_path: Path, policy: str, tmp: Path, kill: bool) -> dict:
    """Replay Table 1 (+ face17) through the graph; return {turn id: answer} and the outage figures."""
    scenario = load_scenario(table1_path)
    nodes = graph_nodes(scenario, table1_path, Options(memory={"policy": policy}), tmp / "unused.json")[:-1]
    for spec in nodes:
        if spec.executable in ("wm_manager", "reference_resolution", "reg"):
            spec.parameters["service_timeout"] = TIMEOUT
    graph = Graph(nodes, tmp)
    player = Player()
    answers: dict = {}
    try:
        graph.start()
        player.clock.publish(clock_message(0.0))
        player.sync_to(0.0)
        for turn in scenario.dialogue:
            kind, message = turn_message(turn)
            if kill and turn.index == KILL_AFTER + 1:
                answers["outage"] = outage(graph, player, kind, message)
            player.sync_to(turn.time)
            player.clock.publish(clock_message(turn.time))
            reply = player.send(kind, message)
            if kill and turn.index == KILL_AFTER + 1:  # the retry of the failed turn: fail fast until served
                deadline = time.monotonic() + 30.0
                while "error" in reply:
                    assert any(words in reply["error"] for words in OUTAGE_ERRORS), reply
                    assert time.monotonic() < deadline, f"the retried turn kept failing: {reply}"
                    player.spin_until(lambda: False, 0.3)
                    reply = player.send(kind, message)
            answers[message["id"]] = answer(reply)
            if turn.index == ASSERT_AFTER:
                result = player.send("ltm", NEW_FACE)
                assert result["ok"] and result["new_entity"], result
        last = scenario.dialogue[-1].time + 1.0
        player.sync_to(last)
        player.clock.publish(clock_message(last))
        answers["reg-face17"] = answer(player.send("reg", {"id": "reg-face17", "target": "face17", "time": last}))
        answers["status"] = player.call(player.status, {}, 5.0)
    finally:
        player.close()
        graph.stop()
    return answers


def outage(graph: Graph, player: Player, kind: str, message: dict) -> dict:
    """SIGKILL the consultant, send the turn (it must fail fast), start the consultant again."""
    index = next(i for i, (spec, _) in enumerate(graph.procs) if spec.executable == "consultant")
    spec, proc = graph.procs[index]
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    player.clock.publish(clock_message(message["time"]))
    started = time.monotonic()
    failed = player.send(kind, message)
    seconds = time.monotonic() - started
    with open(graph.log_dir / f"{spec.name}.restarted.log", "wb") as log:
        new = subprocess.Popen(command(spec), env=graph.env, stdin=subprocess.DEVNULL, stdout=log,
                               stderr=subprocess.STDOUT, preexec_fn=_die_with_parent, process_group=graph.group)
    graph.procs[index] = (spec, new)
    return {"reply": failed, "seconds": seconds}


@pytest.mark.parametrize("policy", ["decay", "displacement"])
def test_sigkilled_consultant_resumes_and_every_later_turn_equals_the_uninterrupted_replay(
        table1_path, tmp_path, policy):
    (tmp_path / "base").mkdir()
    (tmp_path / "kill").mkdir()
    base = replay(table1_path, policy, tmp_path / "base", kill=False)
    killed = replay(table1_path, policy, tmp_path / "kill", kill=True)
    # The turn sent during the outage failed fast with a clear error...
    failed = killed.pop("outage")
    assert any(words in failed["reply"]["error"] for words in OUTAGE_ERRORS), failed
    assert failed["seconds"] < TIMEOUT + 2.0, failed
    # ...which was not cached: its retry under the same id, and every later turn, equal the uninterrupted run.
    for key in [k for k in base if k != "status"]:
        assert killed[key] == base[key], (key, killed[key], base[key])
    assert base["reg-face17"]["description"] and "error" not in base["reg-face17"]
    # The WM Manager reports what the restarted consultant runs: its second incarnation, configured.
    status = killed["status"]
    assert status["incarnation"] == {"faces": 2} and status["configured"] == {"faces": True}
    assert status["running"] == {"faces": status["memory"]["faces"]} and status["running"]["faces"]["policy"] == policy
    assert base["status"]["incarnation"] == {"faces": 1}
    log = (tmp_path / "kill" / "consultant_faces.restarted.log").read_text()
    assert "incarnation 2, 1 runtime entities, 4 runtime facts" in log
