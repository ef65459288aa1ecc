"""``fsreg-graph``: run a scenario through the real multi-process ROS 2 node graph.

Starts every node as its own process, as ``ros2 run fsreg_ros <node>`` would (one
``consultant`` per domain, ``wm_manager``, ``parser``, ``reference_resolution``,
``reg`` and finally ``dialogue_player``), all on sim time driven by the player,
waits for the player to finish, and shuts everything down.  It takes the same
options as ``fsreg-sim`` and gives the same output (``--json`` byte-identical).
The nodes and their parameters come from :mod:`fsreg_ros.ros.graph_spec` (as the launch
file's do).  Every run is a graph of its own: under ``--namespace NS``, or by default a
namespace made for it (``/fsreg_<random>``), every node starts with ``-r __ns:=/NS`` and
``/clock`` remapped to ``/NS/clock`` (see :func:`fsreg_ros.contract.clock_remap`), so
runs share a ROS domain without hearing each other; and every node gets the run's graph
identity (``-p graph:=...``), which it stamps on what it publishes and the player checks
on every answer and event (a message of another graph fails the run).  A namespace
given explicitly is first checked for a graph already running there (one line naming
it, exit 1).

Process hygiene: every child gets ``PR_SET_PDEATHSIG`` = SIGTERM (it dies with
the runner even if the runner is SIGKILLed) and all children share one process
group, which is sent SIGTERM (then SIGKILL after a grace period) on exit,
Ctrl-C or a failed node.  Node output goes to log files, whose tails are shown
when something fails.

Networking: every node gets :func:`fsreg_ros.ros.network.ros_environment` (loopback
only; a widening environment is refused with exit 2 unless FSREG_ALLOW_NETWORK=1).
"""

from __future__ import annotations

import argparse
import ctypes
import json
import os
import secrets
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Callable, Optional, Sequence

from .sim import needs_trace, run_cli, warn_unsayable
from ..contract import CLOCK, GRAPH_PARAMETER, clock_remap, normalise_namespace
from ..ros.graph_spec import PACKAGE, NodeSpec, node_specs, player_spec, policy_settings, resolved
from ..core.lexicon import Lexicon
from ..core.scenario import Scenario, load_scenario
from ..core.simulation.simulator import Options, effective_policies
from ..ros.network import require_loopback, ros_environment

#: Seconds to wait for the player: start-up allowance plus an allowance per turn
#: (the player drives /clock, so a dialogue's own seconds cost no wall time).
RUN_DEADLINE = 120.0
TURN_ALLOWANCE = 1.0
GRACE = 5.0


class GraphError(RuntimeError):
    """A node failed to start, died, or the run exceeded its deadline."""


def executable(name: str) -> list[str]:
    """Return the command that ``ros2 run fsreg_ros <name>`` would run.

    A colcon install (on ``AMENT_PREFIX_PATH``) wins; then the console script beside
    this Python (a venv); then ``python -m`` on the module.
    """
    try:
        from ament_index_python.packages import PackageNotFoundError, get_package_prefix

        try:
            candidate = Path(get_package_prefix(PACKAGE)) / "lib" / PACKAGE / name
            if candidate.is_file() and os.access(candidate, os.X_OK):
                return [str(candidate)]
        except (PackageNotFoundError, OSError):  # not installed by colcon / no AMENT_PREFIX_PATH
            pass
    except ImportError:  # pragma: no cover - ament_index comes with rclpy
        pass
    beside = Path(sys.executable).parent / name
    if beside.is_file():
        return [str(beside)]
    found = shutil.which(name)
    if found:
        return [found]
    return [sys.executable, "-m", f"{PACKAGE}.nodes.{name}"]


def _param(value: object) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(str(v) for v in value) + "]"
    return str(value) if value != "" else "''"  # rcl reads '-p name:=' as no value, '' as the empty text


def unique_namespace(prefix: str = "fsreg") -> str:
    """Return a namespace of its own for one graph: ``/<prefix>_<12 random hex digits>``."""
    return f"/{prefix}_{secrets.token_hex(6)}"


def new_graph_id(runner: str) -> str:
    """Return a new graph identity: the runner's name and 8 random hex digits (``fsreg-up-1a2b3c4d``)."""
    return f"{runner}-{secrets.token_hex(4)}"


