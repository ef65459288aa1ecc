"""``fsreg-ctl``: talk to a live fsreg graph from the command line (no ROS install needed beyond the wheels).

    fsreg-ctl [--namespace NS] say TEXT...                 the human says TEXT: who did they mean?
    fsreg-ctl [--namespace NS] describe ENTITY [--context E...]   the robot describes ENTITY
    fsreg-ctl [--namespace NS] assert ENTITY PROP[:C]... [--domain D]   tell a consultant facts
    fsreg-ctl [--namespace NS] status                      readiness, memory per domain
    fsreg-ctl [--namespace NS] set KEY=VALUE...            change memory settings (or NODE:KEY=VALUE)
    fsreg-ctl [--namespace NS] params get|dump [ITEM...]   read parameters back (dump: ros2 param dump's YAML)
    fsreg-ctl [--namespace NS] watch [--events]            each entity's WM, live
    fsreg-ctl [--namespace NS] wm ENTITY                   one entity's WM now (the wm/state that shows every change)
    fsreg-ctl [--namespace NS] clock SECONDS               set a sim-time graph's clock
    fsreg-ctl [--namespace NS] state reset [--yes]         set the stored state aside, start from the scenario

Every command checks its arguments before anything is sent (numbers finite and in
range, names and messages within the graph's limits, domains among those the graph
announced), waits (``--timeout``) until the graph in the namespace is ready (its WM
Manager's ``wm_manager/ready``), refuses to go on when two graphs share the namespace,
rejects an answer stamped by another graph, and stops with exit 3 within 2 s when the
graph leaves while it waits (its WM Manager stopped or died, or its readiness was lost).
With ``--json`` each prints the answer as one JSON object (``watch``: one per line).
Errors are one line on stderr.  Exit codes: 0 answered, 1 the graph answered with an
error or refused (an unknown entity, a parameter change the node rejected, a clock
earlier than the graph's), 2 bad usage (malformed or out-of-range arguments, a node,
parameter or domain the graph does not have, input over the graph's size limits), 3 no
answer (no graph, not ready, timed out, the graph left, two graphs, another graph's answer).

``set``: a memory setting (``policy``, ``decay_period``, ``capacity``, ...) applies to
every domain's setting; ``DOMAIN.KEY=VALUE`` to one domain's (``inherit`` as the value
makes it follow the node-wide one); ``NODE:KEY=VALUE`` sets a parameter of another node
(``reg:algorithm=greedy``, ``consultant_faces:threshold=0.6``).  Keys, values and
ranges are checked against the node's declared parameters and the settings table (a
node-wide setting a domain overrides, an empty node-wide ``policy`` and ``use_sim_time``
are refused); every node's values are checked before any is set, so a refused command
changes nothing (:meth:`~fsreg_ros.ros.parameter_access.ParameterAccess.set_many`), and
what is printed is read back from the node.  ``assert``: ``PROP`` is certain (1.0), ``PROP:C`` has certainty C.

Commands are a table (:data:`COMMANDS`): adding one is one function registered with
:func:`command` (its arguments, and what it needs: a ready graph, any graph, or none).

``state reset``: every consultant moves its state database aside (never deleting it)
and serves its scenario afresh (no runtime facts, empty WM), as a new incarnation; it
asks for confirmation on the terminal unless ``--yes``, refuses without a terminal and
without ``--yes`` (exit 2), and exits 1 when not confirmed.  It prints what each domain
set aside and where, and returns once the graph is ready again.
"""

from __future__ import annotations

import argparse
import difflib
import json
import os
import secrets
import sys
from dataclasses import dataclass
from typing import Any, Callable, Optional, Sequence

from ..contract.codec import printable
from ..contract import normalise_namespace
from ..contract.naming import check_topic
from ..core.forgetting import settings
from ..core.memory.ticks import MAX_TIME
from ..ros.network import NetworkRefused, enforce_loopback, require_loopback
from ..ros.diagnostics import PERIOD as DIAGNOSTICS_PERIOD, read_statuses, summary
from .arguments import OneLineParser, number, undecodable
from .up import restored_text
from .view import check_host, check_port, serve_view

