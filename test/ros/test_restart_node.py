"""The consultant node's state: recovery, isolation, clock epochs, full disks, damage, migration, outages.

In-process: the node is destroyed and created again on the same state database
(every acknowledged change was committed before its reply, so destroying the node is
as good as SIGKILL for the database); ``test_restart_graph.py`` SIGKILLs real processes.
"""

from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
import yaml
from rclpy.callback_groups import ReentrantCallbackGroup
from std_msgs.msg import String

from fsreg_ros import contract
from fsreg_ros.ros.carrier import CarrierError, qos_profile
from fsreg_ros.contract import STATE_QOS
from fsreg_ros.core.algorithms.generation import generate
from fsreg_ros.core.state.store import StoreError
from fsreg_ros.ros.node_base import StartupError
from fsreg_ros.nodes.consultant import ConsultantNode
from fsreg_ros.ros.remote import RemotePort
from rosutil import DATA, KB, RosSession

pytestmark = pytest.mark.graph

Q = contract.consultant_service("faces")
M = contract.manage_service("faces")
D = contract.debug_service("faces")
POLICY = {"policy": "decay+displacement", "decay_period": 10.0, "capacity": 3}


def start(graph: RosSession, state_dir, kb: str = KB, use_sim_time: bool = False, **params) -> ConsultantNode:
    node = graph.add(ConsultantNode, use_sim_time=use_sim_time, domain="faces", kb=kb, name="consultant_faces",
                     state_dir=str(state_dir), debug=True, **params)
    for service in (Q, M, D):
        graph.wait_service(service)
    return node


def db_path(graph: RosSession, state_dir, namespace: str = "") -> Path:
    """Where the consultant ``consultant_faces`` of this graph's ROS domain keeps its database."""
    domain_id = graph.context.get_domain_id()
    return Path(state_dir) / f"ros_domain_{domain_id}" / namespace / "consultant_faces" / "faces.sqlite3"


def encode(graph: RosSession, entity: str, props: list[str], time: float) -> None:
    graph.call(D, {"op": "encode", "entity": entity, "properties": props, "cause": "speaker", "time": time})


def assert_fact(graph: RosSession, results, entity: str, properties: dict, rid: str) -> dict:
    graph.publish(contract.LTM_ASSERT.name, {"domain": "faces", "entity": entity, "properties": properties,
                                             "id": rid})
    graph.spin_until(lambda: results.latest(id=rid), what=f"assert result {rid}")
    return results.latest(id=rid)


