"""A live fsreg graph for integration tests: started from a scenario, ready, talked to, torn down.

:class:`LiveGraph` starts the graph ``fsreg-up`` starts (one consultant per domain of
the scenario, the WM Manager, the parser, RR and REG; the scenario's dialogue is not
played) either in this process (every node in one executor, fast) or as one process per
node (``processes=True``, exactly as ``fsreg-up`` runs them), under a namespace of its
own (or on a ROS domain of its own), on sim time by default.  It waits until the graph
is ready and offers what a robot's dialogue manager does:

    from fsreg_ros.testing import LiveGraph

    with LiveGraph("scenarios/guess_who_table1.yaml", policy="decay", decay_period=10.0) as robot:
        robot.set_clock(1.0)
        assert robot.say("male, lab-coat, light-hair, glasses")["resolved"] == "face1"
        assert robot.wm("face1") == ["male", "lab-coat", "light-hair", "glasses"]
        robot.set_clock(11.0)                        # one decay tick: the oldest property goes
        assert robot.describe("face1")["text"] == "the person with a lab coat, light hair and glasses"

Every answer is checked to come from this graph (its identity is stamped on every
message); every wait is bounded and fails with a message naming what was awaited.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Mapping, Optional, Sequence, Union

from ..ros.client import ClientError, GraphClient
from ..contract import normalise_namespace
from ..core.forgetting.policies import PARAMETERS
from ..core.lexicon import Lexicon
from ..core.scenario import load_scenario
from ..core.simulation.simulator import Options
from ..tools.graph import Graph, live_nodes, new_graph_id, unique_namespace
from ..ros.diagnostics import Diagnostics
from ..ros.network import ros_environment
from ..ros.sim_clock import now_ns
from .ros_session import RosSession, Timeout

PathLike = Union[str, os.PathLike]


def node_classes() -> dict[str, Any]:
    """Return each executable's node class (imported here: it loads rclpy)."""
    from ..nodes.consultant import ConsultantNode
    from ..nodes.parser import ParserNode
    from ..nodes.reference_resolution import ReferenceResolutionNode
    from ..nodes.reg import RegNode
    from ..nodes.wm_manager import WMManagerNode

    return {"consultant": ConsultantNode, "wm_manager": WMManagerNode, "parser": ParserNode,
            "reference_resolution": ReferenceResolutionNode, "reg": RegNode}