PROG = "fsreg-ctl"
EXIT_OK, EXIT_ERROR, EXIT_USAGE, EXIT_NO_ANSWER = 0, 1, 2, 3
#: Client error kinds that mean "no answer from this graph".
NO_ANSWER = ("not-ready", "timeout", "clash", "foreign", "cancelled", "unavailable", "gone")
#: Memory settings: applied to every domain unless given as DOMAIN.KEY.
MEMORY_KEYS = settings.names()
#: Longest ``--timeout``, seconds (a day).
MAX_TIMEOUT = 86_400.0
#: Seconds without an answer after which a request is sent again (the node answers a repeated id from its cache).
RETRY_AFTER = 4.0
#: Most WM updates ``watch --count`` waits for.
MAX_COUNT = 10**9


class UsageError(ValueError):
    """A command line that cannot be turned into a request."""


@dataclass(frozen=True)
class Command:
    """One subcommand: its help, its arguments, what it needs of the graph, and what it does.

    ``needs``: ``ready`` (waits until the graph serves), ``graph`` (the graph found,
    ready or not: ``status``, ``watch``, ``params``), ``none`` (no graph needed).
    ``run(ctl, client)`` returns the exit code; ``check(args)`` refuses bad arguments
    (UsageError) before any ROS is started.
    """

    name: str
    help: str
    run: Callable[["Ctl", Any], int]
    arguments: Callable[[argparse.ArgumentParser], None]
    needs: str = "ready"
    check: Optional[Callable[[argparse.Namespace], None]] = None


#: Every subcommand, by name, in the order ``--help`` lists them.
COMMANDS: dict[str, Command] = {}


def command(name: str, help: str, *, needs: str = "ready", arguments: Optional[Callable] = None,
            check: Optional[Callable] = None) -> Callable:
    """Register the decorated ``run(ctl, client) -> exit code`` as subcommand ``name``."""
    def register(run: Callable) -> Callable:
        COMMANDS[name] = Command(name, help, run, arguments or (lambda parser: None), needs, check)
        return run
    return register


def build_parser() -> argparse.ArgumentParser:
    common = OneLineParser(add_help=False)
    common.add_argument("--namespace", default=argparse.SUPPRESS, help="the graph's ROS namespace (default: none)")
    common.add_argument("--json", action="store_true", default=argparse.SUPPRESS, help="print JSON")
    common.add_argument("--timeout", type=number(0.0, MAX_TIMEOUT, above=True, unit="seconds"),
                        default=argparse.SUPPRESS, metavar="S",
                        help=f"seconds to wait for the graph and for each answer, in (0, {MAX_TIMEOUT:g}] (default 10)")
    common.add_argument("--graph", default=argparse.SUPPRESS, metavar="ID",
                        help="the graph identity expected (default: the one running in the namespace)")
    common.add_argument("--clock", default=argparse.SUPPRESS, metavar="TOPIC",
                        help="the clock topic 'clock' publishes on (default: the graph's own)")
    parser = OneLineParser(prog=PROG, parents=[common],
                           description="Talk to a live fsreg graph (started with fsreg-up).")
    commands = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    for spec in COMMANDS.values():
        spec.arguments(commands.add_parser(spec.name, parents=[common], help=spec.help))
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
            raise UsageError(f"assert: {printable(repr(item), 80)}: the certainty after ':' must be a number in "
                             "[0, 1]") from None
        if not prop or not 0.0 <= certainty <= 1.0:
            raise UsageError(f"assert: {printable(repr(item), 80)}: give PROP or PROP:C with C in [0, 1]")
        facts[prop] = certainty
    return facts


