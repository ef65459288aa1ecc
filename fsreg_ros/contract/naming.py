"""ROS names: namespaces and the per-graph clock remapping (no ROS import)."""

from __future__ import annotations

from typing import Optional

#: The simulated clock: absolute (ROS convention), ``rosgraph_msgs/msg/Clock``.
#: (:mod:`fsreg_ros.contract.endpoints` re-exports it beside the other endpoint names.)
CLOCK = "/clock"

#: The field in which every published message names its graph (``fsreg_ros.ros.carrier.publish`` stamps it).
GRAPH_FIELD = "graph"
#: The node parameter that gives a node its graph's identity ('' = none: nothing is stamped).
GRAPH_PARAMETER = "graph"


def clock_remap(namespace: str) -> list[str]:
    """Return the ``--ros-args`` remapping that gives a namespaced graph its own ``/clock``.

    Two sim-time graphs on one domain would otherwise follow one clock driven by two
    players, each jumping the other's time.  The runner passes this to every node
    (player included) when it runs a graph under a namespace; an un-namespaced graph
    keeps the global ``/clock``.
    """
    ns = normalise_namespace(namespace)
    return ["-r", f"{CLOCK}:={ns}{CLOCK}"] if ns else []


def normalise_namespace(namespace: Optional[str]) -> str:
    """Return ``namespace`` as ``/a/b`` ('' for none); ValueError if it is not a ROS namespace."""
    text = (namespace or "").strip().strip("/")
    if not text:
        return ""
    for part in text.split("/"):
        if not part or not (part[0].isalpha() or part[0] == "_") or not all(c.isalnum() or c == "_" for c in part):
            raise ValueError(f"namespace {namespace!r}: each part must be letters, digits and '_', "
                             "not starting with a digit")
    return "/" + text
