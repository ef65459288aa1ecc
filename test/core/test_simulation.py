"""The simulator and the fsreg-sim command line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from fsreg_ros.tools.sim import sim_main
from fsreg_ros.core.algorithms.alignment import BASELINE_SIMULATOR, annotate, summarise
from fsreg_ros.core.scenario import load_scenario, parse_scenario
from fsreg_ros.core.simulation.simulator import Options, Simulation, dumps, simulate

POLICIES = ("decay", "displacement", "none")
REPO = Path(__file__).resolve().parents[2]


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
        # what made each WM property enter Q[face1]: the human's description at turn 0 (rule 1)
        "origins": [{"cause": "speaker", "turn": 0}, {"cause": "speaker", "turn": 0}, None],
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
    scenario = load_scenario(table1_path)
    result = Simulation(scenario, Options(memory={"policy": "displacement"})).run()
    none = summarise(Simulation(scenario, Options(memory={"policy": "none"})).run())
    assert first == dumps(annotate(result, none, BASELINE_SIMULATOR))
    assert json.loads(first)["memory"]["faces"]["policy"] == "displacement"


def test_cli_compare_policies_with_paper_expectations(table1_path, capsys):
    code = sim_main(
        [
            str(table1_path),
            "--compare-policies",
            "decay,displacement,none",
            "--expect",
            str(REPO / "config/paper_table1.yaml"),
        ]
    )
    out = capsys.readouterr().out
    assert code == 0
    assert "18/18 robot descriptions match the expected ones" in out
    assert "the person with a lab coat and glasses" in out  # decay, turn 6
    assert "decay         entrainment 0.78 over 5 turns, gain -0.10 over none (0.87)" in out
    assert "displacement  entrainment 0.82 over 5 turns, gain -0.06 over none (0.87)" in out


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
        "op": "encode",
        "domain": "faces",
        "entity": "face1",
        "property": "male",
        "cause": "rr",
        "time": 8.0,
        "turn": 0,
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
        (["--policy", "activation", "--activation-threshold", "-1", "--activation-clock", "hours"],
         "fsreg-sim: error: activation_clock must be one of seconds, episodes, words, got 'hours'\n"),
        (["--activation-clock", "hours"], "activation_clock must be one of seconds, episodes, words, got 'hours'"),
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
    proc = subprocess.run([sys.executable, "-m", "fsreg_ros.tools.sim", str(bad)],
                          capture_output=True, text=True, timeout=60)
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


# ------------------------------------------------------- the CLI does what it says
PAPER = REPO / "config" / "paper_table1.yaml"


def random_scenario(rng, index: int) -> tuple[str, dict]:
    """A random scenario text whose memory blocks may lack parameters, and CLI settings that complete them."""
    rules = ("decay", "displacement", "global-capacity")
    params = {
        "decay": ("decay_period", "--decay-period"),
        "displacement": ("capacity", "--capacity"),
        "global-capacity": ("global_capacity", "--global-capacity"),
    }
    props = [f"p{i}" for i in range(6)]

    def block() -> str:
        chosen = rng.sample(rules, rng.randint(1, 3))
        items = [f"policy: {'+'.join(chosen)}"]
        items += [f"{params[r][0]}: {rng.randint(1, 5)}" for r in chosen if rng.random() < 0.4]
        return "{" + ", ".join(items) + "}"

    entities = "\n".join(f"      e{i}: [{', '.join(rng.sample(props, 3))}]" for i in range(5))
    domain_memory = f"\n    memory: {block()}" if rng.random() < 0.5 else ""
    dialogue = "\n".join(f"  - {{time: {t}.0, speaker: robot, target: e{rng.randrange(5)}}}" for t in range(1, 6))
    text = (
        f"name: random{index}\nmemory: {block()}\ndomains:\n  d:\n    preference: [{', '.join(props)}]"
        f"{domain_memory}\n    entities:\n{entities}\ndialogue:\n{dialogue}\n"
    )
    cli_rules = rng.sample(rules, rng.randint(1, 3))
    cli = {"--policy": "+".join(cli_rules)}
    cli.update({params[r][1]: str(rng.randint(1, 5)) for r in cli_rules})
    return text, cli


def test_cli_memory_options_complete_the_files_settings(tmp_path, capsys):
    """60 random files naming rules without parameters, run with command-line settings that complete them."""
    import random

    rng = random.Random(9)
    for index in range(60):
        text, cli = random_scenario(rng, index)
        path = tmp_path / f"r{index}.yaml"
        path.write_text(text)
        args = [str(path), "--json"] + [x for pair in cli.items() for x in pair]
        assert sim_main(args) == 0, (text, cli, capsys.readouterr().err)
        memory = json.loads(capsys.readouterr().out)["memory"]["d"]
        assert set(memory["policy"].split("+")) == set(cli["--policy"].split("+"))
        for option, value in cli.items():
            if option != "--policy":
                assert memory[option[2:].replace("-", "_")] == (
                    float(value) if option == "--decay-period" else int(value)
                )


def test_cli_policy_with_its_parameter_overrides_a_file_missing_it(tmp_path, capsys):
    path = tmp_path / "s.yaml"
    path.write_text(
        "memory: {policy: decay+global-capacity, decay_period: 10}\n"
        "domains:\n  d:\n    preference: [a, b]\n    entities: {x: [a], y: [b]}\n"
        "dialogue:\n  - {time: 1.0, speaker: robot, target: x}\n"
    )
    assert sim_main([str(path), "--policy", "decay", "--global-capacity", "5", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["memory"]["d"] == {"policy": "decay", "decay_period": 10.0}
    assert sim_main([str(path)]) == 2
    assert "needs 'global_capacity' (add --global-capacity N" in capsys.readouterr().err


def test_cli_compared_policy_missing_its_parameter_names_the_option(table1_path, capsys):
    assert sim_main([str(table1_path), "--compare-policies", "decay,global-capacity"]) == 2
    err = capsys.readouterr().err
    assert (
        "<command line>: domain 'faces': policy 'global-capacity' needs 'global_capacity' (add --global-capacity N"
        in err
    )
    assert sim_main([str(table1_path), "--compare-policies", "decay,global-capacity", "--global-capacity", "4"]) == 0


@pytest.mark.parametrize(
    "args, fragment",
    [
        (["--compare-policies", "decay", "--trace", "t.jsonl"], "--trace writes the events of one run"),
        (["--expect", str(PAPER), "--trace", "t.jsonl"], "--trace writes the events of one run"),
        (["--compare-policies", "decay", "--policy", "none"], "--policy chooses one policy"),
    ],
)
def test_cli_refuses_options_it_would_ignore(table1_path, capsys, args, fragment):
    assert sim_main([str(table1_path), *args]) == 2
    err = capsys.readouterr().err
    assert fragment in err and err.count("\n") == 1


def test_cli_expect_alone_compares_the_policies_it_lists(table1_path, capsys):
    assert sim_main([str(table1_path), "--expect", str(PAPER)]) == 0
    out = capsys.readouterr().out
    assert "18/18 robot descriptions match the expected ones" in out
    assert out.splitlines()[0].split()[-3:] == ["decay", "displacement", "none"]
    assert "ok   = the robot's description has exactly the expected properties" in out
    assert '"male, lab-coat, light-hair, glasses"' in out  # the human's turns are shown


def test_cli_diff_shows_the_expected_description_and_unchecked_turns(table1_path, tmp_path, capsys):
    wrong = tmp_path / "wrong.yaml"
    wrong.write_text("robot_descriptions:\n  none: [[glasses], [dark-hair, male]]\n")
    assert sim_main([str(table1_path), "--expect", str(wrong)]) == 1
    out = capsys.readouterr().out
    assert "DIFF the person with light hair, a lab coat and glasses [expected: glasses]" in out
    assert "ok   the man with dark hair" in out
    assert "--   the woman with glasses" in out
    assert "1/2 robot descriptions match the expected ones" in out
    assert "4 robot turns had no expected description: none: robot turn 3 (turn 5); none: robot turn 4 (turn 7)" in out


def test_cli_table_explains_its_columns(table1_path, capsys):
    assert sim_main([str(table1_path)]) == 0
    out = capsys.readouterr().out
    assert '"male, lab-coat, light-hair, glasses" -> face1' in out
    assert "WM before: the target's working memory just before the robot spoke, least recently used first." in out


def test_cli_lexicon_extends_the_built_in_one(tmp_path, capsys):
    scenario = tmp_path / "s.yaml"
    scenario.write_text(
        "domains:\n  faces:\n    preference: [fedora, glasses, male]\n"
        "    entities: {a: [fedora, male], b: [glasses, male]}\n"
        "dialogue:\n  - {time: 1.0, speaker: human, text: the man in a trilby}\n"
        "  - {time: 2.0, speaker: robot, target: a}\n"
    )
    lexicon = tmp_path / "lex.yaml"
    lexicon.write_text(
        "properties:\n  fedora: {words: fedora, article: a, phrases: [trilby]}\n"
        "domains:\n  faces: {properties: [fedora]}\n"
    )
    assert sim_main([str(scenario), "--lexicon", str(lexicon), "--json"]) == 0
    turns = json.loads(capsys.readouterr().out)["turns"]
    assert turns[0]["description"] == ["male", "fedora"] and turns[0]["resolved"] == "a"
    assert turns[1]["description"] == ["fedora"]
    assert turns[1]["text"] == "the person with a fedora"  # "person": the built-in faces noun


@pytest.mark.parametrize("kind", ["nul", "utf8", "directory", "huge"])
@pytest.mark.parametrize("role", ["scenario", "--expect", "--lexicon"])
def test_cli_bad_files_are_one_line_exit_2(table1_path, tmp_path, capsys, monkeypatch, kind, role):
    from fsreg_ros.core.io import yaml_source

    path = tmp_path / "bad.yaml"
    if kind == "nul":
        path.write_bytes(b"name: x\0\n")
    elif kind == "utf8":
        path.write_bytes(b"name: \xff\xfe\n")
    elif kind == "directory":
        path.mkdir()
    else:
        monkeypatch.setattr(yaml_source, "MAX_FILE_BYTES", 200_000)  # above the built-in lexicon's size
        path.write_text("#" * 200_001)
    args = [str(path)] if role == "scenario" else [str(table1_path), role, str(path)]
    assert sim_main(args) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"fsreg-sim: error: {path}: ") and err.count("\n") == 1


def test_graph_bad_file_is_one_line_exit_2(tmp_path, capsys):
    from fsreg_ros.tools.graph import main as graph_main

    path = tmp_path / "bad.yaml"
    path.write_bytes(b"domains: {}\0")
    assert graph_main([str(path)]) == 2
    err = capsys.readouterr().err
    assert err == f"fsreg-graph: error: {path}: not a text file: NUL byte at offset 11\n"


def test_trace_is_built_only_when_asked_and_changes_nothing(table1_path):
    scenario = load_scenario(table1_path)
    options = Options(memory={"policy": "decay+displacement"})
    plain, traced = Simulation(scenario, options), Simulation(scenario, options, trace=True)
    assert plain.events is None
    assert dumps(plain.run()) == dumps(traced.run())
    assert len(traced.trace()) > 100
    with pytest.raises(ValueError, match="trace=True"):
        plain.trace()


def test_cli_expect_with_json_still_checks(table1_path, tmp_path, capsys):
    wrong = tmp_path / "wrong.yaml"
    wrong.write_text("robot_descriptions:\n  none: [[glasses]]\n")
    assert sim_main([str(table1_path), "--expect", str(wrong), "--json"]) == 1
    assert list(json.loads(capsys.readouterr().out)) == ["none"]
    assert sim_main([str(table1_path), "--expect", str(PAPER), "--json"]) == 0


def test_command_line_sets_every_memory_parameter(table1_path, capsys):
    """--seed and --shared-capacity reach the effective setting, like the other parameters."""
    assert sim_main([str(table1_path), "--json", "--policy", "displacement-random+shared-capacity",
                     "--capacity", "2", "--seed", "3", "--shared-capacity", "4"]) == 0
    memory = json.loads(capsys.readouterr().out)["memory"]
    assert memory == {"faces": {"policy": "displacement-random+shared-capacity", "capacity": 2, "seed": 3,
                                "shared_capacity": 4}}
    assert sim_main([str(table1_path), "--policy", "decay", "--decay-period", "5", "--seed", "-1"]) == 2
    assert capsys.readouterr().err.strip() == "fsreg-sim: error: seed must be >= 0, got -1"
