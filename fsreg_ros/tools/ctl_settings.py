"""``fsreg-ctl`` reading and changing the graph's settings: ``status``, ``set`` (checked, read back), ``params``."""

from __future__ import annotations

import argparse
import difflib
import json
from typing import Any, Optional

from ..contract.codec import printable
from ..ros.diagnostics import PERIOD as DIAGNOSTICS_PERIOD, read_statuses, summary
from .ctl_show import show_status
from .ctl_table import EXIT_OK, Ctl, UsageError, command
from .ctl_values import inherits, memory_key, parse_assignments


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
    shown = {node: {k: "inherit" if node == "wm_manager" and inherits(k, v, client.domains()) else v
                    for k, v in vals.items()} for node, vals in now.items()}
    ctl.emit({"set": now}, f"set {_assignments(shown)}")
    return EXIT_OK


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
        if not colon and memory_key(item, client.domains()):
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
