"""Restored state announced and controllable (issue 28.6) on a live in-process graph.

``wm_manager/status`` reports what each consultant restored; ``fsreg-ctl state reset``
(its :func:`~fsreg_ros.tools.ctl_state.run_state`, driven here through the graph's own client)
moves the state database aside, empties runtime facts and WM, and reports it.
"""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from fsreg_ros.tools import ctl
from fsreg_ros.tools.ctl_state import check_state_args, run_state
from fsreg_ros.tools.ctl_table import EXIT_ERROR, EXIT_OK, EXIT_USAGE, UsageError, build_parser
from fsreg_ros.tools.up import ready_line, ready_report

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "guess_who_table1.yaml"
FRESH = {"fresh": True, "runtime_entities": 0, "runtime_facts": 0, "queues": 0, "run": None, "clock": None,
         "latest": None}


class Tty(io.StringIO):
    def __init__(self, tty: bool) -> None:
        super().__init__()
        self.tty = tty

    def isatty(self) -> bool:
        return self.tty


def test_state_reset_without_yes_needs_a_terminal():
    args = build_parser().parse_args(["state", "reset"])
    with pytest.raises(UsageError, match="no terminal to confirm on; add --yes"):
        check_state_args(args, Tty(False))
    check_state_args(args, Tty(True))  # asked on the terminal instead
    check_state_args(build_parser().parse_args(["state", "reset", "--yes"]), Tty(False))


def test_fsreg_ctl_state_reset_refuses_without_a_terminal_exit_2(capsys, monkeypatch):
    monkeypatch.setattr("sys.stdin", Tty(False))
    assert ctl.main(["state", "reset"]) == EXIT_USAGE
    err = capsys.readouterr().err
    assert err == "fsreg-ctl: error: state reset: no terminal to confirm on; add --yes to reset without asking\n"


def test_the_ready_line_says_what_was_restored_or_fresh():
    restored = {"faces": {"fresh": False, "runtime_entities": 1, "runtime_facts": 3, "queues": 2, "run": 4,
                          "clock": "sim", "latest": 30.0},
                "objects": {**FRESH, "moved_aside": "/s/objects.sqlite3.20260101T000000.old"}}
    report = ready_report("g", "/ns", 82, {"faces": {"policy": "none"}, "objects": {"policy": "none"}}, None,
                          Path("/logs"), lambda name: name, restored)
    assert report["restored"] == restored
    assert ("; state faces: restored 3 runtime facts (1 runtime entities), 2 WM queues from run 4 (sim clock, up to "
            "t=30 s); objects: fresh (the scenario alone, the old state moved aside to "
            "/s/objects.sqlite3.20260101T000000.old); endpoints ") in ready_line(report)


@pytest.mark.graph
def test_state_reset_on_a_live_graph_empties_runtime_facts_and_wm_and_reports_it(tmp_path, capsys):
    from fsreg_ros.testing import LiveGraph

    with LiveGraph(SCENARIO, policy="decay", decay_period=10.0, state_dir=tmp_path) as robot:
        assert robot.status()["restored"] == {"faces": FRESH}
        robot.set_clock(1.0)
        assert robot.say("male, lab-coat, light-hair, glasses")["resolved"] == "face1"
        assert robot.assert_facts("face17", {"female": 1.0}, domain="faces")["ok"]
        assert robot.assert_facts("face2", {"no-glasses": 1.0})["retracted"] == ["glasses"]
        queues = len(robot.client.snapshot("faces"))
        incarnation = robot.status()["incarnation"]["faces"]
        args = build_parser().parse_args(["state", "reset"])
        # not confirmed: nothing is sent
        assert run_state(robot.client, args, lambda data, text: print(text), 10.0, ask=lambda _: "n") == \
            EXIT_ERROR
        assert robot.wm("face1") == ["male", "lab-coat", "light-hair", "glasses"]
        asked: list[str] = []
        code = run_state(robot.client, args, lambda data, text: print(text), 10.0,
                         ask=lambda prompt: asked.append(prompt) or "yes")
        assert code == EXIT_OK and "reset the stored state of faces in graph" in asked[0]
        aside = next(tmp_path.rglob("faces.sqlite3.*.old"))
        out = capsys.readouterr().out
        assert out.endswith(f"faces: set aside 3 runtime facts (1 runtime entities) and {queues} WM queues, the old "
                            f"state moved to {aside}; incarnation {incarnation + 1} serves the scenario afresh\n")
        status = robot.status()
        assert status["ready"] and status["incarnation"] == {"faces": incarnation + 1}
        assert status["restored"] == {"faces": {**FRESH, "moved_aside": str(aside)}}
        assert robot.client.snapshot("faces") == {}  # WM empty
        assert robot.describe("face2")["text"] == "the woman with glasses"  # the scenario's facts again
        reply = robot.describe("face17")
        assert reply["kind"] == "unknown-entity", reply  # the runtime entity is gone
        assert aside.exists()  # set aside, never deleted
