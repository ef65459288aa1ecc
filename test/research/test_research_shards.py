"""fsreg-sweep beyond one process: the same bytes on every engine, shards merged, --resume, merge refusals, git state.

One Dask LocalCluster (loopback, two worker processes) serves the module's --scheduler runs.
"""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from fsreg_ros.research import cli, provenance, sweep
from fsreg_ros.research.ledger import GAMES, Ledger

distributed = pytest.importorskip("distributed", reason="dask[distributed] is in requirements-dev.txt")

# Dynamic games in two domains, WM told or not: runs.csv, summary.csv and recommendation.csv all have intervals.
DYNAMIC = ["--world", "faces+objects", "--changes", "20", "--retraction", "on,off", "--wm-belief",
           "--policies", "displacement,shared-capacity,none", "--capacities", "1,3", "--shared-capacities", "8",
           "--seeds", "5", "--turns", "24", "--no-progress", "--no-plots"]
TINY = ["--policies", "decay,none", "--decay-periods", "5", "--turns", "8", "--no-progress", "--no-plots"]
OUTPUTS = ("runs.csv", "summary.csv", "divergence.csv", "recommendation.csv")


@pytest.fixture(scope="module")
def scheduler():
    """The address of a LocalCluster of two one-thread worker processes on 127.0.0.1."""
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  scheduler_port=0, dashboard_address="127.0.0.1:0", silence_logs=40) as local:
        yield local.scheduler_address


def sweep_to(out: Path, *args: str) -> None:
    assert cli.sweep_main([*args, "--out", str(out)]) == 0


def manifest(out: Path) -> dict:
    return json.loads((out / "manifest.json").read_text())


def same_outputs(a: Path, b: Path) -> None:
    for name in OUTPUTS:
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


@pytest.mark.slow  # the same sweep seven ways, one of them on a cluster started for it
def test_same_bytes_on_every_engine_and_from_shards_merged(tmp_path, scheduler, capsys):
    ref = tmp_path / "jobs1"
    sweep_to(ref, *DYNAMIC, "--jobs", "1")
    sweep_to(tmp_path / "jobs2", *DYNAMIC, "--jobs", "2")
    sweep_to(tmp_path / "local2", *DYNAMIC, "--cluster", "local:2")
    sweep_to(tmp_path / "scheduler", *DYNAMIC, "--scheduler", scheduler)
    for k in (1, 2, 3):
        sweep_to(tmp_path / f"shard{k}", *DYNAMIC, "--shard", f"{k}/3", *(["--scheduler", scheduler] if k == 2 else []))
    capsys.readouterr()
    merged = tmp_path / "merged"
    shards = [str(tmp_path / f"shard{k}") for k in (3, 1, 2)]  # any order
    assert cli.sweep_main(["merge", str(merged), *shards]) == 0
    assert capsys.readouterr().out.startswith(
        f"fsreg-sweep merge: 3 sweeps, 35 distinct runs (7 settings x 5 games) written to {merged / 'runs.csv'}")
    for other in ("jobs2", "local2", "scheduler", "merged"):
        same_outputs(ref, tmp_path / other)
    # What ran where, in each manifest.
    assert manifest(ref)["execution"]["engine"] == "local" and manifest(ref)["parameters"]["jobs"] == 1
    local = manifest(tmp_path / "local2")["execution"]
    assert (local["engine"], local["workers"], local["retried"], local["tasks"]) == ("cluster", 2, 0, 5)
    assert manifest(tmp_path / "scheduler")["execution"]["address"] == scheduler
    assert [manifest(tmp_path / f"shard{k}")["seeds"] for k in (1, 2, 3)] == [[0, 3], [1, 4], [2]]
    assert manifest(tmp_path / "shard2")["execution"]["shard"] == {"shard": "2/3", "index": 2, "count": 3,
                                                                   "all_seeds": [0, 5]}
    combined = manifest(merged)
    assert combined["command"] == "fsreg-sweep merge " + " ".join([str(merged), *shards])
    assert combined["seeds"] == [0, 1, 2, 3, 4] and set(combined["kb_sha256"]) == {"0", "1", "2", "3", "4"}
    assert combined["kb_sha256"] == manifest(ref)["kb_sha256"]
    assert combined["parameters"] | {"jobs": 1} == manifest(ref)["parameters"]
    assert [s["shard"]["shard"] for s in combined["execution"]["shards"]] == ["3/3", "1/3", "2/3"]
    assert [s["execution"]["engine"] for s in combined["execution"]["shards"]] == ["local", "local", "scheduler"]
    assert combined["git"] == manifest(tmp_path / "shard1")["git"]


