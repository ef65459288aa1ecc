"""Recovery through the multi-process graph: a consultant SIGKILLed mid-replay and started again.

Table 1 is replayed through the public harness (``fsreg_ros.testing.LiveGraph`` with
``processes=True``: one process per node, sim time, a namespace of its own), whose
client plays the player's part (the WM Manager's ``sync`` barrier, ``/clock``, then the
turn), with an ``ltm/assert`` of a new face after turn 2.  Once uninterrupted and once
with the consultant SIGKILLed after turn 7: a turn sent during the outage fails fast
with an error; the consultant is started again on the same state database; the WM
Manager configures the new incarnation (and sends the decay tick owed) before it
serves; the failed turn is retried under the same id (the error was not cached) and
succeeds at once, as does every later request (readiness after a restart means the next
request succeeds), and every answer after the restart, including a REG request for the
asserted face, equals the uninterrupted run's.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from fsreg_ros import contract
from fsreg_ros.ros.client import ClientError, GraphClient
from fsreg_ros.core.scenario import load_scenario
from fsreg_ros.testing import LiveGraph

pytestmark = [pytest.mark.graph, pytest.mark.slow]

NEW_FACE = {"light-hair": 1.0, "male": 1.0, "glasses": 1.0, "lab-coat": 1.0}
ASSERT_AFTER = 2  # turn index after which face17 is asserted
KILL_AFTER = 7  # turn index after which the consultant is SIGKILLed
TIMEOUT = 1.5  # service_timeout of the WM Manager, RR and REG (s)
#: What an error during the outage says (RR and REG pass the consultant's error text on).
OUTAGE_ERRORS = ("not configured by the WM Manager", "is not running", "stopped (its liveliness lapsed)",
                 "no reply within")
CONSULTANT = "consultant_faces"


def sync_to(client: GraphClient, t: float, seconds: float = 60.0) -> dict:
    """Call sync(t) until it succeeds (the graph may be reconfiguring a restarted consultant)."""
    deadline = time.monotonic() + seconds
    while True:
        try:
            return client.sync(t, 3 * TIMEOUT)
        except ClientError as err:
            assert time.monotonic() < deadline, f"sync({t}) kept failing: {err}"
            client.spin_for(0.2)


def turn_message(turn) -> tuple[str, dict]:
    message: dict = {"id": f"turn-{turn.index}", "time": turn.time, "turn": turn.index}
    if turn.speaker == "human":
        message["description"] = list(turn.description)
        return "say", message
    message["target"] = turn.target
    return "describe", message


def answer(reply: dict) -> dict:
    """What a reply says (its id and its graph's identity aside: each replay is a graph of its own)."""
    return {k: v for k, v in reply.items() if k not in ("id", "graph")}


def replay(table1_path: Path, policy: str, tmp: Path, kill: bool) -> dict:
    """Replay Table 1 (+ face17) through the graph; return {turn id: answer} and the outage figures."""
    scenario = load_scenario(table1_path)
    timeouts = {name: {"service_timeout": TIMEOUT} for name in ("wm_manager", "reference_resolution", "reg")}
    answers: dict = {}
    with LiveGraph(table1_path, processes=True, policy=policy, parameters=timeouts, state_dir=tmp / "state",
                   log_dir=tmp / "logs") as live:
        client = live.client
        client.set_clock(0.0)
        for turn in scenario.dialogue:
            kind, message = turn_message(turn)
            if kill and turn.index == KILL_AFTER + 1:
                answers["outage"] = outage(live, kind, message)
            sync_to(client, turn.time)
            client.publish_clock(turn.time)
            # Once the WM Manager reports the restarted consultant configured (outage() waits for that on
            # wm_manager/ready; sync alone does not show it), the next request succeeds: the failed turn's retry
            # and the first turn of each pipeline included, although RR and REG each discover the new consultant
            # on their own (they wait for it, see remote.py).
            reply = client.exchange(kind, message, 30.0)
            assert "error" not in reply, (turn.index, reply.get("error"), reply.get("kind"))
            answers[message["id"]] = answer(reply)
            if turn.index == ASSERT_AFTER:
                result = client.assert_facts("face17", NEW_FACE, domain="faces", timeout=30.0)
                assert result["ok"] and result["new_entity"], result
        last = scenario.dialogue[-1].time + 1.0
        sync_to(client, last)
        client.publish_clock(last)
        answers["reg-face17"] = answer(client.exchange("describe", {"id": "reg-face17", "target": "face17",
                                                                    "time": last}, 30.0))
        answers["status"] = client.status(5.0)
    return answers


def outage(live: LiveGraph, kind: str, message: dict) -> dict:
    """SIGKILL the consultant, send the turn (it must fail fast), start the consultant again.

    Returns once the WM Manager reports the new incarnation configured (``wm_manager/ready``):
    the readiness a robot's dialogue manager waits for.
    """
    before = live.client.readiness()["domains"]["faces"]["incarnation"]
    process = live.graph.process(CONSULTANT)
    process.kill()
    process.wait()
    # Readiness is true (issue 28.5): under every policy the WM Manager follows the consultant's liveliness
    # (1 s lease), so it stops reporting the graph ready, also under displacement, which sends nothing.
    live.client.spin_until(lambda: (live.client.readiness() or {}).get("ready") is False, 15.0,
                           "readiness lost after the SIGKILL")
    assert live.client.status(5.0)["configured"]["faces"] is False
    live.client.publish_clock(message["time"])
    started = time.monotonic()
    failed = live.client.exchange(kind, message, 30.0)
    seconds = time.monotonic() - started
    live.graph.restart(CONSULTANT, kill=False)

    def ready() -> bool:
        state = (live.client.readiness() or {}).get("domains", {}).get("faces", {})
        return state.get("incarnation") == before + 1 and bool(state.get("configured"))

    live.client.spin_until(ready, 30.0, "the restarted consultant configured")
    # Any client, not only RR and REG: the first call of a plain client is answered, by the new incarnation.
    info = live.client.call(contract.consultant_service("faces"), {"op": "info"}, 10.0)
    assert info["version"].startswith(f"{before + 1}:"), info["version"]
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
    log = (tmp_path / "kill" / "logs" / "consultant_faces.log").read_text().split("--- restarted (1)")[1]
    assert "incarnation 2, 1 runtime entities, 4 runtime facts" in log
