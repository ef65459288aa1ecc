"""Every parameter of the live graph's nodes, as data, and the YAML of ``ros2 param dump``.

The nodes declare their parameters when they start (``declare_number``, the settings
table, the limits); what a runner must check *before* starting anything -- a
``fsreg-up --params-file`` -- cannot ask them.  :func:`node_parameters` lists each
executable's parameters (name, type, bounds, choices, read-only, set by the runner), the
memory settings generated from :mod:`fsreg_ros.core.forgetting.settings` as the WM Manager declares
them; ``test/ros/test_node_parameters.py`` checks the list against what every node
declares.  :func:`check_parameter` is the one check of a value for a node parameter
(``fsreg-up --params-file``, ``fsreg-ctl set``).

Parameter files are the format ``ros2 param dump`` writes and ``--ros-args
--params-file`` reads (rcl's YAML): node names as keys (``/ns/node``, ``node``,
wildcards ``/**`` and ``*``, namespaces as nested keys), each with ``ros__parameters``
whose nested keys join with ``.`` (``faces: {capacity: 3}`` is ``faces.capacity``).
:func:`read_params_file` reads one with one-line errors naming the file, node and key;
:func:`dump_yaml` writes one.  No ROS import.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable, Mapping, Optional, Sequence, Union

from ..contract.limits import LIMIT_RANGES
from ..core.forgetting import settings
from ..core.algorithms.generation import ALGORITHMS, WM_ORDERS

Number = Union[int, float]
#: Value types, as ``ros2 param describe`` names them.
KINDS = {"bool": "a boolean (true or false)", "int": "a whole number", "float": "a finite number",
         "str": "text", "str[]": "a list of text"}
#: REG's algorithm besides :data:`ALGORITHMS`.
AUTO = "auto"


#: What sets each runner-owned parameter (``ParamSpec.runner``): where to change it instead.
RUNNER_SOURCES = {"domains": "the scenario's domains", "domain": "the scenario's domains", "kb": "the scenario",
                  "use_sim_time": "sim time, or --wall-time (one clock for the whole graph)",
                  "state_dir": "--state-dir", "lexicon": "--lexicon", "graph": "the run (a new identity each start)",
                  "reset_state": "--fresh (a one-shot action of the first start: it moves the state database aside)"}


class ParameterError(ValueError):
    """A parameter name or value that a node would refuse; the message says which and why."""


@dataclass(frozen=True)
class ParamSpec:
    """One declared parameter: its type (``bool``, ``int``, ``float``, ``str``, ``str[]``), bounds, choices.

    ``runner``: set by the runner from the scenario and its own options (``fsreg-up``'s
    ``--namespace``, ``--state-dir``, ``--lexicon``, ``--wall-time``), so a parameters
    file may not set it.  ``inherit``: a per-domain memory setting's marker for "use the
    node-wide value" (outside the bounds).  ``setting``: that memory setting's table row name.
    ``default``: a runner parameter's value when the runner sets none (``''``: the node's own default).
    """

    name: str
    kind: str
    read_only: bool = False
    low: Optional[Number] = None
    high: Optional[Number] = None
    choices: tuple[str, ...] = ()
    runner: bool = False
    inherit: Any = None
    setting: Optional[str] = None
    default: Any = None

    def rule(self) -> str:
        """Return the values allowed, in words: ``a whole number in [1, 10000]``."""
        if self.choices:
            text = "one of " + ", ".join(self.choices)
        elif self.setting is not None and self.low is None and self.kind == "str":
            text = "a forgetting policy (none, or rules joined by +)"
        else:
            text = KINDS[self.kind]
            if self.low is not None:
                text += f" in [{settings.number(self.low)}, {settings.number(self.high)}]"
        if self.inherit is not None:
            text = f"{text}, or {self.inherit!r} (inherit the node-wide '{self.setting}')"
        return text


def _limits() -> list[ParamSpec]:
    return [ParamSpec(name, "int", True, low, high) for name, (low, high) in LIMIT_RANGES.items()]


def _common(*names: str) -> list[ParamSpec]:
    specs = [ParamSpec("use_sim_time", "bool", True, runner=True), ParamSpec("graph", "str", True, runner=True),
             ParamSpec("start_type_description_service", "bool", True)]
    owned = {"domains": ParamSpec("domains", "str[]", True, runner=True),
             "kb": ParamSpec("kb", "str", True, runner=True),
             "lexicon": ParamSpec("lexicon", "str", True, runner=True, default="")}
    return specs + [owned[n] for n in names]


def _asking() -> list[ParamSpec]:
    return [*_common("domains"), *_limits(), ParamSpec("service_timeout", "float", True, 0.05, 600.0),
            ParamSpec("ready_timeout", "float", True, 0.1, 3600.0)]


def _memory(domains: Sequence[str]) -> list[ParamSpec]:
    out = []
    for row in settings.TABLE:
        kind = {str: "str", float: "float", int: "int"}[row.kind]
        out.append(ParamSpec(row.name, kind, low=row.low, high=row.high, setting=row.name, choices=row.choices))
        out += [ParamSpec(f"{d}.{row.name}", kind, low=row.low, high=row.high, setting=row.name,
                          choices=row.choices, inherit=row.inherit) for d in domains]
    return out


def node_parameters(executable: str, domains: Sequence[str]) -> dict[str, ParamSpec]:
    """Return the parameters a node of ``executable`` declares in a graph of ``domains``, by name."""
    specs: list[ParamSpec]
    if executable == "wm_manager":
        specs = [*_common("domains"), *_memory(domains), ParamSpec("service_timeout", "float", False, 0.01, 3600.0)]
    elif executable == "consultant":
        specs = [*_common("kb"), *_limits(), ParamSpec("domain", "str", True, runner=True),
                 ParamSpec("state_dir", "str", True, runner=True, default=""),
                 ParamSpec("threshold", "float", False, 0.0, 1.0),
                 ParamSpec("max_sessions", "int", True, 1, 100_000),
                 ParamSpec("max_sessions_per_client", "int", True, 1, 100_000),
                 ParamSpec("session_timeout", "float", True, 0.01, 3600.0),
                 ParamSpec("state_period", "float", True, 0.0, 60.0),
                 ParamSpec("reset_state", "bool", True, runner=True, default=False),
                 *(ParamSpec(flag, "bool", True) for flag in ("persist_wm", "debug", "retract_on_update"))]
    elif executable == "parser":
        specs = [*_common("kb", "lexicon"), *_limits()]
    elif executable == "reference_resolution":
        specs = _asking()
    elif executable == "reg":
        specs = [*_asking(), *_common("lexicon")[-1:], ParamSpec("algorithm", "str", choices=(AUTO, *ALGORITHMS)),
                 ParamSpec("wm_order", "str", choices=WM_ORDERS)]
    else:
        raise ParameterError(f"no parameters known for executable {executable!r}")
    return {spec.name: spec for spec in specs}


def check_parameter(spec: ParamSpec, value: Any) -> Any:
    """Return ``value`` as the node would hold it (a whole number for a float parameter becomes a float).

    ParameterError (the rule in words and the value given) if the node would refuse it:
    a wrong type, a number outside the bounds (a memory setting: the settings table's
    check, so the message is the table's), a text not among the choices.  A memory
    policy is checked by the forgetting rules' parser.
    """
    if spec.inherit is not None and value == spec.inherit and not isinstance(value, bool) \
            and type(value) is type(spec.inherit):
        return value
    got = _show(value)
    if spec.kind == "bool":
        if not isinstance(value, bool):
            raise ParameterError(f"expected {spec.rule()}, got {got}")
        return value
    if spec.kind in ("int", "float"):
        whole = isinstance(value, int) and not isinstance(value, bool)
        if spec.kind == "int" and not whole or spec.kind == "float" and not (whole or isinstance(value, float)):
            raise ParameterError(f"expected {spec.rule()}, got {got}")
        if spec.kind == "float":
            try:
                value = float(value)
            except OverflowError:
                raise ParameterError(f"expected {spec.rule()}, got {got}") from None
            if not math.isfinite(value):
                raise ParameterError(f"expected {spec.rule()}, got {got}")
        if spec.setting is not None:
            try:
                settings.check_value(spec.setting, value)
            except settings.PolicyError as err:
                raise ParameterError(f"{err} (allowed: {spec.rule()})") from None
        elif spec.low is not None and not spec.low <= value <= spec.high:
            raise ParameterError(f"expected {spec.rule()}, got {got}")
        if spec.kind == "int" and not -2**63 <= value < 2**63:
            raise ParameterError(f"expected {spec.rule()}, got {got}")
        return value
    if spec.kind == "str":
        if not isinstance(value, str):
            raise ParameterError(f"expected {spec.rule()}, got {got}")
        if spec.choices and value not in spec.choices:
            raise ParameterError(f"expected {spec.rule()}, got {got}")
        if spec.setting == "policy":  # '' only as a domain's inherit marker (returned above)
            from ..core.forgetting.policies import PolicyError, parse_rules

            try:
                parse_rules(value)
            except PolicyError as err:
                raise ParameterError(str(err)) from None
        return value
    if not isinstance(value, (list, tuple)) or not all(isinstance(v, str) for v in value):
        raise ParameterError(f"expected {spec.rule()}, got {got}")
    return list(value)


def _show(value: Any) -> str:
    huge = isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 100
    text = f"an integer of {value.bit_length()} bits" if huge else repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


# ------------------------------------------------------------ parameter files
#: The largest parameters file read (a ``ros2 param dump`` of a whole graph is a few KB).
PARAMS_MAX_BYTES = 1024 * 1024


@dataclass(frozen=True)
class FileEntry:
    """One node key of a parameters file: its name pattern (absolute) and its parameters, flattened."""

    pattern: str
    parameters: dict[str, Any]


def read_params_file(path: Path) -> list[FileEntry]:
    """Read a parameters file (the YAML ``ros2 param dump`` writes); ParameterError naming the file and place.

    Read as every user's file is (:func:`fsreg_ros.core.io.yaml_source.read_yaml`): a regular
    file of at most :data:`PARAMS_MAX_BYTES`, YAML of bounded depth and aliases.
    """
    from ..core.io.yaml_source import SourceError, read_yaml

    where = str(path)
    try:
        _, data = read_yaml(path, limit=PARAMS_MAX_BYTES)
    except SourceError as err:
        line = f" (line {err.line})" if err.line is not None else ""
        raise ParameterError(f"{where}: {err.path + ': ' if err.path else ''}{err.message}{line}") from None
    if not isinstance(data, dict) or not data:
        raise ParameterError(f"{where}: expected node names as keys, each with 'ros__parameters' "
                             "(the YAML 'ros2 param dump' writes)")
    entries: list[FileEntry] = []
    _collect(data, "", where, entries)
    return entries


def _collect(data: Mapping, prefix: str, where: str, out: list[FileEntry]) -> None:
    for key, value in data.items():
        if not isinstance(key, str) or not key.strip("/"):
            raise ParameterError(f"{where}: {key!r} is not a node name")
        name = f"{prefix}/{key.strip('/')}"
        if not isinstance(value, dict):
            raise ParameterError(f"{where}: node {name}: expected 'ros__parameters:' under it, got {_show(value)}")
        if "ros__parameters" in value:
            extra = sorted(set(value) - {"ros__parameters"}, key=str)
            if extra:
                raise ParameterError(f"{where}: node {name}: unexpected key {extra[0]!r} beside 'ros__parameters'")
            params = value["ros__parameters"]
            if not isinstance(params, dict):
                raise ParameterError(f"{where}: node {name}: 'ros__parameters' must map names to values")
            flat: dict[str, Any] = {}
            _flatten(params, "", flat, f"{where}: node {name}")
            out.append(FileEntry(name, flat))
        else:
            _collect(value, name, where, out)


def _flatten(params: Mapping, prefix: str, out: dict, where: str) -> None:
    for key, value in params.items():
        if not isinstance(key, str) or not key:
            raise ParameterError(f"{where}: {key!r} is not a parameter name")
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            _flatten(value, name + ".", out, where)
        else:
            out[name] = value


def matches(pattern: str, node: str) -> bool:
    """Return whether a parameters-file node key matches a fully qualified node name (``*``: one name, ``**``: any)."""
    regex = "".join("(/[^/]+)*" if part == "**" else "/[^/]+" if part == "*"
                    else "/" + re.escape(part).replace(r"\*", "[^/]*") for part in pattern.strip("/").split("/"))
    return re.fullmatch(regex, node) is not None


def dump_yaml(nodes: Mapping[str, Mapping[str, Any]]) -> str:
    """Return node name -> parameters as ``ros2 param dump`` writes them (dotted names nested, keys sorted)."""
    import yaml

    out: dict[str, Any] = {}
    for node, params in nodes.items():
        tree: dict[str, Any] = {}
        for name in sorted(params):
            head, *rest = name.split(".", 1)
            place = tree
            while rest:
                place = place.setdefault(head, {})
                head, *rest = rest[0].split(".", 1)
            place[head] = params[name]
        out[node] = {"ros__parameters": tree}
    return yaml.safe_dump(out, default_flow_style=False)


def for_node(entries: Iterable[FileEntry], node: str) -> dict[str, Any]:
    """Return the parameters the file gives the node ``node`` (fully qualified): every matching entry, later wins."""
    merged: dict[str, Any] = {}
    for entry in entries:
        if matches(entry.pattern, node):
            merged.update(entry.parameters)
    return merged