def clock_arguments(namespace: str, clock: Optional[str] = None) -> list[str]:
    """Return the ``--ros-args`` remapping of ``/clock`` for a graph.

    ``clock`` names the topic to follow; None means the graph's own (``<namespace>/clock``
    under a namespace, :func:`fsreg_ros.contract.clock_remap`; ``/clock`` otherwise).
    """
    if clock is None:
        return clock_remap(namespace)
    return [] if clock == CLOCK else ["-r", f"{CLOCK}:={clock}"]


def command(spec: NodeSpec, namespace: str = "", clock: Optional[str] = None) -> list[str]:
    """Return the command line of one node process, under ``namespace`` if given.

    A namespaced graph also gets its own clock (``/clock`` remapped into the namespace,
    :func:`fsreg_ros.contract.clock_remap`): two sim-time graphs on one domain would
    otherwise each jump the other's time.  ``clock`` names another clock topic to follow.
    """
    cmd = executable(spec.executable) + ["--ros-args", "-r", f"__node:={spec.name}"]
    if namespace:
        cmd += ["-r", f"__ns:={namespace}"]
    cmd += clock_arguments(namespace, clock)
    for key, value in spec.parameters.items():
        cmd += ["-p", f"{key}:={_param(value)}"]
    return cmd


def with_identity(nodes: Sequence[NodeSpec], graph: str) -> list[NodeSpec]:
    """Return ``nodes`` with the graph identity ``graph`` as every node's ``graph`` parameter."""
    return [NodeSpec(spec.executable, spec.name, {**spec.parameters, GRAPH_PARAMETER: graph}) for spec in nodes]


def live_nodes(
    scenario: Scenario,
    scenario_path: Path,
    options: Options,
    *,
    graph: str = "",
    lexicon: Optional[Path] = None,
    state_dir: Optional[str] = None,
    use_sim_time: bool = True,
) -> list[NodeSpec]:
    """Return the live graph's nodes for a scenario (no player), from :mod:`fsreg_ros.ros.graph_spec`.

    The scenario gives the domains (and their knowledge), the memory settings (its own,
    with ``options`` merged over them) and, with ``lexicon``, the words; its dialogue is
    not used.  ``graph`` is the identity every node stamps on what it publishes
    ('' = none); ``state_dir`` the consultants' state directory (None: their default).
    """
    policies = {d: policy_settings(p) for d, p in effective_policies(scenario, options).items()}
    nodes = node_specs(resolved(scenario_path), list(scenario.domains), policies, use_sim_time=use_sim_time,
                       algorithm=options.algorithm, wm_order=options.wm_order, lexicon=resolved(lexicon),
                       state_dir=state_dir)
    return with_identity(nodes, graph) if graph else nodes


def graph_nodes(
    scenario: Scenario,
    scenario_path: Path,
    options: Options,
    output: Path,
    trace: Optional[Path] = None,
    lexicon: Optional[Path] = None,
    graph: str = "",
) -> list[NodeSpec]:
    """Return the node processes for one scenario run (the player last), from :mod:`fsreg_ros.ros.graph_spec`.

    The consultants keep their state databases beside ``output`` (a run starts from the KB).
    """
    kb = resolved(scenario_path)
    nodes = live_nodes(scenario, scenario_path, options, lexicon=lexicon,
                       state_dir=str(Path(output).resolve().parent / "state"))
    nodes.append(player_spec(kb, str(output), str(trace) if trace is not None else None, resolved(lexicon)))
    return with_identity(nodes, graph) if graph else nodes


def _die_with_parent() -> None:  # runs in the child between fork and exec
    PR_SET_PDEATHSIG = 1
    ctypes.CDLL("libc.so.6", use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGTERM)


#: Where a node process runs: (command prefix, environment changes) for a node, e.g. ``ip netns exec NS``.
Placement = Callable[[NodeSpec], tuple[list[str], dict]]


