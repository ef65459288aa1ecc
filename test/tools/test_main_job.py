"""The main job's alignment figures: fsreg-sim's JSON keys and summary lines, and --trace-dir / --plot-dir."""

from __future__ import annotations

import json
import secrets
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fsreg_ros.tools.sim import sim_main
from fsreg_ros.core.algorithms.alignment import BASELINE_COMPARED, BASELINE_RUN, BASELINE_SIMULATOR
from fsreg_ros.core.scenario import load_scenario
from fsreg_ros.core.simulation.simulator import Options, Simulation

REPO = Path(__file__).resolve().parents[2]
PAPER = REPO / "config/paper_table1.yaml"


def compare_json(table1_path, capsys, *extra) -> tuple[dict, str]:
    """Return the policies' results of Table 1 (fsreg-sim --json) and what went to stderr."""
    assert sim_main([str(table1_path), "--compare-policies", "decay,displacement,none", "--json", *extra]) == 0
    captured = capsys.readouterr()
    return json.loads(captured.out), captured.err


def robot(result: dict, turn: int) -> dict:
    (record,) = [t for t in result["turns"] if t["turn"] == turn]
    assert record["speaker"] == "robot"
    return record


def test_table1_alignment_blocks(table1_path, capsys):
    runs, _ = compare_json(table1_path, capsys)
    assert runs["decay"]["alignment"] == {
        "robot_turns": 6, "properties": 14, "aligned": 11, "alignment": 0.7857, "described_turns": 5,
        "entrainment": 0.779, "recall": 0.6833, "from_wm": 8,
        "wm_origins": {"human-speech": 3, "rr": 3, "reg-distractor": 2, "robot-speech": 0},
        "none_alignment": 0.8667, "gain_over_none": -0.081, "none_entrainment": 0.8743, "entrainment_gain": -0.0952,
        "paired_turns": 5, "length_matched_gain": -0.2, "length_matched_turns": 5,
        "none_baseline": BASELINE_COMPARED,
    }
    assert runs["displacement"]["alignment"] == {
        "robot_turns": 6, "properties": 15, "aligned": 12, "alignment": 0.8, "described_turns": 5,
        "entrainment": 0.8171, "recall": 0.7333, "from_wm": 10,
        "wm_origins": {"human-speech": 5, "rr": 4, "reg-distractor": 0, "robot-speech": 1},
        "none_alignment": 0.8667, "gain_over_none": -0.0667, "none_entrainment": 0.8743, "entrainment_gain": -0.0571,
        "paired_turns": 5, "length_matched_gain": -0.1667, "length_matched_turns": 6,
        "none_baseline": BASELINE_COMPARED,
    }
    assert runs["none"]["alignment"] == {
        "robot_turns": 6, "properties": 15, "aligned": 13, "alignment": 0.8667, "described_turns": 5,
        "entrainment": 0.8743, "recall": 0.7833, "from_wm": 0,
        "wm_origins": {"human-speech": 0, "rr": 0, "reg-distractor": 0, "robot-speech": 0},
        "none_alignment": 0.8667, "gain_over_none": 0.0, "none_entrainment": 0.8743, "entrainment_gain": 0.0,
        "paired_turns": 5, "length_matched_gain": 0.0, "length_matched_turns": 6,
        "none_baseline": BASELINE_COMPARED,
    }


def test_table1_aligned_properties_and_their_origins_per_turn(table1_path, capsys):
    runs, _ = compare_json(table1_path, capsys)
    decay, displacement, none = runs["decay"], runs["displacement"], runs["none"]
    # Turn 1: the human's words of turn 0, kept in WM, all aligned.
    assert robot(decay, 1)["aligned"] == ["lab-coat", "light-hair", "glasses"]
    assert robot(decay, 1)["wm_origins"] == {"lab-coat": "human-speech", "light-hair": "human-speech",
                                             "glasses": "human-speech"}
    # Turn 7: WM offers what REG ruled out for distractors; the human never said short-hair of face1.
    assert robot(decay, 7)["description"] == ["glasses", "short-hair", "lab-coat"]
    assert robot(decay, 7)["aligned"] == ["glasses", "lab-coat"]
    assert robot(decay, 7)["wm_origins"] == {"glasses": "reg-distractor", "short-hair": "reg-distractor",
                                             "lab-coat": "rr"}
    # Turn 11: the robot's own description of turn 7, and RR checking face1 against "short-hair, glasses, hoodie".
    assert robot(displacement, 11)["aligned"] == ["glasses", "lab-coat"]
    assert robot(displacement, 11)["wm_origins"] == {"short-hair": "rr", "glasses": "robot-speech"}
    assert robot(displacement, 3)["aligned"] == [] and robot(displacement, 3)["wm_origins"] == {"male": "rr"}
    assert robot(none, 11)["aligned"] == ["light-hair", "lab-coat", "glasses"] and robot(none, 11)["wm_origins"] == {}
    # Against the human's last description of face1 (turn 0: male, lab-coat, light-hair, glasses).
    assert (robot(decay, 7)["human_last_turn"], robot(decay, 7)["dice_last"], robot(decay, 7)["recall_last"]) == (
        0, round(2 * 2 / 7, 4), 0.5)
    assert robot(decay, 3)["human_last"] is None and robot(decay, 3)["dice_last"] is None  # face5: not described
    # The raw origins REG reported: what made each WM property enter Q[face1].
    assert robot(decay, 7)["origins"] == [{"cause": "reg-distractor", "turn": 5}, {"cause": "reg-distractor",
                                          "turn": 3}, {"cause": "rr", "turn": 6}]
    # Human turns carry no alignment keys.
    assert all("aligned" not in t and "wm_origins" not in t and "dice_last" not in t
               for t in decay["turns"] if t["speaker"] == "human")