def parse_assignments(items: Sequence[str], domains: Sequence[str]) -> dict[str, dict[str, Any]]:
    """Return ``KEY=VALUE`` items as node -> {parameter: value} (see the module docstring).

    A memory setting's value is checked against the settings table here (``inherit``
    for a domain's setting is its inherit marker); other values stay text, converted to
    the parameter's declared type by the client.
    """
    out: dict[str, dict[str, Any]] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise UsageError(f"set: {printable(repr(item), 80)}: expected KEY=VALUE")
        node, colon, name = key.rpartition(":")
        if colon:
            if not node or not name:
                raise UsageError(f"set: {printable(repr(item), 80)}: expected NODE:KEY=VALUE")
            if node == "wm_manager" and _memory_key(name, domains):
                value = memory_value(item, name, value, domains)
            out.setdefault(node, {})[name] = value
        elif key in MEMORY_KEYS:
            if key == "policy" and value.strip() != "inherit":  # the node-wide value, checked as the node does
                _check_node_wide(item, key, value, domains)
            for domain in domains:
                name = f"{domain}.{key}"
                out.setdefault("wm_manager", {})[name] = memory_value(item, name, value, domains)
        else:
            out.setdefault("wm_manager", {})[key] = memory_value(item, key, value, domains) \
                if _memory_key(key, domains) else value
    return out


def _check_node_wide(item: str, key: str, value: str, domains: Sequence[str]) -> None:
    """Refuse a value the WM Manager refuses for its node-wide ``key`` (an empty policy: WM would silently be off)."""
    from ..ros.node_parameters import ParameterError, check_parameter, node_parameters

    try:
        check_parameter(node_parameters("wm_manager", domains)[key], value)
    except ParameterError as err:
        said = str(err) if str(err).startswith(key) else f"{key}: {err}"
        raise UsageError(f"set {printable(item, 120)}: wm_manager: {said}") from None


def _memory_key(name: str, domains: Sequence[str]) -> bool:
    domain, dot, key = name.rpartition(".")
    return key in MEMORY_KEYS and (not dot or domain in domains)


def memory_value(item: str, name: str, text: str, domains: Sequence[str]) -> Any:
    """Return a memory setting's value from text, checked against the settings table; UsageError naming the rule."""
    domain, dot, key = name.rpartition(".")
    row = settings.setting(key)
    where = f"set {printable(item, 120)}: wm_manager: {name}"
    inherit = f", or 'inherit' (use the node-wide {key})" if dot else ""
    if text.strip() == "inherit":
        if not dot:
            raise UsageError(f"{where}: only a domain's setting (DOMAIN.{key}) inherits")
        return row.inherit
    if not row.is_parameter:
        return text
    rule = f"{row.bounds_text}{inherit}"
    try:
        value: Any = int(text) if row.kind is int else float(text)
    except (ValueError, OverflowError):
        raise UsageError(f"{where}: expected {rule}, got {printable(repr(text), 60)}") from None
    try:
        settings.check_value(key, value)
    except settings.PolicyError as err:
        raise UsageError(f"{where}: {err} (allowed: {rule})") from None
    return value


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
            + (f", next decay tick at {tick:g} s" if isinstance(tick, (int, float)) else "")
            + f"; {restored_text((status.get('restored') or {}).get(domain))}")
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
    bad = undecodable(sys.argv[1:] if argv is None else argv)
    if bad is not None:
        print(f"{PROG}: error: {bad}", file=sys.stderr)
        return EXIT_USAGE
    args = build_parser().parse_args(argv)
    try:
        namespace = normalise_namespace(option(args, "namespace", ""))
        if option(args, "clock", None) is not None:
            try:
                check_topic(args.clock)
            except ValueError as err:
                raise UsageError(f"--clock: {err}") from None
        timeout = float(option(args, "timeout", 10.0))
        spec = COMMANDS[args.command]
        if spec.check is not None:
            spec.check(args)
    except (UsageError, ValueError) as err:
        print(f"{PROG}: error: {err}", file=sys.stderr)
        return EXIT_USAGE
    try:
        os.environ.update(enforce_loopback(dict(os.environ)))
    except NetworkRefused as err:  # pragma: no cover - require_loopback refused it already
        print(f"{PROG}: error: {err}", file=sys.stderr)
        return EXIT_USAGE
    return Ctl(args, namespace, timeout).run()