class Graph:
    """The running node processes of one scenario run (or of a live graph).

    ``env`` is the base environment (:func:`fsreg_ros.ros.network.ros_environment` is applied
    to it); ``clock`` the clock topic to follow (None: the graph's own, see
    :func:`clock_arguments`); ``place`` may run a node elsewhere (a command prefix and
    environment changes per node; tests use it for network namespaces).
    """

    def __init__(self, nodes: Sequence[NodeSpec], log_dir: Path, env: Optional[dict] = None,
                 namespace: str = "", *, clock: Optional[str] = None, place: Optional[Placement] = None,
                 allow_network: Optional[bool] = None) -> None:
        self.nodes = list(nodes)
        self.namespace = normalise_namespace(namespace)
        self.log_dir = log_dir
        self.env = ros_environment(env, allow_network)
        self.clock = clock
        self.place = place
        self.procs: list[tuple[NodeSpec, subprocess.Popen]] = []
        self.group: Optional[int] = None
        self.restarts: dict[str, int] = {}

    def _spawn(self, spec: NodeSpec, log_name: str) -> subprocess.Popen:
        prefix, changes = self.place(spec) if self.place is not None else ([], {})
        with open(self.log_dir / log_name, "ab") as log:
            proc = subprocess.Popen(
                prefix + command(spec, self.namespace, self.clock),
                env={**self.env, **changes},
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=subprocess.STDOUT,
                preexec_fn=_die_with_parent,
                process_group=0 if self.group is None else self.group,
            )
        if self.group is None:
            self.group = proc.pid
        return proc

    def start(self, count: Optional[int] = None) -> None:
        """Start the nodes not started yet (``count``: only up to the ``count``-th node of the graph)."""
        for spec in self.nodes[len(self.procs):count]:
            self.procs.append((spec, self._spawn(spec, f"{spec.name}.log")))

    def restart(self, name: str, kill: bool = True) -> subprocess.Popen:
        """Start node ``name`` again (first SIGKILLing it if it still runs, as a crash would), as a supervisor does.

        Its output goes on in ``<name>.log`` after a marker line.
        """
        index = next(i for i, (spec, _) in enumerate(self.procs) if spec.name == name)
        spec, proc = self.procs[index]
        if kill and proc.poll() is None:
            proc.send_signal(signal.SIGKILL)
        proc.wait()
        self.restarts[name] = self.restarts.get(name, 0) + 1
        with open(self.log_dir / f"{spec.name}.log", "ab") as log:
            log.write(f"--- restarted ({self.restarts[name]}) after exit {proc.returncode} ---\n".encode())
        new = self._spawn(spec, f"{spec.name}.log")
        self.procs[index] = (spec, new)
        return new

    def process(self, name: str) -> subprocess.Popen:
        """Return the process of node ``name``."""
        return next(p for s, p in self.procs if s.name == name)

    def dead(self) -> list[tuple[NodeSpec, int]]:
        """Return the nodes that have exited, with their exit codes."""
        return [(spec, proc.returncode) for spec, proc in self.procs if proc.poll() is not None]

    def wait_for(self, name: str, deadline: float) -> int:
        """Wait for node ``name`` to exit; fail early if any other node dies first."""
        target = next(p for s, p in self.procs if s.name == name)
        while True:
            code = target.poll()
            if code is not None:
                return code
            for spec, proc in self.procs:
                if proc is not target and proc.poll() is not None:
                    raise GraphError(f"node '{spec.name}' exited with code {proc.returncode}\n{self.tail(spec.name)}")
            if time.monotonic() > deadline:
                raise GraphError(f"'{name}' did not finish in time\n{self.tail(name)}")
            time.sleep(0.02)

    def tail(self, name: str, lines: int = 15) -> str:
        """Return the last lines of node ``name``'s log, each prefixed with its name."""
        path = self.log_dir / f"{name}.log"
        text = path.read_text(errors="replace").splitlines()[-lines:] if path.exists() else []
        return "\n".join(f"  [{name}] {line}" for line in text)

    def stop(self) -> None:
        """SIGTERM the process group, then SIGKILL whatever is left after a grace period."""
        if self.group is None:
            return
        alive = [p for _, p in self.procs if p.poll() is None]
        if alive:
            try:
                os.killpg(self.group, signal.SIGTERM)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + GRACE
        for proc in alive:
            try:
                proc.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                pass
        if any(p.poll() is None for _, p in self.procs):
            try:
                os.killpg(self.group, signal.SIGKILL)
            except ProcessLookupError:
                pass
            for _, proc in self.procs:
                proc.wait()