class LiveGraph:
    """One live graph of a scenario's domains, for a test (see the module docstring).

    Memory settings: ``policy``, ``decay_period``, ``capacity``, ... (as ``fsreg-up``'s
    options), merged over the scenario's own.  ``namespace`` (default: a new unique
    one), ``domain_id`` (default: the environment's), ``processes`` (one OS process per
    node), ``use_sim_time`` (default true: the test drives the clock with
    :meth:`set_clock`), ``state_dir`` (default: a temporary directory, removed at the
    end), ``parameters`` (more parameters per node name, e.g. ``{"reg": {"algorithm":
    "greedy"}}``), ``ready_timeout`` (seconds).
    """

    def __init__(self, scenario: PathLike, *, namespace: Optional[str] = None, domain_id: Optional[int] = None,
                 processes: bool = False, lexicon: Optional[PathLike] = None, algorithm: Optional[str] = None,
                 wm_order: str = "lru-first", use_sim_time: bool = True, state_dir: Optional[PathLike] = None,
                 parameters: Optional[Mapping[str, Mapping[str, Any]]] = None, log_dir: Optional[PathLike] = None,
                 ready_timeout: float = 30.0, graph: Optional[str] = None, **memory: Any) -> None:
        unknown = sorted(set(memory) - {"policy", *PARAMETERS})
        if unknown:
            raise TypeError(f"LiveGraph: unknown memory setting(s) {', '.join(unknown)} "
                            f"(known: policy, {', '.join(PARAMETERS)})")
        self.scenario_path = Path(scenario)
        self.lexicon_path = Path(lexicon) if lexicon is not None else None
        self.scenario = load_scenario(self.scenario_path, Lexicon.load(self.lexicon_path))
        self.options = Options(memory={k: v for k, v in memory.items() if v is not None}, algorithm=algorithm,
                               wm_order=wm_order)
        self.namespace = unique_namespace("fsreg_test") if namespace is None else normalise_namespace(namespace)
        self.domain_id = domain_id
        self.processes = processes
        self.use_sim_time = use_sim_time
        self.graph_id = graph or new_graph_id("test")
        self.ready_timeout = ready_timeout
        self._own_dirs: list[Path] = []
        self.state_dir = Path(state_dir) if state_dir is not None else self._temp_dir("fsreg-test-state-")
        self.log_dir = Path(log_dir) if log_dir is not None else None
        self.specs = live_nodes(self.scenario, self.scenario_path, self.options, graph=self.graph_id,
                                lexicon=self.lexicon_path, state_dir=str(self.state_dir), use_sim_time=use_sim_time)
        for spec in self.specs:
            if spec.executable == "consultant":
                spec.parameters["debug"] = True  # the debug service: wm() reads a queue as it is now
            spec.parameters.update((parameters or {}).get(spec.name, {}))
        self.session: Optional[RosSession] = None
        self.client: Optional[GraphClient] = None
        self.graph: Optional[Graph] = None  # the processes, with processes=True
        self.nodes: dict[str, Any] = {}  # the node objects, in-process
        self._diagnostics: list[Diagnostics] = []  # their /diagnostics publishers

    def _temp_dir(self, prefix: str) -> Path:
        path = Path(tempfile.mkdtemp(prefix=prefix))
        self._own_dirs.append(path)
        return path

    # ---------------------------------------------------------------- life
    def start(self) -> "LiveGraph":
        """Start every node and wait until the graph is ready; return self."""
        try:
            if self.processes:
                env = ros_environment()
                if self.domain_id is not None:
                    env["ROS_DOMAIN_ID"] = str(self.domain_id)
                self.log_dir = self.log_dir or self._temp_dir("fsreg-test-logs-")
                self.log_dir.mkdir(parents=True, exist_ok=True)
                self.graph = Graph(self.specs, self.log_dir, env, self.namespace)
                self.session = RosSession(self.namespace, domain_id=int(self.graph.env["ROS_DOMAIN_ID"]))
                self.graph.start()
            else:
                self.session = RosSession(self.namespace, domain_id=self.domain_id)
                classes = node_classes()
                for spec in self.specs:
                    self.nodes[spec.name] = self._add(classes[spec.executable], spec)
            self.client = GraphClient(self.session.probe, self.session.executor, graph=self.graph_id)
            self.wait_ready(self.ready_timeout)
        except BaseException:
            self.close()
            raise
        return self

    def _add(self, node_cls: Any, spec) -> Any:
        params = dict(spec.parameters)
        sim_time = bool(params.pop("use_sim_time", False))
        node = self.session.add(node_cls, use_sim_time=sim_time, name=spec.name, **params)
        self._diagnostics.append(Diagnostics(node))  # as run_node does for an executable
        return node

    def wait_ready(self, timeout: float = 30.0) -> dict:
        """Wait until the graph serves (every consultant configured, every topic matched); its readiness."""
        try:
            return self._client().wait_ready(timeout)
        except ClientError as err:
            raise Timeout(f"{err}{self._dead_nodes()}") from None

    def _dead_nodes(self) -> str:
        if self.graph is None:
            return ""
        return "".join(f"\nnode {spec.name} exited with code {code}:\n{self.graph.tail(spec.name)}"
                       for spec, code in self.graph.dead())

    def restart(self, name: str) -> None:
        """Stop node ``name`` at once (SIGKILL for a process) and start it again; return once it serves again.

        Synchronised positively: a consultant's new incarnation configured by the WM
        Manager (``wm_manager/ready``), a WM Manager's readiness from its new process, or
        for the parser, RR and REG one answer that changes nothing (an empty
        description; a target nobody knows).
        """
        spec = next((s for s in self.specs if s.name == name), None)
        if spec is None:
            raise ValueError(f"no node '{name}' in this graph (its nodes: {', '.join(s.name for s in self.specs)})")
        client = self._client()
        before = client.readiness() or {}
        if self.graph is not None:
            self.graph.restart(name)
        else:
            self.session.remove(self.nodes.pop(name))
            self.nodes[name] = self._add(node_classes()[spec.executable], spec)
        if spec.executable == "consultant":
            domain = spec.parameters["domain"]
            old = before.get("domains", {}).get(domain, {}).get("incarnation")

            def served() -> bool:
                state = (client.readiness() or {}).get("domains", {}).get(domain, {})
                return state.get("incarnation") != old and bool(state.get("configured"))
        elif spec.executable == "wm_manager":
            def served() -> bool:
                message = client.readiness() or {}
                return message.get("pid") != before.get("pid") and bool(message.get("ready"))
        else:
            served = None
        if served is not None:
            try:
                client.spin_until(served, self.ready_timeout, f"{name} serving again after its restart")
            except ClientError as err:
                raise Timeout(f"{err}{self._dead_nodes()}") from None
        self.wait_ready(self.ready_timeout)
        if spec.executable in ("parser", "reference_resolution"):
            client.say(description=[], timeout=self.ready_timeout)
        elif spec.executable == "reg":
            client.describe("fsreg-testing-nobody", timeout=self.ready_timeout)

    def close(self) -> None:
        """Stop every node and remove the temporary directories this graph made."""
        if self.session is not None:
            self.session.close()
            self.session = None
        if self.graph is not None:
            self.graph.stop()
        for path in self._own_dirs:
            shutil.rmtree(path, ignore_errors=True)
        self._own_dirs.clear()

    def __enter__(self) -> "LiveGraph":
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def _client(self) -> GraphClient:
        if self.client is None:
            raise RuntimeError("LiveGraph: start() it first (or use it as a context manager)")
        return self.client

    # ------------------------------------------------------------ talking
    def say(self, text: Optional[str] = None, *, description: Optional[Sequence[str]] = None,
            domain: Optional[str] = None, time: Optional[float] = None, timeout: float = 10.0) -> dict:
        """Say ``text`` (or a property list) as the human; return the ``rr/result`` (``status``, ``resolved``, ...)."""
        return self._client().say(text, description=description, domain=domain, time=time, timeout=timeout)

    def describe(self, target: str, *, context: Optional[Sequence[str]] = None, time: Optional[float] = None,
                 timeout: float = 10.0) -> dict:
        """Ask the robot to describe ``target``; return the ``reg/expression`` (``text``, ``description``, ...)."""
        return self._client().describe(target, context=context, time=time, timeout=timeout)

    def assert_facts(self, entity: Union[str, Mapping[str, Union[Mapping[str, float], Sequence[str]]]],
                     properties: Union[Mapping[str, float], Sequence[str], None] = None, *,
                     domain: Optional[str] = None, timeout: float = 10.0) -> dict:
        """Assert LTM facts (property -> certainty, or a list of certain properties); the ``ltm/assert/result``.

        A batch: a mapping entity -> properties as ``entity``, applied in one commit
        (:meth:`~fsreg_ros.ros.client.GraphClient.assert_facts`).
        """
        return self._client().assert_facts(entity, properties, domain=domain, timeout=timeout)

    def wm(self, entity: str, domain: Optional[str] = None) -> list[str]:
        """Return ``entity``'s working memory, least recently used first."""
        return self._client().wm(entity, domain)

    def status(self) -> dict:
        """Return the WM Manager's ``wm_manager/status``."""
        return self._client().status()

    def set_clock(self, t: float) -> dict:
        """Move the graph's clock to ``t`` seconds; return once the forgetting due by then is applied.

        In-process, also waits until every sim-time node reads the new time.  Later
        requests are stamped with ``t``.
        """
        reply = self._client().set_clock(t)
        if self.graph is None and self.use_sim_time:
            ns = int(round(t * 1e9))
            nodes = list(self.nodes.values())
            self.session.spin_until(lambda: all(now_ns(n) >= ns for n in nodes), 5.0,
                                    what=f"every node's clock at {t}")
        return reply

    def set_memory(self, **settings: Any) -> None:
        """Change memory settings at run time (the WM Manager's parameters, e.g. ``policy="displacement"``)."""
        self._client().set_parameters("wm_manager", settings)

    def set_parameters(self, node: str, **values: Any) -> None:
        """Set parameters of node ``node`` (e.g. ``"reg"``, ``algorithm="greedy"``) all at once."""
        self._client().set_parameters(node, values)

    @property
    def identity(self) -> str:
        """Return this graph's identity, the ``graph`` parameter of every node."""
        return self.graph_id


__all__ = ["LiveGraph", "node_classes"]
