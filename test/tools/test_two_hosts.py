"""Two hosts over DDS: the consultant on one "computer", every other node on another (issue 15, item 6).

Two Linux network namespaces stand for the two computers of a robot, joined by a veth
pair (a point-to-point link with a private /30 of its own).  The consultant runs in the
first, the WM Manager, parser, RR, REG and the dialogue player in the second, each
process started by the runner (``fsreg_ros.tools.graph.Graph``) through ``ip netns exec``.
The network is widened deliberately, as docs/deployment.md says: ``FSREG_ALLOW_NETWORK=1``
and, on each side, a Fast DDS profile whose only transport is UDPv4 whitelisting that
side's veth address, with the other side's address as the initial peer (unicast
discovery; no multicast, no shared memory, no loopback).  Table 1 is played under decay
and must equal the simulator's result and trace exactly; every DDS socket of every node
must be bound to its veth address.  The namespaces (and with them the veth pair) are
removed afterwards, also when the test fails; traffic never leaves the veth pair, and
the run ends by itself (the runner's deadline).

Skipped, with the reason, only where network namespaces cannot be created (not root, no
``ip``, or a kernel/container that refuses).
"""

from __future__ import annotations

import atexit
import json
import os
import secrets
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from fsreg_ros.core.scenario import load_scenario
from fsreg_ros.core.simulation.simulator import Options, Simulation, dumps
from fsreg_ros.tools.graph import Graph, graph_nodes, new_graph_id, unique_namespace

pytestmark = [pytest.mark.graph, pytest.mark.slow]

PROFILE = """<?xml version="1.0" encoding="UTF-8" ?>
<dds xmlns="http://www.eprosima.com/XMLSchemas/fastRTPS_Profiles">
  <profiles>
    <transport_descriptors>
      <transport_descriptor>
        <transport_id>fsreg_two_hosts</transport_id>
        <type>UDPv4</type>
        <interfaceWhiteList><address>{own}</address></interfaceWhiteList>
        <maxInitialPeersRange>32</maxInitialPeersRange>
      </transport_descriptor>
    </transport_descriptors>
    <participant profile_name="fsreg_two_hosts" is_default_profile="true">
      <rtps>
        <userTransports><transport_id>fsreg_two_hosts</transport_id></userTransports>
        <useBuiltinTransports>false</useBuiltinTransports>
        <builtin>
          <initialPeersList>
            <locator><udpv4><address>{peer}</address></udpv4></locator>
            <locator><udpv4><address>{own}</address></udpv4></locator>
          </initialPeersList>
          <metatrafficUnicastLocatorList>
            <locator><udpv4><address>{own}</address></udpv4></locator>
          </metatrafficUnicastLocatorList>
        </builtin>
      </rtps>
    </participant>
  </profiles>
</dds>
"""


def ip(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30)


class Hosts:
    """Two network namespaces joined by a veth pair; removed by :meth:`remove` (and at exit, whatever happens)."""

    def __init__(self) -> None:
        tag = secrets.token_hex(3)
        self.names = (f"fsreg-{tag}-a", f"fsreg-{tag}-b")
        octet = 16 + secrets.randbelow(200)
        self.addresses = (f"10.231.{octet}.1", f"10.231.{octet}.2")
        self.links = (f"fsr{tag}a", f"fsr{tag}b")
        atexit.register(self.remove)

    def create(self) -> None:
        """Create both namespaces and the link; raise RuntimeError with ``ip``'s words if any step is refused."""
        a, b = self.names
        steps = [("netns", "add", a), ("netns", "add", b),
                 ("link", "add", self.links[0], "type", "veth", "peer", "name", self.links[1]),
                 ("link", "set", self.links[0], "netns", a), ("link", "set", self.links[1], "netns", b)]
        for ns, link, address in zip(self.names, self.links, self.addresses):
            steps += [("-n", ns, "addr", "add", f"{address}/30", "dev", link), ("-n", ns, "link", "set", link, "up"),
                      ("-n", ns, "link", "set", "lo", "up")]  # a host reaches its own address through lo
        for step in steps:
            done = ip(*step)
            if done.returncode != 0:
                raise RuntimeError(f"'ip {' '.join(step)}' failed: {done.stderr.strip()}")

    def remove(self) -> None:
        for ns in self.names:
            ip("netns", "del", ns)  # takes its end of the veth pair, and so the pair, with it

    def exists(self) -> bool:
        listed = ip("netns", "list").stdout
        return any(name in listed for name in self.names)


