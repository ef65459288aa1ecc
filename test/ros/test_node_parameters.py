"""The nodes' parameters as data (fsreg_ros.ros.node_parameters) and the YAML of ``ros2 param dump``.

The catalogue is what ``fsreg-up --params-file`` checks a file against before anything
starts, so it must be what the nodes declare: checked against a live graph's nodes.
"""

from __future__ import annotations

import pytest
import yaml

from fsreg_ros.ros.node_parameters import (ParameterError, check_parameter, dump_yaml, for_node, matches,
                                           node_parameters, read_params_file)

KINDS = {1: "bool", 2: "int", 3: "float", 4: "str", 9: "str[]"}


@pytest.mark.graph
def test_the_catalogue_is_what_every_node_declares(table1_path):
    from fsreg_ros.testing import LiveGraph

    with LiveGraph(table1_path) as graph:
        for spec in graph.specs:
            node = graph.nodes[spec.name]
            catalogue = node_parameters(spec.executable, ["faces"])
            assert sorted(catalogue) == sorted(node._parameters), spec.name
            for name, param in catalogue.items():
                described = node.describe_parameter(name)
                assert KINDS[described.type] == param.kind, (spec.name, name)
                assert described.read_only == param.read_only, (spec.name, name)
                ranges = list(described.integer_range) or list(described.floating_point_range)
                if ranges:
                    assert (ranges[0].from_value, ranges[0].to_value) == (param.low, param.high), (spec.name, name)
                else:  # no declared range: a text, a flag, or a domain's memory setting (the table's bounds)
                    assert param.low is None or param.inherit is not None, (spec.name, name)


def test_values_are_checked_as_the_node_checks_them():
    manager = node_parameters("wm_manager", ["faces"])
    assert check_parameter(manager["decay_period"], 5) == 5.0  # a whole number for a float parameter
    assert check_parameter(manager["faces.capacity"], 0) == 0  # the inherit marker
    for name, value, said in (
        ("capacity", 0, "capacity must be >= 1, got 0"),
        ("faces.capacity", -1, "capacity must be >= 1, got -1"),
        ("decay_period", float("inf"), "expected a finite number in [0.01, 1e+06]"),
        ("decay_period", True, "expected a finite number"),
        ("capacity", 2**80, "capacity must be <= 10000"),
        ("faces.policy", "decay+nothing", "unknown forgetting rule 'nothing'"),
        ("service_timeout", 0.0, "expected a finite number in [0.01, 3600], got 0.0"),
    ):
        with pytest.raises(ParameterError, match=said.replace("[", r"\[").replace("+", r"\+")):
            check_parameter(manager[name], value)
    assert check_parameter(manager["activation_clock"], "words") == "words"
    assert check_parameter(manager["faces.activation_clock"], "") == ""  # the inherit marker
    for name in ("activation_clock", "faces.activation_clock"):
        with pytest.raises(ParameterError) as info:
            check_parameter(manager[name], "hours")
        inherit = ", or '' (inherit the node-wide 'activation_clock')" if "." in name else ""
        assert str(info.value) == f"expected one of seconds, episodes, words{inherit}, got 'hours'"
    reg = node_parameters("reg", ["faces"])
    with pytest.raises(ParameterError, match="expected one of auto, sd-pia"):
        check_parameter(reg["algorithm"], "fastest")
    with pytest.raises(ParameterError, match="no parameters known"):
        node_parameters("dialogue_manager", ["faces"])


def test_the_wm_manager_refuses_a_clock_that_is_not_one_and_runs_one_that_is():
    """The node's on-set callback (check_change): the effective policy of every domain, or one line why not."""
    from fsreg_ros.core.forgetting import settings
    from fsreg_ros.ros.memory_parameters import check_change

    values = {row.name: row.default for row in settings.TABLE}
    values |= {f"faces.{row.name}": row.inherit for row in settings.TABLE}
    values |= {"policy": "activation", "activation_threshold": -1.0}
    with pytest.raises(ValueError) as info:
        check_change(values, {"faces.activation_clock": "hours"}, ["faces"])
    assert str(info.value) == ("faces.activation_clock: activation_clock must be one of seconds, episodes, words, "
                               "got 'hours' ('' inherits 'activation_clock')")
    (policy,) = check_change(values, {"activation_clock": "episodes"}, ["faces"]).values()
    assert policy.limits().activation_clock == "episodes"


