"""The multi-process graph: every node its own OS process, as `ros2 run` starts them.

End to end through ``fsreg-graph``, plus process hygiene: Ctrl-C, a node that dies,
and a runner that is SIGKILLed leave no processes behind.
"""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fsreg_ros.tools.sim import sim_main
from fsreg_ros.tools.graph import Graph, GraphError, NodeSpec

pytestmark = [pytest.mark.graph, pytest.mark.slow]
BIN = Path(sys.executable).parent
REPO = Path(__file__).resolve().parents[2]


def children_of(pid: int) -> set[int]:
    """PIDs whose parent is ``pid`` (from /proc)."""
    found = set()
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            ppid = int(stat.rsplit(")", 1)[1].split()[1])
            if ppid == pid:
                found.add(int(entry.name))
    return found


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def wait_until(predicate, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.05)


def test_fsreg_graph_json_equals_fsreg_sim(table1_path, capsys):
    graph = subprocess.run(
        [str(BIN / "fsreg-graph"), str(table1_path), "--policy", "decay", "--json"],
        capture_output=True, text=True, timeout=180,
    )
    assert graph.returncode == 0, graph.stderr
    assert sim_main([str(table1_path), "--policy", "decay", "--json"]) == 0
    assert graph.stdout == capsys.readouterr().out
    robot = [t for t in json.loads(graph.stdout)["turns"] if t["speaker"] == "robot"]
    assert robot[5]["description"] == ["lab-coat", "glasses"]
    assert robot[5]["aligned"] == ["lab-coat", "glasses"]
    assert robot[5]["wm_origins"] == {"lab-coat": "rr", "glasses": "rr"}


def test_fsreg_graph_comparison_json_and_traces_equal_fsreg_sim(table1_path, tmp_path, capsys):
    """The alignment of a comparison (none baseline from its own none run) and --trace-dir, graph == simulator."""
    args = [str(table1_path), "--compare-policies", "displacement,none", "--json", "--trace-dir"]
    graph = subprocess.run(
        [str(BIN / "fsreg-graph"), *args, str(tmp_path / "graph")], capture_output=True, text=True, timeout=240,
    )
    assert graph.returncode == 0, graph.stderr
    assert sim_main([*args, str(tmp_path / "sim")]) == 0
    assert graph.stdout == capsys.readouterr().out
    assert json.loads(graph.stdout)["displacement"]["alignment"]["gain_over_none"] == -0.0667
    for policy in ("displacement", "none"):
        name = f"guess_who_table1-{policy}.jsonl"
        assert (tmp_path / "graph" / name).read_bytes() == (tmp_path / "sim" / name).read_bytes()


def test_two_namespaced_fsreg_graphs_run_side_by_side_on_one_domain(table1_path, capsys):
    """``fsreg-graph --namespace`` twice at once, same ROS_DOMAIN_ID, different policies:
    each run's nodes (and clock) live under their own namespace, and each output equals
    the simulator's for its own policy."""
    runs = {
        ns: subprocess.Popen(
            [str(BIN / "fsreg-graph"), str(table1_path), "--policy", policy, "--json", "--namespace", ns],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )
        for ns, policy in (("robot1", "decay"), ("robot2", "displacement"))
    }
    outputs = {}
    for ns, proc in runs.items():
        out, err = proc.communicate(timeout=240)
        assert proc.returncode == 0, err
        outputs[ns] = out
    for ns, policy in (("robot1", "decay"), ("robot2", "displacement")):
        assert sim_main([str(table1_path), "--policy", policy, "--json"]) == 0
        assert outputs[ns] == capsys.readouterr().out
    assert outputs["robot1"] != outputs["robot2"]