def test_sweeps_of_disjoint_seeds_merge_into_the_sweep_of_all(tmp_path):
    for name, base, seeds in (("low", 0, 2), ("high", 2, 2), ("all", 0, 5), ("last", 4, 1)):
        sweep_to(tmp_path / name, *TINY, "--seed-base", str(base), "--seeds", str(seeds))
    assert cli.sweep_main(["merge", str(tmp_path / "m"), str(tmp_path / "high"), str(tmp_path / "low")]) == 0
    assert manifest(tmp_path / "m")["seeds"] == [0, 1, 2, 3]
    # A merged sweep is a sweep: it merges again.
    assert cli.sweep_main(["merge", str(tmp_path / "again"), str(tmp_path / "m"), str(tmp_path / "last"),
                           "--no-plots"]) == 0
    for name in ("runs.csv", "summary.csv", "divergence.csv"):
        assert (tmp_path / "again" / name).read_bytes() == (tmp_path / "all" / name).read_bytes()


def test_games_file_is_the_sweeps_record(tmp_path):
    out = tmp_path / "s"
    sweep_to(out, *TINY, "--seeds", "3")
    book = Ledger.read(out)
    assert sorted(book.games) == [0, 1, 2] and book.missing() == []
    assert book.header["configuration"]["turns"] == 8 and "seeds" not in book.header["configuration"]
    assert book.header["columns"] == list(sweep.COLUMNS)
    record = book.games[1]
    assert len(record.rows) == 2 and [r["policy"] for r in record.rows] == ["decay", "none"]
    assert len(record.flags[0]) == 4 and set(record.flags[1]) == {"0"}  # none never differs from itself
    assert GAMES in manifest(out)["files"]


# ----------------------------------------------------------------- --resume
def test_resume_plays_only_the_missing_games(tmp_path, monkeypatch, capsys):
    ref = tmp_path / "ref"
    sweep_to(ref, *DYNAMIC)
    out = tmp_path / "cut"
    appended = []
    real_append = Ledger.append

    def interrupted_after_two(self, record):
        stored = real_append(self, record)
        appended.append(record.seed)
        if len(appended) == 2:
            raise KeyboardInterrupt
        return stored

    monkeypatch.setattr(Ledger, "append", interrupted_after_two)
    assert cli.sweep_main([*DYNAMIC, "--out", str(out)]) == 130
    err = capsys.readouterr().err
    assert err == (f"fsreg-sweep: interrupted; 2 of 5 games are kept in {out / GAMES}: the same command with "
                   "--resume plays the rest\n")
    assert not (out / "manifest.json").exists() and not (out / "runs.csv").exists()
    monkeypatch.setattr(Ledger, "append", real_append)
    assert cli.sweep_main([*DYNAMIC, "--out", str(out)]) == 2  # finished games are not thrown away unasked
    assert capsys.readouterr().err == (
        f"fsreg-sweep: error: {out} holds an unfinished sweep (2 of 5 games in games.jsonl): --resume continues it; "
        f"to start afresh, delete {out / GAMES}\n")
    with (out / GAMES).open("ab") as games:
        games.write(b'{"seed":4,"kb_sha2')  # a game torn by the kill: dropped
    played = []
    real_run_seed = sweep.run_seed
    monkeypatch.setattr(sweep, "run_seed", lambda task: played.append(task[1]) or real_run_seed(task))
    assert cli.sweep_main([*DYNAMIC, "--out", str(out), "--resume"]) == 0
    assert played == [2, 3, 4]
    same_outputs(ref, out)
    assert "fsreg-sweep: resumed: 2 games were already done, 3 played now" in capsys.readouterr().out
    execution_record = manifest(out)["execution"]
    assert (execution_record["resumed_games"], execution_record["played_games"]) == (2, 3)
    assert Ledger.read(out).missing() == []
    # Resuming a finished sweep plays nothing and writes the same files.
    played.clear()
    assert cli.sweep_main([*DYNAMIC, "--out", str(out), "--resume"]) == 0
    assert played == [] and manifest(out)["execution"]["resumed_games"] == 5
    same_outputs(ref, out)
    # Without --resume the sweep starts afresh.
    assert cli.sweep_main([*DYNAMIC, "--out", str(out)]) == 0
    assert played == [0, 1, 2, 3, 4]


