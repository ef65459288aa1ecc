#!/usr/bin/env python3
"""Soak the multi-process node graph OPEN-LOOP: human turns and REG requests sent on a schedule.

Starts the live graph as users run it (``fsreg_ros.testing.LiveGraph`` with
``processes=True``, as ``fsreg-up`` runs it: every default, persistence on, sim time, a
namespace of its own; the consultants' debug service off) and plays a dialogue manager
and a perception loop through the harness's public :class:`~fsreg_ros.ros.client.GraphClient`:
``--rate`` human turns per second on ``dialogue/human`` and ``--rate`` REG requests per
second on ``reg/request`` (the REG schedule offset by half a period), each sent at its
scheduled moment whatever the answers (open loop: nothing waits for a reply).  The
graph's clock follows the wall clock (published with every message; the requests are
stamped with it), so decay ticks as it would on a robot.  The turns and targets cycle
through the scenario's dialogue, each with a fresh id.

Latency is measured from each message's *scheduled* moment to its reply (a sender
that falls behind its schedule is not hidden; the largest lateness is reported).  The
sender's cyclic garbage collector is off while it sends and collects the replies (it
keeps every reply, ~10^5 objects with perception, and a full collection paused it ~200 ms
every ~5 s: the whole graph's latency spiked at those moments).
Prints per path: sent, lost (no reply by the end), duplicated (more than one reply),
error replies, p50/p95/p99/max latency; and per node the RSS at start and end and its
slope in MB per 1,000 requests (least squares over samples taken once a second), and the
CPU seconds each node and the sender used during the run.

``--facts-rate N [--batch K]``: also play perception: N facts per second on ``ltm/assert``
(K facts per message, so N/K messages per second, each on its schedule like the rest),
about a pool of ``--facts-entities`` perceived entities of the first domain (new at their
first fact, updated after: certainty 1.0 or 0.8 of one property, so nothing the dialogue
relies on changes); reported: facts sent, applied, refused, lost (no answer) and not sent
(the publisher refused: backpressure), their latency, and how many of the perceived
entities the consultant knows afterwards.  Facts messages move no clock.

``--step``: after the first stage, run further stages at ``--rate`` x 2, x 3, ... (a new
graph each, same counts) until REG's p99 passes 100 ms (or ``--max-rate``), and say at
which rate it did.  ``--kill-consultant-at K``: also run once SIGKILLing the first
domain's consultant just before message K and starting it again at once (as a
supervisor would); prints, besides both runs' figures, the replies that differ.

    scripts/soak.py --turns 1000 --requests 1000 --rate 20
    scripts/soak.py --turns 400 --requests 400 --rate 20 --step
    scripts/soak.py --turns 200 --requests 200 --rate 20 --kill-consultant-at 100
    scripts/soak.py --turns 400 --requests 400 --rate 20 --facts-rate 1000
    scripts/soak.py --turns 400 --requests 400 --rate 20 --facts-rate 10000 --batch 50
    scripts/soak.py --record      # the same run twice: without, then with `fsreg-ctl record` (cost, nothing dropped)

``--clock-hz N``: the graph's clock comes from a simulator instead: a process of its own
publishes ``/clock`` (the graph's clock topic) N times a second, following the wall clock
from the run's start, as Gazebo does every physics step (N = 1000); the sender then
publishes no clock and stamps its requests with the same wall-clock time.  That process's
CPU is reported as ``clock``.

    scripts/soak.py --turns 400 --requests 400 --rate 20 --clock-hz 1000
    scripts/soak.py --turns 400 --requests 400 --rate 20 --clock-hz 1000 --facts-rate 500

``--record``: after the first run, run again with ``fsreg-ctl record`` recording the graph
(its own process, as a robot would run it), print both runs' figures and the cost in p99,
then count every message in the bag against what was sent and answered (the requests and
answers per id, and each consultant's ``wm/events`` numbered without a gap).
"""

from __future__ import annotations