def test_a_recreated_consultant_resumes_ltm_wm_and_policy_and_serves_only_once_configured(graph: RosSession, tmp_path):
    announces = graph.listen(contract.ANNOUNCE.name, STATE_QOS)
    node = start(graph, tmp_path)
    assert db_path(graph, tmp_path).exists()
    graph.spin_until(lambda: announces.latest(incarnation=1, ready=False), what="announce of incarnation 1")
    assert graph.call(M, {"op": "configure", "policy": POLICY, "time": 0.0})["incarnation"] == 1
    graph.spin_until(lambda: announces.latest(incarnation=1, ready=True), what="ready announce")
    results = graph.listen(contract.LTM_ASSERT_RESULT.name)
    assert assert_fact(graph, results, "face9", {"glasses": 1.0, "male": 1.0}, "a1")["ok"]
    encode(graph, "face1", ["male", "glasses", "lab-coat", "light-hair"], 1.0)  # capacity 3: male displaced
    encode(graph, "face9", ["glasses"], 2.0)
    tick = {"op": "decay", "ticks": {"origin": 0.0, "period": 10.0, "first": 1, "count": 1}}
    graph.call(M, tick)  # tick at 10: pops face1's glasses and face9's glasses
    assert graph.call(D, {"op": "snapshot"})["queues"] == {"face1": ["lab-coat", "light-hair"]}
    encode(graph, "face9", ["male"], 12.0)
    before = graph.call(D, {"op": "snapshot"})["queues"]
    graph.remove(node)

    announces.clear()
    start(graph, tmp_path)
    graph.spin_until(lambda: announces.latest(incarnation=2), what="announce of incarnation 2")
    # face9 and its two facts, the queues of face1 and face9, written by incarnation 1 on the system clock up to 12 s
    RESTORED = {"fresh": False, "runtime_entities": 1, "runtime_facts": 2, "queues": 2, "run": 1, "clock": "system",
                "latest": 12.0}
    assert announces.latest(incarnation=2) == {"domain": "faces", "incarnation": 2, "ready": False,
                                               "memory": {"policy": "decay+displacement", "decay_period": 10.0,
                                                          "capacity": 3},
                                               "state": {"wm": "restored", "persisted": True,
                                                         "restored": RESTORED}}
    err = graph.call_error(D, {"op": "holds", "property": "glasses", "entities": ["face9"]})
    assert err.kind == "not-ready" and "incarnation 2" in err.error
    info = graph.call(Q, {"op": "info"})  # info answers (readiness probes), and shows the asserted face
    assert info["entities"][-1] == "face9" and info["policy"] == "decay+displacement"
    # The manager re-sends the tick at 10 (its reply was lost, say), then configures.
    assert graph.call(M, tick)["queues_changed"] == 0  # applied before the restart: not again
    reply = graph.call(M, {"op": "configure", "policy": POLICY, "time": 12.0})
    assert reply == {"memory": POLICY, "queues_changed": 0, "incarnation": 2,
                     "state": {"wm": "restored", "persisted": True, "restored": RESTORED}}
    assert graph.call(D, {"op": "snapshot"})["queues"] == before
    assert graph.call(D, {"op": "holds", "property": "glasses", "entities": ["face9", "face2"]}) == {
        "holds": ["face9", "face2"]}
    encode(graph, "face1", ["glasses"], 13.0)
    assert graph.call(D, {"op": "wm", "entity": "face1"}) == {"queue": ["lab-coat", "light-hair", "glasses"]}


def test_without_persist_wm_ltm_facts_survive_but_wm_starts_empty(graph: RosSession, tmp_path):
    node = start(graph, tmp_path, persist_wm=False)
    graph.call(M, {"op": "configure", "policy": POLICY, "time": 0.0})
    results = graph.listen(contract.LTM_ASSERT_RESULT.name)
    assert assert_fact(graph, results, "face9", {"male": 1.0}, "a2")["ok"]
    encode(graph, "face1", ["male"], 1.0)
    graph.remove(node)
    start(graph, tmp_path, persist_wm=False)
    info = graph.call(Q, {"op": "info"})
    assert info["entities"][-1] == "face9" and info["memory"] == POLICY
    assert info["state"] == {"wm": "not-persisted", "persisted": True, "restored": {
        "fresh": False, "runtime_entities": 1, "runtime_facts": 1, "queues": 0, "run": 1, "clock": None,
        "latest": None}}
    graph.call(M, {"op": "configure", "policy": POLICY, "time": 2.0})
    assert graph.call(D, {"op": "snapshot"})["queues"] == {}


def test_an_unusable_state_dir_stops_the_node_with_one_line(graph: RosSession, tmp_path):
    (tmp_path / "file").write_text("not a directory")
    with pytest.raises(StartupError, match="state database .*file"):
        graph.add(ConsultantNode, domain="faces", kb=KB, name="consultant_faces", state_dir=str(tmp_path / "file"))


