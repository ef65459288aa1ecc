"""The memory settings table (``core/forgetting/settings.py``) against every consumer.

Each memory setting is declared once, in the table; the scenario schema, the command
line, the ``wm_manager`` node's parameters, the graph definition, the launch file, the
contract's policy object and the docs are generated from it.  These tests check every
consumer against the table, and show that a new row reaches all of them with no other
edit (docs/design.md, "Add a memory setting").
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import types
from pathlib import Path

import pytest

from fsreg_ros.core.forgetting import settings
from fsreg_ros.core.forgetting.policies import (
    BOUNDS, DEFAULTS, PARAMETERS, RULE_PARAMETERS, RULES, SETTINGS, PolicyError,
)

REPO = Path(__file__).resolve().parents[2]


def test_the_table_is_well_formed():
    assert settings.TABLE[0].name == "policy" and not settings.TABLE[0].is_parameter
    assert len(set(settings.names())) == len(settings.TABLE)
    for row in settings.parameters():
        if row.choices:  # a choice: text, its fallback (today's behaviour) first, the marker no choice
            assert row.kind is str and row.fallback == row.choices[0] and row.inherit not in row.choices
            assert row.default in row.choices and row.low is None is row.high
        else:
            assert row.kind in (int, float) and row.low < row.high
            assert row.inherit < row.low, f"{row.name}: the inherit marker must not be a real value"
            assert row.low <= row.default <= row.high and isinstance(row.default, row.kind)
        assert row.rules and set(row.rules) <= set(RULES), row.name
        settings.check_value(row.name, row.default)
    for rule in RULES:  # the policy's help names every rule
        assert rule in settings.setting("policy").help


def test_forgetting_takes_its_parameters_from_the_table():
    assert SETTINGS == settings.names() and PARAMETERS == tuple(r.name for r in settings.parameters())
    assert BOUNDS == {r.name: (r.low, r.high) for r in settings.parameters()}
    assert DEFAULTS == {"seed": 0, "activation_decay": 0.5, "activation_clock": "seconds", "episode_window": 1}
    assert RULE_PARAMETERS["displacement-random"] == ("capacity", "seed")
    assert RULE_PARAMETERS["similarity"] == () and RULE_PARAMETERS["decay"] == ("decay_period",)


@pytest.mark.parametrize("value, message", [
    (0.001, "decay_period must be >= 0.01 seconds, got 0.001"),
    (0, "decay_period must be > 0 seconds (at least 0.01), got 0"),
    (float("nan"), "decay_period must be a number of seconds, got nan"),
    (10**400, "decay_period must be a number of seconds, got an integer of 1329 bits"),
    (True, "decay_period must be a number of seconds, got True"),
])
def test_one_check_with_one_line_messages(value, message):
    with pytest.raises(PolicyError) as info:
        settings.check_value("decay_period", value)
    assert str(info.value) == message
    with pytest.raises(PolicyError, match=r"^capacity must be a whole number, got 2\.0$"):
        settings.check_value("capacity", 2.0)
    with pytest.raises(PolicyError, match=r"^seed must be <= 2147483647, got 2147483648$"):
        settings.check_value("seed", 2**31)
    with pytest.raises(PolicyError, match="unknown memory setting 'speed'"):
        settings.check_value("speed", 1)


def test_a_choice_setting_takes_its_choices_only():
    assert [settings.check_value("activation_clock", c) for c in ("seconds", "episodes", "words")] == \
        ["seconds", "episodes", "words"]
    for bad, shown in (("hours", "'hours'"), (1, "1"), ("", "''")):
        with pytest.raises(PolicyError) as info:
            settings.check_value("activation_clock", bad)
        assert str(info.value) == f"activation_clock must be one of seconds, episodes, words, got {shown}"
    from fsreg_ros.core.forgetting.policies import ForgettingPolicy

    # at its fallback a choice is not reported (today's reports stay); else it is
    assert ForgettingPolicy.parse("activation", activation_threshold=-1.0).to_json() == \
        {"policy": "activation", "activation_decay": 0.5, "activation_threshold": -1.0}
    policy = ForgettingPolicy.parse("activation", activation_threshold=-1.0, activation_clock="words")
    assert policy.to_json()["activation_clock"] == "words" and policy.limits().activation_clock == "words"
    assert ForgettingPolicy.parse("displacement", capacity=2, activation_clock="words").limits().activation_clock \
        == "seconds"  # kept for a switch, read only under rule activation


def test_the_scenario_schema_is_the_table():
    from fsreg_ros.core.scenario.schema import MemoryBlock, scenario_json_schema

    assert tuple(MemoryBlock.model_fields) == settings.names()
    schema = scenario_json_schema()["$defs"]["MemoryBlock"]["properties"]
    for row in settings.parameters():
        if row.choices:
            assert schema[row.name]["enum"] == list(row.choices)
        else:
            assert (schema[row.name]["minimum"], schema[row.name]["maximum"]) == (row.low, row.high)
        assert schema[row.name]["description"] == row.description
    assert schema["policy"]["pattern"].count("displacement-random") == 2


def test_the_command_line_options_are_the_table():
    from fsreg_ros.tools.sim import build_parser, options_from_args

    parser = build_parser("fsreg-sim", "")
    actions = {a.dest: a for a in parser._actions}
    for row in settings.TABLE:
        assert row.option in actions[row.name].option_strings and actions[row.name].type is row.kind
    argv = ["s.yaml", "--policy", "decay", "--decay-period", "2.5", "--capacity", "3", "--global-capacity", "9",
            "--seed", "4", "--shared-capacity", "5"]
    memory = options_from_args(parser.parse_args(argv)).memory
    assert memory == {"policy": "decay", "decay_period": 2.5, "capacity": 3, "global_capacity": 9, "seed": 4,
                      "shared_capacity": 5}
    with pytest.raises(PolicyError, match="shared_capacity must be >= 1, got 0"):
        options_from_args(parser.parse_args(["s.yaml", "--shared-capacity", "0"]))


def test_the_node_parameter_descriptors_are_the_table():
    from fsreg_ros.ros.memory_parameters import SETTINGS as NODE_SETTINGS
    from fsreg_ros.ros.memory_parameters import setting_descriptor

    assert NODE_SETTINGS == settings.names()
    for row in settings.parameters():
        descriptor = setting_descriptor(row.name)
        if row.choices:
            assert descriptor.additional_constraints == "one of " + ", ".join(row.choices)
            assert setting_descriptor(row.name, "faces").additional_constraints == \
                f"{row.inherit!r} (inherit) or one of {', '.join(row.choices)}"
            continue
        (bounds,) = descriptor.floating_point_range if row.kind is float else descriptor.integer_range
        assert (bounds.from_value, bounds.to_value) == (row.low, row.high)
        assert row.help in descriptor.description
        # per domain: no ROS range (it would have to reach down to the inherit marker: "Min: 0"); the rule in words
        domain = setting_descriptor(row.name, "faces")
        assert not domain.floating_point_range and not domain.integer_range and row.help in domain.description
        assert domain.additional_constraints == f"{row.inherit!r} (inherit) or {row.bounds_text}"


def test_the_graph_and_the_launch_file_pass_every_setting(monkeypatch):
    from fsreg_ros.core.forgetting.policies import ForgettingPolicy
    from fsreg_ros.ros.graph_spec import node_specs, policy_settings

    every = ForgettingPolicy.from_settings({row.name: row.default for row in settings.TABLE})
    manager = next(s for s in node_specs("kb.yaml", ["faces"], {"faces": policy_settings(every)})
                   if s.executable == "wm_manager")
    assert {k for k in manager.parameters if k in settings.names()} == set(settings.names())  # shared: node-wide
    assert not [k for k in manager.parameters if k.startswith("faces.")]
    other = ForgettingPolicy.from_settings({row.name: row.default for row in settings.TABLE} | {"capacity": 5})
    manager = next(s for s in node_specs("kb.yaml", ["faces", "objects"], {"faces": policy_settings(every),
                                                                           "objects": policy_settings(other)})
                   if s.executable == "wm_manager")
    assert (manager.parameters["faces.capacity"], manager.parameters["objects.capacity"]) == (2, 5)
    assert "capacity" not in manager.parameters and "faces.policy" not in manager.parameters
    arguments = _launch_arguments(monkeypatch)
    for row in settings.TABLE:
        assert arguments[row.name] == ("", f"{row.description} ('' = the preset's, else {row.default})")


def _launch_arguments(monkeypatch) -> dict:
    stub = types.SimpleNamespace(LaunchDescription=None, DeclareLaunchArgument=None, OpaqueFunction=None,
                                 LaunchConfiguration=None, Node=None)
    for name in ("launch", "launch.actions", "launch.substitutions", "launch_ros", "launch_ros.actions"):
        monkeypatch.setitem(sys.modules, name, stub)
    namespace: dict = {}
    exec(compile((REPO / "launch" / "fsreg.launch.py").read_text(), "fsreg.launch.py", "exec"), namespace)
    return namespace["ARGUMENTS"]


def test_the_contract_policy_object_is_the_table():
    from fsreg_ros.contract.codec import MessageError
    from fsreg_ros.contract import PolicySettings, check, json_schemas

    assert tuple(PolicySettings.model_fields) == settings.names()
    policy = PolicySettings.model_validate({"policy": "decay+displacement", "decay_period": 10, "capacity": 2})
    assert policy.to_policy().to_json() == {"policy": "decay+displacement", "decay_period": 10.0, "capacity": 2}
    for bad, message in [({"policy": "decay"}, "policy 'decay' needs 'decay_period' (decay) but it is not set"),
                         ({"policy": "none", "speed": 1}, "unknown memory setting 'speed'"),
                         ({"policy": "none", "capacity": 0}, "capacity must be >= 1, got 0")]:
        with pytest.raises(MessageError, match=re.escape(message)):
            check(PolicySettings, bad)
    reply = json_schemas()["service.wm_manager.sync.reply"]
    assert set(reply["$defs"]["PolicySettings"]["properties"]) == set(settings.names())


def test_the_docs_table_is_the_table():
    text = (REPO / "docs" / "scenario-format.md").read_text()
    section = text[text.index("## Memory settings"):text.index("## Errors")]
    assert [line for line in section.splitlines() if line.startswith("|")] == settings.markdown_table()


# A new row, and what it must reach with no other edit.  Run in a fresh interpreter so that
# every consumer is built from the extended table, as it would be from an edited one.
NEW_SETTING = r'''
import json, sys, types
from fsreg_ros.core.forgetting import settings
settings.TABLE = settings.TABLE + (settings.Setting(
    "patience", int, 5, 0, "similarity: how many encodings an attribute's rival survives", 1, 9,
    rules=("similarity",), fallback=3),)

from fsreg_ros.tools.sim import build_parser, options_from_args
from fsreg_ros.contract import PolicySettings
from fsreg_ros.core.forgetting.policies import ForgettingPolicy
from fsreg_ros.core.scenario import load_scenario
from fsreg_ros.core.scenario.schema import scenario_json_schema
from fsreg_ros.ros.graph_spec import node_specs, policy_settings
from fsreg_ros.ros.memory_parameters import setting_descriptor

out = {}
policy = ForgettingPolicy.parse("similarity", patience=4)
out["policy"] = policy.to_json()
out["fallback"] = ForgettingPolicy.parse("similarity").to_json()
out["schema"] = scenario_json_schema()["$defs"]["MemoryBlock"]["properties"]["patience"]["maximum"]
args = build_parser("fsreg-sim", "").parse_args([sys.argv[1], "--patience", "7"])
out["cli"] = options_from_args(args).memory
scenario = load_scenario(sys.argv[1])
out["scenario"] = scenario.policy_for("faces").to_json()
out["scenario+cli"] = scenario.policy_for("faces", options_from_args(args).memory).to_json()
out["contract"] = PolicySettings.model_validate({"policy": "similarity", "patience": 2}).to_policy().to_json()
spec = [s for s in node_specs("kb", ["faces"], {"faces": policy_settings(policy)}) if s.executable == "wm_manager"]
out["graph"] = spec[0].parameters["patience"]  # one domain: node-wide
(r,) = setting_descriptor("patience").integer_range
out["descriptor"] = [r.from_value, r.to_value]
print(json.dumps(out, sort_keys=True))
'''


def test_a_new_setting_reaches_every_consumer_with_no_other_edit(tmp_path):
    scenario = tmp_path / "s.yaml"
    scenario.write_text("memory: {policy: similarity, patience: 6}\n"
                        "domains:\n  faces:\n    preference: [male]\n    entities: {face1: [male]}\n")
    proc = subprocess.run([sys.executable, "-c", NEW_SETTING, str(scenario)], capture_output=True, text=True,
                          timeout=120, env=dict(os.environ), cwd=REPO)
    assert proc.returncode == 0, proc.stderr
    assert json.loads(proc.stdout) == {
        "policy": {"policy": "similarity", "patience": 4},
        "fallback": {"policy": "similarity", "patience": 3},
        "schema": 9,
        "cli": {"patience": 7},
        "scenario": {"policy": "similarity", "patience": 6},
        "scenario+cli": {"policy": "similarity", "patience": 7},
        "contract": {"policy": "similarity", "patience": 2},
        "graph": 4,
        "descriptor": [1, 9],
    }
