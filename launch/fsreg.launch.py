"""Launch the fsreg node graph for one knowledge base (needs ROS 2 launch / launch_ros).

    ros2 launch fsreg_ros fsreg.launch.py kb:=/path/to/table1.yaml \
        domains:=faces policy:=decay decay_period:=10.0 capacity:=2 namespace:=robot1

Every memory setting is an argument (policy, decay_period, capacity, global_capacity,
seed, shared_capacity: the settings table, ``fsreg_ros/core/forgetting/settings.py``), defaulting
to the WM Manager's own default (policy ``none``).

The nodes and their parameters come from :func:`fsreg_ros.ros.graph_spec.node_specs`, the
same definition ``fsreg-graph`` uses: one consultant per domain (named
consultant_<domain>), the WM Manager, the parser stub, reference resolution and REG,
each domain with the policy given here.  Play a scripted dialogue with
``ros2 run fsreg_ros dialogue_player --ros-args -p scenario:=...`` or talk to the
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

from fsreg_ros.contract import CLOCK, normalise_namespace
from fsreg_ros.core.forgetting import settings
from fsreg_ros.core.forgetting.policies import ForgettingPolicy
from fsreg_ros.ros.graph_spec import PACKAGE, node_specs, policy_settings, resolved

ARGUMENTS = {
    "kb": ("", "scenario/KB YAML file with every domain's LTM"),
    "domains": ("faces", "comma-separated consultant domains"),
    # one argument per memory setting, with the WM Manager's default (core/forgetting/settings.py)
    **{row.name: (str(row.default), row.description) for row in settings.TABLE},
    "algorithm": ("auto", "auto, sd-pia, dist-pia, full-brevity or greedy"),
    "wm_order": ("lru-first", "lru-first, mru-first, preference or strength"),
    "use_sim_time": ("false", "follow /clock"),
    "namespace": ("", "ROS namespace for every node ('' = none)"),
    "lexicon": ("", "lexicon YAML that extends the built-in config/lexicon.yaml ('' = the built-in one)"),
    "state_dir": ("", "the consultants' state directory ('' = theirs, under $XDG_STATE_HOME/fsreg_ros)"),
    "fresh": ("false", "true: start from the KB alone (each consultant moves its state database aside, never "
                       "deleting it) instead of restoring runtime facts and WM from an earlier session"),
}


def _setting(row, text):
    """Return a launch argument's text as the setting's type; ValueError naming the argument."""
    try:
        return row.kind(text)
    except ValueError:
        raise ValueError(f"launch argument {row.name}:={text!r}: expected {row.kind_text}") from None


def _flag(name, text):
    """Return a true/false launch argument as a bool; ValueError naming the argument."""
    if text.strip().lower() not in ("true", "false"):
        raise ValueError(f"launch argument {name}:={text!r}: expected true or false")
    return text.strip().lower() == "true"


def _nodes(context):
    arg = lambda name: LaunchConfiguration(name).perform(context)  # noqa: E731
    domains = [d.strip() for d in arg("domains").split(",") if d.strip()]
    policy = ForgettingPolicy.from_settings({row.name: _setting(row, arg(row.name)) for row in settings.TABLE})
    specs = node_specs(
        arg("kb"),
        domains,
        {domain: policy_settings(policy) for domain in domains},
        use_sim_time=_flag("use_sim_time", arg("use_sim_time")),
        algorithm=arg("algorithm"),
        wm_order=arg("wm_order"),
        lexicon=resolved(arg("lexicon")),
        state_dir=resolved(arg("state_dir")),
    )
    fresh = _flag("fresh", arg("fresh"))
    for spec in specs:
        if fresh and spec.executable == "consultant":
            spec.parameters["reset_state"] = True
    namespace = normalise_namespace(arg("namespace"))
    remappings = [(CLOCK, namespace + CLOCK)] if namespace else []
    return [
        Node(package=PACKAGE, executable=spec.executable, name=spec.name, namespace=namespace,
             parameters=[spec.parameters], remappings=remappings)
        for spec in specs
    ]


def generate_launch_description():
    args = [DeclareLaunchArgument(k, default_value=v, description=d) for k, (v, d) in ARGUMENTS.items()]
    return LaunchDescription(args + [OpaqueFunction(function=_nodes)])
