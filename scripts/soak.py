#!/usr/bin/env python3
"""Soak the multi-process node graph: N human turns and N REG requests at a given rate.

Starts the live graph as one process per node (``fsreg_ros.testing.LiveGraph`` with
``processes=True``, as ``fsreg-up`` runs it: sim time, a namespace of its own) and plays
the player's part through the harness's client: for each message it advances the
graph's clock by ``--step`` sim seconds, calls the WM Manager's ``sync`` barrier, then
publishes a human turn on ``dialogue/human`` or a REG request on ``reg/request``,
alternating, at ``--rate`` messages per wall-clock second, in order (a message waits for
the previous one's reply, at most ``ORDER_WAIT`` after it was sent, so that two runs
are comparable turn by turn).  The turns and targets cycle through the scenario's
dialogue, each with a fresh id.

Prints: lost (no reply by the end) and duplicated (more than one reply) per kind,
replies that are errors, p50/p95/p99 latency (publish -> reply, wall clock), and per
node the RSS at start and end and its slope in MB per 1,000 requests (least squares
over samples taken once a second).

``--kill-consultant-at K`` runs twice: once uninterrupted, once SIGKILLing the
first domain's consultant just before message K and starting it again at once; it
prints, besides the figures of both runs, the replies that differ between the runs.

    scripts/soak.py --turns 1000 --requests 1000 --rate 20
    scripts/soak.py --turns 200 --requests 200 --rate 20 --kill-consultant-at 100
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from fsreg_ros.network import require_loopback, ros_environment  # noqa: E402

require_loopback("soak.py")
os.environ.update(ros_environment())  # before rclpy loads

import psutil  # noqa: E402

from fsreg_ros.client import ClientError  # noqa: E402
from fsreg_ros.core.scenario import Scenario, load_scenario  # noqa: E402
from fsreg_ros.testing import LiveGraph  # noqa: E402

READY_TIMEOUT = 60.0
SYNC_TIMEOUT = 2.0
ORDER_WAIT = 2.0  # at most this long after sending, wait for a message's reply before the next
DRAIN = 15.0  # wall seconds to wait for the last replies (a dead consultant call costs 10 s)


@dataclass
class Sent:
    """One message sent: its kind, index, wall time, and the replies it got."""

    kind: str
    index: int
    sent: float
    replies: list[tuple[float, dict]] = field(default_factory=list)


@dataclass
class RunResult:
    messages: dict[str, Sent]
    rss: dict[str, list[tuple[int, float]]]  # node -> [(requests done, MB)]
    seconds: float
    sync_failures: int
    killed_at: Optional[int] = None


def events(scenario: Scenario, turns: int, requests: int) -> list[tuple[str, dict]]:
    """Return the messages to send, human turns and REG requests alternating, cycling through the dialogue."""
    human = [t for t in scenario.dialogue if t.speaker == "human"]
    robot = [t for t in scenario.dialogue if t.speaker == "robot"]
    out = []
    for i in range(max(turns, requests)):
        if i < turns:
            t = human[i % len(human)]
            msg: dict = {"id": f"h{i}"}
            msg.update({"text": t.text} if t.text is not None else {"description": list(t.description)})
            if t.domain:
                msg["domain"] = t.domain
            out.append(("human", msg))
        if i < requests:
            t = robot[i % len(robot)]
            msg = {"id": f"r{i}", "target": t.target}
            if t.context:
                msg["context"] = list(t.context)
            out.append(("reg", msg))
    return out


#: The client's request kind of each soak message kind.
KINDS = {"human": "say", "reg": "describe"}


def spin_until(live: LiveGraph, predicate, deadline: float) -> bool:
    """Spin the harness's executor until ``predicate()`` or the deadline; whether it came true."""
    while not predicate():
        if time.monotonic() > deadline:
            return False
        live.session.executor.spin_once(timeout_sec=0.002)
    return True


