"""Smoke tests of the benchmarks (bench_core, bench_graph, soak): they run and report (no timings asserted).

A benchmark that starts node processes runs as a process of its own (marked slow); the
quick ones (bench_core --quick, every refused command line) call the script's ``main``
in this process: the same code from the argument checks on (the scripts' start-up, which
refuses a widening environment in a process of its own, is test/ros/test_network.py's).
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "bench_core.py"
_LOADED: dict[str, ModuleType] = {}


def script(name: str) -> ModuleType:
    """Return ``scripts/<name>.py`` loaded as a module in this process (once per process; the environment kept)."""
    if name not in _LOADED:
        env, path = dict(os.environ), list(sys.path)
        spec = importlib.util.spec_from_file_location(f"fsreg_script_{name}", SCRIPT.parent / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        sys.modules[spec.name] = module  # as an import would (dataclasses look their module up there)
        try:
            sys.path.insert(0, str(SCRIPT.parent))
            spec.loader.exec_module(module)
        finally:
            os.environ.clear()
            os.environ.update(env)
            sys.path[:] = path
        _LOADED[name] = module
    return _LOADED[name]


def run_main(name: str, args: list[str], capsys) -> tuple[int, str, str]:
    """Run ``scripts/<name>.py``'s ``main(args)`` here; return its exit code, stdout and stderr."""
    try:
        code = script(name).main(list(args))
    except SystemExit as exit_:
        code = exit_.code
    out, err = capsys.readouterr()
    return code, out, err


def test_bench_core_quick_runs_and_prints_its_table(tmp_path, capsys):
    out = tmp_path / "bench.json"
    code, text, err = run_main("bench_core", ["--quick", "--json", str(out)], capsys)
    assert code == 0, err
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
    # The paired comparisons: each configuration against displacement on the same targets, in sessions of its
    # own; ratios of the two medians with their intervals.
    paired = data["reg_paired"]
    assert (paired["entities"], paired["properties"], paired["trials"], paired["sessions"]) == (1000, 20, 15, 1)
    assert set(paired["configs"]) == {"sd-pia/displ", "sd-pia/act", "sd-pia/act1", "sd-pia/epi", "sd-pia/act-epi",
                                      "sd-pia/act-words"}
    assert paired["baseline"] == "sd-pia/displ"
    assert len(paired["configs"]["sd-pia/displ"]["medians_by_session_ms"]) == 5  # one session per pairing
    unpaired = {r["config"]: r for r in data["reg"] if r["entities"] == 1000}
    for label, figures in paired["configs"].items():  # the same targets, so the same encodings as unpaired
        assert figures["encodings_median"] == unpaired[label]["encodings_median"] and figures["median_ms"] > 0
    assert [(r["config"], r["baseline"], r["pairs"]) for r in paired["ratios"]] == [
        ("sd-pia/act", "sd-pia/displ", 15), ("sd-pia/act1", "sd-pia/displ", 15), ("sd-pia/epi", "sd-pia/displ", 15),
        ("sd-pia/act-epi", "sd-pia/displ", 15), ("sd-pia/act-words", "sd-pia/displ", 15)]
    for r in paired["ratios"]:
        assert r["ci"][0] <= r["ratio"] <= r["ci"][1] and r["resamples"] == 1000
        assert r["ratio"] == pytest.approx(r["median_ms"] / r["baseline_median_ms"])
        assert r["median_ms"] == paired["configs"][r["config"]]["median_ms"]
    assert "Paired, 1,000 x 20 (CPU time;" in text and "sd-pia/act / sd-pia/displ: x" in text


