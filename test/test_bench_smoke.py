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
    assert "REG latency" in text and "Decay tick" in text and "Eager decay tick" in text and "Targets" in text
    for config in ("sd-pia", "dist-pia", "dist-pia/none"):
        assert f"\n{config} " in text
    data = json.loads(out.read_text())
    assert {"meta", "reg", "reg_ratios", "decay", "targets"} <= set(data)
    assert data["meta"]["quick"] is True
    assert {r["config"] for r in data["reg"]} >= {"sd-pia", "dist-pia", "dist-pia/none"}
    assert all(0 < r["median_ms"] <= r["p95_ms"] for r in data["reg"])
    # The lazy buffer and the naive reference end in the same state.
    assert data["decay"] and all(r["same_final_state"] for r in data["decay"])
    # Eager decay over column queues, with an event sink and over dict queues: the same final state.
    eager = data["eager_decay"]
    assert eager["same_final_state"] is True and eager["detail"]["columns"]["in_columns"] > 0
    assert eager["detail"]["dicts"]["in_columns"] == 0
    assert all(eager[f"{label}_ms"] > 0 for label in ("columns", "columns+sink", "dicts"))
    # SD-PIA under a retaining policy really has WM content to walk.
    assert any(r["config"] == "sd-pia" and r["from_wm_mean"] > 0 for r in data["reg"])
