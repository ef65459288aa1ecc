"""The launch file's arguments: their names, defaults and help, and the graph they make, all checked first.

``launch/fsreg.launch.py`` (``ros2 launch fsreg_ros fsreg.launch.py kb:=... policy:=...``) declares
:data:`ARGUMENTS` and builds its nodes from :func:`launch_specs`, which reads every argument's text
and checks all of them before a node starts, as ``fsreg-up`` checks its options: the knowledge base
(required, read and validated with the lexicon given), the domains (each one the KB has, none
twice), the lexicon, REG's ``algorithm`` and ``wm_order``, the ``preset`` and every memory setting
(the policy they make), the flags and the namespace.  A memory setting or ``wm_order`` left empty
(their default) is not given: the preset's value (:mod:`fsreg_ros.core.forgetting.presets`), else the
WM Manager's default (``lru-first`` for ``wm_order``); one given overrides the preset's, as beside
``--preset`` in fsreg-up.  A bad argument is one :class:`ValueError` line naming it, so
``ros2 launch`` prints one error and starts nothing: no half-started graph whose one dead node
leaves the others running.  No ROS import here (tests check it without ``launch``).
"""

from __future__ import annotations

from typing import Callable

from ..contract import normalise_namespace
from ..core.algorithms.generation import ALGORITHMS, AUTO, WM_ORDERS
from ..core.forgetting import presets, settings
from ..core.forgetting.policies import ForgettingPolicy
from ..core.forgetting.settings import PolicyError
from ..core.lexicon import Lexicon, LexiconError
from ..core.scenario import ScenarioError, load_scenario
from .graph_spec import NodeSpec, node_specs, policy_settings, resolved

#: name -> (default, description) of every launch argument.
ARGUMENTS = {
    "kb": ("", "scenario/KB YAML file with every domain's LTM (required)"),
    "domains": ("faces", "comma-separated consultant domains"),
    "preset": ("", "named memory settings and WM order ("
               + "; ".join(f"{p.name}: {p.description}" for p in presets.PRESETS)
               + "); '' = none; a memory argument or wm_order given beside it overrides the preset's"),
    # one argument per memory setting; '' = not given: the preset's, else the WM Manager's default
    **{row.name: ("", f"{row.description} ('' = the preset's, else {row.default})") for row in settings.TABLE},
    "algorithm": (AUTO, f"{AUTO}, {', '.join(ALGORITHMS[:-1])} or {ALGORITHMS[-1]}"),
    "wm_order": ("", f"{', '.join(WM_ORDERS[:-1])} or {WM_ORDERS[-1]} ('' = the preset's, else {WM_ORDERS[0]})"),
    "use_sim_time": ("false", "follow /clock"),
    "namespace": ("", "ROS namespace for every node ('' = none)"),
    "lexicon": ("", "lexicon YAML that extends the built-in config/lexicon.yaml ('' = the built-in one)"),
    "state_dir": ("", "the consultants' state directory ('' = theirs, under $XDG_STATE_HOME/fsreg_ros)"),
    "fresh": ("false", "true: start from the KB alone (each consultant moves its state database aside, never "
                       "deleting it) instead of restoring runtime facts and WM from an earlier session"),
}


def _refused(name: str, text: str, why: str) -> ValueError:
    return ValueError(f"launch argument {name}:={text!r}: {why}")


def _setting(row, text: str):
    """Return a memory setting's text as the setting's type; ValueError naming the argument."""
    try:
        return row.kind(text)
    except ValueError:
        raise _refused(row.name, text, f"expected {row.kind_text}") from None


def _flag(name: str, text: str) -> bool:
    """Return a true/false argument as a bool; ValueError naming the argument."""
    if text.strip().lower() not in ("true", "false"):
        raise _refused(name, text, "expected true or false")
    return text.strip().lower() == "true"


def _choice(name: str, text: str, choices) -> str:
    if text not in choices:
        raise _refused(name, text, f"expected {', '.join(choices[:-1])} or {choices[-1]}")
    return text


def launch_specs(arg: Callable[[str], str]) -> tuple[list[NodeSpec], str]:
    """Return the nodes the launch arguments give, and their namespace ('' or ``/ns``).

    ``arg(name)`` is the text of the argument ``name``.  Every argument is checked before
    anything is returned; the first bad one is a ValueError of one line naming it.
    """
    namespace = normalise_namespace(arg("namespace"))
    sim_time, fresh = _flag("use_sim_time", arg("use_sim_time")), _flag("fresh", arg("fresh"))
    algorithm = _choice("algorithm", arg("algorithm"), (AUTO, *ALGORITHMS))
    wm_order = _choice("wm_order", arg("wm_order"), WM_ORDERS) if arg("wm_order") else None
    given = {row.name: _setting(row, arg(row.name)) for row in settings.TABLE if arg(row.name)}
    try:
        memory, wm_order = presets.apply(arg("preset") or None, given, wm_order)
    except PolicyError as err:
        raise _refused("preset", arg("preset"), str(err)) from None
    policy = ForgettingPolicy.from_settings({row.name: row.default for row in settings.TABLE} | memory)
    lexicon, kb = resolved(arg("lexicon")), resolved(arg("kb"))
    if not kb:
        raise _refused("kb", arg("kb"), "required: the scenario/KB YAML file with every domain's LTM")
    try:
        words = Lexicon.load(lexicon)
    except LexiconError as err:
        raise _refused("lexicon", arg("lexicon"), str(err)) from None
    try:
        scenario = load_scenario(kb, words)
    except ScenarioError as err:  # one line naming the file, the place in it and the line
        raise _refused("kb", arg("kb"), str(err)) from None
    domains = [d.strip() for d in arg("domains").split(",") if d.strip()]
    if not domains:
        raise _refused("domains", arg("domains"), "expected at least one domain")
    for domain in domains:
        if domain not in scenario.domains:
            known = ", ".join(sorted(scenario.domains))
            raise _refused("domains", arg("domains"), f"{kb} has no domain {domain!r} (its domains: {known})")
        if domains.count(domain) > 1:
            raise _refused("domains", arg("domains"), f"{domain!r} given twice")
    specs = node_specs(kb, domains, {domain: policy_settings(policy) for domain in domains}, use_sim_time=sim_time,
                       algorithm=algorithm, wm_order=wm_order or WM_ORDERS[0], lexicon=lexicon,
                       state_dir=resolved(arg("state_dir")))
    for spec in specs:
        if fresh and spec.executable == "consultant":
            spec.parameters["reset_state"] = True
    return specs, namespace
