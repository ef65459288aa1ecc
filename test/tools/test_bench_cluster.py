"""Smoke test of scripts/bench_cluster.py: it runs, the engines agree byte for byte, it reports (no timings)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "bench_cluster.py"


@pytest.mark.slow  # two small sweeps as processes, a LocalCluster, four games in-process
def test_bench_cluster_quick_runs_and_projects(tmp_path):
    out = tmp_path / "bench.json"
    proc = subprocess.run([sys.executable, str(SCRIPT), "--quick", "--json", str(out)], capture_output=True,
                          text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    text = proc.stdout
    assert "outputs: byte-identical (runs.csv, summary.csv, divergence.csv, recommendation.csv)" in text
    assert "ratio cluster / jobs: " in text and "PROJECTION (not measured): 400 games on 50 one-thread workers" in text
    data = json.loads(out.read_text())
    assert data["identical"] is True and data["cluster"]["execution"]["engine"] == "cluster"
    assert data["cluster"]["execution"]["workers"] == 2 and data["cluster"]["execution"]["tasks"] == 4
    game = data["per_game"]
    assert game["settings"] == 131 and game["game_cpu_s"] > 0 and set(game["summary_s"]) == {"8", "16"}
    assert 0 < game["task_bytes"] < game["result_bytes"] and game["ledger_line_bytes"] > 0
    plan = data["projection"]
    assert (plan["games"], plan["workers"], plan["waves"]) == (400, 50, 8)
    assert plan["transfer_mb"] == pytest.approx(400 * (game["task_bytes"] + game["result_bytes"]) / 1e6)
