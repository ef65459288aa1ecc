"""Exclusive properties on the live graph (issue 28.7): asserting ``no-glasses`` retracts ``glasses``."""

from __future__ import annotations

from pathlib import Path

import pytest

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "guess_who_table1.yaml"


@pytest.mark.graph
def test_asserting_no_glasses_retracts_glasses_in_ltm_and_wm_of_the_graph():
    from fsreg_ros.testing import LiveGraph

    with LiveGraph(SCENARIO, policy="decay", decay_period=10.0) as robot:
        robot.set_clock(1.0)
        before = robot.describe("face2")
        assert (before["description"], before["text"]) == (["glasses", "female"], "the woman with glasses")
        assert robot.wm("face2") == ["glasses", "female"]  # rule 1: the robot's own words enter WM
        reply = robot.assert_facts("face2", {"no-glasses": 1.0})
        assert (reply["ok"], reply["updated"], reply["retracted"]) == \
            (True, {"no-glasses": 1.0, "glasses": 0.0}, ["glasses"])
        assert robot.wm("face2") == ["female"]
        after = robot.describe("face2")
        assert (after["description"], after["text"]) == (["female", "t-shirt"], "the woman with a t-shirt")
        refused = robot.assert_facts("face2", {"glasses": 1.0, "no-glasses": 1.0})
        assert (refused["ok"], refused["kind"]) == (False, "contradiction")
        assert "'glasses' and 'no-glasses' exclude each other" in refused["error"]