def test_two_fsreg_graphs_started_together_without_a_namespace_each_run_a_graph_of_their_own(table1_path, capsys):
    """Issue 15: two scripted runs on one ROS domain, no --namespace: each is a graph of its own (its own
    namespace and identity), so both finish and equal the simulator."""
    procs = [subprocess.Popen([str(BIN / "fsreg-graph"), str(table1_path), "--policy", "decay", "--json"],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
    outputs = []
    for proc in procs:
        out, err = proc.communicate(timeout=240)
        assert proc.returncode == 0, err
        outputs.append(out)
    assert sim_main([str(table1_path), "--policy", "decay", "--json"]) == 0
    assert outputs == [capsys.readouterr().out] * 2


def test_every_node_of_a_run_gets_the_runs_identity_and_namespace(table1_path, tmp_path):
    from fsreg_ros.core.scenario import load_scenario
    from fsreg_ros.core.simulation.simulator import Options
    from fsreg_ros.tools.graph import command, graph_nodes, new_graph_id, unique_namespace

    graph, namespace = new_graph_id("fsreg-graph"), unique_namespace()
    assert re.fullmatch(r"fsreg-graph-[0-9a-f]{8}", graph) and re.fullmatch(r"/fsreg_[0-9a-f]{12}", namespace)
    nodes = graph_nodes(load_scenario(table1_path), table1_path, Options(), tmp_path / "r.json", graph=graph)
    for spec in nodes:
        cmd = command(spec, namespace)
        assert f"graph:={graph}" in cmd and f"__ns:={namespace}" in cmd and f"/clock:={namespace}/clock" in cmd


def test_stress_graph_small_n():
    """scripts/stress_graph.sh with a small N (the benchmark runs N=200): alone, two at once, beside a CPU hog;
    every run byte-identical to fsreg-sim."""
    proc = subprocess.run([str(REPO / "scripts" / "stress_graph.sh"), "4"], capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[:4] == ["run 1/4 (alone): identical", "run 2/4 (pair): identical", "run 3/4 (pair): identical",
                         "run 4/4 (hog): identical"]
    assert lines[-1].startswith("stress_graph: 4/4 runs identical to fsreg-sim (alone 1/1, two at once 2/2, "
                                "beside a CPU hog 1/1); 0 differ, 0 failed;")


def test_fsreg_graph_rejects_a_bad_namespace():
    proc = subprocess.run([str(BIN / "fsreg-graph"), "x.yaml", "--namespace", "9lives"], capture_output=True,
                          text=True, timeout=30)
    assert proc.returncode == 2 and "--namespace" in proc.stderr and "Traceback" not in proc.stderr


def test_fsreg_graph_bad_scenario_fails_before_starting_anything(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("domains: {faces: {preference: [a], entities: {e: [a]}}}\n"
                   "dialogue:\n  - {time: 1, speaker: robot}\n")
    proc = subprocess.run([str(BIN / "fsreg-graph"), str(bad)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert "bad.yaml" in proc.stderr and "dialogue[0]" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_ctrl_c_stops_every_node(table1_path):
    runner = subprocess.Popen(
        [str(BIN / "fsreg-graph"), str(table1_path), "--compare-policies", "decay,displacement,none"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
    )
    try:
        wait_until(lambda: len(children_of(runner.pid)) >= 6, 30, "the node processes")
        kids = children_of(runner.pid)
        time.sleep(0.5)
        runner.send_signal(signal.SIGINT)
        assert runner.wait(timeout=30) == 130
        wait_until(lambda: not any(alive(k) for k in kids), 10, "every node to exit")
        assert "Traceback" not in runner.stderr.read()
    finally:
        if runner.poll() is None:
            runner.kill()


def test_sigkilled_runner_leaves_no_orphans(table1_path):
    runner = subprocess.Popen(
        [str(BIN / "fsreg-graph"), str(table1_path), "--compare-policies", "decay,displacement,none"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    wait_until(lambda: len(children_of(runner.pid)) >= 6, 30, "the node processes")
    kids = children_of(runner.pid)
    runner.kill()
    runner.wait(timeout=10)
    wait_until(lambda: not any(alive(k) for k in kids), 10, "orphaned nodes to die (PR_SET_PDEATHSIG)")


def test_a_failing_node_is_reported_and_the_rest_stopped(tmp_path, table1_path):
    nodes = [
        NodeSpec("wm_manager", "wm_manager", {"domains": ["faces"], "policy": "decay", "use_sim_time": True}),
        NodeSpec("consultant", "consultant_faces", {"domain": "faces", "kb": str(tmp_path / "missing.yaml")}),
        NodeSpec("reg", "reg", {"domains": ["faces"]}),
    ]
    graph = Graph(nodes, tmp_path)
    try:
        graph.start()
        with pytest.raises(GraphError) as err:
            graph.wait_for("reg", time.monotonic() + 60)
        assert "consultant_faces" in str(err.value) and "exited with code 2" in str(err.value)
        assert "missing.yaml" in str(err.value)  # the node's own one-line reason
    finally:
        graph.stop()
    assert all(proc.poll() is not None for _, proc in graph.procs)