def run_graph(
    scenario_path: Path,
    options: Options,
    trace: bool = False,
    env: Optional[dict] = None,
    lexicon: Optional[Path] = None,
    namespace: Optional[str] = None,
    record: Optional[Path] = None,
) -> tuple[dict, list[dict]]:
    """Play a scenario through the multi-process graph; return (result, trace).

    The run is a graph of its own: under ``namespace`` (None: a new unique one, '': the
    root namespace) and with a new graph identity that every node stamps and the
    player checks.  ``record``: record every topic to this new rosbag2 folder
    (:mod:`fsreg_ros.ros.recorder`, subscribed before any node starts; the player is started
    only once the recorder matched every writer of the graph, :func:`wait_recorded`, and
    waits for its readers too), then check that it holds every answer and WM event
    (GraphError if not).
    """
    words = Lexicon.load(lexicon)
    scenario = load_scenario(scenario_path, words)  # bad input fails here, before any process
    warn_unsayable("fsreg-graph", words, scenario)
    namespace = unique_namespace() if namespace is None else namespace
    with tempfile.TemporaryDirectory(prefix="fsreg-graph-") as tmp:
        tmp_path = Path(tmp)
        output, trace_file = tmp_path / "result.json", (tmp_path / "trace.jsonl" if trace else None)
        identity = new_graph_id("fsreg-graph")
        nodes = graph_nodes(scenario, scenario_path, options, output, trace_file, lexicon, graph=identity)
        graph = Graph(nodes, tmp_path, env, namespace)
        recorder = None
        if record is not None:
            recorder = start_recorder(record, namespace, identity, scenario_path, options, lexicon)
            nodes[-1].parameters["listeners"] = 1  # the player waits for the recorder's subscriptions too
        try:
            if recorder is not None:  # the player last: turn 1 only once the recording hears every writer
                graph.start(len(nodes) - 1)
                wait_recorded(graph, recorder.recorder, list(scenario.domains))
            graph.start()
            deadline = time.monotonic() + RUN_DEADLINE + TURN_ALLOWANCE * len(scenario.dialogue)
            code = graph.wait_for("dialogue_player", deadline)
            if code != 0 or not output.exists():
                raise GraphError(f"dialogue_player failed (exit {code})\n{graph.tail('dialogue_player')}")
            result = json.loads(output.read_text())
            events = []
            if trace_file is not None and trace_file.exists():
                events = [json.loads(line) for line in trace_file.read_text().splitlines() if line]
        finally:
            graph.stop()
            if recorder is not None:
                recorder.close()
        if record is not None:
            check_recording(record, scenario)
        return result, events


def start_recorder(path: Path, namespace: str, identity: str, scenario_path: Path, options: Options,
                   lexicon: Optional[Path]):
    """Start recording the run's graph to ``path`` (a node of its own, spun in a thread)."""
    os.environ.update(ros_environment())  # before rclpy loads
    from ..core.io.recording import RecordingError
    from ..ros.recorder import RecorderThread

    custom = {"fsreg.graph": identity, "fsreg.namespace": namespace or "/",
              "fsreg.algorithm": options.algorithm or "auto", "fsreg.wm_order": options.wm_order}
    attach = {"scenario": scenario_path, **({"lexicon": lexicon} if lexicon else {})}
    try:
        return RecorderThread(path, namespace, custom=custom, attach=attach)
    except RecordingError as err:
        raise GraphError(f"--record: {err}") from None


def graph_writers(domains: Sequence[str]) -> dict[str, int]:
    """Return how many writers a scenario run's graph has (the player aside) on the topics it always writes."""
    from .. import contract

    each = len(domains)
    return {contract.SEMANTICS.name: 1, contract.RR_RESULT.name: 2, contract.REG_EXPRESSION.name: 1,
            contract.WM_STATE.name: each, contract.WM_EVENTS.name: each, contract.ANNOUNCE.name: each,
            contract.READY.name: 1}


