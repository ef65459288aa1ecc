"""The simulator and the fsreg-sim command line (SPEC sections 2, 5 and 6)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from fsreg_ros.cli import sim_main
from fsreg_ros.core.scenario import load_scenario, parse_scenario
from fsreg_ros.core.simulation import Options, Simulation, dumps, simulate

POLICIES = ("decay", "displacement", "none")
REPO = Path(__file__).resolve().parents[1]


def robot_turns(result: dict) -> list[dict]:
    return [t for t in result["turns"] if t["speaker"] == "robot"]


@pytest.mark.parametrize("policy", POLICIES)
@pytest.mark.parametrize("which", ["table1_path", "table1_text_path"])
def test_table1_reproduces_the_paper(request, which, policy, paper_table1):
    result = simulate(load_scenario(request.getfixturevalue(which)), Options(memory={"policy": policy}))
    got = [set(t["description"]) for t in robot_turns(result)]
    assert got == [set(d) for d in paper_table1[policy]]
    assert all(t["distinguishing"] for t in robot_turns(result))
    humans = [t for t in result["turns"] if t["speaker"] == "human"]
    assert [t["resolved"] for t in humans] == [t["target"] for t in humans]
    assert all(t["status"] == "resolved" for t in humans)


def test_table1_turn6_working_memory(table1_path):
    scenario = load_scenario(table1_path)
    decay = robot_turns(simulate(scenario, Options(memory={"policy": "decay"})))[5]
    displacement = robot_turns(simulate(scenario, Options(memory={"policy": "displacement"})))[5]
    none = robot_turns(simulate(scenario, Options(memory={"policy": "none"})))[5]
    assert decay["wm_before"] == ["lab-coat", "short-hair", "glasses"]
    assert displacement["wm_before"] == ["short-hair", "glasses"]
    assert none["wm_before"] == []
    assert none["algorithm"] == "dist-pia" and decay["algorithm"] == "sd-pia"


def test_table1_exact_records_under_displacement(table1_path):
    result = simulate(load_scenario(table1_path), Options(memory={"policy": "displacement"}))
    assert result["scenario"] == "guess-who-table1"
    assert result["memory"] == {"faces": {"policy": "displacement", "capacity": 2}}
    first = robot_turns(result)[0]
    assert first == {
        "turn": 1,
        "time": 11.0,
        "speaker": "robot",
        "target": "face1",
        "wm_before": ["light-hair", "glasses"],
        "description": ["light-hair", "glasses", "lab-coat"],
        "sources": ["wm", "wm", "ltm"],
        "distinguishing": True,
        "distractors_left": [],
        "text": "the person with light hair, glasses and a lab coat",
        "domain": "faces",
        "algorithm": "sd-pia",
    }
    human = result["turns"][0]
    assert human == {
        "turn": 0,
        "time": 8.0,
        "speaker": "human",
        "target": "face1",
        "description": ["male", "lab-coat", "light-hair", "glasses"],
        "status": "resolved",
        "resolved": "face1",
        "candidates": ["face1"],
        "domain": "faces",
    }


def test_text_turns_report_unknown_words(table1_text_path):
    result = simulate(load_scenario(table1_text_path), Options(memory={"policy": "decay"}))
    turn8 = result["turns"][8]
    assert turn8["description"] == ["dark-hair", "short-hair", "t-shirt", "male"]
    assert turn8["unknown_words"] == ["he"]
    assert result["turns"][0]["unknown_words"] == []


def test_output_is_deterministic(table1_path):
    scenario = load_scenario(table1_path)
    runs = {dumps(simulate(scenario, Options(memory={"policy": p}))) for p in ["decay"] * 3}
    assert len(runs) == 1


def test_cli_json_matches_library_and_is_byte_identical(table1_path, capsys):
    assert sim_main([str(table1_path), "--json", "--policy", "displacement"]) == 0
    first = capsys.readouterr().out
    assert sim_main([str(table1_path), "--json", "--policy", "displacement"]) == 0
    assert capsys.readouterr().out == first
    expected = dumps(simulate(load_scenario(table1_path), Options(memory={"policy": "displacement"})))
    assert first == expected
    assert json.loads(first)["memory"]["faces"]["policy"] == "displacement"


def test_cli_compare_policies_with_paper_expectations(table1_path, capsys):
    code = sim_main(
        [str(table1_path), "--compare-policies", "decay,displacement,none", "--expect", str(REPO / "config/paper_table1.yaml")]
    )
    out = capsys.readouterr().out
    assert code == 0
    assert "18/18 robot descriptions match the expected ones" in out
    assert "the person with a lab coat and glasses" in out  # decay, turn 6
    assert "decay         8/14 properties reused from WM (57%), 2.33 properties per description" in out
    assert "displacement  10/15 properties reused from WM (67%), 2.50 properties per description" in out
    assert "none          0/15 properties reused from WM (0%), 2.50 properties per description" in out


def test_cli_expect_mismatch_exits_1(table1_path, tmp_path, capsys):
    wrong = tmp_path / "wrong.yaml"
    wrong.write_text("robot_descriptions:\n  none: [[glasses]]\n")
    assert sim_main([str(table1_path), "--compare-policies", "none", "--expect", str(wrong)]) == 1
    assert "0/1 robot descriptions match" in capsys.readouterr().out


def test_cli_trace_is_written_in_time_order(table1_path, tmp_path):
    trace = tmp_path / "trace.jsonl"
    assert sim_main([str(table1_path), "--trace", str(trace)]) == 0
    events = [json.loads(line) for line in trace.read_text().splitlines()]
    assert events[0] == {
        "op": "encode", "domain": "faces", "entity": "face1", "property": "male",
        "cause": "rr", "time": 8.0, "turn": 0,
    }
    times = [e["time"] for e in events]
    assert times == sorted(times)
    decays = [e for e in events if e["cause"] == "decay"]
    assert decays and all(e["op"] == "forget" and e["time"] % 10.0 == 0 for e in decays)
    assert {e["cause"] for e in events} == {"rr", "speaker", "reg-distractor", "decay"}


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["--capacity", "0"], "capacity must be >= 1"),
        (["--decay-period", "-1"], "decay_period must be > 0"),
        (["--policy", "forgetful"], "unknown forgetting rule 'forgetful'"),
        (["--policy", "global-capacity"], "needs 'global_capacity'"),
        (["--compare-policies", "decay,bogus"], "unknown forgetting rule 'bogus'"),
    ],
)
def test_cli_bad_options_exit_2_with_one_line(table1_path, capsys, args, fragment):
    assert sim_main([str(table1_path), *args]) == 2
    err = capsys.readouterr().err
    assert fragment in err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_cli_bad_scenario_file_exit_2_without_traceback(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("domains:\n  faces:\n    preference: [a]\n    entities: {e1: [b]}\n")
    proc = subprocess.run(
        [sys.executable, "-m", "fsreg_ros.cli", str(bad)], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert "bad.yaml" in proc.stderr and "domains.faces.entities.e1" in proc.stderr
    assert proc.stderr.count("\n") == 1


def test_missing_file_exit_2(tmp_path, capsys):
    assert sim_main([str(tmp_path / "nope.yaml")]) == 2
    assert "nope.yaml" in capsys.readouterr().err


def test_two_domains_keep_their_own_pools():
    scenario = parse_scenario(
        """
