#!/usr/bin/env python3
"""Benchmark and fault probe of the live view under many coming-and-going browsers (issue 37.8).

Starts a graph of node processes (the public harness, as ``fsreg-up`` runs it) and
``fsreg-ctl view --port 0`` against it, then times ``--rounds`` ``say`` + ``describe``
round trips twice: with no page open, and while ``--clients`` event-stream clients (in a
process of their own) connect to ``/events`` and leave, over and over: a third at once
(a TCP reset before the answer), the others after reading for 0.05-0.5 s, half of them
with a reset (a killed tab), half with a clean close.  Prints each
phase's p50/p99 per kind, how many connections the clients made (and how many were
answered 503 at the cap), and how many lines the view printed on stderr (tracebacks
included: it should print none).

    scripts/bench_view_clients.py [--clients 100] [--rounds 40]

Run it any way: it re-executes itself with ``.venv/bin/python`` (:mod:`venv_python`).
Set ``ROS_DOMAIN_ID`` to a domain of your own first.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import socket
import statistics
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

from venv_python import prepare  # noqa: E402

REPO = prepare("bench_view_clients.py")  # .venv, import path


SCENARIO = REPO / "scenarios" / "guess_who_table1.yaml"


def churn(url: str, clients: int) -> dict:
    """Run ``clients`` threads that open ``/events``, read a while and leave, until stdin ends; return counts."""
    host, port = url.split("//", 1)[1].rstrip("/").rsplit(":", 1)
    counts = {"connections": 0, "refused_503": 0, "errors": 0}  # errors: a connection refused or timed out
    lock = threading.Lock()
    stop = threading.Event()

    def one(seed: int) -> None:
        rng = random.Random(seed)
        while not stop.is_set():
            try:
                sock = socket.create_connection((host, int(port)), timeout=5)
                sock.sendall(b"GET /events HTTP/1.1\r\nHost: x\r\n\r\n")
                if rng.random() < 1 / 3:  # a tab closed at once: gone before the answer
                    sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
                    sock.close()
                    with lock:
                        counts["connections"] += 1
                    continue
                head = sock.recv(4096)
                until = time.monotonic() + rng.uniform(0.05, 0.5)
                try:
                    while time.monotonic() < until:
                        sock.settimeout(max(0.01, until - time.monotonic()))
                        if not sock.recv(65536):
                            break
                except TimeoutError:
                    pass  # read as long as it meant to: it leaves now
                if rng.random() < 0.5:
                    sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
                sock.close()
                with lock:
                    counts["connections"] += 1
                    counts["refused_503"] += head.startswith(b"HTTP/1.0 503")
            except OSError:
                with lock:
                    counts["errors"] += 1

    threads = [threading.Thread(target=one, args=(i,), daemon=True) for i in range(clients)]
    for thread in threads:
        thread.start()
    sys.stdin.read()  # the parent closes it when its timing is done
    stop.set()
    for thread in threads:
        thread.join()
    return counts


def timed(robot, rounds: int) -> dict[str, list[float]]:
    out: dict[str, list[float]] = {"say": [], "describe": []}
    for _ in range(rounds):
        start = time.perf_counter()
        robot.say("male, glasses")
        out["say"].append(time.perf_counter() - start)
        start = time.perf_counter()
        robot.describe("face1")
        out["describe"].append(time.perf_counter() - start)
    return out


def summary(samples: dict[str, list[float]]) -> str:
    parts = []
    for kind, values in samples.items():
        ordered = sorted(values)
        p99 = ordered[min(len(ordered) - 1, int(round(0.99 * (len(ordered) - 1))))]
        parts.append(f"{kind} p50 {statistics.median(ordered) * 1e3:.1f} ms, p99 {p99 * 1e3:.1f} ms")
    return "; ".join(parts)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--clients", type=int, default=100)
    parser.add_argument("--rounds", type=int, default=40)
    parser.add_argument("--churn", metavar="URL", help=argparse.SUPPRESS)  # the clients' own process
    args = parser.parse_args()
    if args.churn:
        print(json.dumps(churn(args.churn, args.clients)))
        return 0
    from fsreg_ros.testing import LiveGraph

    bin_dir = Path(sys.executable).parent
    with LiveGraph(SCENARIO, processes=True) as robot:
        view = subprocess.Popen([str(bin_dir / "fsreg-ctl"), "--namespace", robot.namespace, "view", "--port", "0"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            line = view.stdout.readline()
            url = line.split(" at ", 1)[1].split()[0]
            timed(robot, 3)  # warm-up
            quiet = timed(robot, args.rounds)
            started = time.monotonic()
            clients = subprocess.Popen([sys.executable, __file__, "--churn", url, "--clients", str(args.clients)],
                                       stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
            time.sleep(1.0)  # the clients are coming and going before the timing starts
            busy = timed(robot, args.rounds)
            counts = json.loads(clients.communicate(input="", timeout=60)[0])
            churned = time.monotonic() - started
        finally:
            view.send_signal(signal.SIGINT)
            _, err = view.communicate(timeout=30)
    lines = [line for line in err.splitlines() if line.strip()]
    print(f"view at {url}; {args.rounds} say + describe per phase, {os.environ.get('ROS_DOMAIN_ID', '?')} "
          f"ROS domain")
    print(f"no page open:              {summary(quiet)}")
    print(f"{args.clients} clients coming and going: {summary(busy)}")
    print(f"  over {churned:.0f} s: {counts['connections']} event-stream connections, {counts['refused_503']} "
          f"answered 503 (the cap), {counts['errors']} failed (refused or timed out)")
    print(f"the view's stderr: {len(lines)} lines, {sum('Traceback' in x for x in lines)} tracebacks")
    for line in lines[:5]:
        print(f"  {line}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