# ------------------------------------------------------------------ one robot's state
def test_namespaces_get_their_own_files_and_a_second_live_opener_is_refused_with_the_pid(graph: RosSession, tmp_path):
    start(graph, tmp_path)
    other = RosSession(namespace="robot2", context=graph.context, executor=graph.executor)
    try:
        other.add(ConsultantNode, domain="faces", kb=KB, name="consultant_faces", state_dir=str(tmp_path))
        assert db_path(graph, tmp_path).exists() and db_path(graph, tmp_path, "robot2").exists()
        assert db_path(graph, tmp_path) != db_path(graph, tmp_path, "robot2")
    finally:
        other.close()
    with pytest.raises(StartupError) as err:  # the same ROS domain, namespace and node name: one database
        graph.add(ConsultantNode, domain="faces", kb=KB, name="consultant_faces", state_dir=str(tmp_path))
    text = str(err.value)
    assert str(db_path(graph, tmp_path)) in text and f"in use by process {os.getpid()}" in text
    assert "\n" not in text


def test_every_fact_is_stored_and_in_memory_when_its_answer_goes_out_and_comes_back_after_a_restart(
        graph: RosSession, tmp_path):
    """The facts' commit runs on a writer thread; the answer waits for it and for memory (issue 28.10)."""
    node = start(graph, tmp_path)
    graph.call(M, {"op": "configure", "policy": POLICY, "time": 0.0})
    encode(graph, "face1", ["glasses", "male"], 1.0)
    reader = sqlite3.connect(f"file:{db_path(graph, tmp_path)}?mode=ro", uri=True)
    seen: list[tuple] = []

    def on_result(msg) -> None:  # at the moment the answer arrives: in the database (committed) and in LTM?
        data = json.loads(msg.data)
        facts = {(r["entity"], p, c) for r in data["results"] if r["ok"] for p, c in r["updated"].items()}
        stored = set(reader.execute("SELECT entity, property, certainty FROM facts"))
        seen.append((data["id"], facts <= stored, all(node.service.consultant.certainty(e, p) == c
                                                      for e, p, c in facts), data["applied"]))

    graph.probe.create_subscription(String, contract.LTM_ASSERT_RESULT.name, on_result,
                                    qos_profile(contract.LTM_ASSERT_RESULT.qos))
    batches = 20
    for b in range(batches):  # published without spinning: they wait together, in several groups of commits
        facts = [{"entity": f"seen{b}_{i}", "properties": {"male": 1.0}} for i in range(25)]
        if b == batches - 1:
            facts.append({"entity": "face1", "properties": {"glasses": 0.0}})  # a retraction, last
        graph.publish(contract.LTM_ASSERT.name, {"id": f"b{b}", "domain": "faces", "facts": facts},
                      contract.LTM_ASSERT.qos)
    graph.spin_until(lambda: len(seen) == batches, 30.0, what=f"{batches} answers")
    assert seen == [(f"b{b}", True, True, 25 + (b == batches - 1)) for b in range(batches)]  # in order, too
    info = graph.call(Q, {"op": "info"})
    assert info["entity_count"] == 3 + 25 * batches  # a query after the answers sees every fact
    assert graph.call(D, {"op": "wm", "entity": "face1"})["queue"] == ["male"]
    reader.close()
    graph.remove(node)
    start(graph, tmp_path)
    assert graph.call(Q, {"op": "info"})["entities"][3:] == [f"seen{b}_{i}" for b in range(batches)
                                                             for i in range(25)]


def test_queries_are_answered_while_the_facts_commit_and_see_the_facts_once_answered(graph: RosSession, tmp_path):
    """The fsync is on the writer thread: RR's and REG's queries do not wait for it (issue 28.10)."""
    node = start(graph, tmp_path)
    graph.call(M, {"op": "configure", "policy": POLICY, "time": 0.0})
    store, real = node.service.store, node.service.store.commit
    entered, go = threading.Event(), threading.Event()

    def held(batch):  # the facts' commit holds until the test lets it go
        if batch.durable:
            entered.set()
            assert go.wait(30)
        real(batch)

    store.commit = held
    results = graph.listen(contract.LTM_ASSERT_RESULT.name, contract.LTM_ASSERT_RESULT.qos)
    try:
        graph.publish(contract.LTM_ASSERT.name, {"id": "h1", "domain": "faces", "entity": "face9",
                                                 "properties": {"male": 1.0}}, contract.LTM_ASSERT.qos)
        graph.spin_until(entered.is_set, what="the facts' commit under way")
        info = graph.call(Q, {"op": "info"})  # answered while the commit holds; the fact is not acknowledged yet
        assert "face9" not in info["entities"] and not results.latest(id="h1")
        session = graph.call(Q, {"op": "open", "target": "face1", "client": "reg"})["session"]
        assert graph.call(Q, {"op": "close", "session": session})["members"] == ["face2", "face3"]
    finally:
        go.set()
    graph.spin_until(lambda: results.latest(id="h1"), what="the answer once stored")
    assert results.latest(id="h1")["ok"] and graph.call(Q, {"op": "info"})["entities"][-1] == "face9"