name: two-domains
domains:
  faces:
    preference: [light-hair, dark-hair, glasses, hat]
    entities:
      f1: [light-hair, glasses]
      f2: [dark-hair, glasses]
      f3: [light-hair, hat]
    memory: {policy: displacement, capacity: 1}
  objects:
    preference: [red, blue, large, small]
    entities:
      o1: [red, large]
      o2: [red, small]
      o3: [blue, large]
memory: {policy: decay, decay_period: 100.0}
dialogue:
  - {time: 1.0, speaker: human, description: [glasses, light-hair]}
  - {time: 2.0, speaker: human, description: [large, red]}
  - {time: 3.0, speaker: robot, target: f1}
  - {time: 4.0, speaker: robot, target: o1}
""",
        "two-domains.yaml",
    )
    sim = Simulation(scenario)
    result = sim.run()
    assert result["memory"] == {
        "faces": {"policy": "displacement", "capacity": 1},
        "objects": {"policy": "decay", "decay_period": 100.0},
    }
    f1, o1 = robot_turns(result)
    assert f1["wm_before"] == ["light-hair"]  # capacity 1: only the MRU survives
    assert o1["wm_before"] == ["large", "red"]  # decay 100 s: nothing forgotten yet
    assert o1["description"] == ["large", "red"] and o1["sources"] == ["wm", "wm"]
    assert o1["text"] == "the large red object"
    assert sim.consultants["faces"].wm.length("f1") <= 1
