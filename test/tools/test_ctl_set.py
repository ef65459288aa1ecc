"""``fsreg-ctl`` against a live graph of node processes: a refused command changes nothing (issue 38.2), the
values every path refuses are refused here too (38.3), and the exit codes say who refused (38.8)."""

from __future__ import annotations

import secrets
import subprocess
import sys
from pathlib import Path

import pytest

from fsreg_ros.testing import LiveGraph

pytestmark = [pytest.mark.graph, pytest.mark.slow]

BIN = Path(sys.executable).parent


def ctl(ns: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(BIN / "fsreg-ctl"), "--namespace", ns, *args], capture_output=True, text=True,
                          timeout=90)


def refused(proc: subprocess.CompletedProcess, code: int, stderr: str) -> None:
    assert (proc.returncode, proc.stdout, proc.stderr) == (code, "", stderr)


def test_a_refused_set_changes_nothing_and_refuses_what_every_path_refuses(table1_path):
    ns = f"set_{secrets.token_hex(4)}"
    with LiveGraph(table1_path, namespace=ns, processes=True, policy="decay", decay_period=10.0) as graph:
        before = ctl(ns, "params", "get", "reg:algorithm", "wm_manager:policy", "faces.policy").stdout
        assert before == "reg:algorithm=auto\nwm_manager:policy=decay\nwm_manager:faces.policy=\n"
        # one node's value is fine, another's is not: nothing is set (reg was set before the check, 38.2)
        refused(ctl(ns, "set", "reg:algorithm=greedy", "consultant_faces:threshold=5"), 2,
                "fsreg-ctl: error: set: consultant_faces: threshold: expected a number in [0, 1], got 5.0\n")
        # an empty node-wide policy would be WM off, silently (38.3): refused as the node and a params file refuse it
        refused(ctl(ns, "set", "policy="), 2,
                "fsreg-ctl: error: set policy=: wm_manager: policy must be a non-empty string, got ''\n")
        # one node's clock is the graph's: fixed at start on every node
        refused(ctl(ns, "set", "wm_manager:use_sim_time=false"), 2,
                "fsreg-ctl: error: set: wm_manager: use_sim_time is read-only (set when the node starts: by "
                "fsreg-up from sim time, or --wall-time (one clock for the whole graph))\n")
        assert ctl(ns, "params", "get", "reg:algorithm", "wm_manager:policy", "faces.policy").stdout == before
        assert graph.status()["memory"] == {"faces": {"policy": "decay", "decay_period": 10.0}}
        # a node-wide setting a domain overrides: refused with the reason, never "set" and ignored (37.3)
        assert ctl(ns, "set", "faces.policy=displacement").stdout == "set wm_manager: faces.policy=displacement\n"
        refused(ctl(ns, "set", "wm_manager:policy=none"), 2,
                "fsreg-ctl: error: set: wm_manager: policy: not changed: faces.policy='displacement' overrides the "
                "node-wide value (which applies only to domains that inherit it); set faces.policy instead, or "
                "faces.policy='' to inherit\n")
        assert graph.status()["memory"] == {"faces": {"policy": "displacement", "capacity": 2}}

        # 38.8: what the graph does not know is its answer (exit 1) for wm as for describe; input over the
        # graph's limits is refused before sending (exit 2) for many words as for one long word
        refused(ctl(ns, "wm", "nobody"), 1,
                "fsreg-ctl: error: wm nobody: no consultant knows entity 'nobody' (domains: faces)\n")
        refused(ctl(ns, "describe", "nobody"), 1,
                "fsreg-ctl: error: describe nobody: no consultant knows entity 'nobody' (domains: faces)\n")
        refused(ctl(ns, "say", *["qqqqqqq"] * 7900), 2,
                "fsreg-ctl: error: say: 7900 words; the graph takes at most 1000 (max_list_items)\n")
        refused(ctl(ns, "say", "q" * 70_000), 2, "fsreg-ctl: error: dialogue/human: the message is 70061 bytes; "
                                                 "the graph takes at most 65536 (max_message_bytes)\n")
