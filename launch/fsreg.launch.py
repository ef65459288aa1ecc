"""Launch the fsreg node graph for one knowledge base (needs ROS 2 launch / launch_ros).

    ros2 launch fsreg_ros fsreg.launch.py kb:=/path/to/table1.yaml \
        domains:=faces policy:=decay decay_period:=10.0 capacity:=2

One consultant per domain (named consultant_<domain>), the WM Manager, the parser
stub, reference resolution and REG.  Play a scripted dialogue with
``ros2 run fsreg_ros dialogue_player --ros-args -p scenario:=...`` or talk to the
graph on /dialogue/human and /reg/request.  Set use_sim_time:=true when a player
(or a bag) drives /clock.
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, OpaqueFunction
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

PACKAGE = "fsreg_ros"


def _nodes(context):
    arg = lambda name: LaunchConfiguration(name).perform(context)  # noqa: E731
    domains = [d.strip() for d in arg("domains").split(",") if d.strip()]
    sim = arg("use_sim_time").lower() == "true"
    common = {"use_sim_time": sim}
    nodes = [
        Node(
            package=PACKAGE,
            executable="consultant",
            name=f"consultant_{domain}",
            parameters=[{**common, "domain": domain, "kb": arg("kb")}],
        )
        for domain in domains
    ]
    nodes += [
        Node(
            package=PACKAGE,
            executable="wm_manager",
            name="wm_manager",
            parameters=[
                {
                    **common,
                    "domains": domains,
                    "policy": arg("policy"),
                    "decay_period": float(arg("decay_period")),
                    "capacity": int(arg("capacity")),
                    "global_capacity": int(arg("global_capacity")),
                }
            ],
        ),
        Node(package=PACKAGE, executable="parser", name="parser", parameters=[{**common, "kb": arg("kb")}]),
        Node(
            package=PACKAGE,
            executable="reference_resolution",
            name="reference_resolution",
            parameters=[{**common, "domains": domains}],
        ),
        Node(
            package=PACKAGE,
            executable="reg",
            name="reg",
            parameters=[{**common, "domains": domains, "algorithm": arg("algorithm"), "wm_order": arg("wm_order")}],
        ),
    ]
    return nodes


def generate_launch_description():
    defaults = {
        "kb": ("", "scenario/KB YAML file with every domain's LTM"),
        "domains": ("faces", "comma-separated consultant domains"),
        "policy": ("decay", "none, or decay / displacement / global-capacity joined by +"),
        "decay_period": ("10.0", "decay period delta in seconds"),
        "capacity": ("2", "per-entity WM limit alpha"),
        "global_capacity": ("6", "per-domain WM limit"),
        "algorithm": ("auto", "auto, sd-pia, dist-pia, full-brevity or greedy"),
        "wm_order": ("lru-first", "lru-first, mru-first or preference"),
        "use_sim_time": ("false", "follow /clock"),
    }
    args = [DeclareLaunchArgument(k, default_value=v, description=d) for k, (v, d) in defaults.items()]
    return LaunchDescription(args + [OpaqueFunction(function=_nodes)])
