"""``fsreg-sim --replay DIR --scenario OTHER``: a replay against another world's knowledge base says so in one line
(issue 38.8), besides the turns' DIFF; against the recording's own world it says nothing more."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from fsreg_ros.core.io.recording import CLOCK, STRING, TOPICS_KEY, BagWriter, Channel, encode_clock, encode_string
from fsreg_ros.tools.sim import sim_main

REPO = Path(__file__).resolve().parents[2]
SCENARIO = REPO / "scenarios" / "guess_who_table1.yaml"
TOYS = """name: toys
domains:
  objects:
    preference: [red, blue, ball]
    entities:
      ball1: {red: 1.0, ball: 1.0}
      ball2: {blue: 1.0, ball: 1.0}
"""


@pytest.fixture
def recording(tmp_path) -> Path:
    """A recorded session of the Guess-Who graph: one REG request for face1 and its answer."""
    channels = [Channel("/r/reg/request", STRING, 100), Channel("/r/reg/expression", STRING, 100),
                Channel("/r/wm_manager/ready", STRING, 1, latched=True), Channel("/r/clock", CLOCK, 10)]
    roles = {"/r/reg/request": "request", "/r/reg/expression": "expression", "/r/wm_manager/ready": "ready",
             "/r/clock": "clock"}
    bag = BagWriter(tmp_path / "session", channels, custom={TOPICS_KEY: json.dumps(roles)})
    bag.attach("scenario", SCENARIO)
    bag.write("/r/wm_manager/ready", 1, encode_string({"ready": True, "domains": {
        "faces": {"running": {"policy": "none"}}}}))
    bag.write("/r/clock", 2, encode_clock(1.0))
    bag.write("/r/reg/request", 3, encode_string({"id": "r1", "target": "face1", "time": 1.0}))
    bag.write("/r/reg/expression", 4, encode_string({"id": "r1", "target": "face1", "time": 1.0, "description": [
        "light-hair", "lab-coat", "glasses"], "text": "the person with light hair, a lab coat and glasses"}))
    bag.close()
    return tmp_path / "session"


def notes(out: str) -> list[str]:
    return [line for line in out.splitlines() if line.startswith("note: ")]


def test_another_worlds_scenario_is_named_in_one_line(recording, tmp_path, capsys):
    toys = tmp_path / "toys.yaml"
    toys.write_text(TOYS)
    assert sim_main(["--replay", str(recording), "--scenario", str(toys)]) == 1
    assert notes(capsys.readouterr().out) == [
        f"note: the scenario {toys} does not match the recording: the recording's domains faces are not among its "
        "domains (objects); every turn below may differ for that alone"]


def test_a_scenario_other_than_the_carried_copy_is_named(recording, tmp_path, capsys):
    renamed = tmp_path / "renamed.yaml"
    renamed.write_text(SCENARIO.read_text().replace("name: guess-who-table1", "name: guess-who-renamed"))
    sim_main(["--replay", str(recording), "--scenario", str(renamed)])
    assert notes(capsys.readouterr().out) == [
        f"note: the scenario {renamed} is not the one the graph ran with (the recording carries "
        "guess_who_table1.yaml, which differs)"]


def test_the_recordings_own_world_adds_no_note(recording, capsys):
    sim_main(["--replay", str(recording)])
    sim_main(["--replay", str(recording), "--scenario", str(SCENARIO)])
    assert notes(capsys.readouterr().out) == []