def test_a_restarted_simulation_drops_the_old_runs_wm_and_keeps_facts_and_policy(graph: RosSession, tmp_path):
    graph.set_time(1000.0)
    node = start(graph, tmp_path, use_sim_time=True)
    graph.set_time(1000.0)
    graph.call(M, {"op": "configure", "policy": POLICY})  # at the node's clock: 1000
    results = graph.listen(contract.LTM_ASSERT_RESULT.name)
    assert assert_fact(graph, results, "face9", {"male": 1.0, "glasses": 1.0}, "sim1")["ok"]
    encode(graph, "face1", ["male", "lab-coat", "light-hair", "glasses"], 1000.0)
    graph.call(M, {"op": "decay", "ticks": {"origin": 0.0, "period": 10.0, "first": 100, "count": 1}})
    graph.remove(node)

    graph.set_time(5.0)  # the simulator started again
    announces = graph.listen(contract.ANNOUNCE.name, STATE_QOS)
    start(graph, tmp_path, use_sim_time=True)
    graph.set_time(5.0)
    reply = graph.call(M, {"op": "configure", "policy": POLICY})
    assert reply["state"]["wm"] == "dropped"
    assert "reflects time 1000 s but the clock reads 5 s" in reply["state"]["note"]
    info = graph.call(Q, {"op": "info"})
    assert info["state"] == reply["state"] and info["memory"] == POLICY and "face9" in info["entities"]
    graph.spin_until(lambda: announces.latest(ready=True, incarnation=2), what="the ready announcement")
    assert announces.latest(ready=True, incarnation=2)["state"]["wm"] == "dropped"
    assert graph.call(D, {"op": "snapshot"})["queues"] == {}
    # not the stale decay mark either: the new run's tick at 10 s is applied
    encode(graph, "face1", ["male"], 6.0)
    tick = graph.call(M, {"op": "decay", "ticks": {"origin": 0.0, "period": 10.0, "first": 1, "count": 1}})
    assert tick["queues_changed"] == 1 and graph.call(D, {"op": "snapshot"})["queues"] == {}


def test_a_wall_clock_restart_keeps_wm(graph: RosSession, tmp_path):
    node = start(graph, tmp_path)
    graph.call(M, {"op": "configure", "policy": POLICY})
    now = time.time()
    encode(graph, "face2", ["female", "dark-hair"], now)
    graph.remove(node)
    start(graph, tmp_path)
    reply = graph.call(M, {"op": "configure", "policy": POLICY})  # the node's clock: later than ``now``
    assert reply["state"] == {"wm": "restored", "persisted": True, "restored": {
        "fresh": False, "runtime_entities": 0, "runtime_facts": 0, "queues": 1, "run": 1, "clock": "system",
        "latest": now}}
    assert graph.call(D, {"op": "snapshot"})["queues"] == {"face2": ["female", "dark-hair"]}