def warm_up(live: LiveGraph, messages: list[tuple[str, dict]]) -> None:
    """One real round trip per pipeline (the first call to a new server can be slow), at time 0."""
    live.client.set_clock(0.0, READY_TIMEOUT)
    for kind, msg in messages:
        try:
            live.client.exchange(KINDS[kind], {**msg, "id": f"warm-{msg['id']}", "time": 0.0}, READY_TIMEOUT)
        except ClientError as err:
            raise SystemExit(f"soak.py: error: no reply to the warm-up {kind} message: {err}") from None


def rss_sample(graph, done: int, rss: dict[str, list[tuple[int, float]]]) -> None:
    for spec, proc in graph.procs:
        try:
            rss.setdefault(spec.name, []).append((done, psutil.Process(proc.pid).memory_info().rss / 2**20))
        except psutil.NoSuchProcess:
            pass


def run(args: argparse.Namespace, kill_at: Optional[int]) -> RunResult:
    scenario = load_scenario(args.scenario)
    plan = events(scenario, args.turns, args.requests)
    with LiveGraph(args.scenario, processes=True, policy=args.policy, ready_timeout=READY_TIMEOUT) as live:
        client, graph = live.client, live.graph
        rss: dict[str, list[tuple[int, float]]] = {}
        sync_failures = 0
        messages: dict[str, Sent] = {}
        warm_up(live, plan[:2])
        consultant = f"consultant_{next(iter(scenario.domains))}"
        period, start = 1.0 / args.rate, time.monotonic()
        next_sample, previous = start, None
        for i, (kind, msg) in enumerate(plan):
            if kill_at is not None and i == kill_at:
                graph.restart(consultant)  # SIGKILL, then start it again at once, as a supervisor would
            slot = start + i * period
            spin_until(live, lambda: False, slot)  # spin (collect replies) until this message's slot
            if previous is not None:  # in order: a turn's WM changes land before the next request reads WM
                spin_until(live, lambda: client.answers[previous], max(slot, messages[previous].sent + ORDER_WAIT))
            if time.monotonic() >= next_sample:
                rss_sample(graph, i, rss)
                next_sample += 1.0
            t = (i + 1) * args.step
            client.publish_clock(t)
            try:
                client.sync(t, SYNC_TIMEOUT)
            except ClientError:
                sync_failures += 1
            previous = msg["id"]
            messages[previous] = Sent(kind, i, time.monotonic())
            client.send(KINDS[kind], {**msg, "time": t})
        spin_until(live, lambda: all(client.answers[k] for k in messages), time.monotonic() + DRAIN)
        spin_until(live, lambda: False, time.monotonic() + 0.5)  # late duplicates
        rss_sample(graph, len(plan), rss)
        seconds = time.monotonic() - start
        for key, sent in messages.items():
            sent.replies = [(a.received, a.data) for a in client.answers[key]]
        for spec, code in graph.dead():
            print(f"soak.py: node {spec.name} died (exit {code})\n{graph.tail(spec.name)}", file=sys.stderr)
        return RunResult(messages, rss, seconds, sync_failures, kill_at)


# ------------------------------------------------------------------- figures
def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q / 100 * len(ordered)))] if ordered else float("nan")


def slope(points: list[tuple[int, float]]) -> float:
    """Least-squares MB per 1,000 requests."""
    if len(points) < 2:
        return float("nan")
    n = len(points)
    mx, my = sum(x for x, _ in points) / n, sum(y for _, y in points) / n
    sxx = sum((x - mx) ** 2 for x, _ in points)
    return 1000 * sum((x - mx) * (y - my) for x, y in points) / sxx if sxx else float("nan")