class Ctl:
    """One fsreg-ctl command against one graph."""

    def __init__(self, args: argparse.Namespace, namespace: str, timeout: float) -> None:
        self.args = args
        self.namespace = namespace
        self.timeout = timeout
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
        client = None
        try:
            client = GraphClient(node, executor, graph=option(self.args, "graph", None), timeout=self.timeout,
                                 retry_after=RETRY_AFTER)
            spec = COMMANDS[self.args.command]
            if spec.needs == "graph":  # works on a graph that is not ready (yet)
                self.find(client)
            elif spec.needs == "ready":
                client.wait_ready(self.timeout, pipeline=False)  # requests wait for their own topics (exchange)
            client.notice_leaving = spec.needs != "none"
            return spec.run(self, client)
        except ClientError as err:
            print(printable(f"{PROG}: error: {err}", 2000), file=sys.stderr)
            if err.kind == "usage":
                return EXIT_USAGE
            return EXIT_NO_ANSWER if err.kind in NO_ANSWER else EXIT_ERROR
        except UsageError as err:
            print(printable(f"{PROG}: error: {err}", 2000), file=sys.stderr)
            return EXIT_USAGE
        except KeyboardInterrupt:
            return EXIT_OK
        finally:
            if client is not None:  # what was sent reaches every reader (a recorder too) before the node goes
                client.delivered()
                if client.unheard():  # never silently: a recording that lacks a request says why
                    print(printable(f"{PROG}: warning: {client.unheard()}", 2000), file=sys.stderr)
            executor.shutdown(timeout_sec=1.0)
            node.destroy_node()
            rclpy.try_shutdown(context=context)

    def find(self, client) -> None:
        """Find the graph in the namespace (not necessarily ready)."""
        from ..ros.client import ClientError

        client.spin_until(lambda: client.ready_messages, self.timeout,
                          f"no fsreg graph answers in {client.where()} (is fsreg-up running there?)", "not-ready")
        client.check_clash()
        if client.graph is None:
            (client.graph, _, _), = client.ready_messages
        elif client.readiness() is None:
            raise ClientError(f"graph {client.graph!r} is not in {client.where()}", "not-ready")

    def now(self, client) -> float:
        """Return the graph's clock: a request is stamped with it, never earlier than a ``clock`` that returned."""
        return client.graph_time()


def _error(ctl: Ctl, answer: dict, what: str) -> None:
    """Raise ClientError (exit 1) with the graph's error reply in one line (``--json``: the reply on stdout too)."""
    from ..ros.client import ClientError

    if ctl.json:
        ctl.emit(answer, "")
    raise ClientError(f"{what}: {answer.get('error')}", "error")


# ------------------------------------------------------------------ commands
def _say_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("text", nargs="*", help="what the human says (words)")
    parser.add_argument("--description", metavar="P1,P2", help="a property list instead of text")
    parser.add_argument("--domain", help="the domain the description is about")


def _say_check(args: argparse.Namespace) -> None:
    if bool(args.text) == bool(args.description):
        raise UsageError("say: give the words to say, or --description P1,P2 (not both)")
    if args.description is not None and not _properties(args.description):
        raise UsageError(f"say: --description {printable(repr(args.description), 80)} names no property; "
                         "give P1,P2")


def _properties(text: str) -> list[str]:
    return [p.strip() for p in text.split(",") if p.strip()]


@command("say", "the human says TEXT; print whom RR resolved", arguments=_say_arguments, check=_say_check)
def say(ctl: Ctl, client) -> int:
    args = ctl.args
    if args.domain is not None and args.domain not in client.domains():
        raise UsageError(f"say: the graph has no domain {printable(repr(args.domain), 80)} (its domains: "
                         f"{', '.join(client.domains())})")
    description = _properties(args.description) if args.description else None
    words = len(" ".join(args.text).split())
    if words > client.limits.max_list_items:  # each word is one of the parser's tokens, answered as a list
        raise UsageError(f"say: {words} words; the graph takes at most {client.limits.max_list_items} "
                         "(max_list_items)")
    answer = client.say(" ".join(args.text) if args.text else None, description=description, domain=args.domain,
                        time=ctl.now(client))
    if answer.get("status") == "error" or "error" in answer:
        _error(ctl, answer, "say")
    ctl.emit(answer, show_say(answer))
    return EXIT_OK


def _describe_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("entity")
    parser.add_argument("--context", nargs="+", metavar="E", help="describe against these entities only")


