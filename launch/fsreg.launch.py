"""Launch the fsreg node graph for one knowledge base (needs ROS 2 launch / launch_ros).

    ros2 launch fsreg_ros fsreg.launch.py kb:=/path/to/table1.yaml \
        domains:=faces policy:=decay decay_period:=10.0 capacity:=2 namespace:=robot1

Every memory setting is an argument (policy, decay_period, capacity, ...: the settings
table, ``fsreg_ros/core/forgetting/settings.py``); ``preset:=human-like`` (or ``paper``)
names settings and REG's WM order at once, as ``--preset`` in fsreg-up
(``fsreg_ros/core/forgetting/presets.py``).  An argument left empty (the default) is the
preset's value, else the WM Manager's own default (policy ``none``, order ``lru-first``);
one given beside a preset overrides it (``preset:=human-like episode_window:=2``).
``ros2 launch fsreg_ros fsreg.launch.py --show-args`` lists them all.

The arguments and the nodes they make are :mod:`fsreg_ros.ros.launch_arguments`'s: every
argument is checked before any node starts (a bad one is one error line, and nothing
starts).  The nodes come from :func:`fsreg_ros.ros.graph_spec.node_specs`, the same
definition ``fsreg-graph`` uses: one consultant per domain (named consultant_<domain>),
the WM Manager, the parser stub, reference resolution and REG, each domain with the
policy given here.  Play a scripted dialogue with
``ros2 run fsreg_ros dialogue_player --ros-args -p scenario:=...`` (under a namespace add
``-r __ns:=/robot1 -r /clock:=/robot1/clock``) or talk to the
graph on dialogue/human and reg/request (under the namespace, if one is given).  Set
use_sim_time:=true when a player (or a bag) drives /clock; under a namespace the
nodes follow <namespace>/clock.  As ``fsreg-up`` does: ``lexicon:=FILE`` (its
``--lexicon``), ``state_dir:=DIR`` (``--state-dir``) and ``fresh:=true`` (``--fresh``:
start from the KB alone, the consultants' state databases moved aside, never deleted).
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from fsreg_ros.contract import CLOCK
from fsreg_ros.ros.graph_spec import PACKAGE
from fsreg_ros.ros.launch_arguments import ARGUMENTS, launch_specs


def _nodes(context):
    specs, namespace = launch_specs(lambda name: LaunchConfiguration(name).perform(context))
    remappings = [(CLOCK, namespace + CLOCK)] if namespace else []
    return [
        Node(package=PACKAGE, executable=spec.executable, name=spec.name, namespace=namespace,
             parameters=[spec.parameters], remappings=remappings)
        for spec in specs
    ]


def generate_launch_description():
    args = [DeclareLaunchArgument(k, default_value=v, description=d) for k, (v, d) in ARGUMENTS.items()]
    return LaunchDescription(args + [OpaqueFunction(function=_nodes)])
