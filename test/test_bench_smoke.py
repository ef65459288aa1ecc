"""Smoke test of scripts/bench_core.py: it runs and prints its table (no timings asserted)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "bench_core.py"


def test_bench_core_quick_runs_and_prints_its_table(tmp_path):
    out = tmp_path / "bench.json"
    proc = subprocess.run(
        [sys.executable, str(SCRIPT), "--quick", "--json", str(out)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 0, proc.stderr
    text = proc.stdout
    assert "REG latency" in text and "Decay tick" in text and "Targets" in text
    for config in ("sd-pia", "dist-pia", "dist-pia/none"):
        assert f"\n{config} " in text
    data = json.loads(out.read_text())
    assert {"meta", "reg", "reg_ratios", "decay", "targets"} <= set(data)
    assert data["meta"]["quick"] is True
    assert {r["config"] for r in data["reg"]} >= {"sd-pia", "dist-pia", "dist-pia/none"}
    assert all(0 < r["median_ms"] <= r["p95_ms"] for r in data["reg"])
    # The lazy buffer and the naive reference end in the same state.
    assert data["decay"] and all(r["same_final_state"] for r in data["decay"])
    # SD-PIA under a retaining policy really has WM content to walk.
    assert any(r["config"] == "sd-pia" and r["from_wm_mean"] > 0 for r in data["reg"])
