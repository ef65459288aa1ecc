"""A probe of the control surface (issue 28.11): every ``fsreg-ctl`` command, and ``fsreg-up --params-file``,
fed hostile arguments against a live graph of node processes (the public harness,
:class:`fsreg_ros.testing.LiveGraph`, as ``fsreg-up`` runs them): each refusal is one
line on stderr with the documented exit code (1 the graph refused, 2 bad usage, 3 no
answer or the graph left) and no traceback; what is accepted is reported as it now is.

The commands run in this process (``fsreg-ctl``'s ``main``, its output captured at the
file descriptors, as a terminal would see it): a process per command cost its start-up
and imports each time (over 300 s for the probe at a load of ~20); each command still
makes a ROS participant of its own that discovers the graph, as ``fsreg-ctl`` does, and
waits for it up to :data:`WAIT` s (not the command's 10 s default: discovery on a loaded
machine can take longer).  ``watch`` and ``fsreg-up`` stay processes of their own.
"""

from __future__ import annotations

import json
import os
import secrets
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml

pytestmark = [pytest.mark.graph, pytest.mark.slow]

BIN = Path(sys.executable).parent


#: Seconds each command waits for the graph (``--timeout``) unless the test gives its own.
WAIT = 60.0


@pytest.fixture
def ctl(capfd):
    """Return ``ctl(ns, *args)``: run ``fsreg-ctl --namespace ns args`` in this process; its exit code and output."""
    from fsreg_ros.tools.ctl import main

    def run(ns: str, *args: str) -> subprocess.CompletedProcess:
        argv = ["--namespace", ns, *(() if "--timeout" in args else ("--timeout", f"{WAIT:g}")), *args]
        capfd.readouterr()  # what came before is not this command's
        try:
            code = main(argv)
        except SystemExit as done:  # argparse's refusals
            code = done.code
        out, err = capfd.readouterr()
        return subprocess.CompletedProcess(["fsreg-ctl", *argv], code, out, err)

    return run


def refused(proc: subprocess.CompletedProcess, code: int, *said: str) -> None:
    """One line on stderr naming ``said``, exit ``code``, nothing on stdout, no traceback."""
    assert proc.returncode == code, (proc.args, proc.returncode, proc.stderr)
    assert proc.stderr.startswith("fsreg-ctl: error: ") and proc.stderr.count("\n") == 1, proc.stderr
    assert all(s in proc.stderr for s in said), (said, proc.stderr)
    assert proc.stdout == "" and "Traceback" not in proc.stderr


def test_every_command_refuses_hostile_input_in_one_line(live, ctl):
    ns, graph = live
    # clock: out of range is bad usage; a clock the graph does not take is refused with its reason
    for value in ("nan", "inf", "-inf", "1e300", "-5"):
        refused(ctl(ns, "clock", value), 2, "argument seconds: expected a finite number of seconds in [0, 1e+12]")
    assert ctl(ns, "clock", "5").stdout == "clock at 5 s; the forgetting due by then is applied\n"
    refused(ctl(ns, "clock", "3"), 1, "clock 3 s refused: the graph's clock is at 5 s and does not go back")
    refused(ctl(ns, "--timeout", "inf", "status"), 2, "argument --timeout")
    refused(ctl(ns, "--timeout", "1e308", "watch"), 2, "argument --timeout")

    # set: unknown keys and bad values name the node, the key and what is allowed (exit 2); nothing is changed
    for item, said in (("decay-period=5", "node wm_manager has no parameter 'decay-period' (did you mean "
                                          "decay_period?)"),
                       ("faces.decay_perod=5", "no parameter 'faces.decay_perod' (did you mean faces.decay_period?)"),
                       ("reg:algoritm=greedy", "node reg has no parameter 'algoritm' (did you mean algorithm?)"),
                       ("bogus=1", "node wm_manager has no parameter 'bogus'"),
                       ("faces.capacity=0", "wm_manager: faces.capacity: capacity must be >= 1, got 0 (allowed: a "
                                            "whole number in [1, 10000], or 'inherit'"),
                       ("decay_period=1e999", "decay_period"),
                       ("policy=decay+nothing", "unknown forgetting rule 'nothing'"),
                       ("reg:algorithm=fastest", "reg: algorithm"),
                       ("reg:lexicon=x.yaml", "reg: lexicon is read-only"),
                       ("consultant_faces:threshold=2", "consultant_faces: threshold: expected a number in [0, 1], "
                                                        "got 2.0"),
                       ("nobody:x=1", "no node 'nobody' in graph")):
        refused(ctl(ns, "set", item), 2, said)
    assert graph.status()["memory"] == {"faces": {"policy": "decay", "decay_period": 10.0}}
    changed = ctl(ns, "set", "policy=displacement", "capacity=1", "reg:algorithm=greedy")
    assert changed.stdout == "set wm_manager: faces.policy=displacement, faces.capacity=1; reg: algorithm=greedy\n"
    assert ctl(ns, "params", "get", "faces.capacity", "reg:algorithm").stdout == (
        "wm_manager:faces.capacity=1\nreg:algorithm=greedy\n")
    assert ctl(ns, "set", "faces.capacity=inherit").stdout == "set wm_manager: faces.capacity=inherit\n"
    assert json.loads(ctl(ns, "params", "get", "wm_manager:faces.capacity", "--json").stdout) == {
        "wm_manager": {"faces.capacity": 0}}
    dumped = yaml.safe_load(ctl(ns, "params", "dump", "wm_manager", "reg").stdout)
    assert dumped[f"/{ns}/wm_manager"]["ros__parameters"]["faces"]["policy"] == "displacement"
    assert dumped[f"/{ns}/reg"]["ros__parameters"]["algorithm"] == "greedy"
    refused(ctl(ns, "params", "get", "reg:algoritm"), 2, "node reg has no parameter 'algoritm'")
    refused(ctl(ns, "params", "dump", "reg:algorithm"), 2, "dump takes node names")
    refused(ctl(ns, "params", "get", "nobody"), 2, "no node 'nobody'")

    # errors, not silence: refused before sending, or the graph's error reply (exit 1)
    refused(ctl(ns, "assert", "face1", "male", "--domain", "planets"), 2,
            "the graph has no domain 'planets' (its domains: faces)")
    refused(ctl(ns, "say", "a" * 120_000), 2, "dialogue/human: the message is 120", "at most 65536")
    refused(ctl(ns, "say", *(f"w{i:04d}" + "x" * 35 for i in range(1000))), 2,  # fits; its reading does not
            "say: dialogue/human: its reading on dialogue/semantics (the text and its 1000 unknown words) would be ")
    refused(ctl(ns, "describe", "x" * 1000), 2, "reg/request: field 'target': a name of 1000 characters")
    refused(ctl(ns, "assert", "face1", *[f"p{i}" for i in range(1500)]), 2, "ltm/assert")
    refused(ctl(ns, "say", "--description", "male", "--domain", "planets"), 2, "no domain 'planets'")
    refused(ctl(ns, "wm", "face1", "--domain", "planets"), 2, "no domain 'planets'")
    refused(ctl(ns, "describe", "nobody"), 1, "describe nobody: ")
    refused(ctl(f"{ns}_none", "--timeout", "1", "say", "hi"), 3, "no fsreg graph answers")


