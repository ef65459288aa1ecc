"""``fsreg-up --params-file``: the file ``ros2 param dump`` writes is taken (issue 37.4), checked as every other
path checks a value (issue 38.3), before anything starts; no node process is started here."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from fsreg_ros.ros.graph_spec import node_specs
from fsreg_ros.tools.graph import command, live_nodes
from fsreg_ros.tools.sim import UsageError
from fsreg_ros.tools.up import build_parser, params_from_file

NS = "/robot1"


def _setup(table1_path: Path, *argv: str):
    from fsreg_ros.core.lexicon import Lexicon
    from fsreg_ros.core.scenario import load_scenario
    from fsreg_ros.tools.sim import options_from_args

    args = build_parser().parse_args([str(table1_path), *argv])
    options = options_from_args(args)
    specs = live_nodes(load_scenario(args.scenario, Lexicon.load(None)), args.scenario, options,
                       use_sim_time=not args.wall_time)
    return specs, options


def _dump(table1_path: Path, **wm_manager) -> dict:
    """What ``ros2 param dump`` writes of a graph ``fsreg-up SCENARIO --namespace robot1`` started (two nodes)."""
    kb = str(table1_path.resolve())
    common = {"graph": "fsreg-up-1a2b3c4d", "use_sim_time": True, "start_type_description_service": True}
    manager = {**common, "domains": ["faces"], "policy": "decay", "decay_period": 10.0, "capacity": 2,
               "service_timeout": 10.0, "faces": {"policy": "", "decay_period": 0.0, "capacity": 0}}
    manager.update(wm_manager)
    return {f"{NS}/wm_manager": {"ros__parameters": manager},
            f"{NS}/consultant_faces": {"ros__parameters": {**common, "domain": "faces", "kb": kb, "state_dir": "",
                                                           "threshold": 0.5}}}


def _load(tmp_path: Path, table1_path: Path, data: dict, *argv: str):
    path = tmp_path / "params.yaml"
    path.write_text(yaml.safe_dump(data))
    specs, options = _setup(table1_path, *argv)
    return path, params_from_file(path, specs, NS, options, fresh="--fresh" in argv)


def test_a_dump_of_the_graph_is_taken_with_the_keys_fsreg_up_owns(tmp_path, table1_path):
    path, (given, memory) = _load(tmp_path, table1_path, _dump(table1_path))
    assert memory == {"faces": {"policy": "decay", "decay_period": 10.0}}
    assert given["consultant_faces"] == {"start_type_description_service": True, "threshold": 0.5}
    assert "graph" not in given["wm_manager"] and "domains" not in given["wm_manager"]


@pytest.mark.parametrize("node, key, value, said", [
    ("wm_manager", "use_sim_time", False, "wm_manager: use_sim_time: set by fsreg-up from sim time, or --wall-time "
                                          "(one clock for the whole graph) to True, the file says False"),
    ("wm_manager", "domains", ["faces", "objects"], "wm_manager: domains: set by fsreg-up from the scenario's "
                                                    "domains to ['faces'], the file says ['faces', 'objects']"),
    ("consultant_faces", "state_dir", "/var/fsreg", "consultant_faces: state_dir: set by fsreg-up from "
                                                    "--state-dir to '', the file says '/var/fsreg'"),
    ("consultant_faces", "kb", "/elsewhere.yaml", "consultant_faces: kb: set by fsreg-up from the scenario to "),
    # a dump of a --fresh graph fed back without --fresh: not a second move of the state aside
    ("consultant_faces", "reset_state", True, "consultant_faces: reset_state: set by fsreg-up from --fresh (a "
                                              "one-shot action of the first start: it moves the state database "
                                              "aside) to False, the file says True"),
])
def test_a_key_fsreg_up_owns_that_differs_is_one_line_saying_which_and_why(tmp_path, table1_path, node, key,
                                                                           value, said):
    data = _dump(table1_path)
    data[f"{NS}/{node}"]["ros__parameters"][key] = value
    with pytest.raises(UsageError) as caught:
        _load(tmp_path, table1_path, data)
    message = str(caught.value)
    assert message.startswith(f"{tmp_path / 'params.yaml'}: node {NS}/{said}") and "\n" not in message
    assert message.endswith("; drop it from the file or change that")


def test_reset_state_of_a_dump_is_taken_when_fsreg_up_sets_the_same(tmp_path, table1_path):
    """``reset_state`` is --fresh's one-shot action: a --fresh graph's dump is taken with --fresh (refused without)."""
    data = _dump(table1_path)
    data[f"{NS}/consultant_faces"]["ros__parameters"]["reset_state"] = True  # a dump of a --fresh graph
    _, (given, _) = _load(tmp_path, table1_path, data, "--fresh")  # started the same way: taken as it is
    assert "reset_state" not in given.get("consultant_faces", {})
    data[f"{NS}/consultant_faces"]["ros__parameters"]["reset_state"] = False  # a dump of a graph started without
    _, (given, _) = _load(tmp_path, table1_path, data)
    assert "reset_state" not in given.get("consultant_faces", {})


def test_wall_time_dump_needs_wall_time(tmp_path, table1_path):
    data = _dump(table1_path)
    for entry in data.values():
        entry["ros__parameters"]["use_sim_time"] = False
    _, (_, memory) = _load(tmp_path, table1_path, data, "--wall-time")
    assert memory == {"faces": {"policy": "decay", "decay_period": 10.0}}


def test_an_empty_policy_is_refused_node_wide_and_inherits_per_domain_as_on_every_path(tmp_path, table1_path):
    with pytest.raises(UsageError, match=r": node /robot1/wm_manager: policy: policy must be a non-empty string, "
                                         r"got ''$"):
        _load(tmp_path, table1_path, _dump(table1_path, policy=""))
    # a domain's '' is its inherit marker: taken, and passed to the node so that rcl reads it (not '-p name:=')
    _, (given, memory) = _load(tmp_path, table1_path, _dump(table1_path, policy="displacement"))
    assert memory == {"faces": {"policy": "displacement", "capacity": 2}}
    spec = next(s for s in _setup(table1_path)[0] if s.name == "wm_manager")
    spec.parameters.update(given["wm_manager"])
    assert "faces.policy:=''" in command(spec)


def test_a_node_wide_setting_a_domain_overrides_is_refused_not_ignored(tmp_path, table1_path):
    data = _dump(table1_path, policy="displacement")
    data[f"{NS}/wm_manager"]["ros__parameters"]["faces"]["policy"] = "decay"
    with pytest.raises(UsageError) as caught:
        _load(tmp_path, table1_path, data)
    assert str(caught.value) == (
        f"{tmp_path / 'params.yaml'}: node wm_manager: policy: not changed: faces.policy='decay' overrides the "
        "node-wide value (which applies only to domains that inherit it); set faces.policy instead, or "
        "faces.policy='' to inherit")


def test_rcl_reads_an_empty_text_parameter_as_fsreg_up_passes_it():
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    try:
        spec = next(s for s in node_specs("kb.yaml", ["faces"], {"faces": {"policy": ""}}) if s.name == "wm_manager")
        args = command(spec)[command(spec).index("--ros-args"):]
        node = rclpy.create_node("wm_manager", context=context, cli_args=args,
                                 automatically_declare_parameters_from_overrides=True)
        assert node.get_parameter("policy").value == ""
        node.destroy_node()
    finally:
        rclpy.try_shutdown(context=context)
