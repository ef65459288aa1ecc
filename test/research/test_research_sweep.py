"""fsreg-sweep: games, distinct runs, determinism independent of --jobs, outputs, manifest, bad input."""

import csv
import json

import pytest

from fsreg_ros.research import cli
from fsreg_ros.research.games import ATTRIBUTES, BOARD_SIZE, BeliefPort, make_game, play, scenario_of
from fsreg_ros.research.listener import ListenerOptions
from fsreg_ros.research.stats import bootstrap_ci
from fsreg_ros.research.sweep import COLUMNS, Setting, SweepConfig, reads, recommend, settings, summarise_runs

SMALL = ["--policies", "decay,displacement,none", "--decay-periods", "5,20", "--capacities", "1,3",
         "--seeds", "3", "--turns", "16", "--no-progress"]


def test_game_is_a_guess_who_board_and_deterministic():
    game = make_game(7, 20)
    assert game == make_game(7, 20)
    assert len(game.board) == BOARD_SIZE and list(game.boards) == ["faces"]
    assert len({tuple(p) for p in game.board.values()}) == BOARD_SIZE  # distinct faces
    for props in game.board.values():
        assert [a for a, values in ATTRIBUTES.items() for p in props if p in values] == list(ATTRIBUTES)
    speakers = [t[0] for t in game.turns]
    assert speakers == ["human", "robot"] * 10
    times = [t[1] for t in game.turns]
    assert times == sorted(times) and times[0] > 0
    assert make_game(8, 20).board != game.board
    assert game.changes == () and len(game.shortest) == 10
    assert len(make_game(7, 20, board_size=5).board) == 5
    with pytest.raises(ValueError, match="board size must be in"):
        make_game(7, 20, board_size=49)


def test_human_descriptions_resolve_and_policies_change_the_robot():
    game = make_game(3, 40)
    none = play(game, {"policy": "none"})
    humans = [t for t in none.result["turns"] if t["speaker"] == "human"]
    assert all(t["status"] == "resolved" and t["resolved"] == t["target"] for t in humans)
    robots = [t for t in none.result["turns"] if t["speaker"] == "robot"]
    assert all(t["algorithm"] == "dist-pia" and t["distinguishing"] for t in robots)
    decay = play(game, {"policy": "decay", "decay_period": 20})
    assert {t["algorithm"] for t in decay.result["turns"] if t["speaker"] == "robot"} == {"sd-pia"}
    assert decay.alignment.from_wm > 0 and none.alignment.from_wm == 0
    assert len(scenario_of(game).dialogue) == 40
    assert none.wm_sizes == [0] * 20 and max(decay.wm_sizes) > 0 and none.trace is None


def test_each_policy_runs_only_over_the_parameters_it_reads():
    config = SweepConfig(("decay", "displacement", "decay+displacement", "similarity", "shared-capacity", "none"),
                         (5.0, 10.0), (1, 2), (0,), 10, shared_capacities=(4,))
    grid = settings(config)
    assert grid == [
        Setting("decay", 5.0), Setting("decay", 10.0),
        Setting("displacement", capacity=1), Setting("displacement", capacity=2),
        Setting("decay+displacement", 5.0, 1), Setting("decay+displacement", 5.0, 2),
        Setting("decay+displacement", 10.0, 1), Setting("decay+displacement", 10.0, 2),
        Setting("similarity"), Setting("shared-capacity", shared_capacity=4), Setting("none"),
    ]
    assert len(set(grid)) == len(grid)
    assert reads("displacement-random+global-capacity", {}) == ("capacity", "global_capacity")
    assert reads("displacement", {"capacity": 3}) == ()  # fixed by --memory: not a grid dimension
    # Retraction is a dimension only when facts change, and never for none.
    dynamic = SweepConfig(("decay", "none"), (5.0,), (1,), (0,), 10, changes=10, retraction=(True, False))
    assert settings(dynamic) == [Setting("decay", 5.0), Setting("decay", 5.0, retraction=False), Setting("none")]
    assert settings(SweepConfig(("decay",), (5.0,), (1,), (0,), 10, retraction=(True, False))) == [
        Setting("decay", 5.0)]


