"""What the files in ``config/`` promise in their comments is what the nodes do (issue 37.3).

Every parameter a params file sets, or shows commented out with its range, is one the
node declares, with a value it takes and the range it checks; every ``ros2 param set``
a comment suggests is accepted by the node and changes what runs (never "successful"
and ignored); the sim-time advice says ``true`` where a player drives ``/clock``.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

from fsreg_ros.core.forgetting import settings
from fsreg_ros.ros.memory_parameters import check_change
from fsreg_ros.ros.node_parameters import check_parameter, node_parameters

REPO = Path(__file__).resolve().parents[2]
#: A commented-out parameter with its range: ``# max_list_items: 1000  # [1, 1000000] ...``.
COMMENTED = re.compile(r"^\s*#\s*([a-z_]+):\s*(\S+)\s*#\s*\[([-+.e\d]+),\s*([-+.e\d]+)\]")
#: A suggested run-time change: ``ros2 param set /wm_manager policy displacement``.
PARAM_SET = re.compile(r"ros2 param set /(\w+) (\S+) (\S+)")


def params_files() -> list[Path]:
    out = []
    for path in sorted((REPO / "config").glob("*.yaml")):
        data = yaml.safe_load(path.read_text())
        if isinstance(data, dict) and all(isinstance(v, dict) and "ros__parameters" in v for v in data.values()):
            out.append(path)
    return out


def executable(node: str) -> str:
    return "consultant" if node.startswith("consultant_") else node


def flat(params: dict, prefix: str = "") -> dict:
    out = {}
    for key, value in params.items():
        out.update(flat(value, f"{prefix}{key}.") if isinstance(value, dict) else {f"{prefix}{key}": value})
    return out


def file_values(path: Path) -> dict[str, dict]:
    return {node: flat(entry["ros__parameters"]) for node, entry in yaml.safe_load(path.read_text()).items()}


def domains_of(values: dict[str, dict]) -> list[str]:
    return next((v["domains"] for v in values.values() if "domains" in v), ["faces"])


@pytest.mark.parametrize("path", params_files(), ids=lambda p: p.name)
def test_every_parameter_a_config_file_sets_or_shows_is_one_the_node_takes(path):
    values = file_values(path)
    domains = domains_of(values)
    nodes = {n: node_parameters(executable(n), domains) for n in values if executable(n) != "dialogue_player"}
    for node, params in values.items():
        if node not in nodes:
            continue
        for key, value in params.items():
            assert key in nodes[node], (path.name, node, key)
            if not (key in ("kb", "lexicon", "domain") and value == ""):  # the placeholder the command line fills
                check_parameter(nodes[node][key], value)
    shown = 0
    for line in path.read_text().splitlines():
        found = COMMENTED.match(line)
        if not found or len(nodes) != 1:
            continue
        (catalogue,) = nodes.values()
        name, value, low, high = found.groups()
        spec = catalogue[name]
        check_parameter(spec, yaml.safe_load(value))
        assert (float(low), float(high)) == (spec.low, spec.high), (path.name, name)
        shown += 1
    assert shown or "# max_" not in path.read_text(), path.name


@pytest.mark.parametrize("path", [p for p in params_files() if "ros2 param set" in p.read_text()],
                         ids=lambda p: p.name)
def test_every_suggested_ros2_param_set_is_taken_and_changes_what_runs(path):
    """Applied in order over the file's own values, as the WM Manager's callback checks them."""
    values = file_values(path)
    manager = values["wm_manager"]
    domains = manager["domains"]
    current = {row.name: row.default for row in settings.TABLE}
    current.update({f"{d}.{row.name}": row.inherit for d in domains for row in settings.TABLE})
    current.update({k: v for k, v in manager.items() if k in current})
    suggested = PARAM_SET.findall(path.read_text())
    assert suggested, path.name
    for node, key, text in suggested:
        assert node == "wm_manager", (path.name, node)
        value = check_parameter(node_parameters("wm_manager", domains)[key], yaml.safe_load(text))
        before = {d: p.to_json() for d, p in check_change(current, {}, domains).items()}
        after = {d: p.to_json() for d, p in check_change(current, {key: value}, domains).items()}
        assert after != before, f"{path.name}: 'ros2 param set /{node} {key} {text}' would change nothing"
        current[key] = value


def test_the_sim_time_advice_says_true_where_a_player_drives_the_clock():
    text = (REPO / "config" / "guess_who.yaml").read_text()
    comment = " ".join(line.lstrip("# ") for line in text.splitlines() if line.startswith("#"))
    advice = re.findall(r"Set use_sim_time: (\w+) on every node only when a dialogue player or a bag drives /clock",
                        comment)
    assert advice == ["true"], comment
    live = re.findall(r"Live use follows the system clock \(use_sim_time: (\w+)\)", comment)
    values = {v["use_sim_time"] for v in file_values(REPO / "config" / "guess_who.yaml").values()}
    assert live == ["false"] and values == {False}