def test_a_full_disk_refuses_facts_with_memory_unchanged_and_reg_keeps_answering(graph: RosSession, tmp_path):
    node = start(graph, tmp_path)
    graph.call(M, {"op": "configure", "policy": POLICY, "time": 0.0})
    store = node.service.store
    real_commit = store.commit

    def full(batch):
        raise StoreError(f"state database {store.path}: database or disk is full")

    store.commit = full
    results = graph.listen(contract.LTM_ASSERT_RESULT.name)
    refused = assert_fact(graph, results, "face9", {"male": 1.0}, "full1")
    assert refused["ok"] is False and refused["error"].startswith("not stored: ") and "disk is full" in refused["error"]
    assert "face9" not in graph.call(Q, {"op": "info"})["entities"]  # memory unchanged
    assert graph.call_error(D, {"op": "holds", "property": "male", "entities": ["face9"]}).kind == "KnowledgeError"
    port = RemotePort(graph.probe, "faces", ReentrantCallbackGroup())
    graph.run(port.wait_ready(5.0))
    expression = graph.run(generate("face1", port, "sd-pia", time=3.0, turn=1))
    assert expression.description == ["light-hair"]  # answered though WM cannot be written
    state = graph.call(Q, {"op": "info"})["state"]
    assert state["persisted"] is False and "disk is full" in state["error"]
    store.commit = real_commit  # space again: the next write (a checkpoint) succeeds
    graph.spin_until(lambda: graph.call(Q, {"op": "info"})["state"]["persisted"], 5.0, what="WM stored again")
    before = graph.call(D, {"op": "snapshot"})["queues"]
    assert before  # rule 3 and the description
    graph.remove(node)
    start(graph, tmp_path)
    graph.call(M, {"op": "configure", "policy": POLICY, "time": 4.0})
    assert graph.call(D, {"op": "snapshot"})["queues"] == before


def ghost_rows(path: Path) -> None:
    db = sqlite3.connect(path)
    db.execute("""INSERT INTO queues VALUES ('ghost', '[["male", 1, 1, "rr", 0]]')""")
    db.commit()
    db.close()


def unknown_property_rows(path: Path) -> None:
    db = sqlite3.connect(path)
    db.execute("""INSERT INTO queues VALUES ('face1', '[["wings", 1, 1, "rr", 0]]')""")
    db.commit()
    db.close()


def drop_facts(path: Path) -> None:
    db = sqlite3.connect(path)
    db.execute("DROP TABLE facts")
    db.commit()
    db.close()


@pytest.mark.parametrize("damage, problem", [
    (lambda path: path.write_bytes(b""), "the file is empty (0 bytes)"),
    (drop_facts, "table 'facts' is missing"),
    (ghost_rows, "a WM queue of entity 'ghost', which the domain does not hold"),
    (unknown_property_rows, "the WM queue of 'face1' holds property 'wings', unknown to the KB"),
], ids=["empty", "dropped-table", "ghost-entity", "unknown-property"])
def test_damaged_state_stops_the_node_with_one_line_naming_the_file_and_reset_state(graph, tmp_path, damage, problem):
    graph.remove(start(graph, tmp_path))
    path = db_path(graph, tmp_path)
    damage(path)
    with pytest.raises(StartupError) as err:
        start(graph, tmp_path)
    text = str(err.value)
    assert text.startswith(f"state database {path}: {problem}") and "-p reset_state:=true" in text, text
    assert "\n" not in text
    start(graph, tmp_path, reset_state=True)  # the way out: the old file is moved aside
    assert [p.name for p in path.parent.glob("faces.sqlite3.*.old")]
    assert graph.call(Q, {"op": "info"})["state"]["wm"] == "empty"