def test_resume_refuses_another_sweep_or_other_code(tmp_path, monkeypatch, capsys):
    out = tmp_path / "s"
    sweep_to(out, *TINY, "--seeds", "2")
    assert cli.sweep_main([*TINY, "--seeds", "2", "--out", str(out), "--resume", "--turns", "10"]) == 2
    err = capsys.readouterr().err
    assert err == (f"fsreg-sweep: error: --resume: {out / GAMES} holds another sweep (it differs in configuration: "
                   "turns (8 vs 10)); rerun without --resume to start afresh, or use another --out\n")
    assert cli.sweep_main([*TINY, "--seeds", "3", "--out", str(out), "--resume"]) == 2
    assert "holds another sweep (it differs in seeds)" in capsys.readouterr().err
    real = sweep.git_state
    monkeypatch.setattr(sweep, "git_state", lambda **kw: {**real(**kw), "commit": "f" * 40})
    assert cli.sweep_main([*TINY, "--seeds", "2", "--out", str(out), "--resume"]) == 2
    assert "holds another sweep (it differs in code (commit " in capsys.readouterr().err
    # A resume with nothing to resume starts the sweep.
    assert cli.sweep_main([*TINY, "--seeds", "2", "--out", str(tmp_path / "new"), "--resume"]) == 0


