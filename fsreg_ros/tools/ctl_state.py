"""``fsreg-ctl state reset``: every consultant's stored state set aside, the scenario served afresh (issue 28.6)."""

from __future__ import annotations

import argparse
import sys

from .ctl_table import EXIT_ERROR, EXIT_OK, PROG, Ctl, UsageError, command


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
