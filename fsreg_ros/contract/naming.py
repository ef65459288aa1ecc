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


#: Longest namespace, characters: a ROS name is at most 247 (rmw), and the graph's own names go under it.
MAX_NAMESPACE = 200
_FIRST = frozenset("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ_")
_REST = _FIRST | frozenset("0123456789")


def _is_token(part: str) -> bool:
    """Return whether ``part`` is one ROS name token: ASCII letters, digits and '_', not starting with a digit."""
    return bool(part) and part[0] in _FIRST and all(c in _REST for c in part)


def _shown(text: str) -> str:
    return repr(text) if len(text) <= 60 else repr(text[:57]) + "..."


def normalise_namespace(namespace: Optional[str]) -> str:
    """Return ``namespace`` as ``/a/b`` ('' for none); ValueError if it is not a ROS namespace.

    Each part ASCII letters, digits and '_', not starting with a digit (rcl's rule, so a
    refusal comes here, not as rcl's parse error); at most :data:`MAX_NAMESPACE` characters.
    """
    text = (namespace or "").strip().strip("/")
    if not text:
        return ""
    if len(text) + 1 > MAX_NAMESPACE:
        raise ValueError(f"namespace {_shown(namespace or '')} is {len(text) + 1} characters long: at most "
                         f"{MAX_NAMESPACE} (a ROS name is at most 247, and the graph's own names go under it)")
    if not all(_is_token(part) for part in text.split("/")):
        raise ValueError(f"namespace {_shown(namespace or '')}: each part must be ASCII letters, digits and '_', "
                         "not starting with a digit")
    return "/" + text


def check_topic(name: str) -> str:
    """Return ``name`` (a topic to follow, e.g. ``--clock``) if it is a plain ROS topic name; ValueError otherwise.

    Relative or absolute, parts as a namespace's (:func:`normalise_namespace`), at most
    247 characters: a name rcl would refuse is refused here in one line.
    """
    parts = name[1:].split("/") if name.startswith("/") else name.split("/")
    if not name or len(name) > 247 or not all(_is_token(part) for part in parts):
        raise ValueError(f"{_shown(name)} is not a ROS topic name (parts of ASCII letters, digits and '_', not "
                         "starting with a digit, separated by '/'; at most 247 characters)")
    return name
