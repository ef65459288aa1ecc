"""``fsreg-ctl``: talk to a live fsreg graph from the command line (no ROS install needed beyond the wheels).

    fsreg-ctl [--namespace NS] say TEXT...                 the human says TEXT: who did they mean?
    fsreg-ctl [--namespace NS] describe ENTITY [--context E...]   the robot describes ENTITY
    fsreg-ctl [--namespace NS] assert ENTITY PROP[:C]... [--domain D]   tell a consultant facts
    fsreg-ctl [--namespace NS] status                      readiness, memory per domain
    fsreg-ctl [--namespace NS] set KEY=VALUE...            change memory settings (or NODE:KEY=VALUE)
    fsreg-ctl [--namespace NS] watch [--events]            each entity's WM, live
    fsreg-ctl [--namespace NS] wm ENTITY                   one entity's WM now (the wm/state that shows every change)
    fsreg-ctl [--namespace NS] clock SECONDS               set a sim-time graph's clock
    fsreg-ctl [--namespace NS] record DIR [--duration S]   record every fsreg topic as a rosbag2 folder (MCAP)

Every command waits (``--timeout``) until the graph in the namespace is ready (its WM
Manager's ``wm_manager/ready``), so a first request is not refused; refuses to go on when
two graphs share the namespace; and rejects an answer stamped by another graph.  With
``--json`` each prints the answer as one JSON object (``watch``: one per line).  Errors
are one line on stderr.  Exit codes: 0 answered, 1 the graph answered with an error (an
unknown entity, a refused setting, ...), 2 bad usage, 3 no answer (no graph, not ready,
timed out, two graphs, another graph's answer).

``set``: a memory setting (``policy``, ``decay_period``, ``capacity``, ...) applies to
every domain's setting; ``DOMAIN.KEY=VALUE`` to one domain's; ``NODE:KEY=VALUE`` sets a
parameter of another node (``reg:algorithm=greedy``, ``consultant_faces:threshold=0.6``).
Values are converted to the parameter's type; the keys given to one node are set all at
once or not at all.  ``assert``: ``PROP`` is certain (1.0), ``PROP:C`` has certainty C.
"""

from __future__ import annotations

import argparse
import json
import os
import secrets
import sys
from typing import Any, Optional, Sequence

from ..ros.codec import printable
from ..contract import normalise_namespace
from ..core.forgetting import PARAMETERS
from ..ros.network import NetworkRefused, enforce_loopback, require_loopback
from ..ros.diagnostics import PERIOD as DIAGNOSTICS_PERIOD, read_statuses, summary
from .view import check_port, serve_view

PROG = "fsreg-ctl"
EXIT_OK, EXIT_ERROR, EXIT_USAGE, EXIT_NO_ANSWER = 0, 1, 2, 3
#: Client error kinds that mean "no answer from this graph".
NO_ANSWER = ("not-ready", "timeout", "clash", "foreign", "cancelled", "unavailable")
#: Memory settings: applied to every domain unless given as DOMAIN.KEY.
MEMORY_KEYS = ("policy", *PARAMETERS)


class UsageError(ValueError):
    """A command line that cannot be turned into a request."""


