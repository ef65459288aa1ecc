#!/usr/bin/env python3
"""A simulator's ``/clock``: publish the wall clock since an epoch on a topic N times a second, until Ctrl-C.

    scripts/simulator_clock.py TOPIC HZ EPOCH

``EPOCH`` is a ``CLOCK_MONOTONIC`` reading (Python's ``time.monotonic()`` in any process of
this machine); the clock published is ``max(0, now - EPOCH)``.  A step that falls behind is
not made up by a burst (a simulator publishes one clock per physics step).  Started by
``scripts/soak.py --clock-hz N`` (Gazebo publishes every 1 ms step: N = 1000).  Run it with
the environment of ``scripts/rosenv.sh`` (it refuses one that widens DDS beyond this machine).
"""

import sys
import time

from venv_python import prepare  # noqa: E402

prepare("simulator_clock.py", loopback=True)  # .venv, import path, loopback ROS

import rclpy  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402

USAGE = "usage: simulator_clock.py TOPIC HZ EPOCH"


def main() -> int:
    if "-h" in sys.argv[1:] or "--help" in sys.argv[1:]:
        print(f"{USAGE}\n{__doc__.splitlines()[0]}")
        return 0
    try:
        topic, hz, epoch = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
        if len(sys.argv) != 4 or not hz > 0:
            raise ValueError
    except (IndexError, ValueError):
        print(f"simulator_clock.py: error: {USAGE} (HZ > 0, EPOCH a number)", file=sys.stderr)
        return 2
    rclpy.init()
    node = rclpy.create_node("soak_simulator_clock")
    publisher = node.create_publisher(Clock, topic, 10)
    period, tick = 1.0 / hz, time.monotonic()
    try:
        while rclpy.ok():
            msg = Clock()
            msg.clock.sec, msg.clock.nanosec = divmod(int(max(0.0, time.monotonic() - epoch) * 1e9), 10**9)
            publisher.publish(msg)
            tick += period
            delay = tick - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            else:
                tick = time.monotonic()
    except KeyboardInterrupt:
        pass
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
