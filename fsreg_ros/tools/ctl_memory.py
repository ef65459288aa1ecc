"""``fsreg-ctl`` on working memory and time: ``watch`` (every WM live), ``wm`` (one entity's now), ``clock``."""

from __future__ import annotations

import argparse
import sys

from ..contract.codec import printable
from ..core.memory.ticks import MAX_TIME
from .arguments import number
from .ctl_show import Screen, held_text, show_event, show_state
from .ctl_table import EXIT_OK, MAX_COUNT, Ctl, UsageError, command


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
    held = client.held(args.entity, domain)  # the consultant's open reply: queue, origins, strength
    queue = held["queue"]
    origins = held["origins"] + [None] * len(queue)
    strength = held["strength"] + [None] * len(queue)
    ctl.emit({"entity": args.entity, "domain": domain, **held, "time": ctl.now(client)},
             f"{args.entity} ({domain}): "
             + (", ".join(p + held_text(o, s) for p, o, s in zip(queue, origins, strength)) or "(empty)"))
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