def test_bench_core_paired_targets_judge_the_paired_ratio():
    """``targets()`` judges activation's 1.5x on the paired ratio when there is one, else on the unpaired medians."""
    bench_core = script("bench_core")
    rows = [{"config": c, "entities": 10_000, "properties": 200, "median_ms": m}
            for c, m in (("sd-pia/displ", 1.0), ("sd-pia/act", 1.4), ("sd-pia/act1", 2.0))]
    paired = {"entities": 10_000, "properties": 200, "ratios": [
        {"config": "sd-pia/act", "ratio": 1.62, "ci": [1.55, 1.70]},
        {"config": "sd-pia/act1", "ratio": 1.45, "ci": [1.40, 1.52]}]}
    judged = {t["name"].split(" under ")[1].split(" /")[0]: t
              for t in bench_core.targets({"reg": rows, "reg_ratios": [], "decay": [], "reg_paired": paired})
              if " under " in t["name"]}
    assert judged["activation+displacement"]["value"] == "x1.62 [1.55, 1.70] paired"
    assert judged["activation+displacement"]["verdict"] == "MISSED"
    assert judged["activation alone"]["verdict"] == "met" and judged["activation alone"]["basis"] == "paired"
    unpaired = {t["name"].split(" under ")[1].split(" /")[0]: t
                for t in bench_core.targets({"reg": rows, "reg_ratios": [], "decay": [], "reg_paired": {}})
                if " under " in t["name"]}
    assert unpaired["activation+displacement"]["value"] == "x1.40" and unpaired["activation+displacement"]["verdict"] \
        == "met" and unpaired["activation alone"]["verdict"] == "MISSED"
    # issue 36: episodes+displacement and activation on the entities' own clocks are judged against activation's
    for config, policy in (("sd-pia/epi", "episodes+displacement"),
                           ("sd-pia/act-epi", "activation+displacement on the episodes clock"),
                           ("sd-pia/act-words", "activation+displacement on the words clock")):
        for epi, verdict in ((1.01, "met"), (1.70, "MISSED")):
            pair = {"config": config, "ratio": epi, "ci": [epi - 0.05, epi + 0.05]}
            with_epi = {**paired, "ratios": paired["ratios"] + [pair]}
            judged = {t["name"].split(" under ")[1].split(" /")[0]: t
                      for t in bench_core.targets({"reg": rows, "reg_ratios": [], "decay": [], "reg_paired": with_epi})
                      if " under " in t["name"]}
            assert judged[policy]["verdict"] == verdict
            assert judged[policy]["value"].endswith("paired, activation x1.62")
    # a decay benchmark not run says which option left it out
    for meta, reason in (({"quick": True, "skip_decay": False}, "n/a (--quick)"),
                         ({"quick": False, "skip_decay": True}, "n/a (--skip-decay)")):
        verdicts = {t["name"]: t["verdict"] for t in bench_core.targets(
            {"reg": rows, "reg_ratios": [], "decay": [], "reg_paired": paired, "meta": meta})}
        assert verdicts["decay tick over 100k queues"] == reason


@pytest.mark.parametrize("args, fragment", [
    (["--repeat", "0"], "--repeat must be in [1, 100], got 0"),
    (["--trials", "0"], "--trials must be in [1, 100000], got 0"),
    (["--warmup", "-1"], "--warmup must be in [0, 100000], got -1"),
    (["--ticks", "0"], "--ticks must be in [1, 100000], got 0"),
    (["--resamples", "10"], "--resamples must be in [100, 1000000], got 10"),
])
def test_bench_core_refuses_bad_counts(args, fragment, capsys):
    code, out, err = run_main("bench_core", ["--quick", *args], capsys)
    assert code == 2 and fragment in err and "Traceback" not in err, err
    assert out == ""


# ------------------------------------------------------------------ the graph's benchmarks
GRAPH_SCRIPT = SCRIPT.parent / "bench_graph.py"
SOAK_SCRIPT = SCRIPT.parent / "soak.py"


