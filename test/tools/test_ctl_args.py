"""``fsreg-ctl``'s arguments: every number finite and in range, every refusal one line and exit 2, before any ROS.

No graph is needed: each of these is refused by the argument checks, before a node is
created (issue 28.2, 28.11).  The commands against a live graph: test_ctl_probe.py.
"""

from __future__ import annotations

import pytest

from fsreg_ros.tools import ctl
from fsreg_ros.tools.ctl_table import COMMANDS, UsageError, build_parser
from fsreg_ros.tools.ctl_values import parse_assignments

HUGE = "a" * 200_000


def run(capsys, *argv: str) -> tuple[int, str, str]:
    try:
        code = ctl.main(list(argv))
    except SystemExit as exit_:
        code = exit_.code
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("argv, said", [
    (["clock", "nan"], "argument seconds: expected a finite number of seconds in [0, 1e+12], got nan"),
    (["clock", "inf"], "got inf"),
    (["clock", "-inf"], "got -inf"),
    (["clock", "1e300"], "got 1e300"),
    (["clock", "-5"], "got -5"),
    (["clock", "--", "-5"], "got -5"),
    (["clock", "soon"], "got 'soon'"),
    (["clock", HUGE], "got 'aaaaaaaa"),
    (["--timeout", "inf", "status"], "argument --timeout: expected a finite number of seconds in (0, 86400]"),
    (["--timeout", "1e308", "status"], "got 1e308"),
    (["--timeout", "0", "status"], "got 0"),
    (["--timeout", "nan", "say", "hi"], "got nan"),
    (["status", "--timeout", "-1"], "got -1"),
    (["watch", "--count", "0"], "argument --count: expected a whole number in [1, 1000000000], got 0"),
    (["watch", "--count", "1e3"], "got '1e3'"),
    (["watch", "--count", "99999999999999999999"], "got 99999999999999999999"),
    (["assert", "face1", "male:nan"], "'male:nan': give PROP or PROP:C with C in [0, 1]"),
    (["assert", "face1", "male:inf"], "give PROP or PROP:C with C in [0, 1]"),
    (["assert", "face1", "male:2"], "give PROP or PROP:C with C in [0, 1]"),
    (["assert", "face1", ":0.5"], "give PROP or PROP:C"),
    (["assert", "face1", "male:x"], "the certainty after ':' must be a number in [0, 1]"),
    (["say"], "say: give the words to say, or --description P1,P2 (not both)"),
    (["say", "hi", "--description", "male"], "(not both)"),
    (["set", "capacity"], "set: 'capacity': expected KEY=VALUE or NODE:KEY=VALUE"),
    (["set", "=3"], "expected KEY=VALUE"),
    (["set", "reg:=3"], "expected KEY=VALUE or NODE:KEY=VALUE"),
    (["params", "frob"], "argument action: invalid choice: 'frob'"),
    (["frobnicate"], "argument COMMAND: invalid choice: 'frobnicate'"),
    (["--namespace", "9x", "status"], "9x"),
    ([], "the following arguments are required: COMMAND"),
    (["view", "--port", "70000"], "argument --port: expected a whole number in [0, 65535], got 70000"),
    (["view", "--port", "-1"], "got -1"),
    (["view", "--port", "http"], "got 'http'"),
    (["record", "/tmp", "--duration", "nan"], "argument --duration: expected a finite number of seconds in (0,"),
    (["record", "/tmp", "--segment", "0"], "argument --segment: expected a finite number of seconds in (0, 3600]"),
    (["record", "/"], "record: / exists already; a recording goes to a new folder"),
    (["record", "/tmp/x", "--nice", "20"], "argument --nice: expected a whole number in [0, 19], got 20"),
    (["record", "/tmp/x", "--nice", "1.5"], "argument --nice: expected a whole number in [0, 19], got '1.5'"),
    (["record"], "the following arguments are required: DIR"),
])
def test_bad_arguments_are_one_line_and_exit_2(capsys, argv, said):
    code, out, err = run(capsys, *argv)
    assert code == 2, (argv, err)
    assert out == "" and err.startswith("fsreg-ctl: error: ") and err.count("\n") == 1 and said in err, err
    assert len(err) < 2500 and "Traceback" not in err


def test_every_command_is_one_entry_of_the_table():
    parser = build_parser()
    commands = next(a for a in parser._actions if a.dest == "command")
    assert list(commands.choices) == list(COMMANDS) == [
        "say", "describe", "assert", "status", "set", "params", "watch", "wm", "clock", "view", "record", "state"]
    assert {spec.needs for spec in COMMANDS.values()} <= {"ready", "graph", "none"}


def test_memory_values_are_checked_against_the_settings_table():
    assert parse_assignments(["capacity=3", "faces.decay_period=inherit", "reg:algorithm=greedy"], ["faces"]) == {
        "wm_manager": {"faces.capacity": 3, "faces.decay_period": 0.0}, "reg": {"algorithm": "greedy"}}
    for item, said in (("capacity=0", "faces.capacity: capacity must be >= 1, got 0 (allowed: a whole number in "
                                      "[1, 10000], or 'inherit' (use the node-wide capacity))"),
                       ("faces.decay_period=0.001", "decay_period must be >= 0.01 seconds"),
                       ("decay_period=nan", "decay_period must be a number of seconds, got nan"),
                       ("wm_manager:capacity=inherit", "only a domain's setting (DOMAIN.capacity) inherits"),
                       ("seed=1.5", "expected a whole number in [0, 2147483647]")):
        with pytest.raises(UsageError) as err:
            parse_assignments([item], ["faces"])
        assert str(err.value).startswith(f"set {item}: wm_manager: ") and said in str(err.value), str(err.value)