import argparse
import gc
import itertools
import math
import os
import sys
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

from venv_python import prepare  # noqa: E402

REPO = prepare("soak.py", loopback=True)  # .venv, import path, loopback ROS

import psutil  # noqa: E402

from fsreg_ros import contract  # noqa: E402
from fsreg_ros.ros.client import ClientError  # noqa: E402
from fsreg_ros.core.scenario import Scenario, load_scenario  # noqa: E402
from fsreg_ros.testing import LiveGraph  # noqa: E402

READY_TIMEOUT = 60.0
DRAIN = 15.0  # wall seconds without a reply after which the unanswered are lost (a dead consultant call costs 10 s)
#: REG p99 (ms) that ends --step.
STEP_LIMIT_MS = 100.0
#: The client's request kind of each soak message kind.
KINDS = {"human": "say", "reg": "describe", "facts": "assert"}


@dataclass
class Sent:
    """One message: its kind, index, scheduled and actual send times (monotonic), and the replies it got."""

    kind: str
    index: int
    due: float
    sent: float
    replies: list[tuple[float, dict]] = field(default_factory=list)
    facts: int = 0  # facts it carries (perception messages)


@dataclass
class RunResult:
    rate: float
    messages: dict[str, Sent]
    rss: dict[str, list[tuple[int, float]]]  # node -> [(requests sent, MB)]
    seconds: float
    late_ms: float  # the most a message left after its scheduled moment
    killed_at: Optional[int] = None
    busy: int = 0  # facts messages the publisher refused (backpressure)
    cpu: dict[str, float] = field(default_factory=dict)  # node -> CPU seconds used during the run
    known: Optional[tuple[int, int]] = None  # (perceived entities the consultant knows, of how many)
    clock_hz: float = 0.0  # --clock-hz (0: the sender publishes the clock with every message)


def schedule(scenario: Scenario, turns: int, requests: int, rate: float, facts_rate: float = 0.0, batch: int = 1,
             pool: int = 100) -> list[tuple[float, str, dict]]:
    """Return (offset s, kind, message) in time order.

    Human turns at ``rate``, REG at ``rate`` half a period later, and ``facts_rate`` facts
    per second in messages of ``batch`` facts over the same span.
    """
    human = [t for t in scenario.dialogue if t.speaker == "human"]
    robot = [t for t in scenario.dialogue if t.speaker == "robot"]
    if (turns and not human) or (requests and not robot):
        raise SystemExit("soak.py: error: the scenario's dialogue needs human and robot turns to cycle through")
    period = 1.0 / rate
    out = []
    for i in range(turns):
        t = human[i % len(human)]
        msg: dict = {"text": t.text} if t.text is not None else {"description": list(t.description)}
        if t.domain:
            msg["domain"] = t.domain
        out.append((i * period, "human", msg))
    for i in range(requests):
        t = robot[i % len(robot)]
        msg = {"target": t.target}
        if t.context:
            msg["context"] = list(t.context)
        out.append((i * period + period / 2, "reg", msg))
    if facts_rate:
        out += facts_plan(scenario, max(turns, requests) * period, facts_rate, batch, pool)
    return sorted(out, key=lambda item: item[0])