def test_a_request_after_clock_is_stamped_at_or_after_it(live, ctl):
    """Issue 28.8: ``say`` right after ``clock 30`` was stamped 25.0; each is interleaved here with a clock step."""
    ns, graph = live
    for t in (12.0, 30.0, 30.5, 47.25):
        assert ctl(ns, "clock", f"{t:g}").returncode == 0
        said = json.loads(ctl(ns, "say", "female,", "glasses", "--json").stdout)
        described = json.loads(ctl(ns, "describe", "face2", "--json").stdout)
        assert said["time"] >= t and described["time"] >= t, (t, said["time"], described["time"])


def test_watch_and_a_waiting_command_notice_the_graph_leaving(live):
    ns, graph = live
    watch = subprocess.Popen([str(BIN / "fsreg-ctl"), "--namespace", ns, "watch", "--json"], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    try:
        fd, deadline, first = watch.stdout.fileno(), time.monotonic() + 60, b""
        while b"\n" not in first:  # it watches: the current state came
            assert watch.poll() is None and time.monotonic() < deadline, watch.stderr.read()
            if select.select([fd], [], [], 0.1)[0]:
                first += os.read(fd, 4096)
        manager = graph.graph.process("wm_manager")
        manager.send_signal(signal.SIGKILL)  # dies without a word: its readiness writer's liveliness lapses
        manager.wait()
        code = watch.wait(timeout=30)
        err = watch.stderr.read()
    finally:
        if watch.poll() is None:
            watch.kill()
    assert code == 3 and err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith(f"fsreg-ctl: error: graph '{graph.identity}' in namespace /{ns} ") and " left: " in err


def test_fsreg_up_takes_a_params_file_checked_before_anything_starts(table1_path, tmp_path, ctl):
    bad = tmp_path / "bad.yaml"
    for text, said in (("/**:\n  ros__parameters:\n    capacity: 0\n", "capacity must be >= 1, got 0"),
                       ("/**/reg:\n  ros__parameters:\n    algoritm: greedy\n", "no parameter 'algoritm'"),
                       ("/elsewhere/reg:\n  ros__parameters:\n    algorithm: greedy\n", "is not a node of this graph"),
                       ("/**:\n  ros__parameters:\n    use_sim_time: false\n", "set by fsreg-up"),
                       ("/**:\n  ros__parameters:\n    decay_period: .inf\n",
                        "decay_period: expected a finite number")):
        bad.write_text(text)
        proc = subprocess.run([str(BIN / "fsreg-up"), str(table1_path), "--namespace", "pf", "--params-file",
                               str(bad)], capture_output=True, text=True, timeout=60)
        assert proc.returncode == 2 and proc.stdout == "", proc.stderr
        assert proc.stderr.startswith(f"fsreg-up: error: {bad}: ") and said in proc.stderr, proc.stderr
        assert proc.stderr.count("\n") == 1

    ns = f"pf_{secrets.token_hex(4)}"
    good = tmp_path / "good.yaml"  # as ros2 param dump writes it, with a wildcard as a robot builder would
    good.write_text(f"/**/reg:\n  ros__parameters:\n    algorithm: greedy\n"
                    f"/{ns}/wm_manager:\n  ros__parameters:\n    faces:\n      policy: displacement\n"
                    "      capacity: 3\n")
    up = subprocess.Popen([str(BIN / "fsreg-up"), str(table1_path), "--namespace", ns, "--params-file", str(good),
                           "--state-dir", str(tmp_path / "state"), "--json"], stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, text=True)
    try:
        ready = json.loads(up.stdout.readline() or "{}")
        assert ready.get("memory") == {"faces": {"policy": "displacement", "capacity": 3}}, up.stderr
        assert ctl(ns, "params", "get", "reg:algorithm", "faces.capacity").stdout == (
            "reg:algorithm=greedy\nwm_manager:faces.capacity=3\n")
    finally:
        up.send_signal(signal.SIGTERM)
        assert up.wait(timeout=60) == 0
