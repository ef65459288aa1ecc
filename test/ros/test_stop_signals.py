"""Ctrl-C under ``ros2 launch``: every node process exits 0, quietly, within 2 s (issue 37 item 1).

A terminal's Ctrl-C reaches every process of the group and launch forwards its own
SIGINT a few ms later (or escalates to SIGTERM): each node process of the graph, started
as the launch file starts it, gets two signals.  ``scripts/stress_signals.py`` runs the
same rounds 50 times.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from fsreg_ros.testing.stop_signals import stop_round
from rosutil import KB


@pytest.mark.slow
@pytest.mark.graph
@pytest.mark.parametrize("case, gap", [("int-int", 0.005), ("int-int", 0.02), ("int-term", 0.005)])
def test_every_node_exits_0_quietly_within_2_s_of_two_signals(tmp_path, case, gap):
    ended = stop_round(KB, tmp_path, case, gap)
    assert [e.name for e in ended] == ["consultant_faces", "wm_manager", "parser", "reference_resolution", "reg"]
    problems = {e.name: (e.problems(), e.stderr[-600:]) for e in ended if e.problems()}
    assert problems == {}


STUCK_SCRIPT = r'''
import os, signal, threading
from rclpy.node import Node
from fsreg_ros.ros.node_base import run_node

class Stuck(Node):  # a callback that never returns, then Ctrl-C
    NODE_NAME = "stuck"
    def __init__(self):
        super().__init__("stuck")
        self.create_timer(0.01, self.tick)
    def tick(self):
        os.kill(os.getpid(), signal.SIGINT)
        os.kill(os.getpid(), signal.SIGINT)
        os.kill(os.getpid(), signal.SIGTERM)
        threading.Event().wait()

print("ended", run_node(Stuck, ["x"]))
'''


def test_a_node_stuck_in_a_callback_still_exits_0_with_one_line():
    """No node can hang: the first signal arms a watchdog that ends the process (exit 0) 1.5 s later."""
    proc = subprocess.run([sys.executable, "-c", STUCK_SCRIPT], env=dict(os.environ), capture_output=True, text=True,
                          timeout=30)
    assert (proc.returncode, proc.stdout) == (0, "")
    assert proc.stderr == ("[stuck]: still stopping 1.5 s after SIGINT (a callback that does not return?): "
                           "exiting now\n")


HELD_SCRIPT = r'''
import ctypes, os, signal
from fsreg_ros.ros.process_stop import StopSignals

StopSignals("held", deadline=0.2).install()
os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C: the handler runs at once, in this thread
ctypes.PyDLL(None).sleep(60)  # then C code holds the interpreter (as a DDS deadlock inside rcl did)
print("not ended")
'''


def test_a_node_whose_interpreter_is_held_by_c_code_still_ends():
    """A ``ros2 run`` node stayed alive after Ctrl-C: its main thread, holding the interpreter, deadlocked in
    Fast DDS (eProsima/Fast-DDS#6502) while destroying a publisher, so the watchdog thread never ran.
    faulthandler's watchdog needs no interpreter: exit 1 with the stacks, 1.5 s after the deadline."""
    proc = subprocess.run([sys.executable, "-c", HELD_SCRIPT], env=dict(os.environ), capture_output=True, text=True,
                          timeout=20)
    assert (proc.returncode, proc.stdout) == (1, "")
    assert proc.stderr.startswith("Timeout (0:00:01.700000)!\n") and "most recent call first" in proc.stderr
