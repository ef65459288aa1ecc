"""``/diagnostics`` (issue 24.4): every node's DiagnosticStatus, and fsreg-ctl status reading them."""

from __future__ import annotations

from pathlib import Path

import pytest

from fsreg_ros.ros.diagnostics import LATENCY_SAMPLES, RATE_WINDOW, RequestStats, summary

SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "guess_who_table1.yaml"


def test_request_stats_rate_p95_and_refusals():
    now = [100.0]
    stats = RequestStats(clock=lambda: now[0])
    assert stats.values() == {"requests": 0, "refused": 0, "request_rate_hz": 0.0, "latency_p95_ms": None}
    for i in range(20):
        stats.record(0.001 * (i + 1), refused=(i % 5 == 0))
    assert (stats.total, stats.refused) == (20, 4)
    assert stats.p95_ms() == pytest.approx(19.0)  # nearest rank: the 19th of 1..20 ms
    assert stats.rate() == 20 / RATE_WINDOW
    now[0] += RATE_WINDOW + 0.1  # the window has passed: no recent requests, the totals stay
    assert stats.values()["request_rate_hz"] == 0.0 and stats.values()["requests"] == 20
    for _ in range(LATENCY_SAMPLES):
        stats.record(0.5)
    assert stats.p95_ms() == pytest.approx(500.0)  # only the latest samples count


def test_summary_lines():
    lines = summary({"/robot/consultant_faces": {"level": "OK", "message": "ready", "values": {
        "domain": "faces", "requests": "3", "refused": "0", "request_rate_hz": "0.3", "latency_p95_ms": "1.2"}}})
    assert lines == ["/robot/consultant_faces: OK ready; domain faces; requests 3, refused 0, request_rate_hz 0.3, "
                     "latency_p95_ms 1.2"]


@pytest.mark.graph
def test_every_node_reports_on_diagnostics():
    from fsreg_ros.ros.diagnostics import read_statuses
    from fsreg_ros.testing import LiveGraph

    with LiveGraph(SCENARIO, policy="decay", decay_period=10.0) as robot:
        robot.set_clock(1.0)
        assert robot.say("male, lab-coat, light-hair, glasses")["resolved"] == "face1"
        client = robot.client
        statuses = read_statuses(client.node, client.spin_for, client.node.get_namespace(), wait=2.5)
        ns = client.node.get_namespace()
        assert sorted(statuses) == sorted(f"{ns}/{name}" for name in robot.nodes)
        assert {s["level"] for s in statuses.values()} == {"OK"}
        faces = statuses[f"{ns}/consultant_faces"]["values"]
        assert faces["ready"] == "true" and faces["last_write_ok"] == "true" and faces["domain"] == "faces"
        queues = client.state("faces", current=True)["queues"]  # RR encoded for every candidate too
        assert int(faces["wm_properties"]) == sum(len(q) for q in queues.values()) == 18
        assert int(faces["entities_in_wm"]) == len(queues)
        assert int(faces["requests"]) >= 3  # RR's open, walk and close at least
        manager = statuses[f"{ns}/wm_manager"]
        assert (manager["message"], manager["values"]["ready"], manager["values"]["faces.configured"]) == \
            ("ready", "true", "true")
        rr = statuses[f"{ns}/reference_resolution"]["values"]
        assert rr["faces.alive"] == "true" and int(rr["requests"]) == 1 and rr["refused"] == "0"
