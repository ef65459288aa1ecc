"""Stop a graph's node processes the way a terminal's Ctrl-C under ``ros2 launch`` does (issue 37 item 1).

A terminal's Ctrl-C reaches every process of the launch's process group, and ``launch``
forwards its own SIGINT to each node a few milliseconds later: each node sees two
signals.  :func:`stop_round` starts the live graph's node processes from
:func:`fsreg_ros.ros.graph_spec.node_specs` (the definition the launch file uses, one
process per node, in one process group, under a namespace of their own), waits until
every node spins (its first ``/diagnostics`` status), sends the first signal to the
group and the second to every node ``gap`` seconds later, and returns how each process
ended: exit code, seconds from the first signal, its stderr.

Used by ``test/ros/test_stop_signals.py`` (a few rounds) and ``scripts/stress_signals.py``
(50 rounds).  Layer: testing (may import ros and tools).
"""

from __future__ import annotations

import os
import signal
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

from ..ros.graph_spec import node_specs
from ..ros.network import ros_environment

#: The cases: (first signal, to the process group; second signal, to each node).
CASES = {"int-int": (signal.SIGINT, signal.SIGINT), "int-term": (signal.SIGINT, signal.SIGTERM)}
#: Seconds a node may take to exit after the first signal.
STOP_LIMIT = 2.0
#: Seconds the node processes get to start and spin (a loaded machine: 1-5 s).
START_LIMIT = 30.0


@dataclass
class Stopped:
    """How one node process ended."""

    name: str
    code: int
    seconds: float
    stderr: str

    def problems(self) -> list[str]:
        """Return what is wrong (empty: exit 0, no traceback, within :data:`STOP_LIMIT`)."""
        found = []
        if self.code != 0:
            found.append(f"exit code {self.code}")
        if "Traceback" in self.stderr or "KeyboardInterrupt" in self.stderr:
            found.append("a traceback on stderr")
        if self.seconds > STOP_LIMIT:
            found.append(f"exited {self.seconds:.2f} s after the first signal")
        return found


def _command(spec, namespace: str) -> list[str]:
    from ..tools.graph import command  # the command fsreg-graph starts a node with

    return command(spec, namespace)


def wait_spinning(names: Sequence[str], namespace: str, procs: Sequence[subprocess.Popen],
                  timeout: float = START_LIMIT) -> None:
    """Return once every node of ``names`` (under ``namespace``) has published a ``/diagnostics`` status.

    A node publishes its first status a second after it starts spinning.  RuntimeError
    when a process exits first or the time runs out.
    """
    import rclpy
    from diagnostic_msgs.msg import DiagnosticArray
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    from ..ros.diagnostics import NAME_PREFIX, TOPIC

    wanted = {f"{NAME_PREFIX}{namespace}/{name}" for name in names}
    heard: set[str] = set()
    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    try:
        node = rclpy.create_node("stop_probe", context=context)
        node.create_subscription(DiagnosticArray, TOPIC, lambda a: heard.update(s.name for s in a.status), 10)
        executor = SingleThreadedExecutor(context=context)
        executor.add_node(node)
        deadline = time.monotonic() + timeout
        while not wanted <= heard:
            if any(p.poll() is not None for p in procs):
                raise RuntimeError("a node process exited while starting")
            if time.monotonic() > deadline:
                raise RuntimeError(f"not spinning within {timeout:g} s: {sorted(wanted - heard)}")
            executor.spin_once(timeout_sec=0.1)
        executor.shutdown()
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)


def stop_round(kb: str, workdir: Path, case: str, gap: float = 0.005, namespace: str = "/stop") -> list[Stopped]:
    """Start the graph's node processes, stop them with the two signals of ``case`` ``gap`` s apart; how each ended."""
    first, second = CASES[case]
    workdir.mkdir(parents=True, exist_ok=True)
    specs = node_specs(kb, ["faces"], {"faces": {"policy": "none"}}, use_sim_time=True,
                       state_dir=str(workdir / "state"))
    env = ros_environment(dict(os.environ))
    procs: list[tuple[str, subprocess.Popen, Path]] = []
    group = 0
    try:
        for spec in specs:
            err = workdir / f"{spec.name}.err"
            with open(err, "wb") as sink:
                proc = subprocess.Popen(_command(spec, namespace), env=env, stdin=subprocess.DEVNULL,
                                        stdout=subprocess.DEVNULL, stderr=sink, process_group=group)
            group = group or proc.pid
            procs.append((spec.name, proc, err))
        wait_spinning([name for name, _, _ in procs], namespace, [p for _, p, _ in procs])
        start = time.monotonic()
        os.killpg(group, first)  # the terminal's Ctrl-C: every process of the group
        time.sleep(gap)  # the stimulus: launch's own signal follows a few ms later
        for _, proc, _ in procs:
            if proc.poll() is None:
                proc.send_signal(second)
        ended: dict[str, float] = {}  # node name -> seconds from the first signal to its exit
        while len(ended) < len(procs) and time.monotonic() < start + STOP_LIMIT + 3.0:
            for name, proc, _ in procs:
                if name not in ended and proc.poll() is not None:
                    ended[name] = time.monotonic() - start
            time.sleep(0.01)  # polling the processes' exits (a benchmark's resolution, not a wait for a state)
        for name, proc, _ in procs:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        now = time.monotonic()
        return [Stopped(name, proc.returncode, ended.get(name, now - start), err.read_text(errors="replace"))
                for name, proc, err in procs]
    finally:
        for _, proc, _ in procs:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
