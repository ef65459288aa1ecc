"""``fsreg-ctl`` talking with the graph: ``say`` (the human), ``describe`` (the robot), ``assert`` (facts)."""

from __future__ import annotations

import argparse

from ..contract.codec import printable
from .ctl_show import show_assert, show_describe, show_say
from .ctl_table import EXIT_OK, Ctl, UsageError, answer_error, command
from .ctl_values import parse_facts


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
        answer_error(ctl, answer, "say")
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
        answer_error(ctl, answer, f"describe {printable(args.entity, 80)}")
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
        answer_error(ctl, answer, f"assert {printable(args.entity, 80)}")
    ctl.emit(answer, show_assert(answer))
    return EXIT_OK