def test_single_run_baseline_is_the_simulator_under_none_or_the_run_itself(table1_path, capsys):
    assert sim_main([str(table1_path), "--policy", "decay", "--decay-period", "40", "--json"]) == 0
    block = json.loads(capsys.readouterr().out)["alignment"]
    assert (block["aligned"], block["properties"], block["gain_over_none"]) == (14, 16, 0.0083)
    assert (block["entrainment"], block["entrainment_gain"], block["none_entrainment"]) == (0.9143, 0.04, 0.8743)
    assert block["none_baseline"] == BASELINE_SIMULATOR
    assert sim_main([str(table1_path), "--policy", "none", "--json"]) == 0
    block = json.loads(capsys.readouterr().out)["alignment"]
    assert (block["alignment"], block["gain_over_none"], block["none_baseline"]) == (0.8667, 0.0, BASELINE_RUN)


def test_main_job_summary_lines(table1_path, capsys):
    assert sim_main([str(table1_path), "--expect", str(PAPER)]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    start = lines.index(next(line for line in lines if line.startswith("decay         entrainment")))
    assert lines[start:start + 11] == [
        "decay         entrainment 0.78 over 5 turns, gain -0.10 over none (0.87); length-matched -0.20 aligned "
        "(5 turns); aligned 11/14 (79%), recall 0.68; from WM 8/14: human-speech 3, rr 3, reg-distractor 2, "
        "robot-speech 0; 2.33 properties per description",
        "displacement  entrainment 0.82 over 5 turns, gain -0.06 over none (0.87); length-matched -0.17 aligned "
        "(6 turns); aligned 12/15 (80%), recall 0.73; from WM 10/15: human-speech 5, rr 4, reg-distractor 0, "
        "robot-speech 1; 2.50 properties per description",
        "none          entrainment 0.87 over 5 turns, gain +0.00 over none (0.87); length-matched +0.00 aligned "
        "(6 turns); aligned 13/15 (87%), recall 0.78; from WM 0/15: human-speech 0, rr 0, reg-distractor 0, "
        "robot-speech 0; 2.50 properties per description",
        "entrainment: the mean Dice of the robot's description with the human's most recent description of the same "
        "referent, over the robot turns whose referent the human had described; unlike the aligned share, length "
        "alone cannot raise it (Dice falls with every property the human did not say and every one of theirs left "
        "out).",
        "gain over none: entrainment minus that of the same game under policy none (no working memory), paired turn "
        "by turn; the none figure comes from the none run of this comparison. One game: no interval (fsreg-sweep "
        "gives intervals over many games).",
        "length-matched: the mean change in aligned properties against none on the turns where both descriptions are "
        "as long.",
        "aligned: the robot's properties that the human had already used for the same referent earlier in the game "
        "(the share can rise just by saying less); recall: the mean share of the human's last description repeated.",
        "from WM: the properties the robot took from the target's working memory, counted by what had put each there "
        "(human-speech = the human's own description, rr = reference resolution checking a candidate, "
        "reg-distractor = REG ruling out a distractor, robot-speech = the robot's own earlier description).",
        "properties per description: the mean number of properties in the robot's descriptions.",
        "",
        "conclusion: on this one dialogue (5 paired turns), compared with no working memory the robot's entrainment "
        "with the human (Dice with the human's last description) is lower under decay (-0.10) and displacement "
        "(-0.06). One game is no evidence either way: fsreg-sweep measures the gain over many games, with intervals "
        "(docs/research.md).",
    ]
    assert "reused from WM" not in out
    assert "  11  face1     2/2 aligned, Dice 0.67 with H0; from WM: lab-coat (rr), glasses (rr)" in out
    assert "   3  face5     0/2 aligned  " in out  # no human description of face5: no Dice
    assert "18/18 robot descriptions match the expected ones" in out


def test_single_run_table_shows_alignment(table1_path, capsys):
    assert sim_main([str(table1_path), "--policy", "displacement"]) == 0
    out = capsys.readouterr().out
    assert "  11  face1     2/3 aligned, Dice 0.57 with H0; from WM: short-hair (rr), glasses (robot-speech)" in out
    assert "the none figure comes from the core simulator under policy none. One game: no interval" in out
    assert "is lower under displacement (-0.06)" in out


@pytest.mark.slow  # draws three PNGs (matplotlib)
def test_trace_dir_and_plot_dir_write_one_file_per_policy(table1_path, tmp_path, capsys):
    traces, plots = tmp_path / "traces", tmp_path / "plots" / "deep"
    runs, err = compare_json(table1_path, capsys, "--trace-dir", str(traces), "--plot-dir", str(plots))
    scenario = load_scenario(table1_path)
    for policy in ("decay", "displacement", "none"):
        simulation = Simulation(scenario, Options(memory={"policy": policy}), trace=True)
        simulation.run()
        written = traces / f"guess_who_table1-{policy}.jsonl"
        assert [json.loads(line) for line in written.read_text().splitlines()] == simulation.trace()
        png = plots / f"guess_who_table1-{policy}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and str(png) in err  # --json: paths on stderr
    assert list(runs) == ["decay", "displacement", "none"]


@pytest.mark.slow  # draws a PNG (matplotlib)
def test_plot_dir_in_text_mode_says_where(table1_path, tmp_path, capsys):
    assert sim_main([str(table1_path), "--policy", "decay", "--plot-dir", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[-1] == (f"files written: {tmp_path / 'guess_who_table1-decay.png'}, "
                                    f"{tmp_path / 'guess_who_table1-decay.pdf'}")
    assert (tmp_path / "guess_who_table1-decay.pdf").read_bytes().startswith(b"%PDF")


def test_unwritable_plot_dir_is_one_line_exit_2(table1_path, tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert sim_main([str(table1_path), "--plot-dir", str(blocker / "sub")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("fsreg-sim: error: ") and err.count("\n") == 1


# ---------------------------------------------------------------------- exit code (the graph runner)
def _long_table1(table1_path: Path, out: Path, rounds: int = 25) -> Path:
    """Table 1's dialogue played ``rounds`` times (100 s apart): a run long enough to outlast DDS discovery."""
    import yaml

    data = yaml.safe_load(table1_path.read_text())
    turns = data["dialogue"]
    data["dialogue"] = [{**turn, "time": turn["time"] + 100.0 * r} for r in range(rounds) for turn in turns]
    out.write_text(yaml.safe_dump(data, sort_keys=False))
    return out


@pytest.mark.slow  # starts node processes
def test_the_main_job_fails_loudly_when_its_event_stream_is_not_its_own(table1_path, tmp_path):
    """A run that hears another graph's events exits non-zero and prints no table (issue 20): its origins,
    alignment and timelines would be built from data that is not its own.  (The dialogue is long, so the
    intruder is discovered during the run: a publisher nobody has discovered yet cannot be heard.)"""
    from std_msgs.msg import String

    from fsreg_ros import contract
    from fsreg_ros.ros.carrier import qos_profile, to_msg
    from fsreg_ros.testing import RosSession

    namespace = f"mainjob_{secrets.token_hex(4)}"
    foreign = {"op": "encode", "domain": "faces", "entity": "face1", "property": "male", "cause": "rr", "time": 0.0,
               "turn": 0, "seq": 1, "incarnation": 1, "graph": "someone-else"}
    job = None
    try:
        with RosSession(namespace) as ros:  # the intruder is there before the job starts
            pub = ros.probe.create_publisher(String, contract.WM_EVENTS.name, qos_profile(contract.EVENTS_QOS))
            scenario = _long_table1(table1_path, tmp_path / "long.yaml")
            job = subprocess.Popen([str(Path(sys.executable).parent / "fsreg-graph"), str(scenario), "--namespace",
                                    namespace, "--compare-policies", "decay,displacement,none"],
                                   stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            deadline = time.monotonic() + 240
            while job.poll() is None:  # the player sees a writer too many, or hears its event
                assert time.monotonic() < deadline, "the main job did not end"
                if pub.get_subscription_count():
                    pub.publish(to_msg(foreign))
                ros.spin_for(0.1)
        out, err = job.communicate(timeout=60)
    finally:
        if job is not None and job.poll() is None:
            job.kill()
    assert job.returncode == 1, (out, err)
    assert out == ""
    assert err.startswith("fsreg-graph: failed: dialogue_player failed (exit 1)")
    assert "another graph publishes in this namespace" in err, err