def test_an_edited_kb_migrates_runtime_facts_and_wm_and_lists_what_it_drops(graph: RosSession, tmp_path):
    kb = tmp_path / "kb.yaml"
    scenario = yaml.safe_load(Path(KB).read_text())
    kb.write_text(yaml.safe_dump(scenario))
    node = start(graph, tmp_path, kb=str(kb))
    graph.call(M, {"op": "configure", "policy": POLICY, "time": 0.0})
    results = graph.listen(contract.LTM_ASSERT_RESULT.name)
    assert assert_fact(graph, results, "face9", {"male": 1.0, "glasses": 1.0}, "m1")["ok"]
    assert assert_fact(graph, results, "face3", {"lab-coat": 0.9}, "m2")["ok"]
    assert assert_fact(graph, results, "face2", {"female": 0.0}, "m3")["ok"]
    encode(graph, "face1", ["male", "glasses", "lab-coat"], 1.0)
    encode(graph, "face2", ["dark-hair"], 2.0)
    graph.remove(node)

    faces = scenario["domains"]["faces"]
    faces["preference"].remove("glasses")  # the scenario no longer knows glasses ...
    del faces["entities"]["face2"]  # ... nor face2
    faces["entities"]["face1"] = ["light-hair", "male", "lab-coat"]
    kb.write_text(yaml.safe_dump(scenario))
    start(graph, tmp_path, kb=str(kb))
    graph.call(M, {"op": "configure", "policy": POLICY})  # at the node's clock (the asserts used it too)
    info = graph.call(Q, {"op": "info"})
    assert info["entities"] == ["face1", "face3", "face9"]
    holds = {p: graph.call(D, {"op": "holds", "property": p, "entities": info["entities"]})["holds"]
             for p in ("male", "lab-coat")}
    assert holds == {"male": ["face1", "face3", "face9"], "lab-coat": ["face1", "face3"]}  # face3's runtime fact
    assert graph.call(D, {"op": "snapshot"})["queues"] == {"face1": ["male", "lab-coat"]}
    old = list(db_path(graph, tmp_path).parent.glob("faces.sqlite3.*.old"))
    assert len(old) == 1  # the database as the old KB had it, kept aside
    node = graph.nodes[-1]
    graph.remove(node)
    start(graph, tmp_path, kb=str(kb))  # migrated once: the next start restores as usual
    assert graph.call(Q, {"op": "info"})["state"]["wm"] == "restored"


def test_the_migration_log_lists_the_dropped_facts(tmp_path):
    kb = tmp_path / "kb.yaml"
    scenario = yaml.safe_load(Path(KB).read_text())
    kb.write_text(yaml.safe_dump(scenario))
    from fsreg_ros.core.consultant.consultant import Consultant
    from fsreg_ros.core.consultant.service import ConsultantService
    from fsreg_ros.core.state.store import DomainStore, fingerprint

    def service(text):
        spec = yaml.safe_load(text)["domains"]["faces"]
        entities = {e: ({p: 1.0 for p in f} if isinstance(f, list) else f) for e, f in spec["entities"].items()}
        c = Consultant("faces", entities, spec["preference"])
        store = DomainStore(tmp_path / "f.sqlite3", fingerprint(spec["preference"], entities, 0.5, {}))
        return ConsultantService(c, store=store), store

    first, store = service(kb.read_text())
    first.restore(store.open())
    first.ltm_assert("face9", {"glasses": 1.0, "male": 1.0}, 1.0)
    first.ltm_assert("face2", {"glasses": 1.0}, 1.0)
    first.shutdown()
    scenario["domains"]["faces"]["preference"].remove("glasses")
    del scenario["domains"]["faces"]["entities"]["face2"]
    scenario["domains"]["faces"]["entities"]["face1"] = ["light-hair", "male", "lab-coat"]
    second, store = service(yaml.safe_dump(scenario))
    report = second.restore(store.open())
    second.shutdown()
    assert report.migrated and report.runtime_facts == 1
    assert report.dropped == ["face9.glasses: unknown property", "face2: no longer in the KB"]
    assert "face9.glasses: unknown property; face2: no longer in the KB" in report.summary()