def sockets_of(pid: int) -> list[tuple[str, str, int]]:
    """Return the (protocol, local address, port) of every socket of process ``pid``, read in its own network
    namespace (``/proc/<pid>/net``: psutil reads the caller's)."""
    inodes = set()
    for fd in Path(f"/proc/{pid}/fd").iterdir():
        try:
            target = os.readlink(fd)
        except OSError:
            continue
        if target.startswith("socket:["):
            inodes.add(target[8:-1])
    found = []
    for protocol in ("udp", "tcp", "udp6", "tcp6"):
        try:
            lines = Path(f"/proc/{pid}/net/{protocol}").read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            fields = line.split()
            if fields[9] in inodes:
                address, port = fields[1].split(":")
                if len(address) == 8:  # IPv4, little-endian hex
                    address = ".".join(str(int(address[i:i + 2], 16)) for i in (6, 4, 2, 0))
                found.append((protocol, address, int(port, 16)))
    return found


def can_create_namespaces() -> str:
    """Return why network namespaces cannot be made here ('' when they can)."""
    if os.geteuid() != 0:
        return "network namespaces need root"
    if shutil.which("ip") is None:
        return "the 'ip' tool (iproute2) is not installed"
    probe = f"fsreg-probe-{secrets.token_hex(3)}"
    made = ip("netns", "add", probe)
    ip("netns", "del", probe)
    return "" if made.returncode == 0 else f"'ip netns add' is refused here: {made.stderr.strip()}"


def test_table1_with_the_consultant_on_another_host_equals_the_simulator(table1_path, tmp_path):
    reason = can_create_namespaces()
    if reason:
        pytest.skip(reason)
    hosts = Hosts()
    try:
        try:
            hosts.create()
        except RuntimeError as err:
            pytest.skip(f"cannot build the two hosts: {err}")
        profiles = []
        for own, peer, side in zip(hosts.addresses, reversed(hosts.addresses), "ab"):
            path = tmp_path / f"profile-{side}.xml"
            path.write_text(PROFILE.format(own=own, peer=peer))
            profiles.append(path)
        env = {k: v for k, v in os.environ.items() if not k.startswith(("FASTRTPS_", "FASTDDS_", "ROS_STATIC"))}
        env.update(FSREG_ALLOW_NETWORK="1", ROS_AUTOMATIC_DISCOVERY_RANGE="SYSTEM_DEFAULT")

        def place(spec):
            side = 0 if spec.executable == "consultant" else 1
            return (["ip", "netns", "exec", hosts.names[side]],
                    {"FASTRTPS_DEFAULT_PROFILES_FILE": str(profiles[side]),
                     "FASTDDS_DEFAULT_PROFILES_FILE": str(profiles[side])})

        scenario = load_scenario(table1_path)
        options = Options(memory={"policy": "decay"})
        output, trace = tmp_path / "result.json", tmp_path / "trace.jsonl"
        nodes = graph_nodes(scenario, table1_path, options, output, trace, graph=new_graph_id("two-hosts"))
        graph = Graph(nodes, tmp_path, env, unique_namespace(), place=place, allow_network=True)
        sockets: dict[str, set] = {}
        try:
            graph.start()
            deadline = time.monotonic() + 180
            while graph.process("dialogue_player").poll() is None:
                assert time.monotonic() < deadline, graph.tail("dialogue_player")
                dead = [(s.name, c) for s, c in graph.dead() if s.name != "dialogue_player"]
                assert not dead, (dead, [graph.tail(name) for name, _ in dead])
                for spec, proc in graph.procs:  # every socket each node has while the graph runs
                    if proc.poll() is None:
                        sockets.setdefault(spec.name, set()).update(sockets_of(proc.pid))
                time.sleep(0.2)
            assert graph.process("dialogue_player").returncode == 0, graph.tail("dialogue_player")
        finally:
            graph.stop()
        simulation = Simulation(scenario, options, trace=True)
        assert output.read_text() == dumps(simulation.run())
        assert [json.loads(line) for line in trace.read_text().splitlines()] == simulation.trace()
        # Every socket of every node (seen while the run went on) is a UDP socket on its own side's veth
        # address: nothing on 0.0.0.0, loopback or another interface.
        assert set(sockets) == {spec.name for spec in nodes}
        for name, conns in sockets.items():
            own = hosts.addresses[0 if name.startswith("consultant") else 1]
            assert conns and all(protocol == "udp" and address == own for protocol, address, _ in conns), (name, conns)
    finally:
        hosts.remove()
    assert not hosts.exists()


def test_the_profiles_are_what_docs_deployment_shows():
    """docs/deployment.md describes this test; its profile is this one."""
    docs = (Path(__file__).resolve().parents[2] / "docs" / "deployment.md").read_text()
    assert "<interfaceWhiteList><address>{own}</address></interfaceWhiteList>" in docs
    assert "test/tools/test_two_hosts.py" in docs