def build_parser() -> argparse.ArgumentParser:
    common = argparse.ArgumentParser(add_help=False)
    common.add_argument("--namespace", default=argparse.SUPPRESS, help="the graph's ROS namespace (default: none)")
    common.add_argument("--json", action="store_true", default=argparse.SUPPRESS, help="print JSON")
    common.add_argument("--timeout", type=float, default=argparse.SUPPRESS, metavar="S",
                        help="seconds to wait for the graph and for each answer (default 10)")
    common.add_argument("--graph", default=argparse.SUPPRESS, metavar="ID",
                        help="the graph identity expected (default: the one running in the namespace)")
    common.add_argument("--clock", default=argparse.SUPPRESS, metavar="TOPIC",
                        help="the clock topic 'clock' publishes on (default: the graph's own)")
    parser = argparse.ArgumentParser(prog=PROG, parents=[common],
                                     description="Talk to a live fsreg graph (started with fsreg-up).")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    say = commands.add_parser("say", parents=[common], help="the human says TEXT; print whom RR resolved")
    say.add_argument("text", nargs="*", help="what the human says (words)")
    say.add_argument("--description", metavar="P1,P2", help="a property list instead of text")
    say.add_argument("--domain", help="the domain the description is about")
    describe = commands.add_parser("describe", parents=[common], help="the robot describes ENTITY")
    describe.add_argument("entity")
    describe.add_argument("--context", nargs="+", metavar="E", help="describe against these entities only")
    facts = commands.add_parser("assert", parents=[common], help="tell a consultant facts about ENTITY")
    facts.add_argument("entity")
    facts.add_argument("properties", nargs="+", metavar="PROP[:C]", help="a property, with certainty C (default 1)")
    facts.add_argument("--domain", help="the consultant's domain (default: the one knowing ENTITY, or the only one)")
    commands.add_parser("status", parents=[common], help="readiness and memory of every domain")
    settings = commands.add_parser("set", parents=[common], help="change memory settings or node parameters")
    settings.add_argument("assignments", nargs="+", metavar="KEY=VALUE")
    watch = commands.add_parser("watch", parents=[common], help="show each entity's WM live (Ctrl-C ends)")
    watch.add_argument("--events", action="store_true", help="also print every encode/forget event")
    watch.add_argument("--count", type=int, metavar="N", help="stop after N WM updates")
    wm = commands.add_parser("wm", parents=[common], help="one entity's WM, least recently used first")
    wm.add_argument("entity")
    wm.add_argument("--domain")
    view = commands.add_parser("view", parents=[common],
                               help="serve a live web page of the graph's WM on 127.0.0.1 (Ctrl-C ends)")
    view.add_argument("--port", type=int, default=None, metavar="N",
                      help="TCP port of the page (default 8765; 0 takes a free port)")
    view.add_argument("--host", default="127.0.0.1", metavar="ADDRESS",
                      help="address to bind (default 127.0.0.1: this machine only)")
    clock = commands.add_parser("clock", parents=[common], help="set a sim-time graph's clock to SECONDS")
    clock.add_argument("seconds", type=float)
    record = commands.add_parser("record", parents=[common],
                                 help="record every fsreg topic to a new rosbag2 folder DIR (MCAP) until Ctrl-C")
    record.add_argument("directory", metavar="DIR", help="the recording's folder (must not exist)")
    record.add_argument("--duration", type=float, metavar="S", help="stop after S seconds (wall clock)")
    record.add_argument("--segment", type=float, default=1.0, metavar="S",
                        help="close a segment every S seconds: what a killed recorder can lose at most (default 1)")
    return parser


def option(args: argparse.Namespace, name: str, default: Any) -> Any:
    return getattr(args, name, default)


def parse_facts(items: Sequence[str]) -> dict[str, float]:
    """Return ``PROP`` / ``PROP:C`` items as property -> certainty."""
    facts: dict[str, float] = {}
    for item in items:
        prop, sep, value = item.rpartition(":")
        if not sep:
            prop, value = item, "1"
        try:
            certainty = float(value)
        except ValueError:
            raise UsageError(f"assert: {item!r}: the certainty after ':' must be a number in [0, 1]") from None
        if not prop or not 0.0 <= certainty <= 1.0:
            raise UsageError(f"assert: {item!r}: give PROP or PROP:C with C in [0, 1]")
        facts[prop] = certainty
    return facts


def parse_assignments(items: Sequence[str], domains: Sequence[str]) -> dict[str, dict[str, str]]:
    """Return ``KEY=VALUE`` items as node -> {parameter: value text} (see the module docstring)."""
    out: dict[str, dict[str, str]] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise UsageError(f"set: {item!r}: expected KEY=VALUE")
        node, colon, name = key.rpartition(":")
        if colon:
            out.setdefault(node, {})[name] = value
        elif key in MEMORY_KEYS:
            for domain in domains:
                out.setdefault("wm_manager", {})[f"{domain}.{key}"] = value
        else:
            out.setdefault("wm_manager", {})[key] = value
    return out


# ---------------------------------------------------------------- output
def show_say(answer: dict) -> str:
    status = answer.get("status")
    heard = ", ".join(answer.get("description") or []) or "nothing known"
    unknown = answer.get("unknown_words") or []
    tail = f"; heard: {heard}" + (f"; unknown words: {', '.join(unknown)}" if unknown else "")
    if status == "resolved":
        return f"{answer.get('resolved')} (resolved{tail})"
    if status == "ambiguous":
        return f"ambiguous: {', '.join(answer.get('candidates') or [])}{tail}"
    return f"{status}{tail}"