def wait_recorded(graph: Graph, recorder, domains: Sequence[str]) -> None:
    """Wait until ``recorder`` matched every writer of the graph but the player (:meth:`Recorder.wait_matched`).

    The recorder has a participant of its own, so what it must match is counted
    (:func:`graph_writers`), not only discovered.  A node that dies meanwhile fails the
    run; a match still missing after the wait is one warning line.
    """
    def between() -> None:
        for spec, code in graph.dead():
            raise GraphError(f"node '{spec.name}' exited with code {code}\n{graph.tail(spec.name)}")
        time.sleep(0.05)

    warning = recorder.wait_matched(writers=graph_writers(domains), between=between)
    if warning is not None:
        print(f"fsreg-graph: warning: --record: {warning}", file=sys.stderr)


def check_recording(path: Path, scenario: Scenario) -> None:
    """Raise GraphError unless the recording holds an answer to every turn and every WM event without a gap."""
    from ..core.io.recording import open_recording
    from ..core.simulation.replay import ReplayError, check_events

    recording = open_recording(path)
    for speaker, role in (("human", "rr"), ("robot", "expression")):
        wanted = sum(1 for t in scenario.dialogue if t.speaker == speaker)
        heard = len({m.data.get("id") for m in recording.on(role) if isinstance(m.data, dict)})
        if heard < wanted:
            raise GraphError(f"recording {path} is incomplete: {heard} of {wanted} answers to {speaker} turns")
    try:
        check_events(str(path), [m.data for m in recording.on("events") if isinstance(m.data, dict)])
    except ReplayError as err:
        raise GraphError(f"recording incomplete: {err}") from None


def refuse_running_graph(namespace: str) -> None:
    """Raise GraphError naming the graph that already runs in ``namespace`` on this ROS domain, if one does."""
    os.environ.update(ros_environment())
    from ..ros.client import DISCOVERY_WAIT, find_graph  # rclpy: only once the environment is set

    running = find_graph(namespace, DISCOVERY_WAIT)
    if running is not None:
        raise GraphError(f"{running}; choose another --namespace")


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run ``fsreg-graph SCENARIO.yaml [--namespace NS] [options]``: the scenario through the node graph."""
    require_loopback("fsreg-graph")  # exits 2 if the environment would take DDS off this machine
    extra = argparse.ArgumentParser(add_help=False)
    extra.add_argument("--namespace", default=None)
    extra.add_argument("--record", type=Path, default=None)
    known, rest = extra.parse_known_args(sys.argv[1:] if argv is None else list(argv))
    if known.record is not None and known.record.exists():
        print(f"fsreg-graph: error: --record: {known.record} exists already; a recording goes to a new folder",
              file=sys.stderr)
        return 2
    namespace: Optional[str] = None  # each run its own
    if known.namespace is not None:
        try:
            namespace = normalise_namespace(known.namespace)
        except ValueError as err:
            print(f"fsreg-graph: error: --namespace: {err}", file=sys.stderr)
            return 2
    checked: list[bool] = []

    def graph_args(args: argparse.Namespace, options: Options) -> tuple[dict, list[dict]]:
        if namespace is not None and not checked:  # a namespace given: is a graph running there already?
            checked.append(True)
            refuse_running_graph(namespace)
        record = known.record
        if record is not None and (args.compare_policies or args.expect):  # one recording per compared policy
            record = record / f"{args.scenario.stem}-{options.memory.get('policy')}"
        # The trace only when an option writes it: alignment reads the result records alone.
        return run_graph(args.scenario, options, trace=needs_trace(args), lexicon=args.lexicon, namespace=namespace,
                         record=record)

    try:
        return run_cli(
            "fsreg-graph",
            "Play a scenario through the multi-process fsreg ROS 2 node graph (sim time). Each run is a graph of "
            "its own, in a namespace made for it; --namespace NS runs every node under the ROS namespace /NS "
            "instead, with its own NS/clock (refused if a graph already runs there). --record DIR records every "
            "topic to the rosbag2 folder DIR (with --compare-policies: DIR/<scenario>-<policy> per run).",
            graph_args,
            rest,
            failures=(GraphError,),
        )
    except KeyboardInterrupt:  # children are stopped by run_graph's finally
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