def test_activation_runs_over_its_thresholds():
    """ACT-R activation (issue 27): tau is a grid dimension, d fixed (--memory activation_decay=D, else 0.5)."""
    config = SweepConfig(("activation+displacement",), (5.0,), (2,), (0,), 10, activation_thresholds=(-1.5, -0.8))
    assert settings(config) == [Setting("activation+displacement", capacity=2, activation_threshold=-1.5),
                                Setting("activation+displacement", capacity=2, activation_threshold=-0.8)]
    assert settings(config)[0].memory({"activation_decay": 0.4}) == {
        "policy": "activation+displacement", "activation_decay": 0.4, "capacity": 2, "activation_threshold": -1.5}
    assert settings(config)[1].label() == "activation+displacement alpha=2, tau=-0.8"
    assert reads("activation", {"activation_threshold": -1.0}) == ("activation_clock",)  # (an axis when given)


def test_activation_runs_on_each_clock_given_as_a_setting_of_its_own():
    """--activation-clocks (issue 36): each clock a setting, beside tau; none given: today's grid, no clock column."""
    config = SweepConfig(("activation",), (5.0,), (2,), (0,), 10, activation_thresholds=(-1.0,),
                         activation_clocks=("seconds", "episodes", "words"))
    assert settings(config) == [Setting("activation", activation_threshold=-1.0, activation_clock=c)
                                for c in ("seconds", "episodes", "words")]
    assert settings(config)[2].memory({}) == {"policy": "activation", "activation_threshold": -1.0,
                                              "activation_clock": "words"}
    assert settings(config)[1].label() == "activation tau=-1, clock=episodes"
    assert "activation_clock" in cli_columns(config)
    today = SweepConfig(("activation",), (5.0,), (2,), (0,), 10, activation_thresholds=(-1.0,))
    assert settings(today) == [Setting("activation", activation_threshold=-1.0)]
    assert "activation_clock" not in cli_columns(today)


def cli_columns(config) -> tuple:
    from fsreg_ros.research.sweep import columns

    return columns(config)


def test_setting_memory_and_labels():
    setting = Setting("displacement-random+shared-capacity", capacity=2, shared_capacity=6)
    assert setting.memory({}, seed=5) == {"policy": "displacement-random+shared-capacity", "capacity": 2,
                                          "shared_capacity": 6, "seed": 5}
    assert setting.memory({"seed": 9}, seed=5)["seed"] == 9
    assert setting.wm == "shared" and Setting("decay", 5.0, retraction=False).wm == "per-domain, not told"
    assert Setting("decay+displacement", 10.0, 2).label() == "decay+displacement delta=10, alpha=2"
    assert scenario_of(make_game(1, 4)).domains["faces"].attributes["hoodie"] == "clothing"