def show_describe(answer: dict) -> str:
    sources = ", ".join(f"{p}: {s}" for p, s in zip(answer.get("description") or [], answer.get("sources") or []))
    left = answer.get("distractors_left") or []
    note = "" if answer.get("distinguishing", True) else f"; not distinguishing from {', '.join(left)}"
    return f"\"{answer.get('text')}\" ({sources or 'nothing to say'}{note})"


def show_assert(answer: dict) -> str:
    updated = ", ".join(f"{p} {c:g}" for p, c in (answer.get("updated") or {}).items())
    retracted = answer.get("retracted") or []
    what = "added" if answer.get("new_entity") else "updated"
    return (f"{answer.get('entity')} ({answer.get('domain')}): {what} {updated}"
            + (f"; retracted from WM: {', '.join(retracted)}" if retracted else ""))


def show_status(status: dict) -> str:
    lines = [f"graph {status.get('graph') or '(unnamed)'}: {'ready' if status.get('ready') else 'NOT ready'}, "
             f"time {status.get('time'):g} s"]
    for domain in status.get("domains") or []:
        running = (status.get("running") or {}).get(domain)
        tick = (status.get("next_tick") or {}).get(domain)
        lines.append(
            f"  {domain}: memory {json.dumps((status.get('memory') or {}).get(domain), sort_keys=True)}, "
            f"running {json.dumps(running, sort_keys=True)}, incarnation "
            f"{(status.get('incarnation') or {}).get(domain)}, "
            f"{'configured' if (status.get('configured') or {}).get(domain) else 'not configured'}"
            + (f", next decay tick at {tick:g} s" if isinstance(tick, (int, float)) else ""))
    return "\n".join(lines)


def show_state(state: dict) -> str:
    queues = state.get("queues") or {}
    body = "  ".join(f"{entity}: [{', '.join(props)}]" for entity, props in queues.items()) or "(empty)"
    return f"t={state.get('time', 0):.2f} {state.get('domain')}  {body}"


def show_event(event: dict) -> str:
    return (f"t={event.get('time', 0):.2f} {event.get('op')} {event.get('domain')} {event.get('entity')} "
            f"{event.get('property')} ({event.get('cause')})")


class Screen:
    """``watch`` on a terminal: every domain's queues redrawn in place after each update."""

    def __init__(self, out) -> None:
        self.out = out
        self.states: dict[str, dict] = {}

    def update(self, state: dict) -> None:
        self.states[str(state.get("domain"))] = state
        lines = ["\x1b[H\x1b[J" + f"{PROG} watch: working memory (least recently used first); Ctrl-C ends"]
        for domain, st in sorted(self.states.items()):
            lines.append(f"{domain} at t={st.get('time', 0):.2f} s")
            queues = st.get("queues") or {}
            width = max((len(e) for e in queues), default=0)
            lines += [f"  {e.ljust(width)}  {', '.join(q)}" for e, q in queues.items()] or ["  (empty)"]
        self.out.write("\n".join(lines) + "\n")
        self.out.flush()


# ------------------------------------------------------------------ main
def main(argv: Optional[Sequence[str]] = None) -> int:
    """Run ``fsreg-ctl``; return its exit code."""
    require_loopback(PROG)
    args = build_parser().parse_args(argv)
    try:
        namespace = normalise_namespace(option(args, "namespace", ""))
        timeout = float(option(args, "timeout", 10.0))
        if not timeout > 0:
            raise UsageError(f"--timeout must be positive, got {timeout:g}")
        facts = parse_facts(args.properties) if args.command == "assert" else None
        if args.command == "say" and bool(args.text) == bool(args.description):
            raise UsageError("say: give the words to say, or --description P1,P2 (not both)")
        if args.command == "view":
            args.port = check_port(args.port)
        if args.command == "watch" and args.count is not None and args.count < 1:
            raise UsageError("watch: --count must be at least 1")
        if args.command == "record":
            check_record(args)
    except (UsageError, ValueError) as err:
        print(f"{PROG}: error: {err}", file=sys.stderr)
        return EXIT_USAGE
    try:
        os.environ.update(enforce_loopback(dict(os.environ)))
    except NetworkRefused as err:  # pragma: no cover - require_loopback refused it already
        print(f"{PROG}: error: {err}", file=sys.stderr)
        return EXIT_USAGE
    return Ctl(args, namespace, timeout, facts).run()