@pytest.mark.slow  # starts node processes
def test_bench_graph_runs_the_default_graph_and_checks_its_targets(tmp_path):
    out = tmp_path / "graph.json"
    proc = subprocess.run(
        [sys.executable, str(GRAPH_SCRIPT), "--worlds", "table1", "--turns", "4", "--rounds", "1", "--json", str(out)],
        capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0, proc.stderr
    data = json.loads(out.read_text())
    (row,) = data["rows"]
    assert row["world"] == "table1" and row["entities"] == 16 and row["turns"] == 4
    assert set(row["paths"]) == {"human", "robot"}
    for path in row["paths"].values():
        # every turn took consultant calls, so the graph's turn costs more than one bare hop
        assert path["calls"] >= 1 and path["graph_p50"] > row["hop_p50"] > 0
        assert path["hop_budget"] == 1.5 * (path["calls"] + 2)
    assert [line.split(":")[0] for line in data["checks"]] == [
        "Table 1 human turn -> rr/result", "Table 1 reg/request -> reg/expression"]
    assert "every default (persistence on" in proc.stdout


@pytest.mark.slow  # starts node processes
def test_soak_sends_open_loop_and_accounts_for_every_message():
    proc = subprocess.run([sys.executable, str(SOAK_SCRIPT), "--turns", "10", "--requests", "10", "--rate", "10"],
                          capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("== uninterrupted: open loop, 10 human turns/s + 10 REG requests/s, "
                               "/clock with every message, 20 messages")
    assert any(line.startswith("human  sent 10, lost 0, duplicated 0, errors 0;") for line in lines), proc.stdout
    assert any(line.startswith("reg    sent 10, lost 0, duplicated 0, errors 0;") for line in lines), proc.stdout
    assert any(line.strip().startswith("consultant_faces") for line in lines)


@pytest.mark.slow  # starts node processes
def test_soak_with_perception_accounts_for_every_fact():
    proc = subprocess.run([sys.executable, str(SOAK_SCRIPT), "--turns", "10", "--requests", "10", "--rate", "10",
                           "--facts-rate", "100", "--batch", "5", "--facts-entities", "7"],
                          capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    facts = [line for line in lines if line.startswith("facts  ")]
    assert facts and facts[0].startswith("facts  sent 100 (20 messages of 5), applied 100, refused 0, lost 0, "
                                         "not sent (publisher refused) 0 messages, duplicated 0;"), proc.stdout
    assert "  the consultant knows 7 of the 7 perceived entities" in lines
    assert any(line.startswith("reg    sent 10, lost 0,") for line in lines), proc.stdout


@pytest.mark.parametrize("args, fragment", [
    (["--facts-rate", "nan"], "--facts-rate must be a number in [0, 1000000], got nan"),
    (["--facts-rate", "10", "--batch", "0"], "--batch must be in [1, 1000]"),
])
def test_soak_refuses_bad_perception_arguments(args, fragment, capsys):
    code, out, err = run_main("soak", args, capsys)
    assert code == 2 and fragment in err and "Traceback" not in err, err


BENCH_FACTS = Path(__file__).resolve().parents[2] / "scripts" / "bench_facts.py"


@pytest.mark.slow  # starts a consultant process
def test_bench_facts_answers_every_query_and_fact():
    proc = subprocess.run([sys.executable, str(BENCH_FACTS), "--facts-rate", "200", "--batch", "10", "--queries", "10",
                           "--seconds", "2", "--facts-entities", "7"], capture_output=True, text=True, timeout=180)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].startswith("== bench_facts: 200 facts/s in messages of 10, 10 queries/s, 2 s;"), proc.stdout
    assert lines[1].startswith("queries 20, unanswered 0; query latency ms p50 "), proc.stdout
    assert lines[2].startswith("facts sent 400, answered messages 40 of 40, applied 400; facts latency ms"), proc.stdout
    assert lines[3].startswith("consultant CPU "), proc.stdout


@pytest.mark.parametrize("args, fragment", [
    (["--facts-rate", "inf"], "--facts-rate must be a number in [0, 1000000], got inf"),
    (["--queries", "0"], "--queries must be a number in [0.1, 10000], got 0"),
    (["--seconds", "nan"], "--seconds must be a number in [0.1, 3600], got nan"),
    (["--batch", "1001"], "--batch must be in [1, 1000]"),
])
def test_bench_facts_refuses_bad_arguments(args, fragment, capsys):
    code, out, err = run_main("bench_facts", args, capsys)
    assert code == 2 and fragment in err and "Traceback" not in err, err


BENCH_RSS = BENCH_FACTS.parent / "bench_rss.py"


@pytest.mark.parametrize("args, fragment", [
    (["--every", "0"], "--every must be in [1, 100000], got 0"),
    (["--requests", "2999"], "--requests must be in [3000, 10000000] with --every 500 (3 samples after REG's "
                             "1,024-entry cache filled), got 2999"),
    (["--requests", "1000", "--every", "100"], "--requests must be in [1400, 10000000] with --every 100"),
])
def test_bench_rss_refuses_too_few_samples(args, fragment, capsys):
    """Too few requests to fit a slope after the warm-up gave a silent 'nan bytes/request'; now one line, exit 2."""
    code, out, err = run_main("bench_rss", args, capsys)
    assert code == 2 and fragment in err and "Traceback" not in err, err
