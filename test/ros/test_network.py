"""DDS stays on this machine: the environment every fsreg process gets, and the sockets it binds.

The multi-process graph is started as ``fsreg-graph`` starts it and every node
process's sockets are listed (psutil).  What Fast DDS 2.14 with rmw_fastrtps allows
under ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` is asserted exactly: every socket
that receives (the DDS well-known ports and the loopback transport's own socket) is
bound to 127.0.0.1; the only others are the two send-only sockets (ephemeral ports)
of the UDPv4 transport that rmw_fastrtps itself adds for LOCALHOST, one on 0.0.0.0
and one per non-loopback interface address.  No TCP socket at all.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

from rosutil import RosSession

from fsreg_ros.core.scenario import load_scenario
from fsreg_ros.core.simulation.simulator import Options
from fsreg_ros.tools.graph import Graph, graph_nodes
from fsreg_ros.ros.network import (
    ALLOW_NETWORK,
    PROFILE_VARIABLES,
    NetworkRefused,
    check_loopback,
    loopback_profile,
    ros_environment,
)

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent
LOOPBACK = "127.0.0.1"
CLEAN = {"PATH": os.environ.get("PATH", ""), "ROS_LOG_DIR": os.environ["ROS_LOG_DIR"]}


def dds_ports(domain: int, participants: int = 120) -> set[int]:
    """The RTPS well-known ports of a domain (multicast, then two unicast per participant)."""
    base = 7400 + 250 * domain
    return {base, base + 1} | {base + 10 + 2 * i for i in range(participants)} | {
        base + 11 + 2 * i for i in range(participants)
    }


def ephemeral_range() -> range:
    low, high = Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()
    return range(int(low), int(high) + 1)


def interface_addresses() -> set[str]:
    """The host's non-loopback IPv4 addresses."""
    return {
        a.address for addrs in psutil.net_if_addrs().values() for a in addrs
        if a.family.name == "AF_INET" and not a.address.startswith("127.")
    }


# ------------------------------------------------------------------ environment
def test_the_test_process_runs_with_the_loopback_profile():
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    for name in PROFILE_VARIABLES:
        assert os.environ[name] == str(loopback_profile())
    assert loopback_profile() == REPO / "config" / "fastdds_localhost.xml"


def test_default_environment_is_loopback_with_the_profile():
    env = ros_environment(CLEAN)
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert env["FASTRTPS_DEFAULT_PROFILES_FILE"] == env["FASTDDS_DEFAULT_PROFILES_FILE"] == str(loopback_profile())
    assert 20 <= int(env["ROS_DOMAIN_ID"]) < 90


@pytest.mark.parametrize(
    "variable, value, said",
    [
        ("ROS_AUTOMATIC_DISCOVERY_RANGE", "", "ROS_AUTOMATIC_DISCOVERY_RANGE='' would send DDS discovery off"),
        ("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNET", "ROS_AUTOMATIC_DISCOVERY_RANGE='SUBNET' would send"),
        ("ROS_AUTOMATIC_DISCOVERY_RANGE", "localhost", "ROS_AUTOMATIC_DISCOVERY_RANGE='localhost' would send"),
        ("ROS_STATIC_PEERS", "192.0.2.7", "ROS_STATIC_PEERS='192.0.2.7' would connect DDS to other machines"),
        ("ROS_DISCOVERY_SERVER", "10.0.0.1:11811", "ROS_DISCOVERY_SERVER='10.0.0.1:11811' would connect"),
        ("FASTRTPS_DEFAULT_PROFILES_FILE", "/etc/my.xml", "FASTRTPS_DEFAULT_PROFILES_FILE='/etc/my.xml' replaces"),
    ],
)
def test_a_widening_environment_is_refused(variable, value, said):
    with pytest.raises(NetworkRefused) as err:
        ros_environment({**CLEAN, variable: value})
    assert str(err.value).startswith(said)
    assert f"{ALLOW_NETWORK}=1" in str(err.value) and "\n" not in str(err.value)