class Ctl:
    """One fsreg-ctl command against one graph."""

    def __init__(self, args: argparse.Namespace, namespace: str, timeout: float,
                 facts: Optional[dict[str, float]]) -> None:
        self.args = args
        self.namespace = namespace
        self.timeout = timeout
        self.facts = facts
        self.json = bool(option(args, "json", False))

    def emit(self, data: Any, text: str) -> None:
        print(json.dumps(data, sort_keys=True) if self.json else text, flush=True)

    def run(self) -> int:
        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions

        from ..ros.client import ClientError, GraphClient
        from .graph import clock_arguments

        context = rclpy.Context()
        rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
        executor = SingleThreadedExecutor(context=context)
        remaps = (["-r", f"__ns:={self.namespace}"] if self.namespace else [])
        remaps += clock_arguments(self.namespace, option(self.args, "clock", None))
        node = rclpy.create_node(f"fsreg_ctl_{secrets.token_hex(4)}", context=context,
                                 cli_args=["--ros-args", *remaps] if remaps else None)
        executor.add_node(node)
        try:
            client = GraphClient(node, executor, graph=option(self.args, "graph", None), timeout=self.timeout)
            return self.command(client)
        except ClientError as err:
            print(printable(f"{PROG}: error: {err}", 2000), file=sys.stderr)
            if err.kind == "usage":
                return EXIT_USAGE
            return EXIT_NO_ANSWER if err.kind in NO_ANSWER else EXIT_ERROR
        except UsageError as err:
            print(f"{PROG}: error: {err}", file=sys.stderr)
            return EXIT_USAGE
        except KeyboardInterrupt:
            return EXIT_OK
        finally:
            executor.shutdown(timeout_sec=1.0)
            node.destroy_node()
            rclpy.try_shutdown(context=context)

    def command(self, client) -> int:
        from ..ros.client import ClientError

        args = self.args
        if args.command == "record":  # records whatever comes, graph or not (yet)
            return self._record(client)
        if args.command in ("status", "watch", "view"):  # these work on a graph that is not ready (yet)
            self._find(client)
        else:  # say, describe and assert wait for their own topics to match (GraphClient.exchange)
            client.wait_ready(self.timeout, pipeline=False)
        if args.command == "say":
            description = [p.strip() for p in args.description.split(",") if p.strip()] if args.description else None
            answer = client.say(" ".join(args.text) if args.text else None, description=description,
                                domain=args.domain)
            self.emit(answer, show_say(answer))
            if answer.get("status") == "error" or "error" in answer:
                raise ClientError(f"say: {answer.get('error')}", "error")
        elif args.command == "describe":
            answer = client.describe(args.entity, context=args.context)
            if "error" in answer:
                raise ClientError(f"describe {args.entity}: {answer['error']}", "error")
            self.emit(answer, show_describe(answer))
        elif args.command == "assert":
            answer = client.assert_facts(args.entity, self.facts, domain=args.domain)
            if not answer.get("ok"):
                raise ClientError(f"assert {args.entity}: {answer.get('error')}", "error")
            self.emit(answer, show_assert(answer))
        elif args.command == "status":
            status = client.status()
            # every node's /diagnostics (at 1 Hz: one period and a little more hears each node once)
            status["diagnostics"] = read_statuses(client.node, client.spin_for, client.node.get_namespace(),
                                                  wait=DIAGNOSTICS_PERIOD * 1.5)
            self.emit(status, "\n".join([show_status(status), *summary(status["diagnostics"])]))
        elif args.command == "set":
            return self._set(client)
        elif args.command == "wm":
            domain = args.domain or client.domain_of(args.entity)
            state = client.state(domain, current=True)  # wm/state as of now: no debug service needed
            queue = list((state.get("queues") or {}).get(args.entity, []))
            self.emit({"entity": args.entity, "domain": domain, "queue": queue, "time": state.get("time")},
                      f"{args.entity} ({domain}): {', '.join(queue) or '(empty)'}")
        elif args.command == "clock":
            reply = client.set_clock(args.seconds)
            self.emit(reply, f"clock at {args.seconds:g} s; the forgetting due by then is applied")
        elif args.command == "watch":
            return self._watch(client)
        elif args.command == "view":
            try:
                return serve_view(client, args.host, args.port, announce=lambda text: print(text, flush=True))
            except OSError as err:
                raise ClientError(f"view: cannot serve on {args.host}:{args.port}: {err.strerror or err}",
                                  "usage") from None
        return EXIT_OK

    def _find(self, client) -> None:
        """Find the graph in the namespace (not necessarily ready)."""
        from ..ros.client import ClientError

        client.spin_until(lambda: client.ready_messages, self.timeout,
                          f"no fsreg graph answers in {client.where()} (is fsreg-up running there?)", "not-ready")
        client.check_clash()
        if client.graph is None:
            (client.graph, _, _), = client.ready_messages
        elif client.readiness() is None:
            raise ClientError(f"graph {client.graph!r} is not in {client.where()}", "not-ready")

    def _set(self, client) -> int:
        changes = parse_assignments(self.args.assignments, client.domains())
        for node_name, values in changes.items():
            client.set_parameters(node_name, values)
        text = "; ".join(f"{node}: " + ", ".join(f"{k}={v}" for k, v in values.items())
                         for node, values in changes.items())
        self.emit({"set": changes}, f"set {text}")
        return EXIT_OK

    def _watch(self, client) -> int:
        from ..ros.client import ClientError

        args = self.args
        seen = {"states": 0}
        screen = Screen(sys.stdout) if sys.stdout.isatty() and not self.json else None

        def on_state(state: dict) -> None:
            seen["states"] += 1
            if screen is not None:
                screen.update(state)
            else:
                self.emit(state, show_state(state))

        def on_event(event: dict) -> None:
            if screen is None:
                self.emit(event, show_event(event))

        client.watch(on_state, on_event if args.events else None)
        while args.count is None or seen["states"] < args.count:
            client.executor.spin_once(timeout_sec=0.1)
            if client.foreign is not None:
                raise ClientError(client.foreign, "foreign")
        return EXIT_OK

    def _record(self, client) -> int:
        """``record``: every fsreg topic of the namespace to a rosbag2 folder until Ctrl-C, SIGTERM or --duration."""
        import signal
        import time
        from pathlib import Path

        from ..core.recording import RecordingError
        from ..ros.client import ClientError
        from ..ros.recorder import Recorder, graph_knowledge

        args = self.args
        try:  # recording starts at once: nothing that comes while the graph is looked for is lost
            recorder = Recorder(client.node, Path(args.directory), segment_seconds=args.segment,
                                custom={"fsreg.namespace": self.namespace or "/"})
        except (RecordingError, OSError) as err:
            raise UsageError(f"record: {err}") from None

        def stop(signum, frame) -> None:
            raise KeyboardInterrupt

        previous = {sig: signal.signal(sig, stop) for sig in (signal.SIGINT, signal.SIGTERM)}
        print(f"{PROG}: recording {len(recorder.topics)} topics of {client.where()} to {args.directory}"
              + (f" for {args.duration:g} s" if args.duration else " (Ctrl-C ends)"), file=sys.stderr, flush=True)
        deadline = None if args.duration is None else time.monotonic() + args.duration
        try:
            try:  # a graph up: note what it runs with (knowledge base, lexicon, REG options) for a replay
                client.spin_until(lambda: client.ready_messages, self.timeout, "readiness", "not-ready")
                client.check_clash()
                if client.graph is None:
                    (client.graph, _, _), = client.ready_messages
                custom, attach = graph_knowledge(client, self.timeout)
                recorder.bag.custom.update(custom)
                for key, source in attach.items():
                    recorder.bag.attach(key, source)
            except ClientError as err:
                if err.kind == "clash":
                    raise
                print(f"{PROG}: note: no graph answered in {client.where()} within {self.timeout:g} s; recording "
                      "whatever comes (a replay will need --scenario)", file=sys.stderr, flush=True)
            while deadline is None or time.monotonic() < deadline:
                client.executor.spin_once(timeout_sec=0.05)
        except KeyboardInterrupt:
            pass
        finally:
            for sig in previous:  # closing the bag is not interrupted
                signal.signal(sig, signal.SIG_IGN)
            path = recorder.close()
        counts = recorder.counts
        self.emit({"recorded": str(path), "messages": sum(counts.values()), "counts": counts},
                  f"recorded {recorder.summary()}")
        return EXIT_OK


def check_record(args: argparse.Namespace) -> None:
    """Refuse a ``record`` command line that cannot be recorded (one line, exit 2)."""
    import math
    from pathlib import Path

    for name in ("duration", "segment"):
        value = getattr(args, name)
        if value is not None and not (math.isfinite(value) and 0 < value <= 7 * 86400):
            raise UsageError(f"record: --{name} must be a positive number of seconds, got {value:g}")
    if Path(args.directory).exists():
        raise UsageError(f"record: {args.directory} exists already; a recording goes to a new folder")


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