@pytest.mark.slow  # the same sweep in one process and in several
def test_same_arguments_same_files_whatever_jobs(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    assert cli.sweep_main([*SMALL, "--out", str(a), "--jobs", "1"]) == 0
    assert cli.sweep_main([*SMALL, "--out", str(b), "--jobs", "2", "--no-plots"]) == 0
    for name in ("runs.csv", "divergence.csv", "summary.csv"):
        assert (a / name).read_bytes() == (b / name).read_bytes()
    rows = list(csv.DictReader((a / "runs.csv").open()))
    assert tuple(rows[0]) == COLUMNS
    assert len(rows) == 3 * (2 + 2 + 1)  # decay over 2 periods, displacement over 2 capacities, none once
    assert len({(r["policy"], r["decay_period"], r["capacity"], r["seed"]) for r in rows}) == len(rows)
    none = [r for r in rows if r["policy"] == "none"]
    assert all(float(r["entrainment_gain"]) == 0 and float(r["divergence"]) == 0 for r in none)
    assert all(r["decay_period"] == "" and r["capacity"] == "" for r in none)
    assert all(r["capacity"] == "" for r in rows if r["policy"] == "decay")
    assert all(r["decay_period"] == "" for r in rows if r["policy"] == "displacement")
    for r in rows:
        assert 0 <= float(r["share"]) <= 1 and 0 <= float(r["entrainment"]) <= 1
        assert float(r["overspecification"]) >= 0 and float(r["outdated_rate"]) == 0
        assert r["robot_turns"] == "8" and r["divergence_k10"] == ""
    summary = list(csv.DictReader((a / "summary.csv").open()))
    assert [int(r["games"]) for r in summary] == [3] * 5
    for r in summary:
        assert float(r["entrainment_gain_low"]) <= float(r["entrainment_gain"]) <= float(r["entrainment_gain_high"])


@pytest.mark.slow  # a sweep, then the same again from its manifest
def test_manifest_reproduces_the_run(tmp_path):
    out = tmp_path / "m"
    argv = [*SMALL, "--out", str(out), "--board-size", "12"]
    assert cli.sweep_main(argv) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["command"] == "fsreg-sweep " + " ".join(argv)
    assert manifest["seeds"] == [0, 1, 2] and set(manifest["kb_sha256"]) == {"0", "1", "2"}
    assert manifest["parameters"]["policies"] == ["decay", "displacement", "none"]
    assert manifest["parameters"]["turns"] == 16 and manifest["parameters"]["board_size"] == 12
    assert manifest["game"]["board_size"] == 12 and manifest["game"]["world"] == "faces"
    assert manifest["distinct_runs"] == 15
    git = manifest["git"]
    assert {"commit", "dirty", "diff_sha256"} <= set(git)
    assert git["commit"] is None or (len(git["commit"]) == 40 and isinstance(git["dirty"], bool))
    assert len(git["diff_sha256"]) == 64 if git["dirty"] else git["diff_sha256"] is None and git["diff_absent"]
    assert manifest["execution"]["engine"] == "local" and manifest["execution"]["workers"] == 1
    assert manifest["environment"]["python"].count(".") == 2
    assert set(manifest["environment"]["libraries"]) == {"numpy", "matplotlib", "tqdm", "pyyaml", "pydantic"}
    assert manifest["started"] <= manifest["finished"] and manifest["started"].endswith("+00:00")
    assert len(manifest["files"]) == len(set(manifest["files"]))
    for name in ("policy-decay.png", "policy-displacement.png", "divergence_by_turn.png", "summary.csv"):
        assert name in manifest["files"] and (out / name).stat().st_size > 1000
    assert "divergence.png" not in manifest["files"] and "distinguishing_rate.png" not in manifest["files"]


def test_printed_summary_counts_distinct_runs(tmp_path, capsys):
    assert cli.sweep_main([*SMALL, "--out", str(tmp_path / "p"), "--no-plots"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"fsreg-sweep: 15 distinct runs (5 settings x 3 games) written to {tmp_path / 'p' / 'runs.csv'}"
    assert [line.split("  ")[1].strip() for line in lines[2:7]] == [
        "decay delta=5", "decay delta=20", "displacement alpha=1", "displacement alpha=3", "none"]
    assert any("percentile bootstrap CI over games (10,000 resamples, seed 0), n = 3" in line for line in lines)


def test_dirty_tree_changes_the_manifest(tmp_path, monkeypatch):
    from fsreg_ros.research import provenance

    outputs = {("rev-parse", "--show-toplevel"): b"/x\n", ("rev-parse", "HEAD"): b"a" * 40 + b"\n",
               ("diff", "HEAD", "--binary"): b"diff --git a/games.py ...", ("diff", "HEAD", "--name-only", "-z"):
               b"games.py\0", ("ls-files", "--others", "--exclude-standard", "-z"): b""}
    monkeypatch.setattr(provenance, "_git", lambda *args, cwd=None: outputs[args])
    state = provenance.git_state()
    assert state["dirty"] is True and state["commit"] == "a" * 40 and len(state["diff_sha256"]) == 64
    assert state["changed_files"] == ["games.py"] and state["untracked_files"] == []
    outputs[("diff", "HEAD", "--binary")] = outputs[("diff", "HEAD", "--name-only", "-z")] = b""
    clean = provenance.git_state()
    assert clean["dirty"] is False and clean["diff_sha256"] is None and clean["diff_absent"].startswith("clean tree")


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--capacities", "0"], "--capacities: 0 is out of range"),
        (["--decay-periods", "x"], "--decay-periods: 'x' is not a number"),
        (["--policies", "forget-all"], "forget-all"),
        (["--turns", "1"], "--turns must be in [2, 10000]"),
        (["--jobs", "0"], "--jobs must be in [1, 256]"),
        (["--board-size", "1"], "--board-size must be in [2, 48]"),
        (["--changes", "-1"], "--changes must be in [0, 100]"),
        (["--changes", "nan"], "--changes must be in [0, 100]"),
        (["--retraction", "maybe"], "--retraction: expected on, off or on,off"),
        (["--shared-capacities", "0"], "--shared-capacities: 0 is out of range"),
        (["--human-memory", "policy=bogus"], "bogus"),
        (["--human-memory", "decay"], "--human-memory 'decay': expected KEY=VALUE"),
        (["--activation-clocks", "seconds,hours"],
         "--activation-clocks: expected one or more of seconds, episodes, words, got 'seconds,hours'"),
    ],
)
def test_bad_sweep_input_is_one_line(tmp_path, capsys, extra, message):
    assert cli.sweep_main([*SMALL, "--out", str(tmp_path / "o"), *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "o" / "runs.csv").exists()


def test_human_with_its_own_wm_hears_the_robot(tmp_path):
    game = make_game(5, 30)
    plain = play(game, {"policy": "displacement", "capacity": 2})
    human_wm = {"policy": "decay", "decay_period": 30}
    played = play(game, {"policy": "displacement", "capacity": 2}, human_memory=human_wm)
    humans = [t for t in played.result["turns"] if t["speaker"] == "human"]
    assert all(t["status"] == "resolved" and t["resolved"] == t["target"] for t in humans)
    assert [t["description"] for t in humans] != [t["description"] for t in plain.result["turns"]
                                                  if t["speaker"] == "human"]
    assert played.result == play(game, {"policy": "displacement", "capacity": 2}, human_memory=human_wm).result
    out = tmp_path / "h"
    assert cli.sweep_main([*SMALL, "--out", str(out), "--no-plots", "--human-memory", "policy=decay",
                           "--human-memory", "decay_period=10"]) == 0
    assert json.loads((out / "manifest.json").read_text())["parameters"]["human_memory"] == {
        "policy": "decay", "decay_period": 10}


def test_sweep_runs_the_new_rules_reproducibly(tmp_path):
    args = ["--policies", "none,displacement-lfu,displacement-random,similarity,shared-capacity",
            "--capacities", "2", "--shared-capacities", "2", "--seeds", "3", "--turns", "30", "--no-progress",
            "--no-plots"]
    a, b = tmp_path / "a", tmp_path / "b"
    assert cli.sweep_main([*args, "--out", str(a)]) == 0
    assert cli.sweep_main([*args, "--out", str(b), "--jobs", "2"]) == 0
    assert (a / "runs.csv").read_bytes() == (b / "runs.csv").read_bytes()
    rows = list(csv.DictReader((a / "runs.csv").open()))
    assert sorted({r["policy"] for r in rows}) == ["displacement-lfu", "displacement-random", "none",
                                                   "shared-capacity", "similarity"]
    lfu = [float(r["mean_wm_occupancy"]) for r in rows if r["policy"] == "displacement-lfu"]
    pooled = [float(r["mean_wm_occupancy"]) for r in rows if r["policy"] == "shared-capacity"]
    assert all(x <= 2 for x in pooled) and max(lfu) > 2  # one pool of 2 vs 2 per face


def test_bootstrap_is_seeded_and_brackets_the_mean():
    values = [0.1, 0.3, 0.2, 0.5, 0.0, 0.4]
    a, b = bootstrap_ci(values), bootstrap_ci(values)
    assert a == b and a.low < a.mean < a.high and a.n == 6
    assert bootstrap_ci([0.2, 0.2]).low == bootstrap_ci([0.2, 0.2]).high == 0.2
    assert bootstrap_ci([1.0]).text(2) == "1.00 [1.00, 1.00]" and bootstrap_ci([]).n == 0
    assert bootstrap_ci([-1.0, 1.0, 2.0]).text(1, signed=True).startswith("+0.7 [")


# ------------------------------------------------------------- dynamic games (the follow-up)
def test_dynamic_game_changes_facts_and_keeps_entities_distinct():
    game = make_game(4, 100, world="faces+objects", changes=20)
    assert list(game.boards) == ["faces", "objects"] and len(game.changes) == 20
    assert [c.time for c in game.changes] == sorted(c.time for c in game.changes)
    assert {c.domain for c in game.changes} == {"faces", "objects"}
    for change in game.changes:
        attribute = {"glasses", "no-glasses"} if change.old in ("glasses", "no-glasses") else None
        assert change.old != change.new and (attribute is None or change.new in attribute)
    assert {t[3] for t in game.turns} == {"faces", "objects"}
    assert game.kb_hash() != make_game(4, 100, world="faces+objects").kb_hash()


def test_wm_told_or_not_and_what_the_robot_says_when_it_believes_its_wm():
    game = make_game(1, 200, world="faces+objects", changes=30)
    memory = {"policy": "displacement", "capacity": 6}
    told = play(game, memory, wm_belief=True)
    stale = play(game, memory, retract=False, wm_belief=True)
    checked = play(game, memory, retract=False)
    assert sum(map(len, told.outdated)) == 0  # retraction: WM never holds what stopped holding
    assert sum(map(len, checked.outdated)) == 0  # SD-PIA checks WM against LTM: nothing stale is said
    said = sum(map(len, stale.outdated))
    assert said > 0  # WM not told and believed: stale properties are said
    # ... and each of them is a property the entity had before a change, never one it never had.
    for record, outdated in zip([t for t in stale.result["turns"] if t["speaker"] == "robot"], stale.outdated):
        for prop in outdated:
            assert any(c.entity == record["target"] and c.old == prop and c.time <= record["time"]
                       for c in game.changes)


def test_belief_port_narrows_by_a_stale_property():
    from fsreg_ros.core.consultant.consultant import Consultant
    from fsreg_ros.core.algorithms.port import run_sync
    from fsreg_ros.core.algorithms.generation import generate

    kb = Consultant("d", {"t": {"glasses": 1.0}, "u": {"no-glasses": 1.0}}, ["glasses", "no-glasses"],
                    retract_on_update=False)
    kb.encode("t", ["glasses"], "speaker", 0.0, 0)
    kb.assert_facts("t", {"glasses": 0.0, "no-glasses": 1.0}, 1.0)
    assert kb.queue("t") == ["glasses"]  # not told: the stale property stays
    believed = run_sync(generate("t", BeliefPort(kb), "sd-pia", time=2.0, turn=1))
    assert believed.description == ["glasses"] and believed.sources == ["wm"] and believed.distinguishing
    from fsreg_ros.core.consultant.local_port import LocalPort

    checked = run_sync(generate("u", LocalPort(kb), "sd-pia", time=3.0, turn=2))
    assert checked.description == []  # u and t are both no-glasses now: nothing distinguishes u
    assert not checked.distinguishing


@pytest.mark.slow  # a sweep of every setting
def test_recommendation_picks_the_most_entrainment_within_each_bound(tmp_path, capsys):
    args = ["--world", "faces+objects", "--changes", "30", "--retraction", "on,off", "--wm-belief",
            "--policies", "displacement,shared-capacity,none", "--capacities", "1,6", "--shared-capacities", "4,64",
            "--seeds", "3", "--turns", "60", "--no-progress"]
    out = tmp_path / "f"
    assert cli.sweep_main([*args, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "recommendation: per WM configuration" in printed
    rows = list(csv.DictReader((out / "recommendation.csv").open()))
    assert [(r["wm"], r["max_outdated_rate"]) for r in rows] == [
        (wm, bound) for wm in ("per-domain", "per-domain, not told", "shared", "shared, not told")
        for bound in ("0.01", "0.05")]
    assert summarise_runs([]) == []
    for row in rows:
        assert row["policy"] and float(row["outdated_rate"]) <= float(row["max_outdated_rate"]) + 1e-9
    assert (out / "tradeoff.png").stat().st_size > 1000
    assert "tradeoff.png" in json.loads((out / "manifest.json").read_text())["files"]


def test_recommend_by_hand():
    from fsreg_ros.research.stats import Estimate

    def entry(setting, entrainment, outdated):
        return {"setting": setting, "n": 3, "estimates": {
            "entrainment": Estimate(entrainment, entrainment, entrainment, 3),
            "entrainment_gain": Estimate(0.0, 0.0, 0.0, 3),
            "outdated_rate": Estimate(outdated, outdated, outdated, 3)}}

    summary = [entry(Setting("decay", 10.0, retraction=False), 0.80, 0.004),
               entry(Setting("decay", 40.0, retraction=False), 0.85, 0.03),
               entry(Setting("decay", 80.0, retraction=False), 0.90, 0.08),
               entry(Setting("none"), 0.75, 0.0)]
    table = recommend(summary)
    assert [(t["wm"], t["bound"], t["best"]["setting"].decay_period) for t in table] == [
        ("per-domain, not told", 0.01, 10.0), ("per-domain, not told", 0.05, 40.0)]
    assert [t["allowed"] for t in table] == [2, 3]


@pytest.mark.parametrize("retract", [True, False])
def test_retract_on_update_decides_whether_ltm_changes_reach_wm(retract):
    from fsreg_ros.core.consultant.consultant import Consultant

    kb = Consultant("d", {"t": {"glasses": 1.0, "hat": 0.6}}, ["glasses", "hat"], retract_on_update=retract)
    kb.encode("t", ["glasses", "hat"], "speaker", 0.0, 0)
    result = kb.assert_facts("t", {"glasses": 0.0}, 1.0)
    assert result.retracted == ["glasses"]  # LTM: glasses no longer hold either way
    assert kb.queue("t") == (["hat"] if retract else ["glasses", "hat"])
    assert kb.set_threshold(0.7, 2.0) == ([("t", "hat")] if retract else [])
    assert kb.queue("t") == ([] if retract else ["glasses", "hat"])
    assert kb.properties_of("t") == []


def test_fact_changes_are_consistent_with_the_exclusive_groups_and_play_as_without_them(monkeypatch):
    """Every change names the old value at 0 itself: the exclusion retracts nothing more, so results are unchanged."""
    import fsreg_ros.research.games as games
    from fsreg_ros.core.consultant.consultant import Consultant

    game = make_game(1, 200, world="faces+objects", changes=30)
    robots = {d: Consultant(d, {e: dict.fromkeys(p, 1.0) for e, p in board.items()}, games.ROBOT_ORDERS[d],
                            exclusive=games.EXCLUSIVE[d]) for d, board in game.boards.items()}
    for change in game.changes:
        robot = robots[change.domain]
        assert robot.effective_update(change.entity, change.facts()) == change.facts()
        robot.assert_facts(change.entity, change.facts(), change.time)
        for values in games.EXCLUSIVE[change.domain]:
            assert len(set(values) & set(robot.properties_of(change.entity))) == 1
    memory = {"policy": "decay+displacement", "decay_period": 10.0, "capacity": 4}
    with_groups = play(game, memory, listener=ListenerOptions(missing=0.1), trace=True)
    monkeypatch.setattr(games, "EXCLUSIVE", {d: () for d in games.EXCLUSIVE})
    without = play(game, memory, listener=ListenerOptions(missing=0.1), trace=True)
    assert with_groups.result == without.result and with_groups.trace == without.trace
    assert with_groups.outdated == without.outdated and with_groups.heard == without.heard
