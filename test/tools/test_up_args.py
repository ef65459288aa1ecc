"""``fsreg-up``'s and ``fsreg-ctl``'s arguments as a user can type them, any bytes: one line and exit 2, before any
node starts (issue 38.6).  No graph is needed: each is refused by the argument checks."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from fsreg_ros.tools import ctl, up

BIN = Path(sys.executable).parent


def run(main, capsys, *argv: str) -> tuple[int, str, str]:
    try:
        code = main(list(argv))
    except SystemExit as exit_:
        code = exit_.code
    out, err = capsys.readouterr()
    return code, out, err


def one_line(code: int, out: str, err: str, tool: str, said: str) -> None:
    assert code == 2 and out == "", (code, err)
    assert err.startswith(f"{tool}: error: ") and err.count("\n") == 1 and said in err, err
    assert "Traceback" not in err and len(err) < 600, err


@pytest.mark.parametrize("argv, said", [
    (["--namespace", "ñ", "status"], "namespace 'ñ': each part must be ASCII letters, digits and '_', not starting "
                                     "with a digit"),
    (["--namespace", "a" * 4000, "status"], "is 4001 characters long: at most 200 (a ROS name is at most 247"),
    (["--clock", "bad topic!", "status"], "--clock: 'bad topic!' is not a ROS topic name"),
    (["--clock", "", "clock", "5"], "--clock: '' is not a ROS topic name"),
    (["say", os.fsdecode(b"\xff\xfe")], r"argument 2 is not UTF-8 text (its bytes: b'\xff\xfe'); give text in UTF-8"),
    (["describe", os.fsdecode(b"\xff")], r"argument 2 is not UTF-8 text (its bytes: b'\xff')"),
    (["assert", os.fsdecode(b"\xff"), "female"], r"argument 2 is not UTF-8 text"),
    (["say", "--description", ",,,"], "say: --description ',,,' names no property; give P1,P2"),
    (["say", "--description", " , "], "names no property"),
])
def test_fsreg_ctl_refuses_every_typed_argument_in_one_line(capsys, argv, said):
    one_line(*run(ctl.main, capsys, *argv), "fsreg-ctl", said)


@pytest.mark.parametrize("argv, said", [
    (["--ready-timeout", "nan"], "argument --ready-timeout: expected a finite number of seconds in (0, 86400], "
                                 "got nan"),
    (["--ready-timeout", "inf"], "got inf"),
    (["--ready-timeout", "0"], "got 0"),
    (["--ready-timeout", "-1"], "got -1"),
    (["--ready-timeout", "soon"], "got 'soon'"),
    (["--log-dir", "/proc/x"], "--log-dir: cannot make /proc/x a folder: No such file or directory"),
    (["--namespace", "ñ"], "--namespace: namespace 'ñ': each part must be ASCII letters"),
    (["--clock", "bad topic!"], "--clock: 'bad topic!' is not a ROS topic name"),
    (["--clock", ""], "--clock: '' is not a ROS topic name"),
    (["--lexicon", os.fsdecode(b"\xff.yaml")], r"argument 3 is not UTF-8 text (its bytes: b'\xff.yaml')"),
    (["--bogus"], "unrecognized arguments: --bogus (see fsreg-up --help)"),
])
def test_fsreg_up_refuses_every_typed_argument_in_one_line(capsys, table1_path, argv, said):
    one_line(*run(up.main, capsys, str(table1_path), *argv), "fsreg-up", said)


def test_the_shell_bytes_reach_the_check_as_they_do_from_a_terminal():
    """The same refusal from the real executable, given raw bytes on its command line."""
    proc = subprocess.run([str(BIN / "fsreg-ctl"), "say", b"\xff\xfe"], capture_output=True, timeout=60)
    assert proc.returncode == 2 and proc.stdout == b""
    assert proc.stderr == (b"fsreg-ctl: error: argument 2 is not UTF-8 text (its bytes: b'\\xff\\xfe'); "
                           b"give text in UTF-8\n")