@command("describe", "the robot describes ENTITY", arguments=_describe_arguments)
def describe(ctl: Ctl, client) -> int:
    args = ctl.args
    answer = client.describe(args.entity, context=args.context, time=ctl.now(client))
    if "error" in answer:
        _error(ctl, answer, f"describe {printable(args.entity, 80)}")
    ctl.emit(answer, show_describe(answer))
    return EXIT_OK


def _assert_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("entity")
    parser.add_argument("properties", nargs="+", metavar="PROP[:C]", help="a property, with certainty C (default 1)")
    parser.add_argument("--domain", help="the consultant's domain (default: the one knowing ENTITY, or the only one)")


@command("assert", "tell a consultant facts about ENTITY", arguments=_assert_arguments,
         check=lambda args: parse_facts(args.properties) and None)
def assert_(ctl: Ctl, client) -> int:
    args = ctl.args
    answer = client.assert_facts(args.entity, parse_facts(args.properties), domain=args.domain)
    if not answer.get("ok"):
        _error(ctl, answer, f"assert {printable(args.entity, 80)}")
    ctl.emit(answer, show_assert(answer))
    return EXIT_OK


@command("status", "readiness and memory of every domain, and every node's /diagnostics", needs="graph")
def status(ctl: Ctl, client) -> int:
    reply = client.status()
    # every node's /diagnostics (at 1 Hz: one period and a little more hears each node once)
    reply["diagnostics"] = read_statuses(client.node, client.spin_for, client.node.get_namespace(),
                                         wait=DIAGNOSTICS_PERIOD * 1.5)
    ctl.emit(reply, "\n".join([show_status(reply), *summary(reply["diagnostics"])]))
    return EXIT_OK


def _set_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("assignments", nargs="+", metavar="KEY=VALUE")


def _set_check(args: argparse.Namespace) -> None:
    for item in args.assignments:
        key, sep, _ = item.partition("=")
        node, colon, name = key.rpartition(":")
        if not sep or not key or colon and not (node and name):
            raise UsageError(f"set: {printable(repr(item), 80)}: expected KEY=VALUE or NODE:KEY=VALUE")


@command("set", "change memory settings or node parameters (checked, then read back)", arguments=_set_arguments,
         check=_set_check)
def set_(ctl: Ctl, client) -> int:
    from ..ros.client import ClientError

    changes = parse_assignments(ctl.args.assignments, client.domains())
    for node_name, values in changes.items():  # every node and key checked before anything is set
        client.require_node(node_name)
        known = client.list_parameters(node_name)
        for name in values:
            if name not in known:
                close = difflib.get_close_matches(name, known, n=1)
                hint = f"did you mean {close[0]}?" if close else f"its parameters: {', '.join(known)}"
                raise UsageError(f"set: node {node_name} has no parameter {printable(repr(name), 80)} ({hint})")
    try:
        now = client.set_many(changes)  # every node's values checked first, then all set or none
    except ClientError as err:
        raise ClientError(f"set: {err}", err.kind) from None
    shown = {node: {k: "inherit" if node == "wm_manager" and _inherits(k, v, client.domains()) else v
                    for k, v in vals.items()} for node, vals in now.items()}
    ctl.emit({"set": now}, f"set {_assignments(shown)}")
    return EXIT_OK


def _inherits(name: str, value: Any, domains: Sequence[str]) -> bool:
    """Return whether a domain's memory setting is at its inherit marker (it follows the node-wide value)."""
    domain, dot, key = name.rpartition(".")
    return bool(dot) and domain in domains and key in MEMORY_KEYS and value == settings.setting(key).inherit


def _assignments(values: dict[str, dict[str, Any]]) -> str:
    return "; ".join(f"{node}: " + ", ".join(f"{k}={_text(v)}" for k, v in params.items())
                     for node, params in values.items())


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, list):
        return "[" + ", ".join(_text(v) for v in value) + "]"
    return f"{value:g}" if isinstance(value, float) else str(value)


def _params_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=("get", "dump"), help="get: KEY=VALUE lines; dump: ros2 param dump's YAML")
    parser.add_argument("items", nargs="*", metavar="ITEM",
                        help="NODE, NODE:KEY, or a memory setting (KEY, DOMAIN.KEY) of wm_manager "
                             "(default: every node)")


