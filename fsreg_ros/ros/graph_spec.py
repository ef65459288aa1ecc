"""The one definition of the fsreg node graph: which nodes, named how, with which parameters.

Both ``fsreg-graph`` (:mod:`fsreg_ros.tools.graph`, one process per node) and
``launch/fsreg.launch.py`` (``ros2 launch``) build their nodes from :func:`node_specs`;
a test checks that the launch file's nodes equal it.  No ROS import here, so the launch
file and tools can use it without rclpy.

The graph: one ``consultant`` per domain (named ``consultant_<domain>``), the
``wm_manager`` (the memory settings the domains share node-wide, ``policy``, and the
ones they do not per domain, ``<domain>.policy``: :func:`memory_parameters`), the
``parser`` stub, ``reference_resolution`` and ``reg``; a scripted replay adds the
``dialogue_player`` last.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping, Optional, Sequence

from ..core.forgetting import settings

#: The package whose executables the nodes are.
PACKAGE = "fsreg_ros"


@dataclass
class NodeSpec:
    """One node process: executable (of :data:`PACKAGE`), node name and parameters."""

    executable: str
    name: str
    parameters: dict = field(default_factory=dict)


def node_specs(
    kb: str,
    domains: Sequence[str],
    policies: Mapping[str, Mapping[str, Any]],
    *,
    use_sim_time: bool = True,
    algorithm: Optional[str] = None,
    wm_order: str = "lru-first",
    lexicon: Optional[str] = None,
    state_dir: Optional[str] = None,
) -> list[NodeSpec]:
    """Return the live graph's nodes (no player) for a knowledge base.

    ``policies`` maps each domain to ``{"policy": name, "decay_period"?: ..., ...}`` (the
    settings table's names); a setting that is ``None`` or absent is not passed (the WM
    Manager's default holds).
    ``state_dir`` is the consultants' state directory (None: their default).
    """
    domains = list(domains)
    sim = {"use_sim_time": use_sim_time}
    language = {"lexicon": lexicon} if lexicon else {}
    manager: dict = {**sim, "domains": domains, **memory_parameters(domains, policies)}
    reg: dict = {**sim, "domains": domains, "wm_order": wm_order, **language}
    if algorithm:
        reg["algorithm"] = algorithm
    state = {"state_dir": state_dir} if state_dir else {}
    nodes = [NodeSpec("consultant", f"consultant_{d}", {**sim, "domain": d, "kb": kb, **state}) for d in domains]
    nodes += [
        NodeSpec("wm_manager", "wm_manager", manager),
        NodeSpec("parser", "parser", {**sim, "kb": kb, **language}),
        NodeSpec("reference_resolution", "reference_resolution", {**sim, "domains": domains}),
        NodeSpec("reg", "reg", reg),
    ]
    return nodes


def memory_parameters(domains: Sequence[str], policies: Mapping[str, Mapping[str, Any]]) -> dict[str, Any]:
    """Return the WM Manager's memory parameters for each domain's settings (``policies``, as :func:`node_specs`).

    A setting every domain gives with one value is the node-wide parameter (``policy``),
    so ``ros2 param get/set /wm_manager policy`` reads and changes what runs; one the
    domains give differently is each domain's own (``faces.policy``), and a setting not
    given stays the WM Manager's default.
    """
    out: dict[str, Any] = {}
    for row in settings.TABLE:
        given = {d: policies[d].get(row.name) for d in domains}
        values = set(map(repr, given.values()))
        if len(values) == 1 and None not in given.values():
            out[row.name] = given[domains[0]]
            continue
        out.update({f"{d}.{row.name}": v for d, v in given.items() if v is not None})
    return out


def player_spec(scenario: str, output: Optional[str] = None, trace: Optional[str] = None,
                lexicon: Optional[str] = None) -> NodeSpec:
    """Return the dialogue player's node (it drives ``/clock``, so it needs no ``use_sim_time``)."""
    params: dict = {"scenario": scenario}
    if output is not None:
        params["output"] = output
    if lexicon:
        params["lexicon"] = lexicon
    if trace is not None:
        params["trace"] = trace
    return NodeSpec("dialogue_player", "dialogue_player", params)


def policy_settings(policy) -> dict:
    """Return a :class:`~fsreg_ros.core.forgetting.policies.ForgettingPolicy` as :func:`node_specs` settings."""
    return {"policy": policy.name, **{row.name: policy.given(row.name) for row in settings.parameters()}}


def resolved(path: Optional[Path]) -> Optional[str]:
    """Return an absolute path as text (None stays None): nodes may run in another directory."""
    return str(Path(path).resolve()) if path else None
