"""``fsreg-ctl``'s long-running commands: ``view`` (a live web page of the WM), ``record`` (a rosbag2 folder)."""

from __future__ import annotations

import argparse
import sys

from ..contract.codec import printable
from .arguments import number
from .ctl_table import EXIT_OK, PROG, Ctl, UsageError, command
from .view import check_host, check_port, serve_view


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