@command("params", "read parameters back: get (NODE:KEY=VALUE lines) or dump (the YAML ros2 param dump writes)",
         needs="graph", arguments=_params_arguments)
def params(ctl: Ctl, client) -> int:
    from ..ros.node_parameters import dump_yaml

    args = ctl.args
    wanted: dict[str, Optional[list[str]]] = {}
    for item in args.items or client.node_names():
        node, colon, key = item.rpartition(":")
        if not colon and _memory_key(item, client.domains()):
            node, key = "wm_manager", item
        elif not colon:
            node, key = item, ""
        if args.action == "dump" and key:
            raise UsageError(f"params dump: {printable(item, 80)}: dump takes node names (get reads single keys)")
        client.require_node(node)
        if key:
            if wanted.get(node, []) is not None:
                wanted.setdefault(node, []).append(key)
        else:
            wanted[node] = None
    values: dict[str, dict[str, Any]] = {}
    for node, keys in wanted.items():
        known = client.list_parameters(node)
        for key in keys or ():
            if key not in known:
                close = difflib.get_close_matches(key, known, n=1)
                raise UsageError(f"params get: node {node} has no parameter {printable(repr(key), 80)}"
                                 + (f" (did you mean {close[0]}?)" if close else ""))
        values[node] = client.get_parameters(node, keys or known)
    if args.action == "dump":
        prefix = "" if client.namespace == "/" else client.namespace
        print(json.dumps({f"{prefix}/{n}": v for n, v in values.items()}, sort_keys=True) if ctl.json
              else dump_yaml({f"{prefix}/{n}": v for n, v in values.items()}), end="\n" if ctl.json else "", flush=True)
    else:
        ctl.emit(values, "\n".join(f"{node}:{k}={_text(v)}" for node, vals in values.items() for k, v in vals.items()))
    return EXIT_OK


def _watch_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--events", action="store_true", help="also print every encode/forget event")
    parser.add_argument("--count", type=number(1, MAX_COUNT, integer=True), metavar="N",
                        help="stop after N WM updates")


@command("watch", "show each entity's WM live (Ctrl-C ends; exit 3 when the graph leaves)", needs="graph",
         arguments=_watch_arguments)
def watch(ctl: Ctl, client) -> int:
    from ..ros.client import ClientError

    args = ctl.args
    seen = {"states": 0}
    screen = Screen(sys.stdout) if sys.stdout.isatty() and not ctl.json else None

    def on_state(state: dict) -> None:
        seen["states"] += 1
        if screen is not None:
            screen.update(state)
        else:
            ctl.emit(state, show_state(state))

    def on_event(event: dict) -> None:
        if screen is None:
            ctl.emit(event, show_event(event))

    client.watch(on_state, on_event if args.events else None)
    while args.count is None or seen["states"] < args.count:
        client.executor.spin_once(timeout_sec=0.1)
        client.check_gone()
        if client.foreign is not None:
            raise ClientError(client.foreign, "foreign")
    return EXIT_OK


def _wm_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("entity")
    parser.add_argument("--domain")


@command("wm", "one entity's WM, least recently used first", arguments=_wm_arguments)
def wm(ctl: Ctl, client) -> int:
    from ..ros.client import ClientError

    args = ctl.args
    if args.domain is not None and args.domain not in client.domains():
        raise UsageError(f"wm: the graph has no domain {printable(repr(args.domain), 80)} (its domains: "
                         f"{', '.join(client.domains())})")
    try:
        domain = args.domain or client.domain_of(args.entity)
    except ClientError as err:  # an entity the graph does not know: the graph's answer (exit 1), as describe's
        if err.kind != "usage":
            raise
        raise ClientError(f"wm {printable(args.entity, 80)}: {err}", "error") from None
    state = client.state(domain, current=True)  # wm/state as of now: no debug service needed
    queue = list((state.get("queues") or {}).get(args.entity, []))
    ctl.emit({"entity": args.entity, "domain": domain, "queue": queue, "time": state.get("time")},
             f"{args.entity} ({domain}): {', '.join(queue) or '(empty)'}")
    return EXIT_OK


