"""``fsreg-up``: start the live node graph of a scenario's domains and keep it up.

    fsreg-up SCENARIO [--namespace NS] [memory options] [--params-file FILE] [--state-dir DIR] [--fresh]
             [--wall-time] [--view [PORT]] [--record DIR]

Starts one process per node, as ``fsreg-graph`` does (a ``consultant`` per domain of
the scenario, the ``wm_manager`` with the scenario's memory settings and the command
line's merged over them, the ``parser``, ``reference_resolution`` and ``reg``, with the
scenario's lexicon); the scenario's dialogue, if any, is not played.  Before starting it
looks for a graph already running in the namespace (a node of a graph's name, or a WM
Manager's readiness) and refuses with one line naming it.  Then it waits until every
consultant is configured (``wm_manager/ready``) and every topic is matched, prints one
line containing ``ready`` (the namespace, the graph's identity, the ROS domain, the
clock, what each consultant restored from its state database -- runtime facts and WM
queues, from which run and clock epoch -- or ``fresh``, and where to talk to it;
``--json``: one JSON object), and stays up.  ``--fresh`` starts from the scenario alone:
each consultant moves its state database aside (never deleting it; the ready line
says where) instead of restoring it.  Ctrl-C or
SIGTERM stops every node (SIGTERM to the process group, SIGKILL after a grace period;
every node also dies with this process) and leaves no process behind; exit 0.

``--record DIR`` records every fsreg topic to a new rosbag2 folder from before the first
node starts until the graph stops (:mod:`fsreg_ros.ros.recorder`), with a copy of the
scenario (and lexicon) for ``fsreg-sim --replay DIR``.

A node that exits is reported with the tail of its log and everything is stopped
(exit 1), or, with ``--respawn``, it is started again (at most ``MAX_RESPAWNS`` times
per node); its state survives in its state database.

``--params-file FILE`` gives the nodes parameters in the YAML ``ros2 param dump``
writes (``/**`` wildcards, node names, namespaces), each key and value checked against
the node's parameters before anything starts (:mod:`fsreg_ros.tools.params_file`); the
memory options on the command line win over the file, the file over the scenario.

Time: sim time by default (the nodes follow ``/clock``, under a namespace
``<namespace>/clock``, or ``--clock TOPIC``; ``fsreg-ctl clock T`` or a simulator drives
it); ``--wall-time`` makes the nodes follow the system clock.  Exit codes: 0 stopped by
Ctrl-C/SIGTERM, 1 failed (a node died, not ready in time, a graph already there), 2 bad
input or a refused network environment.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import tempfile
import time
from pathlib import Path
from typing import Optional, Sequence

from .. import contract
from .sim import INPUT_ERRORS, UsageError, add_memory_options, one_line, options_from_args
from ..contract import normalise_namespace
from ..contract.naming import check_topic
from ..contract.codec import printable
from ..core.algorithms.generation import ALGORITHMS, WM_ORDERS
from ..core.lexicon import Lexicon
from ..core.consultant.persistence import time_text
from ..core.scenario import coverage_warning, load_scenario
from ..core.simulation.simulator import effective_policies
from .arguments import OneLineParser, number, undecodable
from .graph import Graph, clock_arguments, live_nodes, new_graph_id
from ..ros.network import NetworkRefused, enforce_loopback, require_loopback
from .view import DEFAULT_HOST, DEFAULT_PORT, LiveView

PROG = "fsreg-up"
EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2
#: Times one node is started again with --respawn before fsreg-up gives up.
MAX_RESPAWNS = 5
#: Seconds between two checks of the node processes while up.
POLL = 0.1
#: Longest ``--ready-timeout``, seconds (a day, as fsreg-ctl's ``--timeout``).
MAX_READY_TIMEOUT = 86_400.0


class UpError(RuntimeError):
    """The graph could not be started or kept up (one line, exit 1)."""


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineParser(
        prog=PROG,
        description="Start the live fsreg node graph of a scenario's domains and keep it up until Ctrl-C or "
                    "SIGTERM (talk to it with fsreg-ctl).")
    parser.add_argument("scenario", type=Path, help="scenario/KB YAML file (its dialogue is not played)")
    parser.add_argument("--namespace", default="", help="ROS namespace of every node (default: none)")
    add_memory_options(parser)  # one per memory setting, from the settings table
    parser.add_argument("--algorithm", choices=ALGORITHMS, help="default: sd-pia, or dist-pia under policy none")
    parser.add_argument("--wm-order", choices=WM_ORDERS, help="order SD-PIA walks WM in (default lru-first)")
    parser.add_argument("--lexicon", type=Path, help="lexicon YAML that extends the built-in config/lexicon.yaml")
    parser.add_argument("--state-dir", type=Path, metavar="DIR",
                        help="the consultants' state directory (default: theirs, under $XDG_STATE_HOME/fsreg_ros)")
    parser.add_argument("--fresh", action="store_true",
                        help="start from the scenario alone: each consultant moves its state database aside "
                             "(never deleted; the ready line says where) instead of restoring it")
    parser.add_argument("--wall-time", action="store_true", help="follow the system clock instead of /clock")
    parser.add_argument("--clock", metavar="TOPIC",
                        help="the clock topic to follow under sim time (default: /clock, or <namespace>/clock)")
    parser.add_argument("--log-dir", type=Path, metavar="DIR", help="node logs (default: a new temporary directory)")
    parser.add_argument("--ready-timeout", type=number(0.0, MAX_READY_TIMEOUT, above=True, unit="seconds"),
                        default=60.0, metavar="S",
                        help=f"seconds to wait for the graph to be ready, in (0, {MAX_READY_TIMEOUT:g}] (default 60)")
    parser.add_argument("--params-file", type=Path, metavar="FILE",
                        help="node parameters in the YAML 'ros2 param dump' writes ('/**' wildcards, node names); "
                             "checked before anything starts; memory options on the command line win over it")
    parser.add_argument("--respawn", action="store_true", help="start a node that exits again (default: stop all)")
    parser.add_argument("--json", action="store_true", help="print the ready line as one JSON object")
    parser.add_argument("--view", nargs="?", type=int, const=DEFAULT_PORT, default=None, metavar="PORT",
                        help=f"also serve the live web view on 127.0.0.1:PORT (default {DEFAULT_PORT}; 0: a free port)")
    parser.add_argument("--record", type=Path, metavar="DIR",
                        help="record every fsreg topic from the start to a new rosbag2 folder DIR (MCAP)")
    return parser


def ready_report(graph_id: str, namespace: str, domain_id: int, memory: dict, clock: Optional[str],
                 log_dir: Path, resolve, restored: Optional[dict] = None) -> dict:
    """Return what the ready line says, as data: identity, where, memory, clock, state, endpoints, logs.

    ``restored``: per domain, what its consultant took up from its state database
    (``wm_manager/status`` ``restored``; :class:`~fsreg_ros.contract.RestoredState`).
    """
    topics = (contract.HUMAN, contract.RR_RESULT, contract.REG_REQUEST, contract.REG_EXPRESSION, contract.LTM_ASSERT,
              contract.LTM_ASSERT_RESULT, contract.WM_STATE, contract.WM_EVENTS, contract.READY)
    services = [contract.STATUS.name, contract.SYNC.name] + [contract.consultant_service(d) for d in memory]
    return {
        "ready": True,
        "graph": graph_id,
        "namespace": namespace or "/",
        "ros_domain_id": domain_id,
        "memory": memory,
        "clock": clock,
        "restored": dict(restored or {}),
        "topics": {t.name: resolve(t.name) for t in topics},
        "services": {s: resolve(s) for s in services},
        "logs": str(log_dir),
        "pid": os.getpid(),
    }


def ready_line(report: dict) -> str:
    """Return the one-line text form of :func:`ready_report`."""
    ns = report["namespace"]
    memory = "; ".join(f"{d}: " + ", ".join(f"{k} {v}" for k, v in m.items()) for d, m in report["memory"].items())
    clock = f"sim time on {report['clock']}" if report["clock"] else "wall-clock time"
    ctl = "fsreg-ctl" + (f" --namespace {ns}" if ns != "/" else "")
    endpoints = ", ".join(list(report["topics"].values()) + list(report["services"].values()))
    return (f"{PROG}: ready: graph {report['graph']} in namespace {ns} on ROS domain {report['ros_domain_id']}; "
            f"{memory}; {clock}; {state_text(report.get('restored') or {})}; endpoints {endpoints}; "
            f"talk to it with: {ctl} say TEXT | describe ENTITY | status | watch"
            + (f"; live view at {report['view']}" if report.get("view") else "") + f"; logs in {report['logs']}"
            + (f"; recording to {report['recording']}" if report.get("recording") else ""))


def restored_text(r: Optional[dict]) -> str:
    """Return what one consultant restored at start (its ``restored``): ``fresh (...)`` or ``restored ...``."""
    if not r:
        return "state unknown"
    aside = f", the old state moved aside to {r['moved_aside']}" if r.get("moved_aside") else ""
    if r.get("fresh"):
        return f"fresh (the scenario alone{aside})"
    epoch = ", ".join(x for x in (f"{r['clock']} clock" if r.get("clock") else "",
                                  f"up to {time_text(r.get('clock'), r['latest'])}" if r.get("latest") is not None
                                  else "") if x)
    dropped = f" ({r['queues_dropped']} dropped: WM of another clock or run)" if r.get("queues_dropped") else ""
    return (f"restored {r['runtime_facts']} runtime facts ({r['runtime_entities']} runtime entities), "
            f"{r['queues']} WM queues{dropped} from run {r.get('run')}" + (f" ({epoch})" if epoch else "") + aside)


def state_text(restored: dict) -> str:
    """Return the ready line's state part: what each domain's consultant restored, or ``fresh``."""
    return "state " + ("; ".join(f"{d}: {restored_text(r)}" for d, r in sorted(restored.items())) or "unknown")


class Stop(Exception):
    """Ctrl-C or SIGTERM arrived."""


def _on_signal(signum, frame) -> None:
    raise Stop(signal.Signals(signum).name)


def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run ``fsreg-up``; return its exit code."""
    require_loopback(PROG)  # exits 2 if the environment would take DDS off this machine
    bad = undecodable(sys.argv[1:] if argv is None else argv)
    if bad is not None:
        print(f"{PROG}: error: {bad}", file=sys.stderr)
        return EXIT_BAD_INPUT
    args = build_parser().parse_args(argv)
    try:
        namespace = normalise_namespace(args.namespace)
    except ValueError as err:
        print(f"{PROG}: error: --namespace: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.view is not None and not 0 <= args.view <= 65535:
        print(f"{PROG}: error: --view: the port must be between 0 and 65535, got {args.view}", file=sys.stderr)
        return EXIT_BAD_INPUT
    if args.record is not None:
        from ..core.io.recording import RecordingError, check_target

        try:
            check_target(args.record)
        except RecordingError as err:
            print(printable(f"{PROG}: error: --record: {err}"), file=sys.stderr)
            return EXIT_BAD_INPUT
    if args.log_dir is not None:
        try:  # before anything starts: a folder that cannot be made is bad input, not a failure later
            args.log_dir.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            print(printable(f"{PROG}: error: --log-dir: cannot make {args.log_dir} a folder: "
                            f"{err.strerror or err}"), file=sys.stderr)
            return EXIT_BAD_INPUT
    try:
        lexicon = Lexicon.load(args.lexicon)
        scenario = load_scenario(args.scenario, lexicon)
        options = options_from_args(args)
        policies = effective_policies(scenario, options)
        clock = None if args.wall_time else (args.clock if args.clock is not None else
                                             f"{namespace}{contract.CLOCK}" if namespace else contract.CLOCK)
        if clock is not None:
            try:
                check_topic(clock)
            except ValueError as err:
                raise UsageError(f"--clock: {err}") from None
        file_params, memory = {}, None
        if args.params_file is not None:
            specs = live_nodes(scenario, args.scenario, options, lexicon=args.lexicon, state_dir=_state_dir(args),
                               use_sim_time=not args.wall_time)
            file_params, memory = params_from_file(args.params_file, specs, namespace, options, fresh=args.fresh)
    except INPUT_ERRORS as err:
        print(f"{PROG}: error: {one_line(err)}", file=sys.stderr)
        return EXIT_BAD_INPUT
    warning = coverage_warning(lexicon, scenario)
    if warning:
        print(f"{PROG}: warning: {warning}", file=sys.stderr)
    try:
        env = enforce_loopback(dict(os.environ))
    except NetworkRefused as err:  # pragma: no cover - require_loopback refused it already
        print(f"{PROG}: error: {err}", file=sys.stderr)
        return EXIT_BAD_INPUT
    os.environ.update(env)
    previous = {sig: signal.signal(sig, _on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        return Up(args, scenario, options, policies, namespace, clock, env, file_params, memory).run()
    except Stop:
        return EXIT_OK
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def params_from_file(path: Path, specs: Sequence, namespace: str, options, fresh: bool = False) -> tuple[dict, dict]:
    """Return (node -> parameters from ``--params-file``, each domain's memory with them); UsageError if invalid.

    ``specs``: the graph's nodes as fsreg-up would start them (the file's runner-owned keys must agree;
    ``fresh``: ``--fresh`` is given, so ``reset_state`` is true).
    """
    from .params_file import check_memory, overrides

    mark_fresh(specs, fresh)
    runner = {spec.name: spec.parameters for spec in specs}
    domains = list(runner["wm_manager"]["domains"])
    given = overrides(path, domains, namespace, options.memory, runner)
    return given, check_memory(path, runner["wm_manager"], given.get("wm_manager", {}), domains)


def mark_fresh(specs: Sequence, fresh: bool) -> None:
    """``--fresh``: start from the scenario alone, each consultant moving its database aside (``reset_state``)."""
    if fresh:
        for spec in specs:
            if spec.executable == "consultant":
                spec.parameters["reset_state"] = True


def _state_dir(args: argparse.Namespace) -> Optional[str]:
    return str(args.state_dir.resolve()) if args.state_dir else None


class Up:
    """One fsreg-up run: the probe that checks and waits, the node processes, the loop that keeps them up."""

    def __init__(self, args: argparse.Namespace, scenario, options, policies: dict, namespace: str,
                 clock: Optional[str], env: dict, file_params: Optional[dict] = None,
                 memory: Optional[dict] = None) -> None:
        self.args = args
        self.wm_order = options.wm_order  # --wm-order, else --preset's, else lru-first
        self.namespace = namespace
        self.clock = clock
        self.env = env
        self.graph_id = new_graph_id(PROG)
        self.memory = {d: p.to_json() for d, p in policies.items()}
        self.log_dir = args.log_dir or Path(tempfile.mkdtemp(prefix="fsreg-up-"))
        self.specs = live_nodes(scenario, args.scenario, options, graph=self.graph_id, lexicon=args.lexicon,
                                state_dir=_state_dir(args),
                                use_sim_time=not args.wall_time)
        for spec in self.specs:  # --params-file (checked): over the scenario's, under the command line's
            spec.parameters.update((file_params or {}).get(spec.name, {}))
        if memory is not None:
            self.memory = memory
        mark_fresh(self.specs, args.fresh)
        self.graph: Optional[Graph] = None
        self.respawns: dict[str, int] = {}

    def run(self) -> int:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        from ..ros.client import DISCOVERY_WAIT, ClientError, GraphClient

        self.log_dir.mkdir(parents=True, exist_ok=True)
        context = rclpy.Context()
        rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
        executor = SingleThreadedExecutor(context=context)
        remaps = ["-r", f"__ns:={self.namespace}"] if self.namespace else []
        remaps += clock_arguments(self.namespace, self.clock)
        node = rclpy.create_node("fsreg_up", context=context, cli_args=["--ros-args", *remaps] if remaps else None)
        executor.add_node(node)
        recorder = None
        try:
            client = GraphClient(node, executor, graph=self.graph_id)
            running = client.find_running(DISCOVERY_WAIT)
            if running is not None:
                print(f"{PROG}: error: {running}; stop it, or choose another --namespace or ROS_DOMAIN_ID",
                      file=sys.stderr)
                return EXIT_FAILED
            if self.args.record is not None:  # subscribed before any node starts: the recording starts with the graph
                recorder = self._recorder(node)
            self.graph = Graph(self.specs, self.log_dir, self.env, self.namespace, clock=self.clock)
            self.graph.start()
            for spec in self.specs:  # --fresh is for this start only: a respawned node takes up its state
                spec.parameters.pop("reset_state", None)
            self._wait_ready(client)
            if recorder is not None:
                self._wait_recorded(client, recorder)
            restored = client.status().get("restored") or {}
            report = ready_report(self.graph_id, self.namespace, context.get_domain_id(), self.memory, self.clock,
                                  self.log_dir, node.resolve_topic_name, restored)
            view = self._start_view(client)
            if view is not None:
                report["view"] = view.url
            if recorder is not None:
                report["recording"] = str(self.args.record)
            print(json.dumps(report, sort_keys=True) if self.args.json else ready_line(report), flush=True)
            while True:
                self._supervise()
                if view is None:
                    client.spin_for(POLL)
                else:
                    stop = time.monotonic() + POLL
                    while time.monotonic() < stop:
                        view.step()
        except (UpError, ClientError) as err:
            print(f"{PROG}: error: {err}", file=sys.stderr)
            return EXIT_FAILED
        except OSError as err:  # --view's port
            print(f"{PROG}: error: --view: cannot serve on {DEFAULT_HOST}:{self.args.view}: {err.strerror or err}",
                  file=sys.stderr)
            return EXIT_FAILED
        finally:
            signal.signal(signal.SIGINT, signal.SIG_IGN)  # stopping is not interrupted
            signal.signal(signal.SIGTERM, signal.SIG_IGN)
            if self.graph is not None:
                self.graph.stop()
                print(f"{PROG}: stopped graph {self.graph_id} ({len(self.graph.procs)} nodes); logs in {self.log_dir}",
                      file=sys.stderr)
            if recorder is not None:
                recorder.close()
                if recorder.error is not None:  # the recorder's thread stopped when a write failed (a full disk)
                    print(printable(f"{PROG}: error: --record: writing {self.args.record} failed: {recorder.error}; "
                                    "what was written before is kept there"), file=sys.stderr)
                print(f"{PROG}: recorded {recorder.summary()}", file=sys.stderr)
            executor.shutdown(timeout_sec=1.0)
            node.destroy_node()
            rclpy.try_shutdown(context=context)

    def _start_view(self, client):
        """Serve the live view (``--view``) from this process; None without the option."""
        if self.args.view is None:
            return None
        view = LiveView(client, DEFAULT_HOST, self.args.view)  # OSError: the port is taken
        view.start()
        return view

    def _recorder(self, node):
        """Start recording every fsreg topic on ``node`` (:mod:`fsreg_ros.ros.recorder`), with what a replay needs."""
        from ..core.io.recording import RecordingError
        from ..ros.recorder import Recorder

        custom = {"fsreg.graph": self.graph_id, "fsreg.namespace": self.namespace or "/",
                  "fsreg.algorithm": self.args.algorithm or "auto", "fsreg.wm_order": self.wm_order}
        attach = {"scenario": self.args.scenario, **({"lexicon": self.args.lexicon} if self.args.lexicon else {})}
        try:
            return Recorder(node, self.args.record, custom=custom, attach=attach)
        except (RecordingError, OSError) as err:
            raise UpError(f"--record: {err}") from None

    def _wait_recorded(self, client, recorder) -> None:
        """Wait until the recording's readers matched every writer of the graph (:meth:`Recorder.wait_matched`)."""
        def between() -> None:
            self._supervise(starting=True)
            client.spin_for(0.05)

        warning = recorder.wait_matched(between=between)
        if warning is not None:
            print(f"{PROG}: warning: --record: {warning}", file=sys.stderr)

    def _wait_ready(self, client) -> None:
        from ..ros.client import ClientError

        deadline = time.monotonic() + self.args.ready_timeout
        while True:
            self._supervise(starting=True)
            try:
                client.wait_ready(min(1.0, max(0.0, deadline - time.monotonic())))
                return
            except ClientError as err:
                if err.kind != "not-ready":
                    raise
                if time.monotonic() >= deadline:
                    raise UpError(f"not ready within {self.args.ready_timeout:g} s: {err}") from None

    def _supervise(self, starting: bool = False) -> None:
        """Respawn or report a node that exited."""
        for spec, code in self.graph.dead():
            tail = self.graph.tail(spec.name)
            if self.args.respawn and self.respawns.get(spec.name, 0) < MAX_RESPAWNS:
                self.respawns[spec.name] = self.respawns.get(spec.name, 0) + 1
                print(f"{PROG}: node {spec.name} exited with code {code}; starting it again "
                      f"({self.respawns[spec.name]} of {MAX_RESPAWNS})\n{tail}", file=sys.stderr, flush=True)
                self.graph.restart(spec.name, kill=False)
                continue
            when = "while starting" if starting else "while up"
            raise UpError(f"node {spec.name} exited with code {code} {when}; stopping the graph\n{tail}")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