def test_params_files_as_ros2_param_dump_writes_them(tmp_path):
    path = tmp_path / "p.yaml"
    path.write_text("/**:\n  ros__parameters:\n    threshold: 0.6\n"
                    "robot1:\n  wm_manager:\n    ros__parameters:\n      faces:\n        capacity: 3\n"
                    "/robot1/reg:\n  ros__parameters: {algorithm: greedy}\n")
    entries = read_params_file(path)
    assert [(e.pattern, e.parameters) for e in entries] == [
        ("/**", {"threshold": 0.6}), ("/robot1/wm_manager", {"faces.capacity": 3}),
        ("/robot1/reg", {"algorithm": "greedy"})]
    assert for_node(entries, "/robot1/wm_manager") == {"threshold": 0.6, "faces.capacity": 3}
    assert matches("/**/reg", "/a/b/reg") and matches("/*/reg", "/a/reg") and not matches("/*/reg", "/a/b/reg")
    assert matches("/**", "/reg") and not matches("/robot1/reg", "/robot2/reg") and matches("reg", "/reg")
    dumped = dump_yaml({"/robot1/wm_manager": {"faces.capacity": 3, "capacity": 2, "faces.policy": "decay"}})
    assert dumped == ("/robot1/wm_manager:\n  ros__parameters:\n    capacity: 2\n    faces:\n      capacity: 3\n"
                      "      policy: decay\n")
    (tmp_path / "d.yaml").write_text(dumped)
    assert [(e.pattern, e.parameters) for e in read_params_file(tmp_path / "d.yaml")] == [
        ("/robot1/wm_manager", {"capacity": 2, "faces.capacity": 3, "faces.policy": "decay"})]
    assert yaml.safe_load(dumped)  # plain YAML


@pytest.mark.parametrize("text, said", [
    ("[1, 2]\n", "expected node names as keys"),
    ("reg: 3\n", "node /reg: expected 'ros__parameters:' under it, got 3"),
    ("reg:\n  ros__parameters: 3\n", "node /reg: 'ros__parameters' must map names to values"),
    ("reg:\n  ros__parameters: {}\n  extra: 1\n", "node /reg: unexpected key 'extra' beside 'ros__parameters'"),
    ("reg: {ros__parameters: {", "not valid YAML: "),
])
def test_a_bad_params_file_is_one_line_naming_the_file(tmp_path, text, said):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(ParameterError) as err:
        read_params_file(path)
    assert str(err.value).startswith(f"{path}: ") and said in str(err.value) and "\n" not in str(err.value)


@pytest.mark.graph
def test_a_run_time_change_is_applied_where_it_says_or_refused_with_the_reason(table1_path):
    """``ros2 param set`` (the nodes' own callbacks): use_sim_time is the graph's, fixed at start on every node;
    a node-wide memory setting is what runs in every domain that inherits it, and changing it while a domain
    overrides it is refused, not "successful" and ignored."""
    from rclpy.parameter import Parameter

    from fsreg_ros.testing import LiveGraph

    with LiveGraph(table1_path, policy="decay", decay_period=10.0) as graph:
        for name, node in graph.nodes.items():
            result = node.set_parameters([Parameter("use_sim_time", value=False)])[0]
            assert not result.successful and "read-only" in result.reason, (name, result.reason)
            assert node.get_parameter("use_sim_time").value is True, name
        manager = graph.nodes["wm_manager"]
        # the graph's shared settings are the node-wide parameters: get reports what runs, set changes it
        assert manager.get_parameter("policy").value == "decay" and manager.get_parameter("faces.policy").value == ""
        assert manager.set_parameters([Parameter("policy", value="displacement")])[0].successful
        assert graph.status()["memory"] == {"faces": {"policy": "displacement", "capacity": 2}}
        assert manager.set_parameters([Parameter("faces.policy", value="decay")])[0].successful
        result = manager.set_parameters([Parameter("policy", value="none")])[0]
        assert result.reason == ("policy: not changed: faces.policy='decay' overrides the node-wide value (which "
                                 "applies only to domains that inherit it); set faces.policy instead, or "
                                 "faces.policy='' to inherit")
        assert manager.get_parameter("policy").value == "displacement"
        assert graph.status()["memory"] == {"faces": {"policy": "decay", "decay_period": 10.0}}
        # inherit again ('' is the domain's marker): the node-wide value runs, and follows a change
        assert manager.set_parameters([Parameter("faces.policy", value="")])[0].successful
        assert manager.set_parameters([Parameter("policy", value="none")])[0].successful
        assert graph.status()["memory"] == {"faces": {"policy": "none"}}
        result = manager.set_parameters([Parameter("policy", value="")])[0]  # node-wide: no policy is not 'none'
        assert not result.successful and result.reason == "policy must be a non-empty string, got ''"


@pytest.mark.graph
def test_the_wm_manager_node_refuses_a_clock_and_runs_activation_on_the_one_set(table1_path):
    """``ros2 param set /wm_manager activation_clock ...``: one line why not, or the clock runs in every domain."""
    from rclpy.parameter import Parameter

    from fsreg_ros.testing import LiveGraph

    with LiveGraph(table1_path, policy="activation", activation_threshold=-1.0) as graph:
        manager = graph.nodes["wm_manager"]
        assert graph.status()["memory"] == {"faces": {"policy": "activation", "activation_decay": 0.5,
                                                      "activation_threshold": -1.0}}
        result = manager.set_parameters([Parameter("activation_clock", value="hours")])[0]
        assert not result.successful
        assert result.reason == "activation_clock must be one of seconds, episodes, words, got 'hours'"
        assert manager.get_parameter("activation_clock").value == "seconds"
        assert manager.set_parameters([Parameter("activation_clock", value="episodes")])[0].successful
        assert graph.status()["memory"] == {"faces": {"policy": "activation", "activation_decay": 0.5,
                                                      "activation_threshold": -1.0, "activation_clock": "episodes"}}