def report(result: RunResult, title: str) -> str:
    lines = [f"== {title}: {len(result.messages)} messages in {result.seconds:.1f} s, "
             f"{result.sync_failures} sync calls failed"]
    for kind in ("human", "reg"):
        sent = [s for s in result.messages.values() if s.kind == kind]
        if not sent:
            continue
        lost = sum(1 for s in sent if not s.replies)
        dup = sum(1 for s in sent if len(s.replies) > 1)
        errors = sum(1 for s in sent if s.replies and s.replies[0][1].get("error"))
        ms = [1000 * (s.replies[0][0] - s.sent) for s in sent if s.replies]
        lines.append(f"{kind:6} sent {len(sent)}, lost {lost}, duplicated {dup}, errors {errors}; latency ms "
                     f"p50 {percentile(ms, 50):.1f} p95 {percentile(ms, 95):.1f} p99 {percentile(ms, 99):.1f} "
                     f"max {max(ms, default=float('nan')):.1f}")
    errors = Counter(s.replies[0][1]["error"][:120] for s in result.messages.values()
                     if s.replies and s.replies[0][1].get("error"))
    lines += [f"  error x{n}: {text}" for text, n in errors.most_common(5)]
    lost = [k for k, s in result.messages.items() if not s.replies]
    if lost:
        lines.append(f"  lost: {', '.join(lost[:20])}")
    lines.append("RSS MB start -> end, slope MB per 1,000 requests:")
    for name, points in sorted(result.rss.items()):
        lines.append(f"  {name:22} {points[0][1]:7.1f} -> {points[-1][1]:7.1f}  {slope(points):+.3f}")
    return "\n".join(lines)


def answer(sent: Sent) -> object:
    """Return what a reply says, for comparing runs (description or resolution, or the error)."""
    if not sent.replies:
        return "lost"
    data = sent.replies[0][1]
    if data.get("error"):
        return f"error: {data['error'][:80]}"
    if sent.kind == "reg":
        return tuple(data.get("description") or ())
    return (data.get("status"), data.get("resolved"))


def compare(base: RunResult, killed: RunResult) -> str:
    differ = [(k, answer(s), answer(killed.messages[k])) for k, s in base.messages.items()
              if answer(s) != answer(killed.messages[k])]
    after = [d for d in differ if base.messages[d[0]].index >= (killed.killed_at or 0)]
    lines = [f"== kill at message {killed.killed_at}: {len(differ)} of {len(base.messages)} replies differ "
             f"from the uninterrupted run ({len(after)} at or after the kill)"]
    for kind in ("human", "reg"):
        n = sum(1 for k, _, _ in differ if base.messages[k].kind == kind)
        lines.append(f"  {kind}: {n} differ")
    lines += [f"  {k}: {a!r} -> {b!r}" for k, a, b in differ[:15]]
    return "\n".join(lines)


def main(argv: Optional[list[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="soak.py", description=__doc__.split("\n\n")[0])
    default = REPO / "scenarios" / "guess_who_table1.yaml"  # Table 1 (or $FSREG_SHARED_DATA/table1.yaml)
    if not default.is_file() and os.environ.get("FSREG_SHARED_DATA"):
        default = Path(os.environ["FSREG_SHARED_DATA"]) / "table1.yaml"
    parser.add_argument("scenario", type=Path, nargs="?", default=default)
    parser.add_argument("--turns", type=int, default=1000, help="human turns (default 1000)")
    parser.add_argument("--requests", type=int, default=1000, help="REG requests (default 1000)")
    parser.add_argument("--rate", type=float, default=20.0, help="messages per wall second (default 20)")
    parser.add_argument("--step", type=float, default=1.0, help="sim seconds per message (default 1)")
    parser.add_argument("--policy", default="decay", help="forgetting policy (default decay)")
    parser.add_argument("--kill-consultant-at", type=int, metavar="K",
                        help="also run once SIGKILLing and restarting the consultant before message K")
    args = parser.parse_args(argv)
    if args.rate <= 0 or args.turns < 0 or args.requests < 0 or args.step <= 0:
        parser.error("--rate and --step must be positive, --turns and --requests not negative")
    if not args.scenario.is_file():
        parser.error(f"scenario not found: {args.scenario}")
    base = run(args, None)
    print(report(base, "uninterrupted"), flush=True)
    if args.kill_consultant_at is not None:
        killed = run(args, args.kill_consultant_at)
        print(report(killed, f"consultant SIGKILLed and restarted at message {args.kill_consultant_at}"))
        print(compare(base, killed))
    return 0


if __name__ == "__main__":
    sys.exit(main())