# ------------------------------------------------------------------ outages and restarts, seen by RR and REG
def test_the_first_request_after_each_restart_succeeds(graph: RosSession, tmp_path):
    port = RemotePort(graph.probe, "faces", ReentrantCallbackGroup())
    node = start(graph, tmp_path)
    graph.call(M, {"op": "configure", "policy": POLICY, "time": 0.0})
    graph.run(port.wait_ready(5.0))
    for restart in range(4):
        graph.remove(node)
        node = start(graph, tmp_path)
        graph.call(M, {"op": "configure", "policy": POLICY, "time": 1.0 + restart})  # the WM Manager's
        expression = graph.run(generate("face2", port, "sd-pia", time=1.0 + restart, turn=restart))
        assert expression.description[-1] == "female" and expression.distinguishing


def _consultant_process(state_dir: Path) -> subprocess.Popen:
    return subprocess.Popen(
        [sys.executable, "-m", "fsreg_ros.nodes.consultant", "--ros-args", "-r", "__node:=consultant_outage",
         "-p", "domain:=procfaces", "-p", f"kb:={DATA / 'proc.yaml'}", "-p", f"state_dir:={state_dir}"],
        env=dict(os.environ), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


@pytest.mark.slow
def test_an_outage_is_answered_by_liveliness_not_after_the_timeout(graph: RosSession, tmp_path):
    """A consultant frozen mid-call (SIGSTOP: its DDS threads too): the call in flight fails because its
    liveliness lapsed, and calls while it is down fail as 'not running', never by the 10 s timeout (the
    test gives each call 8 s; how fast this is, ~1 s lease + grace, is not a test's business)."""
    proc = _consultant_process(tmp_path)
    try:
        port = RemotePort(graph.probe, "procfaces", ReentrantCallbackGroup(), timeout=10.0)
        graph.run(port.wait_ready(20.0), timeout=25.0)
        graph.spin_until(lambda: port.alive, 5.0, what="the consultant's liveliness")

        async def info():
            try:
                return await port.info()
            except CarrierError as err:
                return err

        os.kill(proc.pid, signal.SIGSTOP)
        err = graph.run(info(), timeout=8.0)
        assert isinstance(err, CarrierError) and err.kind == "unavailable", err
        assert "liveliness lapsed" in err.error, err.error  # not the timeout
        err = graph.run(info(), timeout=8.0)  # while it is down
        assert isinstance(err, CarrierError) and err.kind == "unavailable" and "not running" in err.error, err
    finally:
        proc.kill()
        proc.wait()


def test_a_restart_the_manager_reports_is_waited_for_once(graph: RosSession, tmp_path):
    """RR's and REG's port learns a restart from the WM Manager's report (``wm_manager/ready``), waits for that
    incarnation to be configured and to answer, and waits in vain at most once per incarnation."""
    port = RemotePort(graph.probe, "faces", ReentrantCallbackGroup())
    node = start(graph, tmp_path)
    graph.call(M, {"op": "configure", "policy": POLICY, "time": 0.0})
    assert port.needs_round_trip()  # nothing answered yet
    graph.run(port.wait_ready(5.0))
    port.reported(1, True)
    assert not port.needs_round_trip()  # the manager reports the incarnation that answered
    graph.remove(node)
    node = start(graph, tmp_path)  # incarnation 2 ...
    port.reported(2, False)  # ... which the manager has seen but not configured yet
    assert port.needs_round_trip()
    graph.call(M, {"op": "configure", "policy": POLICY, "time": 1.0})
    port.reported(2, True)
    assert graph.run(port.wait_ready(5.0))["version"].startswith("2:")  # answered by the new incarnation
    assert not port.needs_round_trip()
    expression = graph.run(generate("face2", port, "sd-pia", time=1.0, turn=0))
    assert expression.description == ["dark-hair", "female"]
    # A restart the manager reports but never configures is waited for once, then no more.
    port.reported(3, False)
    assert port.needs_round_trip()
    with pytest.raises(CarrierError, match="restarted \\(incarnation 3\\) and the WM Manager did not configure it"):
        graph.run(port.wait_ready(0.3))
    assert not port.needs_round_trip()