def facts_plan(scenario: Scenario, seconds: float, rate: float, batch: int, pool: int) -> list[tuple[float, str, dict]]:
    """Return the perception messages: ``rate`` facts/s for ``seconds``, ``batch`` per message.

    Fact i is about ``perceived<i mod pool>`` of the first domain: a new entity at its first
    fact, then updates (one property of the preference order, certainty 1.0 or 0.8: it holds).
    """
    domain, spec = next(iter(scenario.domains.items()))
    preference = list(spec.preference)
    count = int(seconds * rate)
    messages, period = [], batch / rate
    for start in range(0, count, batch):
        facts = []
        for i in range(start, min(count, start + batch)):
            prop = preference[(i // pool) % len(preference)]
            facts.append({"entity": f"perceived{i % pool}", "properties": {prop: 1.0 if (i // pool) % 2 else 0.8}})
        msg: dict = {"domain": domain, "facts": facts} if batch > 1 else {"domain": domain, **facts[0]}
        messages.append((start // batch * period, "facts", msg))
    return messages


def facts_in(msg: dict) -> int:
    """Return how many facts a perception message carries."""
    return len(msg["facts"]) if "facts" in msg else 1


def spin_until(live: LiveGraph, predicate, deadline: float) -> bool:
    """Spin the harness's executor until ``predicate()`` or the deadline; whether it came true."""
    while not predicate():
        now = time.monotonic()
        if now >= deadline:
            return False
        live.session.executor.spin_once(timeout_sec=min(0.002, deadline - now))
    return True


def warm_up(live: LiveGraph, plan: list[tuple[float, str, dict]]) -> set[str]:
    """One real round trip per pipeline (the first call to a new server can be slow), at time 0; return the ids."""
    live.client.set_clock(0.0, READY_TIMEOUT)
    ids = set()
    for kind in KINDS:
        msg = next((m for _, k, m in plan if k == kind), None)
        if msg is None:
            continue
        stamp = {} if kind == "facts" else {"time": 0.0}
        try:
            key = live.client.new_id("warm")
            ids.add(key)
            reply = live.client.exchange(KINDS[kind], {**msg, "id": key, **stamp}, READY_TIMEOUT)
        except ClientError as err:
            raise SystemExit(f"soak.py: error: no reply to the warm-up {kind} message: {err}") from None
        if reply.get("error"):
            raise SystemExit(f"soak.py: error: the warm-up {kind} message was refused: {reply['error']}")
    return ids


def cpu_seconds(graph, recorder: Optional["Recording"] = None) -> dict[str, float]:
    """Return the CPU seconds (user + system) each node process, this sender and the recorder have used so far."""
    out = {}
    procs = [(spec.name, proc.pid) for spec, proc in graph.procs] + [("sender (soak.py)", os.getpid())]
    if recorder is not None:
        procs.append(("recorder (fsreg-ctl)", recorder.proc.pid))
    for name, pid in procs:
        try:
            times = psutil.Process(pid).cpu_times()
        except psutil.NoSuchProcess:
            continue
        out[name] = times.user + times.system
    return out


def rss_sample(graph, done: int, rss: dict[str, list[tuple[int, float]]]) -> None:
    for spec, proc in graph.procs:
        try:
            rss.setdefault(spec.name, []).append((done, psutil.Process(proc.pid).memory_info().rss / 2**20))
        except psutil.NoSuchProcess:
            pass


class Recording:
    """``fsreg-ctl record`` of the soaked graph, in its own process."""

    def __init__(self, live: LiveGraph, path: Path) -> None:
        import subprocess

        self.path = path
        self.proc = subprocess.Popen([str(Path(sys.executable).parent / "fsreg-ctl"), "--namespace", live.namespace,
                                      "record", str(path)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                     env=os.environ)
        client = live.client
        pubs = [client._publishers[k] for k in KINDS.values()]  # the recorder's subscriptions matched: 2 readers
        if not spin_until(live, lambda: all(p.get_subscription_count() >= 2 for p in pubs),
                          time.monotonic() + READY_TIMEOUT):
            raise SystemExit("soak.py: error: the recorder did not subscribe in time")

    def holds(self, ids: set[str]) -> bool:
        """Whether the recording's closed segments hold an answer to each of ``ids`` and a WM event.

        Only then is the recorder matched with every writer the soak's answers come from
        (discovery is per pair of processes: the recorder can hear the sender before RR).
        """
        from fsreg_ros.core.io.recording import RecordingError, open_recording

        try:
            recording = open_recording(self.path)
        except RecordingError:  # no segment closed yet
            return False
        answered = {m.data.get("id") for role in ("rr", "expression", "assert_result") for m in recording.on(role)
                    if isinstance(m.data, dict)}
        return ids <= answered and bool(recording.on("events"))

    def stop(self) -> None:
        import signal

        self.proc.send_signal(signal.SIGINT)
        out, err = self.proc.communicate(timeout=120)
        if self.proc.returncode != 0:
            raise SystemExit(f"soak.py: error: fsreg-ctl record exited {self.proc.returncode}: {err.decode()[-500:]}")


class SimulatorClock:
    """``--clock-hz``: a process publishing the graph's clock N times a second from ``epoch`` (CLOCK_MONOTONIC)."""

    def __init__(self, live: LiveGraph, hz: float, epoch: float) -> None:
        import subprocess

        topic = live.client.node.resolve_topic_name(contract.CLOCK)
        self.proc = subprocess.Popen([sys.executable, str(REPO / "scripts" / "simulator_clock.py"), topic, repr(hz),
                                      repr(epoch)],
                                     env=dict(os.environ), stdin=subprocess.DEVNULL)
        self.ps = psutil.Process(self.proc.pid)

    def cpu(self) -> float:
        try:
            times = self.ps.cpu_times()
        except psutil.Error:
            return 0.0
        return times.user + times.system

    def stop(self) -> None:
        import signal

        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(timeout=5)
        except Exception:  # noqa: BLE001 - a publisher that does not stop is killed
            self.proc.kill()
            self.proc.wait()


def run(args: argparse.Namespace, rate: float, kill_at: Optional[int], record: Optional[Path] = None) -> RunResult:
    scenario = load_scenario(args.scenario)
    plan = schedule(scenario, args.turns, args.requests, rate, args.facts_rate, args.batch, args.facts_entities)
    memory = {"policy": args.policy} if args.policy else {}
    debug_off = {f"consultant_{d}": {"debug": False} for d in scenario.domains}  # as fsreg-up runs them
    with LiveGraph(args.scenario, processes=True, parameters=debug_off, ready_timeout=READY_TIMEOUT,
                   **memory) as live:
        client, graph = live.client, live.graph
        rss: dict[str, list[tuple[int, float]]] = {}
        messages: dict[str, Sent] = {}
        recorder = Recording(live, record) if record is not None else None
        ids = warm_up(live, plan)
        deadline = time.monotonic() + READY_TIMEOUT
        while recorder is not None and not recorder.holds(ids):  # again until the recorder hears every writer
            if time.monotonic() > deadline:
                raise SystemExit("soak.py: error: the recorder did not hear the warm-up's answers in time")
            spin_until(live, lambda: False, time.monotonic() + 1.0)
            if not recorder.holds(ids):
                ids = warm_up(live, plan)
        for kind in KINDS:
            client.wait_matched(KINDS[kind], READY_TIMEOUT)
        consultant = f"consultant_{next(iter(scenario.domains))}"
        simulator = None
        if args.clock_hz:
            epoch = time.monotonic() + 3.0  # the clock starts at 0 when the run does, once the process is up
            simulator = SimulatorClock(live, args.clock_hz, epoch)
            spin_until(live, lambda: False, epoch)
        cpu_before = cpu_seconds(graph, recorder)
        clock_cpu = simulator.cpu() if simulator else 0.0
        gc.collect()
        gc.disable()  # the sender's own pauses: see quiet_gc()
        start = epoch if simulator else time.monotonic()
        next_sample, late, busy = start, 0.0, 0
        for i, (offset, kind, msg) in enumerate(plan):
            if kill_at is not None and i == kill_at:
                graph.restart(consultant)  # SIGKILL, then start it again at once, as a supervisor would
            due = start + offset
            spin_until(live, lambda: False, due)  # collect replies until this message's moment
            now = time.monotonic()
            late = max(late, now - due)
            if now >= next_sample:
                rss_sample(graph, i, rss)
                next_sample += 1.0
            key = client.new_id(kind)
            if kind == "facts":  # perception moves no clock; the consultant stamps it with its own
                try:
                    client.send(KINDS[kind], {"id": key, **msg})
                except ClientError:  # backpressure: the publisher refused it (counted, not retried)
                    busy += 1
                    continue
                messages[key] = Sent(kind, i, due, time.monotonic(), facts=facts_in(msg))
                continue
            stamp = now - start  # the robot's clock follows the wall clock
            if simulator is None:
                client.publish_clock(stamp)
            messages[key] = Sent(kind, i, due, time.monotonic())
            client.send(KINDS[kind], {**msg, "id": key, "time": stamp})
        waiting = set(messages)  # wait for the last replies while they still come (DRAIN s without one: lost)

        def drained() -> bool:
            waiting.difference_update([k for k in itertools.islice(waiting, 500) if client.answers[k]])
            return not waiting

        while waiting:
            before = len(waiting)
            spin_until(live, drained, time.monotonic() + DRAIN)
            waiting.difference_update([k for k in list(waiting) if client.answers[k]])
            if len(waiting) == before:
                break
        spin_until(live, lambda: False, time.monotonic() + 0.5)  # late duplicates
        gc.enable()
        rss_sample(graph, len(plan), rss)
        seconds = time.monotonic() - start
        cpu = {name: used - cpu_before.get(name, 0.0) for name, used in cpu_seconds(graph, recorder).items()}
        if simulator is not None:
            cpu["clock"] = simulator.cpu() - clock_cpu
            simulator.stop()
        for key, sent in messages.items():
            sent.replies = [(a.received, a.data) for a in client.answers.pop(key, [])]
        if recorder is not None:
            recorder.stop()
        known = None
        facts_msgs = [m for _, k, m in plan if k == "facts"]
        if facts_msgs:
            pool = {f["entity"] for m in facts_msgs for f in (m.get("facts") or [m])}
            domain = facts_msgs[0]["domain"]
            try:
                info = client.call(contract.consultant_service(domain), {"op": "info"}, READY_TIMEOUT)
                known = (len(pool & set(info.get("entities") or ())), len(pool))
            except ClientError as err:
                print(f"soak.py: cannot ask the consultant of {domain} what it knows: {err}", file=sys.stderr)
        for spec, code in graph.dead():
            print(f"soak.py: node {spec.name} died (exit {code})\n{graph.tail(spec.name)}", file=sys.stderr)
        return RunResult(rate, messages, rss, seconds, late * 1e3, kill_at, busy=busy, known=known, cpu=cpu,
                         clock_hz=args.clock_hz)


# ------------------------------------------------------------------- figures
def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(q / 100 * len(ordered)))] if ordered else float("nan")


def latencies(result: RunResult, kind: str) -> list[float]:
    """Milliseconds from each answered message's scheduled moment to its first reply."""
    return [1000 * (s.replies[0][0] - s.due) for s in result.messages.values() if s.kind == kind and s.replies]


def slope(points: list[tuple[int, float]]) -> float:
    """Least-squares MB per 1,000 requests."""
    if len(points) < 2:
        return float("nan")
    n = len(points)
    mx, my = sum(x for x, _ in points) / n, sum(y for _, y in points) / n
    sxx = sum((x - mx) ** 2 for x, _ in points)
    return 1000 * sum((x - mx) * (y - my) for x, y in points) / sxx if sxx else float("nan")


def report(result: RunResult, title: str) -> str:
    load = os.getloadavg()
    clock = f"/clock at {result.clock_hz:g} Hz from a simulator process" if result.clock_hz else \
        "/clock with every message"
    lines = [f"== {title}: open loop, {result.rate:g} human turns/s + {result.rate:g} REG requests/s, {clock}, "
             f"{len(result.messages)} messages in {result.seconds:.1f} s, sender at most {result.late_ms:.1f} ms "
             f"behind schedule; load average {load[0]:.2f} on {os.cpu_count()} cores"]
    for kind in ("human", "reg"):
        sent = [s for s in result.messages.values() if s.kind == kind]
        if not sent:
            continue
        lost = sum(1 for s in sent if not s.replies)
        dup = sum(1 for s in sent if len(s.replies) > 1)
        errors = sum(1 for s in sent if s.replies and s.replies[0][1].get("error"))
        ms = latencies(result, kind)
        lines.append(f"{kind:6} sent {len(sent)}, lost {lost}, duplicated {dup}, errors {errors}; latency ms "
                     f"p50 {percentile(ms, 50):.1f} p95 {percentile(ms, 95):.1f} p99 {percentile(ms, 99):.1f} "
                     f"max {max(ms, default=float('nan')):.1f}")
    lines += facts_report(result)
    errors = Counter(s.replies[0][1]["error"][:120] for s in result.messages.values()
                     if s.replies and s.replies[0][1].get("error") and s.kind != "facts")
    lines += [f"  error x{n}: {text}" for text, n in errors.most_common(5)]
    lost = [k for k, s in result.messages.items() if not s.replies]
    if lost:
        lines.append(f"  lost: {', '.join(lost[:20])}")
    lines.append("RSS MB start -> end, slope MB per 1,000 requests:")
    for name, points in sorted(result.rss.items()):
        lines.append(f"  {name:22} {points[0][1]:7.1f} -> {points[-1][1]:7.1f}  {slope(points):+.3f}")
    if result.cpu:
        lines.append(f"CPU seconds used in the {result.seconds:.1f} s (share of one core): " + ", ".join(
            f"{name} {used:.1f} ({used / result.seconds:.0%})" for name, used in sorted(result.cpu.items())))
    return "\n".join(lines)


def facts_report(result: RunResult) -> list[str]:
    """Return the perception lines: facts sent, applied, refused, lost, not sent; latency; what is known."""
    sent = [s for s in result.messages.values() if s.kind == "facts"]
    if not sent and not result.busy:
        return []
    applied = refused = lost = 0
    errors: Counter = Counter()
    for s in sent:
        if not s.replies:
            lost += s.facts
            continue
        data = s.replies[0][1]
        if "results" in data:
            applied += data.get("applied", 0)
            refused += data.get("refused", 0)
            errors.update(r.get("error", "")[:100] for r in data["results"] if not r.get("ok"))
        elif data.get("ok"):
            applied += 1
        else:
            refused += s.facts
            errors[(data.get("error") or "")[:100]] += s.facts
    dup = sum(1 for s in sent if len(s.replies) > 1)
    per = max((s.facts for s in sent), default=1)
    ms = latencies(result, "facts")
    lines = [f"facts  sent {sum(s.facts for s in sent)} ({len(sent)} messages of {per}), applied {applied}, "
             f"refused {refused}, lost {lost}, not sent (publisher refused) {result.busy} messages, duplicated "
             f"{dup}; latency ms p50 {percentile(ms, 50):.1f} p95 {percentile(ms, 95):.1f} "
             f"p99 {percentile(ms, 99):.1f} max {max(ms, default=float('nan')):.1f}"]
    if result.known is not None:
        lines.append(f"  the consultant knows {result.known[0]} of the {result.known[1]} perceived entities")
    lines += [f"  refused x{n}: {text}" for text, n in errors.most_common(3)]
    return lines


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
    by_index = {s.index: s for s in killed.messages.values()}
    pairs = [(s, by_index[s.index]) for s in base.messages.values() if s.index in by_index]
    differ = [(a, answer(a), answer(b)) for a, b in pairs if answer(a) != answer(b)]
    after = [d for d in differ if d[0].index >= (killed.killed_at or 0)]
    lines = [f"== kill at message {killed.killed_at}: {len(differ)} of {len(pairs)} replies differ "
             f"from the uninterrupted run ({len(after)} at or after the kill; timing differs between open-loop "
             "runs, so decay can differ too)"]
    for kind in ("human", "reg"):
        lines.append(f"  {kind}: {sum(1 for s, _, _ in differ if s.kind == kind)} differ")
    lines += [f"  #{s.index} {s.kind}: {a!r} -> {b!r}" for s, a, b in differ[:15]]
    return "\n".join(lines)


def recording_report(result: RunResult, path: Path) -> str:
    """Count every message of the recording against what was sent and answered (nothing may be dropped)."""
    from fsreg_ros.core.io.recording import open_recording
    from fsreg_ros.core.simulation.replay import ReplayError, check_events

    recording = open_recording(path)
    lines = [f"== recording {path}: {len(recording.messages)} messages"
             + (f"; {recording.lost}" if recording.lost else "")]
    dropped = 0
    for kind, request, reply in (("human", "human", "rr"), ("reg", "request", "expression")):
        sent = {k for k, s in result.messages.items() if s.kind == kind}
        answered = {k for k in sent if result.messages[k].replies}
        got_requests = {m.data.get("id") for m in recording.on(request) if isinstance(m.data, dict)}
        got_replies = {m.data.get("id") for m in recording.on(reply) if isinstance(m.data, dict)}
        missing = len(sent - got_requests) + len(answered - got_replies)
        dropped += missing
        lines.append(f"  {request}: {len(sent & got_requests)} of {len(sent)} sent; {reply}: "
                     f"{len(answered & got_replies)} of {len(answered)} answers")
        gone = sorted(result.messages[k].index for k in (sent - got_requests) | (answered - got_replies))
        if gone:
            lines.append(f"    missing from the bag (message indices): {', '.join(map(str, gone[:20]))}"
                         + (" ..." if len(gone) > 20 else ""))
    events = [m.data for m in recording.on("events") if isinstance(m.data, dict)]
    try:
        check_events(str(path), events)
        lines.append(f"  wm/events: {len(events)}, numbered without a gap")
    except ReplayError as err:
        dropped += 1
        lines.append(f"  wm/events: {err}")
    lines.append(f"  dropped: {dropped}")
    return "\n".join(lines)


def write_csv(result: RunResult, path: Path) -> None:
    """Write one line per message: index, kind, scheduled offset (s), latency (ms; empty if lost)."""
    start = min(s.due for s in result.messages.values())
    rows = ["index,kind,offset_s,latency_ms"]
    for s in sorted(result.messages.values(), key=lambda s: s.index):
        latency = f"{1000 * (s.replies[0][0] - s.due):.2f}" if s.replies else ""
        rows.append(f"{s.index},{s.kind},{s.due - start:.3f},{latency}")
    path.write_text("\n".join(rows) + "\n", encoding="utf-8")


def main(argv: Optional[list[str]] = None) -> int:
    parser = argparse.ArgumentParser(prog="soak.py", description=__doc__.split("\n\n")[0])
    default = REPO / "scenarios" / "guess_who_table1.yaml"  # Table 1 (or $FSREG_SHARED_DATA/table1.yaml)
    if not default.is_file() and os.environ.get("FSREG_SHARED_DATA"):
        default = Path(os.environ["FSREG_SHARED_DATA"]) / "table1.yaml"
    parser.add_argument("scenario", type=Path, nargs="?", default=default)
    parser.add_argument("--turns", type=int, default=1000, help="human turns (default 1000)")
    parser.add_argument("--requests", type=int, default=1000, help="REG requests (default 1000)")
    parser.add_argument("--rate", type=float, default=20.0, help="human turns and REG requests per second, each "
                        "(default 20)")
    parser.add_argument("--facts-rate", type=float, default=0.0, metavar="N",
                        help="also assert N facts per second on ltm/assert (default 0: none)")
    parser.add_argument("--batch", type=int, default=1, metavar="K",
                        help="facts per ltm/assert message (default 1: one message per fact)")
    parser.add_argument("--facts-entities", type=int, default=100, metavar="P",
                        help="perceived entities the facts are about, new at their first fact (default 100)")
    parser.add_argument("--step", action="store_true", help=f"raise the rate stage by stage until REG p99 passes "
                        f"{STEP_LIMIT_MS:g} ms")
    parser.add_argument("--max-rate", type=float, default=400.0, help="highest rate --step tries (default 400)")
    parser.add_argument("--policy", help="forgetting policy (default: the scenario's)")
    parser.add_argument("--csv", type=Path, help="write every message of the first run here: index, kind, "
                        "scheduled offset s, latency ms (empty: lost)")
    parser.add_argument("--kill-consultant-at", type=int, metavar="K",
                        help="also run once SIGKILLing and restarting the consultant before message K")
    parser.add_argument("--record", action="store_true",
                        help="also run once recording with fsreg-ctl record; the cost and a count of the bag")
    parser.add_argument("--clock-hz", type=float, default=0.0, metavar="N",
                        help="a simulator process publishes /clock N times a second (default 0: the sender "
                             "publishes it with every message)")
    args = parser.parse_args(argv)
    if not (math.isfinite(args.clock_hz) and 0 <= args.clock_hz <= 10_000):
        parser.error(f"--clock-hz must be a number in [0, 10000], got {args.clock_hz:g}")
    if not 0 < args.rate <= args.max_rate or args.turns < 0 or args.requests < 0 or args.turns + args.requests == 0:
        parser.error("--rate must be positive and at most --max-rate; --turns and --requests not negative, "
                     "not both 0")
    if not (math.isfinite(args.facts_rate) and 0 <= args.facts_rate <= 1_000_000):
        parser.error(f"--facts-rate must be a number in [0, 1000000], got {args.facts_rate:g}")
    if not 1 <= args.batch <= 1000 or not 1 <= args.facts_entities <= 1_000_000:
        parser.error("--batch must be in [1, 1000] (the consultants' max_list_items) and --facts-entities in "
                     "[1, 1000000]")
    if not args.scenario.is_file():
        parser.error(f"scenario not found: {args.scenario}")
    base = run(args, args.rate, None)
    print(report(base, "uninterrupted"), flush=True)
    if args.csv:
        write_csv(base, args.csv)
    if args.step:
        stage, result = 1, base
        while percentile(latencies(result, "reg"), 99) <= STEP_LIMIT_MS:
            stage += 1
            rate = args.rate * stage
            if rate > args.max_rate:
                print(f"== step: REG p99 stayed <= {STEP_LIMIT_MS:g} ms up to {args.rate * (stage - 1):g}/s "
                      f"(--max-rate {args.max_rate:g})")
                break
            result = run(args, rate, None)
            print(report(result, f"step {stage}"), flush=True)
        else:
            held = f"; it held at {result.rate - args.rate:g}/s" if stage > 1 else ""
            print(f"== step: REG p99 passed {STEP_LIMIT_MS:g} ms at {result.rate:g} requests/s "
                  f"({percentile(latencies(result, 'reg'), 99):.1f} ms){held}")
    if args.record:
        import tempfile

        with tempfile.TemporaryDirectory(prefix="fsreg-soak-") as tmp:
            path = Path(tmp) / "soak"
            recorded = run(args, args.rate, None, record=path)
            print(report(recorded, "recorded (fsreg-ctl record)"), flush=True)
            for kind in ("human", "reg"):
                before, after = (percentile(latencies(r, kind), 99) for r in (base, recorded))
                print(f"== recording cost, {kind}: p99 {before:.1f} -> {after:.1f} ms ({(after / before - 1):+.0%})")
            print(recording_report(recorded, path), flush=True)
    if args.kill_consultant_at is not None:
        killed = run(args, args.rate, args.kill_consultant_at)
        print(report(killed, f"consultant SIGKILLed and restarted at message {args.kill_consultant_at}"))
        print(compare(base, killed))
    return 0


if __name__ == "__main__":
    sys.exit(main())