def test_allow_network_leaves_the_users_choice_alone():
    env = ros_environment({**CLEAN, ALLOW_NETWORK: "1", "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET",
                           "ROS_STATIC_PEERS": "192.0.2.7"})
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SUBNET" and env["ROS_STATIC_PEERS"] == "192.0.2.7"
    assert not any(name in env for name in PROFILE_VARIABLES)
    assert ros_environment({**CLEAN, ALLOW_NETWORK: "1"})["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"


def test_an_empty_static_peers_list_is_no_peer():
    check_loopback({**CLEAN, "ROS_STATIC_PEERS": ""})


@pytest.mark.parametrize("variable, value", [("ROS_AUTOMATIC_DISCOVERY_RANGE", ""), ("ROS_STATIC_PEERS", "10.1.2.3")])
def test_fsreg_graph_refuses_with_one_line_and_exit_2(tmp_path, variable, value):
    env = {**os.environ, variable: value}
    env.pop(ALLOW_NETWORK, None)
    proc = subprocess.run([str(BIN / "fsreg-graph"), str(tmp_path / "never-read.yaml")],
                          env=env, capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert proc.stderr.startswith(f"fsreg-graph: error: {variable}={value!r} ")
    assert proc.stderr.count("\n") == 1 and "Traceback" not in proc.stderr


def test_rosenv_refuses_static_peers_and_exports_the_profile():
    script = 'set -e; . scripts/rosenv.sh; echo "$FASTRTPS_DEFAULT_PROFILES_FILE $ROS_AUTOMATIC_DISCOVERY_RANGE"'
    env = {**os.environ, "FSREG_PYTHON": sys.executable}
    env.pop(ALLOW_NETWORK, None)
    ok = subprocess.run(["bash", "-c", script], cwd=REPO, env=env, capture_output=True, text=True, timeout=60)
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout == f"{loopback_profile()} LOCALHOST\n"
    bad = subprocess.run(["bash", "-c", script], cwd=REPO, env={**env, "ROS_STATIC_PEERS": "10.1.2.3"},
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and bad.stdout == ""
    assert "error: ROS_STATIC_PEERS='10.1.2.3' would connect DDS to other machines" in bad.stderr
    assert bad.stderr.count("\n") == 1


# ---------------------------------------------------------------------- sockets
@pytest.mark.graph
@pytest.mark.slow
def test_every_node_process_listens_on_loopback_only(table1_path, tmp_path):
    scenario = load_scenario(table1_path)
    nodes = graph_nodes(scenario, table1_path, Options(), tmp_path / "result.json")[:-1]  # all but the player
    graph = Graph(nodes, tmp_path)
    assert graph.env["FASTRTPS_DEFAULT_PROFILES_FILE"] == str(loopback_profile())
    try:
        graph.start()
        with RosSession() as probe:  # one real round trip: the graph talks over the profile's transports
            status = probe.call("/wm_manager/status", {}, timeout=30.0)
            assert status["domains"] and probe.call("/consultant/faces", {"op": "info"}, timeout=30.0)
        time.sleep(0.5)
        domain, ephemeral, interfaces = int(graph.env["ROS_DOMAIN_ID"]), ephemeral_range(), interface_addresses()
        for spec, proc in graph.procs:
            assert proc.poll() is None, graph.tail(spec.name)
            sockets = psutil.Process(proc.pid).net_connections(kind="inet")
            assert all(s.type.name == "SOCK_DGRAM" for s in sockets), (spec.name, sockets)
            receiving = [s.laddr for s in sockets if s.laddr.ip == LOOPBACK]
            others = [s.laddr for s in sockets if s.laddr.ip != LOOPBACK]
            assert len([a for a in receiving if a.port in dds_ports(domain)]) == 2, (spec.name, receiving)
            assert sorted(a.ip for a in others) == sorted({"0.0.0.0"} | interfaces), (spec.name, others)
            assert all(a.port in ephemeral and a.port not in dds_ports(domain) for a in others), (spec.name, others)
    finally:
        graph.stop()


@pytest.mark.parametrize("script", ["soak.py", "fuzz.py", "bench_facts.py", "bench_graph.py", "bench_rss.py"])
def test_the_scripts_refuse_a_widening_environment(script):
    env = {**os.environ, "ROS_AUTOMATIC_DISCOVERY_RANGE": "SUBNET"}
    env.pop(ALLOW_NETWORK, None)
    proc = subprocess.run([sys.executable, str(REPO / "scripts" / script)], env=env, capture_output=True, text=True,
                          timeout=60)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr == (f"{script}: error: ROS_AUTOMATIC_DISCOVERY_RANGE='SUBNET' would send DDS discovery off "
                           "this machine (fsreg needs LOCALHOST); unset it, or set FSREG_ALLOW_NETWORK=1 to use "
                           "the network deliberately (docs/deployment.md)\n")


# ------------------------------------------------------------------ node processes
def node_env(**changes: str) -> dict:
    """The environment ``ros2 run`` would give a node: the user's, with no fsreg variables set for it."""
    env = {k: v for k, v in os.environ.items()
           if k not in (*PROFILE_VARIABLES, "ROS_AUTOMATIC_DISCOVERY_RANGE", ALLOW_NETWORK)}
    env.update(changes)
    return env


@pytest.mark.parametrize(
    "variable, value, said",
    [
        ("FASTDDS_ENVIRONMENT_FILE", "/tmp/fastdds_env.json",
         "FASTDDS_ENVIRONMENT_FILE='/tmp/fastdds_env.json' lets Fast DDS read a discovery server or peers"),
        ("ROS_DISCOVERY_SERVER", "127.0.0.1:11811", "ROS_DISCOVERY_SERVER='127.0.0.1:11811' would connect DDS"),
        ("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNET", "ROS_AUTOMATIC_DISCOVERY_RANGE='SUBNET' would send"),
    ],
)
def test_a_node_started_by_hand_refuses_a_widening_environment(tmp_path, variable, value, said):
    """The node itself enforces the policy (``ros2 run`` and the launch file start it without any runner)."""
    proc = subprocess.run([str(BIN / "parser")], env=node_env(**{variable: value}), cwd=tmp_path,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2
    assert proc.stderr.startswith(f"parser: error: {said}") and proc.stderr.count("\n") == 1, proc.stderr
    assert f"{ALLOW_NETWORK}=1" in proc.stderr


@pytest.mark.parametrize("name", ["DEFAULT_FASTRTPS_PROFILES.xml", "DEFAULT_FASTDDS_PROFILES.xml"])
def test_a_profile_in_the_working_directory_is_refused_by_nodes_and_runners(tmp_path, name):
    """Fast DDS loads such a file after ours, replacing the loopback profile."""
    (tmp_path / name).write_text("<profiles/>\n")
    node = subprocess.run([str(BIN / "parser")], env=node_env(), cwd=tmp_path, capture_output=True, text=True,
                          timeout=60)
    runner = subprocess.run([str(BIN / "fsreg-graph"), "never-read.yaml"], env=node_env(), cwd=tmp_path,
                            capture_output=True, text=True, timeout=60)
    for proc, prog in ((node, "parser"), (runner, "fsreg-graph")):
        assert proc.returncode == 2, proc.stderr
        assert proc.stderr == (f"{prog}: error: {tmp_path / name} (a Fast DDS profile in the working directory) "
                               "replaces fsreg's loopback profile; move it, run from another directory, or set "
                               f"{ALLOW_NETWORK}=1 to use the network deliberately (docs/deployment.md)\n")
    with pytest.raises(NetworkRefused):
        check_loopback(CLEAN, cwd=str(tmp_path))
    check_loopback(CLEAN, cwd=str(REPO))


@pytest.mark.graph
def test_a_node_started_without_any_fsreg_environment_listens_on_loopback_only(tmp_path):
    """As ``ros2 run fsreg_ros parser`` starts it: no profile variable, no discovery range; the node loads the
    loopback profile itself, so every socket it receives on is bound to 127.0.0.1."""
    log = tmp_path / "parser.log"
    with open(log, "wb") as out:
        proc = subprocess.Popen([str(BIN / "parser")], env=node_env(), cwd=tmp_path, stdout=out,
                                stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 30
        while b"parser ready" not in log.read_bytes():
            assert proc.poll() is None and time.monotonic() < deadline, log.read_text()
            time.sleep(0.05)
        domain = int(os.environ["ROS_DOMAIN_ID"])
        sockets = psutil.Process(proc.pid).net_connections(kind="inet")
        receiving = [s.laddr for s in sockets if s.laddr.port in dds_ports(domain)]
        assert len(receiving) == 2 and all(a.ip == LOOPBACK for a in receiving), sockets
        assert all(s.laddr.ip in {LOOPBACK, "0.0.0.0"} | interface_addresses() for s in sockets)
        assert all(s.laddr.ip == LOOPBACK or s.laddr.port in ephemeral_range() for s in sockets), sockets
    finally:
        proc.terminate()
        proc.wait(timeout=10)


@pytest.mark.graph
@pytest.mark.slow
def test_no_fast_dds_line_reaches_a_tool_after_a_kill_9_or_with_an_unlockable_port(tmp_path):
    """No Fast DDS log line on a tool's stdout or stderr (issue 37 item 7): its answer is the one line.

    A node process killed with SIGKILL leaves its shared-memory port files in ``/dev/shm``; and
    when Fast DDS cannot lock a port file it logged ``RTPS_TRANSPORT_SHM Error ... Failed init_port
    fastrtps_portNNNN: open_and_lock_file failed`` (in CI, before a tool's answer).  Here a parser
    of a domain of its own is killed with SIGKILL, and the lock files of that domain's first
    ports are symlink loops, so that opening them fails as it did in CI.  The loopback profile
    turns Fast DDS's log off.
    """
    domain = (int(os.environ["ROS_DOMAIN_ID"]) + 117) % 230
    env = {**node_env(), "ROS_DOMAIN_ID": str(domain)}
    ports = [7400 + 250 * domain + 11 + 2 * i for i in range(4)]
    log = tmp_path / "parser.log"
    with open(log, "wb") as out:
        parser = subprocess.Popen([str(BIN / "parser")], env=env, cwd=tmp_path, stdout=out, stderr=subprocess.STDOUT)
    try:
        deadline = time.monotonic() + 30
        while b"parser ready" not in log.read_bytes():
            assert parser.poll() is None and time.monotonic() < deadline, log.read_text()
            time.sleep(0.05)
        left = [port for port in ports if Path(f"/dev/shm/fastrtps_port{port}").exists()]
        assert left, "the parser opened no shared-memory port of its domain"
    finally:
        parser.kill()  # SIGKILL: its port files stay behind
        parser.wait(timeout=10)
    assert all(Path(f"/dev/shm/fastrtps_port{port}").exists() for port in left)  # stale, as kill -9 leaves them
    locks = [Path(f"/dev/shm/fastrtps_port{port}_el") for port in ports]
    for lock in locks:
        lock.unlink(missing_ok=True)
        lock.symlink_to(lock)
    try:
        proc = subprocess.run([str(BIN / "fsreg-ctl"), "--namespace", "nobody_here", "status", "--json",
                               "--timeout", "1"], env=env, cwd=tmp_path, capture_output=True, text=True, timeout=60)
    finally:
        for lock in locks:
            lock.unlink(missing_ok=True)
    assert (proc.returncode, proc.stdout) == (3, "")
    assert proc.stderr == (f"fsreg-ctl: error: no fsreg graph answers in namespace /nobody_here on "
                           f"ROS domain {domain} (is fsreg-up running there?): nothing within 1 s\n")
