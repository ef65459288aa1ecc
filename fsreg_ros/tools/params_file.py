"""``fsreg-up --params-file FILE``: node parameters from the YAML ``ros2 param dump`` writes, checked before any start.

The file's node keys (``/ns/node``, ``node``, ``/**``, ``/**/node``, nested namespaces)
are matched against the graph's fully qualified node names (:mod:`fsreg_ros.ros.node_parameters`);
every key must be a parameter the node declares (a wildcard entry's key, of at least one
node it matches), and every value must be one the node takes; the memory settings,
merged, must make a valid policy for every domain.  A key the runner sets from the
scenario and its own options (``domains``, ``domain``, ``kb``, ``use_sim_time``,
``state_dir``, ``lexicon``) is accepted when it equals what ``fsreg-up`` sets, and
refused naming the option that sets it otherwise, so the file ``ros2 param dump`` writes
of a graph started the same way is taken as it is; ``graph`` (the identity of the run
that was dumped) is replaced by the new run's.  Errors are one line naming the file,
the node and the key.

Precedence: the scenario's memory settings, then the file, then ``fsreg-up``'s memory
options (``--policy``, ``--capacity``, ...), each over the one before.
"""

from __future__ import annotations

import difflib
from pathlib import Path
from typing import Any, Mapping, Sequence

from ..core.forgetting import settings
from ..ros.node_parameters import (RUNNER_SOURCES, ParameterError, check_parameter, matches, node_parameters,
                                   read_params_file)
from .sim import UsageError


def node_names(domains: Sequence[str]) -> dict[str, str]:
    """Return the live graph's node names -> their executables."""
    names = {f"consultant_{d}": "consultant" for d in domains}
    names.update(wm_manager="wm_manager", parser="parser", reference_resolution="reference_resolution", reg="reg")
    return names


def overrides(path: Path, domains: Sequence[str], namespace: str, options_memory: Mapping[str, Any],
              runner: Mapping[str, Mapping[str, Any]]) -> dict[str, dict[str, Any]]:
    """Return node name -> the parameters the file sets (checked); UsageError naming the file, node and key.

    ``options_memory`` are the memory settings given as command-line options: they win
    over the file's for every domain.  ``runner``: node name -> the parameters
    ``fsreg-up`` sets (a runner-owned key of the file must equal its value there, or the
    node's default when it sets none).
    """
    entries = read_params_file_checked(path)
    names = node_names(domains)
    full = {name: f"{namespace}/{name}" for name in names}
    for entry in entries:
        if not any(matches(entry.pattern, f) for f in full.values()):
            raise UsageError(f"{path}: node {entry.pattern} is not a node of this graph (its nodes: "
                             f"{', '.join(sorted(full.values()))})")
    out: dict[str, dict[str, Any]] = {}
    for name, executable in names.items():
        catalogue = node_parameters(executable, domains)
        given: dict[str, Any] = {}
        for entry in entries:
            if not matches(entry.pattern, full[name]):
                continue
            wildcard = "*" in entry.pattern
            for key, value in entry.parameters.items():
                spec = catalogue.get(key)
                where = f"{path}: node {full[name]}: {key}"
                if spec is None:
                    if wildcard and any(key in node_parameters(e, domains) for e in names.values()):
                        continue  # a wildcard's key for other nodes (as rcl does: ignored where undeclared)
                    close = difflib.get_close_matches(key, list(catalogue), n=1)
                    raise UsageError(f"{path}: node {full[name]}: no parameter {key!r}"
                                     + (f" (did you mean {close[0]}?)" if close else ""))
                if spec.runner:
                    _check_runner(where, key, value, runner.get(name, {}).get(key, spec.default))
                    continue
                try:
                    given[key] = check_parameter(spec, value)
                except ParameterError as err:
                    raise UsageError(f"{where}: {err}") from None
        if given:
            out[name] = given
    if options_memory and "wm_manager" in out:
        for key in options_memory:
            out["wm_manager"].pop(key, None)
            for domain in domains:
                out["wm_manager"].pop(f"{domain}.{key}", None)
    return out


def _check_runner(where: str, key: str, value: Any, expected: Any) -> None:
    """Accept a runner-owned key equal to what fsreg-up sets (``graph``: any); UsageError saying what sets it."""
    if key == "graph" or value == expected and type(value) is type(expected):
        return
    raise UsageError(f"{where}: set by fsreg-up from {RUNNER_SOURCES.get(key, 'its options')} to "
                     f"{_show(expected)}, the file says {_show(value)}; drop it from the file or change that")


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def read_params_file_checked(path: Path):
    try:
        return read_params_file(path)
    except ParameterError as err:
        raise UsageError(str(err)) from None


def check_memory(path: Path, runner: Mapping[str, Any], given: Mapping[str, Any], domains: Sequence[str]) -> dict:
    """Return each domain's effective policy (as JSON) with the file's WM Manager parameters; UsageError if invalid.

    ``runner``: the WM Manager's parameters as fsreg-up sets them; ``given``: the file's.
    Checked as a change at run time is (:func:`~fsreg_ros.ros.memory_parameters.check_change`):
    a node-wide setting that a domain overrides is refused, not ignored.
    """
    from ..ros.memory_parameters import check_change

    values: dict[str, Any] = {row.name: row.default for row in settings.TABLE}
    values.update({f"{d}.{row.name}": row.inherit for d in domains for row in settings.TABLE})
    values.update({k: v for k, v in runner.items() if k in values})
    try:
        policies = check_change(values, {k: v for k, v in given.items() if k in values}, domains)
    except ValueError as err:
        raise UsageError(f"{path}: node wm_manager: {err}") from None
    return {d: p.to_json() for d, p in policies.items()}
