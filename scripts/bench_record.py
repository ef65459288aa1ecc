#!/usr/bin/env python3
"""Benchmark of the bag writer a recorder runs (:class:`fsreg_ros.core.io.recording.BagWriter`), no ROS.

A recording of every topic of a graph (``fsreg_ros.ros.recorder.channels``) written
``--segments`` one-second segments of ``--per-segment`` ``wm/events`` messages each (the
soak's rate is ~700 a second), on a clock the benchmark moves, so every segment is opened,
filled and closed as a recorder's would be.  Reported: the CPU milliseconds one segment
costs (its messages, opening it, closing it: rosbags writes 14 YAML documents a segment)
and the microseconds a message costs, and whether ruamel.yaml's C emitter is in use
(``ruamel.yaml.clib``, requirements.txt), then the merge a clean close does.
Usage: ``scripts/bench_record.py [--segments N] [--per-segment M] [--pure-yaml]``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

from venv_python import prepare  # noqa: E402

prepare("bench_record.py")  # .venv, import path

from fsreg_ros import contract  # noqa: E402
from fsreg_ros.core.io.recording import BagWriter, Channel, encode_string  # noqa: E402

EVENT = {"op": "encode", "domain": "faces", "entity": "face1", "property": "male", "cause": "rr", "time": 1.0,
         "turn": 3, "seq": 5, "incarnation": 1, "graph": "fsreg-up-c4a0334b"}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="bench_record.py", description=__doc__.split("\n\n")[0])
    parser.add_argument("--segments", type=int, default=30, help="one-second segments written (default 30)")
    parser.add_argument("--per-segment", type=int, default=700, help="messages a segment (default 700)")
    parser.add_argument("--pure-yaml", action="store_true",
                        help="hide ruamel.yaml's C emitter (as without ruamel.yaml.clib installed)")
    args = parser.parse_args(argv)
    if not 1 <= args.segments <= 10_000 or not 0 <= args.per_segment <= 1_000_000:
        parser.error("--segments must be in [1, 10000] and --per-segment in [0, 1000000]")
    if args.pure_yaml:
        sys.modules["_ruamel_yaml"] = None  # type: ignore[assignment]  # its import fails: the pure emitter
    import ruamel.yaml.main as ruamel

    topics = contract.graph_topics("/bench")
    channels = [Channel(t.name, t.msgtype, t.qos.depth, t.qos.latched, t.qos.lease) for t in topics]
    events = next(t.name for t in topics if t.topic is contract.WM_EVENTS)
    raw = encode_string(EVENT)
    ticks = [0]
    with tempfile.TemporaryDirectory(prefix="fsreg-bench-record-") as tmp:
        writer = BagWriter(Path(tmp) / "bag", channels, custom={"fsreg.topics": "{}"}, now=lambda: ticks[0])
        start = time.process_time()
        for segment in range(args.segments):
            for i in range(args.per_segment):
                writer.write(events, segment * 10**9 + i, raw)
            ticks[0] = (segment + 1) * 10**9
            writer.poll()  # closes the segment, as the recorder's thread does once it is a second old
        used = time.process_time() - start
        merge = time.process_time()
        writer.close()
        merged = time.process_time() - merge
    messages = args.segments * args.per_segment
    emitter = "C (ruamel.yaml.clib)" if ruamel.CEmitter is not None else "pure Python"
    print(f"{args.segments} segments of {args.per_segment} messages ({len(channels)} topics), YAML emitter "
          f"{emitter}: {1000 * used / args.segments:.1f} ms CPU a segment, "
          f"{1e6 * used / max(messages, 1):.1f} us a message all told; merge at close {merged:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
