"""``use_sim_time`` fixed when a node starts: one clock for the whole graph.

A graph's nodes share one time (sim time on ``/clock``, or the wall clock: the runner
sets it for every node, ``fsreg-up --wall-time``, the launch file's ``use_sim_time``).
Changing it on one node at run time would jump that node's clock (decay ticking on the
wall clock while the others follow ``/clock``), so every fsreg node declares it
read-only: ``ros2 param set NODE use_sim_time ...`` and ``fsreg-ctl set`` are refused
with the reason, as a parameters file setting it otherwise is
(:data:`fsreg_ros.ros.node_parameters.RUNNER_SOURCES`).
"""

from __future__ import annotations

from rcl_interfaces.msg import ParameterDescriptor, ParameterType

DESCRIPTION = ("follow /clock (sim time) instead of the system clock; set for every node of the graph when it "
               "starts (read-only: one clock for the whole graph)")


def fix_use_sim_time(node) -> None:
    """Make ``node``'s ``use_sim_time`` read-only at its start value (call before any parameter callback)."""
    fixed = ParameterDescriptor(description=DESCRIPTION, read_only=True, type=ParameterType.PARAMETER_BOOL)
    node.set_descriptor("use_sim_time", fixed)
