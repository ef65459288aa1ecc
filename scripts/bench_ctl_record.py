#!/usr/bin/env python3
"""Time ``fsreg-ctl describe`` without and with a recorder, and count what the recording holds (issue 38.4).

Starts ``fsreg-up`` (table 1) in a namespace of its own, runs ``--runs`` describes, then
starts ``fsreg-ctl record`` and runs as many again; prints each phase's median wall time
(a whole process: start, discovery, readiness, the request, leaving) and how many of the
describes of the second phase the bag holds (by id) and how many warned on stderr.
Run it with the ROS environment set (``source scripts/rosenv.sh``) and ``ROS_DOMAIN_ID``
of your own::

    .venv/bin/python scripts/bench_ctl_record.py --runs 8
"""

from __future__ import annotations

import argparse
import signal
import statistics
import subprocess
import sys
import tempfile
import time
import uuid
from pathlib import Path

from venv_python import prepare  # noqa: E402

REPO = prepare("bench_ctl_record.py", loopback=True)  # .venv, import path, loopback ROS
BIN = Path(sys.executable).parent


def ctl(ns: str, *args: str) -> tuple[float, subprocess.CompletedProcess]:
    start = time.monotonic()
    done = subprocess.run([str(BIN / "fsreg-ctl"), "--namespace", ns, *args], capture_output=True, text=True,
                          timeout=120)
    return time.monotonic() - start, done


def describes(ns: str, runs: int) -> tuple[list[float], int]:
    times, warned = [], 0
    for _ in range(runs):
        took, done = ctl(ns, "describe", "face1")
        assert done.returncode == 0, done
        times.append(took)
        warned += "warning" in done.stderr
    return times, warned


def named(ns: str) -> None:
    """Wait until the graph's WM Manager names a recorder on ``wm_manager/ready`` (an older one names none)."""
    from fsreg_ros import contract
    from fsreg_ros.testing.ros_session import RosSession

    with RosSession(ns) as session:
        ready = session.listen(f"{ns}/{contract.READY.name}", contract.STATE_QOS)
        session.spin_until(lambda: any(m.get("recorders", True) for m in ready), 60.0, what="the recorder named")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=8)
    args = parser.parse_args()
    ns = f"/bench_{uuid.uuid4().hex[:6]}"
    work = Path(tempfile.mkdtemp(prefix="bench_ctl_record_"))
    up = subprocess.Popen([str(BIN / "fsreg-up"), str(REPO / "scenarios" / "guess_who_table1.yaml"),
                           "--namespace", ns, "--state-dir", str(work / "state")],
                          stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    recorder = None
    try:
        ctl(ns, "status")  # waits for the graph
        plain, _ = describes(ns, args.runs)
        recorder = subprocess.Popen([str(BIN / "fsreg-ctl"), "--namespace", ns, "record", str(work / "bag")],
                                    stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        named(ns)
        recorded, warned = describes(ns, args.runs)
    finally:
        if recorder is not None:
            recorder.send_signal(signal.SIGINT)
            recorder.wait(60)
        up.send_signal(signal.SIGINT)
        up.wait(60)
    from fsreg_ros.core.io.recording import open_recording

    held = len({m.data["id"] for m in open_recording(work / "bag").on("request")})
    print(f"describe, no recorder: median {statistics.median(plain):.2f} s ({args.runs} runs)")
    print(f"describe, fsreg-ctl record running: median {statistics.median(recorded):.2f} s; "
          f"the bag holds {held} of {args.runs} requests; {warned} warned")
    return 0


if __name__ == "__main__":
    sys.exit(main())
