"""The live component as a robot builder runs it: ``fsreg-up`` starts the graph, ``fsreg-ctl`` talks to it.

Each test starts ``fsreg-up`` in a namespace of its own (on the test run's ROS domain),
waits for its one ``ready`` line, and drives it through ``fsreg-ctl`` exactly as a user
would, checking the printed answers, ``--json`` objects and exit codes.  Stopping it
with SIGTERM or Ctrl-C must leave no process behind (checked with psutil over every
descendant seen while it ran).
"""

from __future__ import annotations

import json
import os
import re
import secrets
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

pytestmark = [pytest.mark.graph, pytest.mark.slow]

BIN = Path(sys.executable).parent
READY_TIMEOUT = 90.0
NODE_NAMES = ("consultant_faces", "wm_manager", "parser", "reference_resolution", "reg")


def namespace() -> str:
    return f"live_{secrets.token_hex(4)}"


class Up:
    """One ``fsreg-up`` process, its ready line, and every process it started."""

    def __init__(self, *args: str, cwd=None) -> None:
        self.proc = subprocess.Popen([str(BIN / "fsreg-up"), *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     text=True, cwd=cwd)
        self.ready = self._read_ready()
        self.descendants = psutil.Process(self.proc.pid).children(recursive=True)

    def _read_ready(self) -> str:
        fd, deadline, data = self.proc.stdout.fileno(), time.monotonic() + READY_TIMEOUT, b""
        while b"\n" not in data:
            if self.proc.poll() is not None or time.monotonic() > deadline:
                self.stop()
                raise AssertionError(f"fsreg-up not ready (exit {self.proc.returncode}): {data!r} "
                                     f"{self.proc.stderr.read()}")
            if select.select([fd], [], [], 0.1)[0]:
                data += os.read(fd, 4096)
        return data.decode().strip()

    @property
    def log_dir(self) -> Path:
        return Path(self.ready.rsplit("logs in ", 1)[1])

    def stop(self, sig: int = signal.SIGTERM) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
        try:
            return self.proc.wait(timeout=30)
        finally:
            if self.proc.poll() is None:
                self.proc.kill()


def ctl(ns: str, *args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    return subprocess.run([str(BIN / "fsreg-ctl"), "--namespace", ns, *args], capture_output=True, text=True,
                          timeout=timeout)


def gone(processes: list) -> bool:
    return not any(p.is_running() and p.status() != psutil.STATUS_ZOMBIE for p in processes)


def wait_gone(processes: list, seconds: float = 15.0) -> None:
    deadline = time.monotonic() + seconds
    while not gone(processes):
        assert time.monotonic() < deadline, [p for p in processes if p.is_running()]
        time.sleep(0.1)


@pytest.fixture
def table1_up(table1_path, tmp_path):
    ns = namespace()
    up = Up(str(table1_path), "--namespace", ns, "--policy", "decay", "--decay-period", "10",
            "--state-dir", str(tmp_path / "state"))
    try:
        yield ns, up
    finally:
        up.stop()


def test_fsreg_up_and_fsreg_ctl_as_a_user_runs_them(table1_up):
    ns, up = table1_up
    assert up.ready.startswith("fsreg-up: ready: graph fsreg-up-") and f"in namespace /{ns} on ROS domain" in up.ready
    assert f"faces: policy decay, decay_period 10.0; sim time on /{ns}/clock" in up.ready
    assert up.ready.count("\n") == 0
    assert f"; endpoints /{ns}/dialogue/human, /{ns}/rr/result, " in up.ready and f"/{ns}/consultant/faces;" in up.ready
    names = sorted(p.cmdline()[1].rsplit("/", 1)[-1] for p in up.descendants)
    assert names == ["consultant", "parser", "reference_resolution", "reg", "wm_manager"]

    status = ctl(ns, "status", "--json")
    assert status.returncode == 0, status.stderr
    reply = json.loads(status.stdout)
    assert reply["ready"] is True and reply["configured"] == {"faces": True}
    assert reply["graph"] == up.ready.split("graph ")[1].split(" ")[0]

    assert ctl(ns, "clock", "1").stdout == "clock at 1 s; the forgetting due by then is applied\n"
    said = ctl(ns, "say", "male,", "lab-coat,", "light-hair,", "glasses")
    assert said.returncode == 0 and said.stdout == "face1 (resolved; heard: male, lab-coat, light-hair, glasses)\n"
    # Each entry's origin and strength: RR's check of the human's words put them in WM (before the reference
    # episode began), then the episode the resolution began used them again: 2 episodes, the last one current.
    held = "[rr; age 0, 2 episodes]"
    assert ctl(ns, "wm", "face1").stdout == (
        f"face1 (faces): male {held}, lab-coat {held}, light-hair {held}, glasses {held}\n")
    assert ctl(ns, "clock", "11").returncode == 0  # one decay tick: male goes
    described = ctl(ns, "describe", "face1")
    read = "[rr; age 1, 2 episodes]"  # REG read them in face1's episode 2, which its open began
    assert described.stdout == (
        f'"the person with a lab coat, light hair and glasses" (lab-coat: wm {read}, light-hair: wm {read}, '
        f'glasses: wm {read})\n'), described.stdout
    asserted = ctl(ns, "assert", "face17", "male", "glasses:0.9")
    assert asserted.stdout == "face17 (faces): added male 1, glasses 0.9\n", asserted.stderr
    changed = ctl(ns, "set", "policy=displacement", "capacity=1")
    assert changed.stdout == "set wm_manager: faces.policy=displacement, faces.capacity=1\n", changed.stderr
    assert json.loads(ctl(ns, "status", "--json").stdout)["running"] == {"faces": {"policy": "displacement",
                                                                                   "capacity": 1}}
    watched = ctl(ns, "watch", "--count", "1", "--json")
    state = json.loads(watched.stdout)
    assert state["domain"] == "faces" and all(len(q) <= 1 for q in state["queues"].values())

    # Errors: one line each, with the exit code saying who failed.
    unknown = ctl(ns, "describe", "nobody")
    assert unknown.returncode == 1 and unknown.stderr == (
        "fsreg-ctl: error: describe nobody: no consultant knows entity 'nobody' (domains: faces)\n")
    refused = ctl(ns, "set", "decay_period=-1")  # the settings table's range, checked before sending
    assert refused.returncode == 2 and refused.stderr == (
        "fsreg-ctl: error: set decay_period=-1: wm_manager: faces.decay_period: decay_period must be > 0 seconds "
        "(at least 0.01), got -1.0 (allowed: a number in [0.01, 1e+06] seconds, or 'inherit' (use the node-wide "
        "decay_period))\n")
    bad = ctl(ns, "set", "decay_period=soon")
    assert bad.returncode == 2 and "expected a number in [0.01, 1e+06] seconds" in bad.stderr
    usage = ctl(ns, "assert", "face1", "male:2")
    assert usage.returncode == 2 and usage.stderr.startswith("fsreg-ctl: error: assert: 'male:2'")
    nobody = ctl(namespace(), "status", "--timeout", "2")
    assert nobody.returncode == 3 and "no fsreg graph answers in namespace /live_" in nobody.stderr
    assert all("Traceback" not in r.stderr for r in (unknown, refused, bad, usage, nobody))

    descendants = up.descendants
    assert up.stop(signal.SIGTERM) == 0
    wait_gone(descendants)
    assert "fsreg-up: stopped graph" in up.proc.stderr.read()


def test_a_restart_says_what_it_restored_and_fresh_starts_from_the_scenario(table1_path, tmp_path):
    """Issue 28.6: the ready line and status say what was restored; --fresh moves the state aside and says where.

    On the system clock with a policy without decay, so the WM stored is the WM restored.
    """
    ns, state = namespace(), tmp_path / "state"
    args = [str(table1_path), "--namespace", ns, "--policy", "displacement", "--capacity", "5", "--wall-time",
            "--state-dir", str(state)]
    first = Up(*args)
    try:
        assert "; state faces: fresh (the scenario alone); endpoints " in first.ready
        assert ctl(ns, "say", "male,", "lab-coat,", "light-hair,", "glasses").returncode == 0
        assert ctl(ns, "assert", "face17", "male").stdout == "face17 (faces): added male 1\n"
        changed = ctl(ns, "assert", "face2", "no-glasses")
        assert changed.stdout == "face2 (faces): updated no-glasses 1, glasses 0; retracted from WM: glasses\n"
        queues = len(json.loads(ctl(ns, "watch", "--count", "1", "--json").stdout)["queues"])
        assert queues > 0
    finally:
        assert first.stop() == 0
    second = Up(*args)
    try:
        restored = re.escape(f"restored 3 runtime facts (1 runtime entities), {queues} WM queues from run 1 "
                             "(system clock, up to ") + r"\d{4}-\d\d-\d\d \d\d:\d\d:\d\d UTC\)"
        assert re.search(f"; state faces: {restored}; endpoints ", second.ready), second.ready
        status = ctl(ns, "status")
        assert re.search(f", configured; {restored}\n", status.stdout), status.stdout
        assert json.loads(ctl(ns, "describe", "face2", "--json").stdout)["text"] == "the woman with a t-shirt"
    finally:
        assert second.stop() == 0
    third = Up(*args, "--fresh")
    try:
        (aside,) = state.rglob("faces.sqlite3.*.old")
        assert f"; state faces: fresh (the scenario alone, the old state moved aside to {aside}); endpoints " in \
            third.ready, third.ready
        unknown = ctl(ns, "describe", "face17")
        assert unknown.returncode == 1 and "no consultant knows entity 'face17'" in unknown.stderr
        assert json.loads(ctl(ns, "describe", "face2", "--json").stdout)["text"] == "the woman with glasses"
    finally:
        assert third.stop() == 0


def refusal(stderr: str, ns: str, first: str) -> None:
    """A second fsreg-up in a namespace that has a graph is refused in one line, before or after it starts.

    Before: the first graph was discovered within the start-up look (``DISCOVERY_WAIT``).  After: discovery
    took longer on a loaded machine, so the second graph started, met the first one's readiness while
    waiting for its own, and stopped its nodes again (a second line says so).
    """
    lines = stderr.splitlines()
    if lines[0].startswith(f"fsreg-up: error: namespace /{ns} on ROS domain "):
        assert "already has a graph" in lines[0] and "stop it, or choose another --namespace" in lines[0]
        assert len(lines) == 1
    else:
        assert lines[0].startswith(f"fsreg-up: error: two graphs in namespace /{ns} on ROS domain "), stderr
        assert f"'{first}'" in lines[0], stderr
        assert len(lines) == 2 and lines[1].startswith("fsreg-up: stopped graph fsreg-up-"), stderr


def test_ctrl_c_stops_every_node_and_a_second_graph_in_the_namespace_is_refused(table1_path, tmp_path):
    ns = namespace()
    up = Up(str(table1_path), "--namespace", ns, "--state-dir", str(tmp_path / "state"), "--json", "--wall-time")
    report = json.loads(up.ready)
    assert report["ready"] is True and report["namespace"] == f"/{ns}" and report["clock"] is None
    assert report["ros_domain_id"] == int(os.environ["ROS_DOMAIN_ID"]) and report["graph"].startswith("fsreg-up-")
    assert report["memory"] == {"faces": {"policy": "decay", "decay_period": 10.0}}  # the scenario's own
    assert report["topics"]["dialogue/human"] == f"/{ns}/dialogue/human"
    assert report["services"]["consultant/faces"] == f"/{ns}/consultant/faces"
    try:
        second = subprocess.run([str(BIN / "fsreg-up"), str(table1_path), "--namespace", ns], capture_output=True,
                                text=True, timeout=120)
        assert second.returncode == 1 and second.stdout == ""
        refusal(second.stderr, ns, report["graph"])
        graph = subprocess.run([str(BIN / "fsreg-graph"), str(table1_path), "--namespace", ns], capture_output=True,
                               text=True, timeout=120)
        assert graph.returncode == 1  # refused at start, or (slow discovery) on meeting the first graph's answers
        refused = ("already has a graph", "two graphs in", "another graph")
        assert any(text in graph.stderr for text in refused), graph.stderr
        assert json.loads(ctl(ns, "status", "--json").stdout)["ready"] is True  # the first one is unharmed
    finally:
        code = up.stop(signal.SIGINT)
    assert code == 0
    wait_gone(up.descendants)


def test_hostile_clock_values_do_not_stop_the_nodes(table1_path, tmp_path):
    """A negative /clock killed every sim-time node (issue 19, item 2); the processes must all live on."""
    from rosgraph_msgs.msg import Clock

    from fsreg_ros import contract
    from fsreg_ros.testing import RosSession

    ns = namespace()
    up = Up(str(table1_path), "--namespace", ns, "--state-dir", str(tmp_path / "state"))
    try:
        logs = {name: up.log_dir / f"{name}.log" for name in NODE_NAMES}
        with RosSession(ns) as ros:
            pub = ros.probe.create_publisher(Clock, "/clock", 10)  # remapped into the namespace, as the nodes'
            ros.spin_until(lambda: pub.get_subscription_count() >= 5, 30.0, "the nodes' clock subscriptions")
            msg = Clock()
            msg.clock.sec = -1
            # every node took it, and said so (positive evidence it arrived; resent: /clock is best effort)
            warned = lambda: all(f"ignored a /{ns}/clock message (sec=-1, nanosec=0)" in p.read_text()  # noqa: E731
                                 for p in logs.values())
            ros.spin_until(lambda: pub.publish(msg) or warned(), 30.0, "every node's warning")
            for sec, nanosec in ((-2**31, 2**32 - 1), (2**31 - 1, 2**32 - 1), (-5, 1), (4, 0)):
                msg.clock.sec, msg.clock.nanosec = sec, nanosec
                pub.publish(msg)
            ros.spin_until(lambda: ros.call(contract.STATUS.name, {}, 10.0)["time"] == 4.0, 30.0,
                           "the WM Manager at 4 s")
        assert all(p.is_running() and p.status() != psutil.STATUS_ZOMBIE for p in up.descendants)
        assert ctl(ns, "say", "female,", "glasses").stdout.startswith("face2 (resolved")
    finally:
        up.stop()


def test_fsreg_up_bad_input_is_one_line_and_exit_2(tmp_path, table1_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("domains: {faces: {preference: [a], entities: {e: [b]}}}\n")
    for args, said in (([str(bad)], "bad.yaml"), ([str(table1_path), "--namespace", "9x"], "--namespace"),
                       ([str(table1_path), "--policy", "decay+nothing"], "nothing"),
                       ([str(table1_path), "--policy", "global-capacity+decay", "--global-capacity", "0"],
                        "global_capacity")):
        proc = subprocess.run([str(BIN / "fsreg-up"), *args], capture_output=True, text=True, timeout=60)
        assert proc.returncode == 2, (args, proc.stderr)
        assert proc.stderr.startswith("fsreg-up: error: ") and said in proc.stderr and proc.stderr.count("\n") == 1
        assert proc.stdout == ""


def test_a_node_that_dies_is_reported_or_respawned(table1_path, tmp_path):
    ns = namespace()
    up = Up(str(table1_path), "--namespace", ns, "--respawn", "--state-dir", str(tmp_path / "state"))
    try:
        consultant = next(p for p in up.descendants if p.cmdline()[1].endswith("/consultant"))
        consultant.kill()
        deadline = time.monotonic() + 60
        while True:  # respawned: a second incarnation, configured
            status = json.loads(ctl(ns, "status", "--json").stdout or "{}")
            if status.get("incarnation", {}).get("faces") == 2 and status.get("ready"):
                break
            assert time.monotonic() < deadline, status
            time.sleep(0.5)
        assert ctl(ns, "say", "female,", "glasses").stdout.startswith("face2 (resolved")
    finally:
        assert up.stop() == 0
    assert "node consultant_faces exited with code -9; starting it again (1 of 5)" in up.proc.stderr.read()

    ns = namespace()
    up = Up(str(table1_path), "--namespace", ns, "--state-dir", str(tmp_path / "state2"))
    reg = next(p for p in up.descendants if p.cmdline()[1].endswith("/reg"))
    reg.kill()
    assert up.proc.wait(timeout=60) == 1
    err = up.proc.stderr.read()
    assert "fsreg-up: error: node reg exited with code -9 while up; stopping the graph" in err
    wait_gone(up.descendants)
