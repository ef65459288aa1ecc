"""``fsreg-ctl``'s command table: the subcommands (:data:`COMMANDS`), the parser, exit codes, one command's run.

A subcommand is one function registered with :func:`command` in the module of its
family (:mod:`fsreg_ros.tools.ctl` lists them); :class:`Ctl` starts the ROS node and
the graph client, waits for what the command needs, and turns errors into exit codes.
"""

from __future__ import annotations

import argparse
import json
import secrets
import sys
from dataclasses import dataclass
from typing import Any, Callable, Optional

from ..contract.codec import printable
from .arguments import OneLineParser, number

PROG = "fsreg-ctl"
EXIT_OK, EXIT_ERROR, EXIT_USAGE, EXIT_NO_ANSWER = 0, 1, 2, 3
#: Client error kinds that mean "no answer from this graph".
NO_ANSWER = ("not-ready", "timeout", "clash", "foreign", "cancelled", "unavailable", "gone")
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


def answer_error(ctl: Ctl, answer: dict, what: str) -> None:
    """Raise ClientError with the graph's error reply in one line (``--json``: the reply on stdout too).

    Exit 1, or 2 (bad usage) for an input refused for its size (kind ``too-large``): what
    was sent is at fault, not the graph's state.
    """
    from ..ros.client import ClientError

    if ctl.json:
        ctl.emit(answer, "")
    raise ClientError(f"{what}: {answer.get('error')}", "usage" if answer.get("kind") == "too-large" else "error")