@pytest.mark.slow  # a real Ctrl-C: SIGINT to fsreg-sweep's process group, as a terminal sends it, then --resume
@pytest.mark.parametrize("engine", [["--jobs", "2"], ["--cluster", "local:2"]], ids=["jobs", "cluster"])
def test_ctrl_c_then_resume_loses_no_finished_game(tmp_path, engine):
    args = [*DYNAMIC[:-6], "--seeds", "16", "--turns", "30", "--no-plots", *engine]
    out = tmp_path / "run"
    tool = Path(sys.executable).parent / "fsreg-sweep"
    process = subprocess.Popen([str(tool), *args, "--out", str(out)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, start_new_session=True)
    games = out / GAMES
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and process.poll() is None:
        if games.exists() and games.read_bytes().count(b"\n") >= 3:
            break
        time.sleep(0.02)
    assert process.poll() is None, "the sweep ended before it could be interrupted"
    os.killpg(process.pid, signal.SIGINT)  # the sweep and its workers, as Ctrl-C in a terminal
    stdout, stderr = process.communicate(timeout=120)
    assert process.returncode == 130, stderr
    kept = len(Ledger.read(out).games)
    assert 2 <= kept < 16
    assert f"fsreg-sweep: interrupted; {kept} of 16 games are kept" in stderr
    assert "Traceback" not in stderr and "KeyboardInterrupt" not in stderr  # nor from a worker
    done = subprocess.run([str(tool), *args, "--out", str(out), "--resume"], capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr
    assert f"resumed: {kept} games were already done, {16 - kept} played now" in done.stdout
    sweep_to(tmp_path / "ref", *[a for a in args if a not in engine])
    same_outputs(tmp_path / "ref", out)


# ------------------------------------------------------------------ merge refusals
def refused(capsys, *argv: str) -> str:
    assert cli.sweep_main(["merge", *argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    return err.removeprefix("fsreg-sweep merge: error: ").rstrip("\n")


def test_merge_refuses_what_is_not_one_sweep(tmp_path, monkeypatch, capsys):
    a, b, c = (tmp_path / n for n in ("a", "b", "c"))
    sweep_to(a, *TINY, "--seeds", "3", "--shard", "1/3")
    sweep_to(b, *TINY, "--seeds", "3", "--shard", "2/3")
    out = str(tmp_path / "out")
    assert refused(capsys, out, str(a), str(b)) == "merge: shard 3/3 missing"
    sweep_to(c, *TINY, "--seeds", "3", "--shard", "3/3", "--turns", "10")
    assert refused(capsys, out, str(a), str(b), str(c)) == (
        f"merge: {c} and {a} are sweeps of different configurations: turns (10 vs 8)")
    real = sweep.git_state
    monkeypatch.setattr(sweep, "git_state", lambda **kw: {**real(**kw), "commit": "c" * 40, "diff_sha256": None})
    sweep_to(c, *TINY, "--seeds", "3", "--shard", "3/3")
    monkeypatch.setattr(sweep, "git_state", real)
    message = refused(capsys, out, str(a), str(b), str(c))
    assert message.startswith(f"merge: {c} and {a} ran different code: commit cccccccccccc vs commit ")
    sweep_to(c, *TINY, "--seeds", "3", "--shard", "3/3")
    assert cli.sweep_main(["merge", out, str(a), str(b), str(c)]) == 0  # now it is one sweep
    capsys.readouterr()
    # Overlapping seeds, a split of another size, an unfinished sweep, the output among the inputs.
    d, e = tmp_path / "d", tmp_path / "e"
    sweep_to(d, *TINY, "--seeds", "3")
    sweep_to(e, *TINY, "--seeds", "3", "--seed-base", "2")
    assert refused(capsys, out, str(d), str(e)) == f"merge: {e} and {d} overlap: both have seed 2"
    f = tmp_path / "f"
    sweep_to(f, *TINY, "--seeds", "3", "--shard", "1/2")
    assert refused(capsys, out, str(b), str(f)).startswith("merge: shards of different splits: ")
    g = tmp_path / "g"
    sweep_to(g, *TINY, "--seeds", "2", "--seed-base", "10")
    assert refused(capsys, out, str(g), str(b)) == f"merge: {g} is no shard (no --shard) but other inputs are; " \
                                                   "merge shards of one split, or sweeps without --shard"
    (d / "manifest.json").unlink()
    assert refused(capsys, out, str(d), str(e)) == (
        f"merge: {d} is not a finished sweep (no manifest.json); finish it with its command and --resume")
    assert refused(capsys, str(a), str(a), str(b)) == f"merge: the output {a} is one of the inputs"
    assert refused(capsys, out, str(tmp_path / "nowhere")).startswith(f"merge: {tmp_path / 'nowhere'} is not a "
                                                                      "finished sweep")


# ------------------------------------------------------------------ the diff hash
def git(repo: Path, *args: str) -> None:
    subprocess.run(["git", "-c", "user.name=t", "-c", "user.email=t@example.org", *args], cwd=repo, check=True,
                   capture_output=True)


def test_diff_hash_covers_the_whole_repository_and_names_what_changed(tmp_path):
    repo = tmp_path / "repo"
    package = repo / "pkg" / "research"
    package.mkdir(parents=True)
    (package / "sweep.py").write_text("x = 1\n")
    (repo / ".gitignore").write_text("out/\n")
    git(repo, "init", "-q")
    git(repo, "add", "-A")
    git(repo, "commit", "-qm", "first")
    clean = provenance.git_state(where=package)
    assert clean["dirty"] is False and clean["diff_sha256"] is None
    assert clean["diff_absent"] == "clean tree: no tracked change and no untracked file" and len(clean["commit"]) == 40
    # An untracked file outside the package's directory (the bug: it was left out, and the hash was of nothing).
    (repo / "notes.txt").write_text("a\n")
    (repo / "out").mkdir()
    (repo / "out" / "runs.csv").write_text("ignored\n")
    state = provenance.git_state(where=package)
    empty = "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"
    assert state["dirty"] is True and state["diff_sha256"] not in (None, empty)
    assert state["untracked_files"] == ["notes.txt"] and state["changed_files"] == []
    (repo / "notes.txt").write_text("b\n")
    assert provenance.git_state(where=package)["diff_sha256"] != state["diff_sha256"]  # content counts, not only names
    (package / "sweep.py").write_text("x = 2\n")
    changed = provenance.git_state(where=package)
    assert changed["changed_files"] == ["pkg/research/sweep.py"] and changed["untracked_files"] == ["notes.txt"]
    # A sweep's own output directory inside the repository is not part of the code.
    (repo / "results").mkdir()
    (repo / "results" / "games.csv").write_text("1\n")
    assert provenance.git_state(exclude=[repo / "results"], where=package)["untracked_files"] == ["notes.txt"]
    assert provenance.git_state(where=package)["untracked_files"] == ["notes.txt", "results/games.csv"]
    outside = provenance.git_state(where=tmp_path)
    assert outside == {"commit": None, "dirty": None, "diff_sha256": None,
                       "diff_absent": "not a git checkout (or git is not installed)"}
    assert os.environ.get("GIT_DIR") is None