def _clock_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("seconds", type=number(0.0, MAX_TIME, unit="seconds"),
                        help=f"the time, in [0, {MAX_TIME:g}] s and not earlier than the graph's clock")


@command("clock", "set a sim-time graph's clock to SECONDS (refused: a wall-clock graph, a clock going back)",
         arguments=_clock_arguments)
def clock(ctl: Ctl, client) -> int:
    seconds = ctl.args.seconds
    reply = client.set_clock(seconds, confirm=True)
    ctl.emit(reply, f"clock at {seconds:g} s; the forgetting due by then is applied")
    return EXIT_OK


def _view_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--port", type=number(0, 65535, integer=True), default=None, metavar="N",
                        help="TCP port of the page (default 8765; 0 takes a free port)")
    parser.add_argument("--host", default="127.0.0.1", metavar="ADDRESS",
                        help="address to bind (default 127.0.0.1: this machine only)")


def _view_check(args: argparse.Namespace) -> None:
    args.port = check_port(args.port)
    try:
        check_host(args.host)
    except ValueError as err:
        raise UsageError(f"view: {err}") from None


@command("view", "serve a live web page of the graph's WM on 127.0.0.1 (Ctrl-C ends)", needs="graph",
         arguments=_view_arguments, check=_view_check)
def view(ctl: Ctl, client) -> int:
    from ..ros.client import ClientError

    args = ctl.args
    try:
        return serve_view(client, args.host, args.port, announce=lambda text: print(text, flush=True))
    except OSError as err:
        raise ClientError(f"view: cannot serve on {args.host}:{args.port}: {err.strerror or err}", "usage") from None


def _record_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("directory", metavar="DIR", help="the recording's folder (must not exist)")
    parser.add_argument("--duration", type=number(0.0, 7 * 86400, above=True, unit="seconds"), metavar="S",
                        help="stop after S seconds (wall clock)")
    parser.add_argument("--segment", type=number(0.0, 3600, above=True, unit="seconds"), default=1.0, metavar="S",
                        help="close a segment every S seconds: what a killed recorder can lose at most (default 1)")
    parser.add_argument("--nice", type=number(0, 19, integer=True), default=10, metavar="N",
                        help="run the recorder N nice levels below where it was started, so it never takes the "
                        "graph's CPU (0-19, default 10)")


def check_record(args: argparse.Namespace) -> None:
    """Refuse a ``record`` command line that cannot be recorded (one line, exit 2)."""
    from ..core.io.recording import RecordingError, check_target

    try:
        check_target(args.directory)
    except RecordingError as err:
        raise UsageError(f"record: {err}") from None


@command("record", "record every fsreg topic to a new rosbag2 folder DIR (MCAP) until Ctrl-C", needs="none",
         arguments=_record_arguments, check=check_record)
def record(ctl: Ctl, client) -> int:
    """``record``: every fsreg topic of the namespace to a rosbag2 folder until Ctrl-C, SIGTERM or --duration.

    Recording starts at once (nothing that comes while the graph is looked for is lost).
    """
    import signal
    import time
    from pathlib import Path

    from ..core.io.recording import RecordingError
    from ..ros.client import ClientError
    from ..ros.recorder import Recorder, graph_knowledge, lower_priority

    args = ctl.args
    lower_priority(args.nice)  # every thread of this process, DDS's too; the recorder's thread inherits it
    try:  # recording starts at once: nothing that comes while the graph is looked for is lost
        recorder = Recorder(client.node, Path(args.directory), segment_seconds=args.segment,
                            custom={"fsreg.namespace": ctl.namespace or "/"}, nice=0)
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
            client.spin_until(lambda: client.ready_messages, ctl.timeout, "readiness", "not-ready")
            client.check_clash()
            if client.graph is None:
                (client.graph, _, _), = client.ready_messages
            custom, attach = graph_knowledge(client, ctl.timeout)
            recorder.bag.custom.update(custom)
            for key, source in attach.items():
                recorder.attach(key, source)
        except ClientError as err:
            if err.kind == "clash":
                raise
            print(f"{PROG}: note: no graph answered in {client.where()} within {ctl.timeout:g} s; recording "
                  "whatever comes (a replay will need --scenario)", file=sys.stderr, flush=True)
        # The recorder's own thread records; this process's client is not spun meanwhile (its
        # subscriptions to the answers are not needed, and an executor wake-up per answer is
        # what recording must not cost).
        while (deadline is None or time.monotonic() < deadline) and recorder.error is None:
            time.sleep(0.05 if deadline is None else max(0.0, min(0.05, deadline - time.monotonic())))
    except KeyboardInterrupt:
        pass
    finally:
        for sig in previous:  # closing the bag is not interrupted
            signal.signal(sig, signal.SIG_IGN)
        path = recorder.close()
    if recorder.error is not None:
        raise ClientError(f"record: writing {path} failed: {printable(recorder.error)}; what was written before "
                          "is kept there", "failed")
    counts = recorder.counts
    ctl.emit({"recorded": str(path), "messages": sum(counts.values()), "counts": counts},
             f"recorded {recorder.summary()}")
    return EXIT_OK


# ------------------------------------------------------------------ state
def _state_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("action", choices=["reset"], help="reset: move every state database aside (never deleted)")
    parser.add_argument("--yes", action="store_true", help="do not ask for confirmation (needed without a terminal)")


def check_state_args(args: argparse.Namespace, stdin=None) -> None:
    """Refuse ``state reset`` without ``--yes`` when there is no terminal to confirm on (UsageError: exit 2)."""
    stdin = sys.stdin if stdin is None else stdin
    if not args.yes and not (stdin is not None and stdin.isatty()):
        raise UsageError("state reset: no terminal to confirm on; add --yes to reset without asking")


@command("state", "the consultants' stored state: 'reset' sets it aside and serves the scenario afresh",
         arguments=_state_arguments, check=check_state_args)
def state(ctl: Ctl, client) -> int:
    """``state reset [--yes]`` (issue 28.6): :func:`run_state`."""
    return run_state(client, ctl.args, ctl.emit, ctl.timeout)


def run_state(client, args: argparse.Namespace, emit, timeout: float, ask=input) -> int:
    """``state reset``: confirm, reset every domain's consultant, wait until the graph serves again; exit code.

    Each consultant checkpoints, moves its database aside and serves its KB afresh as a
    new incarnation (manage op ``reset``); this returns once the WM Manager configured
    every new incarnation.  Not confirmed: nothing is sent, exit 1.
    """
    from ..ros.client import ClientError

    domains = client.domains()
    if not args.yes:
        answer = ask(f"{PROG}: reset the stored state of {', '.join(domains)} in graph {client.graph} "
                     f"({client.where()}): runtime facts and WM are set aside; continue? [y/N] ")
        if answer.strip().lower() not in ("y", "yes"):
            print(f"{PROG}: state reset not confirmed; nothing changed", file=sys.stderr)
            return EXIT_ERROR
    replies: dict[str, dict] = {}
    client.notice_leaving = False  # each consultant is unready until configured again: expected, waited for below
    for domain in domains:
        try:
            replies[domain] = client.reset_state(domain, timeout)
        except ClientError as err:
            done = f" ({', '.join(replies)} reset already)" if replies else ""
            raise ClientError(f"state reset of '{domain}': {err}{done}", err.kind) from None

    def serving() -> bool:
        ready = client.readiness() or {}
        states = ready.get("domains") or {}
        return bool(ready.get("ready")) and all(
            (states.get(d) or {}).get("incarnation") == reply["incarnation"] for d, reply in replies.items())

    client.spin_until(serving, timeout, "the graph serving again after the state reset", "not-ready")
    lines = []
    for domain, reply in replies.items():
        cleared = reply["cleared"]
        lines.append(f"{domain}: set aside {cleared['runtime_facts']} runtime facts ({cleared['runtime_entities']} "
                     f"runtime entities) and {cleared['queues']} WM queues"
                     + (f", the old state moved to {reply['moved_aside']}" if reply.get("moved_aside") else "")
                     + f"; incarnation {reply['incarnation']} serves the scenario afresh")
    emit({"reset": replies}, "\n".join(lines))
    return EXIT_OK


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
