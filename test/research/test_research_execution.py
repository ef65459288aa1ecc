"""The research execution layer: engines, task order, retries, loopback binding, rclpy-free workers, CLI checks.

One Dask LocalCluster (loopback, two one-thread worker processes) serves the module;
tests that need their own cluster (``--cluster local:N``, the binding check) start one.
"""

import os
import signal
import sys
import time

import psutil
import pytest

from fsreg_ros.research import cli, execution
from fsreg_ros.research.execution import Engine, EngineError, dask_client, engine_from_args, run_tasks
from fsreg_ros.research.sweep import SweepConfig, run_seed

distributed = pytest.importorskip("distributed", reason="dask[distributed] is in requirements-dev.txt")

SMALL = ["--policies", "decay,none", "--decay-periods", "5,20", "--seeds", "3", "--turns", "12", "--no-progress",
         "--no-plots"]


def square(x):
    return x * x


def fails_on_three(x):
    if x == 3:
        raise ValueError("task three is bad")
    return x


def interrupts_itself(_):
    os.kill(os.getpid(), signal.SIGINT)  # as Ctrl-C to the process group reaches a busy worker
    time.sleep(5)


def rclpy_loaded():
    return "rclpy" in sys.modules


@pytest.fixture(scope="module")
def cluster():
    """A LocalCluster of two one-thread worker processes on 127.0.0.1, and a client of it."""
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  scheduler_port=0, dashboard_address="127.0.0.1:0", silence_logs=40) as local:
        with distributed.Client(local) as client:
            yield local, client


# ------------------------------------------------------------------ engines
def test_a_jobs_worker_stops_the_task_it_runs_on_ctrl_c_and_ignores_one_between_tasks():
    """What a ``--jobs`` worker's initializer installs, run here: no traceback from a waiting worker."""
    previous = signal.getsignal(signal.SIGINT)
    try:
        execution._local_worker_start()
        os.kill(os.getpid(), signal.SIGINT)  # waiting for a task: ignored (the default handler raises)
        assert square(3) == 9
        with pytest.raises(KeyboardInterrupt):
            execution.LocalTask(interrupts_itself)(None)
        assert execution.LocalTask(square)(4) == 16 and not execution._RUNNING
        os.kill(os.getpid(), signal.SIGINT)
        assert square(2) == 4
    finally:
        signal.signal(signal.SIGINT, previous)


@pytest.mark.parametrize("engine", [Engine("local", 1), Engine("local", 2)], ids=["jobs1", "jobs2"])
def test_local_engines_return_results_in_task_order(engine):
    seen = []
    job = run_tasks(square, list(range(7)), engine, progress=False, on_result=lambda i, r: seen.append((i, r)))
    assert job.results == [x * x for x in range(7)]
    assert sorted(seen) == [(i, i * i) for i in range(7)] and job.retried == 0
    assert job.describe() == {"engine": "local", "label": engine.label(), "workers": engine.workers, "tasks": 7,
                              "retried": 0}
    with pytest.raises(ValueError, match="task three is bad"):
        run_tasks(fails_on_three, [1, 2, 3, 4], engine, progress=False)
    assert run_tasks(square, [], engine, progress=False).results == []


def test_dask_engine_returns_results_in_task_order_and_raises_a_task_error(cluster):
    local, client = cluster
    engine = Engine("scheduler", 0, local.scheduler_address)
    seen = []
    job = run_tasks(square, list(range(9)), engine, progress=False, client=client,
                    on_result=lambda i, r: seen.append(i))
    assert job.results == [x * x for x in range(9)] and sorted(seen) == list(range(9))
    assert job.workers == 2 and job.retried == 0 and job.address == local.scheduler_address
    assert job.describe()["address"] == local.scheduler_address
    with pytest.raises(ValueError, match="task three is bad"):
        run_tasks(fails_on_three, [1, 2, 3, 4], engine, progress=False, client=client)


def test_a_failed_dask_job_quietens_dask_logs_for_its_teardown_and_restores_them(cluster, monkeypatch):
    """A job that stops early (a task's error here; Ctrl-C in test_research_shards) tears down a
    client whose scheduler may be gone: Dask's and tornado's loggers say nothing meanwhile (their
    CommClosedError tracebacks are not the user's error), and get their own levels back after."""
    import logging

    local, client = cluster
    names = ("distributed.client", "tornado.application", "distributed")
    before = {name: logging.getLogger(name).level for name in names}
    seen = {}
    real = client.cancel

    def cancel(futures):  # the teardown of the failed job: what the loggers would let through now
        seen.update({name: logging.getLogger(name).isEnabledFor(logging.CRITICAL) for name in names})
        return real(futures)

    monkeypatch.setattr(client, "cancel", cancel)
    with pytest.raises(ValueError, match="task three is bad"):
        run_tasks(fails_on_three, [1, 2, 3, 4], Engine("scheduler", 0, local.scheduler_address), progress=False,
                  client=client)
    assert seen == {name: False for name in names}  # quiet while tearing down
    assert {name: logging.getLogger(name).level for name in names} == before  # and restored
    seen.clear()
    assert run_tasks(square, [1, 2], Engine("scheduler", 0, local.scheduler_address), progress=False,
                     client=client).results == [1, 4]
    assert seen == {name: True for name in names}  # a job that finishes is not quietened


def test_a_closed_dask_connection_is_not_a_traceback_during_a_job(caplog):
    """tornado's "Exception in callback" for a closed Dask connection (logged by the client's thread,
    maybe before an interrupted job gets to quieten its teardown) is dropped during a job, and only it."""
    import logging

    from distributed.comm.core import CommClosedError

    log = logging.getLogger("tornado.application")

    def callback_error(error):
        try:
            raise error
        except Exception:
            log.error("Exception in callback %r", "_track_future", exc_info=True)

    with execution.quiet_teardown():
        callback_error(CommClosedError("in <TCP (closed) ConnectionPool.gather>: Stream is closed"))
        callback_error(RuntimeError("a real bug"))
    callback_error(CommClosedError("after the job"))
    logged = [str(r.exc_info[1]) for r in caplog.records if r.name == "tornado.application"]
    assert logged == ["a real bug", "after the job"]  # the closed connection during the job alone is dropped


def test_a_worker_with_other_code_fails_the_job_audibly(cluster):
    _, client = cluster
    assert execution.SameCode(square, execution.code_fingerprint())(3) == 9
    future = client.submit(execution.SameCode(square, "0" * 64), 3, pure=False)
    with pytest.raises(EngineError, match=r"^worker \S+ runs other fsreg_ros code \(files [0-9a-f]{12}, the caller's "
                                          r"000000000000\): install the same commit on every worker$"):
        future.result()


def test_the_same_progress_bar_on_every_engine(cluster, capsys):
    import re

    _, client = cluster
    bars = []
    for engine, own in ((Engine("local", 1), None), (Engine("local", 2), None), (Engine("cluster", 2), client)):
        run_tasks(square, list(range(4)), engine, progress=True, desc="fsreg-sweep", unit="game", done=2,
                  client=own)
        err = capsys.readouterr().err
        first, last = (re.sub(r"\|.*\|", "|bar|", line.strip()) for line in (err.split("\r")[1], err.split("\r")[-1]))
        bars.append((first, re.sub(r"\[.*\]", "[time, rate]", last)))
        assert re.search(r"\d(game/s|s/game)\]$", last)
    assert bars == [("fsreg-sweep:  33%|bar| 2/6 [00:00<?, ?game/s]", "fsreg-sweep: 100%|bar| 6/6 [time, rate]")] * 3


def test_workers_never_import_rclpy(cluster):
    _, client = cluster
    config = SweepConfig(("decay", "none"), (5.0,), (1,), (0, 1), 8)
    run_tasks(run_seed, [(config, 0), (config, 1)], Engine("cluster", 2), progress=False, client=client)
    assert set(client.run(rclpy_loaded).values()) == {False}
    assert len(client.run(rclpy_loaded)) == 2


def test_local_cluster_binds_loopback_only():
    me = psutil.Process()
    before = {c.laddr for c in me.net_connections("tcp") if c.status == psutil.CONN_LISTEN}
    with dask_client(Engine("cluster", 2)) as client:
        info = client.scheduler_info(n_workers=-1)
        assert client.scheduler.address.startswith("tcp://127.0.0.1:")
        assert client.dashboard_link.startswith("http://127.0.0.1:")
        workers = info["workers"]
        assert len(workers) == 2
        for address, worker in workers.items():
            assert address.startswith("tcp://127.0.0.1:") and worker["nanny"].startswith("tcp://127.0.0.1:")
        pids = client.run(os.getpid)
        listening = [c.laddr for c in me.net_connections("tcp") if c.status == psutil.CONN_LISTEN
                     and c.laddr not in before]
        for pid in pids.values():
            listening += [c.laddr for c in psutil.Process(pid).net_connections("tcp")
                          if c.status == psutil.CONN_LISTEN]
        # scheduler, its HTTP endpoint, two nannies (here) and each worker's comm and HTTP ports
        assert len(listening) >= 8
        assert {a.ip for a in listening} == {"127.0.0.1"}
        assert 8787 not in {a.port for a in listening}  # free ports, not the default dashboard port
    assert all(not psutil.pid_exists(pid) or psutil.Process(pid).status() == psutil.STATUS_ZOMBIE
               for pid in pids.values())


def test_an_unreachable_scheduler_is_one_line(monkeypatch, tmp_path, capsys):
    monkeypatch.setattr(execution, "CONNECT_TIMEOUT", 1)
    import socket

    with socket.socket() as probe:  # a port nothing listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    assert cli.sweep_main([*SMALL, "--out", str(tmp_path / "o"), "--scheduler", f"tcp://127.0.0.1:{port}"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"fsreg-sweep: error: --scheduler tcp://127.0.0.1:{port}: cannot connect")
    assert err.count("\n") == 1 and not (tmp_path / "o" / "runs.csv").exists()


# ------------------------------------------------------------- the CLI's checks
@pytest.mark.parametrize(
    "extra, message",
    [
        (["--cluster", "local:0"], "--cluster local:N: N must be in [1, 256], got 0"),
        (["--cluster", "local:257"], "--cluster local:N: N must be in [1, 256], got 257"),
        (["--cluster", "foo"], "--cluster: expected local:N (N Dask workers on this machine), got 'foo'"),
        (["--cluster", "local:two"], "--cluster: expected local:N"),
        (["--scheduler", "localhost:8786"], "--scheduler: expected tcp://HOST:PORT"),
        (["--scheduler", "tcp://"], "--scheduler: expected tcp://HOST:PORT"),
        (["--scheduler", "http://h:8786"], "--scheduler: expected tcp://HOST:PORT"),
        (["--scheduler", "tcp://h:99999"], "--scheduler tcp://h:99999: port must be in [1, 65535], got 99999"),
        (["--scheduler", "tcp://h:0"], "port must be in [1, 65535], got 0"),
        (["--jobs", "2", "--cluster", "local:2"],
         "give one of --jobs, --cluster, --scheduler, not --jobs and --cluster"),
        (["--jobs", "300"], "--jobs must be in [1, 256], got 300"),
        (["--shard", "3/2"], "--shard 3/2: K must be in [1, N]"),
        (["--shard", "0/2"], "--shard 0/2: K must be in [1, N]"),
        (["--shard", "2"], "--shard: expected K/N"),
        (["--shard", "1/4"], "--shard 1/4: 4 shards of 3 games leave some empty"),
    ],
)
def test_bad_engine_input_is_one_line(tmp_path, capsys, extra, message):
    assert cli.sweep_main([*SMALL, "--out", str(tmp_path / "o"), *extra]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err
    assert not (tmp_path / "o").exists()


def test_engine_from_arguments():
    parser = cli.sweep_parser()
    base = ["--out", "x"]
    assert engine_from_args(parser.parse_args(base)) == Engine("local", 1)
    assert engine_from_args(parser.parse_args([*base, "--jobs", "3"])) == Engine("local", 3)
    assert engine_from_args(parser.parse_args([*base, "--cluster", "local:4"])) == Engine("cluster", 4)
    assert engine_from_args(parser.parse_args([*base, "--scheduler", "tcp://[::1]:8786"])) == Engine(
        "scheduler", 0, "tcp://[::1]:8786")
    assert Engine("scheduler", 0, "tcp://node-7.cluster:8786").label() == "Dask scheduler tcp://node-7.cluster:8786"
    with pytest.raises(EngineError, match="unknown engine 'ssh'"):
        Engine("ssh")


# ------------------------------------------------------- a worker killed mid-sweep
@pytest.mark.slow  # eight games on two workers, one of them killed
def test_a_worker_killed_mid_sweep_loses_no_game(cluster, tmp_path, capsys):
    import threading

    local, client = cluster
    args = ["--policies", "decay,displacement,none", "--decay-periods", "5,20", "--capacities", "2", "--seeds", "8",
            "--turns", "40", "--no-progress", "--no-plots"]
    assert cli.sweep_main([*args, "--out", str(tmp_path / "ref")]) == 0
    pids = client.run(os.getpid)
    out = tmp_path / "killed"
    killed = []

    def kill_one_worker_once_a_game_is_done():
        games = out / "games.jsonl"
        while not killed and not (out / "manifest.json").exists():
            if games.exists() and games.read_bytes().count(b"\n") >= 2:  # the header and one game
                busy = [w for w, keys in client.processing().items() if keys]
                if busy:
                    os.kill(pids[busy[0]], signal.SIGKILL)
                    killed.append(busy[0])
                    return
            threading.Event().wait(0.01)

    killer = threading.Thread(target=kill_one_worker_once_a_game_is_done)
    killer.start()
    try:
        assert cli.sweep_main([*args, "--out", str(out), "--scheduler", local.scheduler_address]) == 0
    finally:
        killer.join()
    assert killed, "the sweep ended before a worker could be killed"
    for name in ("runs.csv", "summary.csv", "divergence.csv"):
        assert (out / name).read_bytes() == (tmp_path / "ref" / name).read_bytes()
    import json

    execution_record = json.loads((out / "manifest.json").read_text())["execution"]
    assert execution_record["engine"] == "scheduler" and execution_record["retried"] >= 1
    printed = capsys.readouterr().out.splitlines()[-1]
    assert printed.startswith(f"fsreg-sweep: ran on Dask scheduler {local.scheduler_address} (2 workers at the "
                              "start); ") and printed.endswith("retried after a worker was lost")
    assert int(printed.split("; ")[1].split()[0]) == execution_record["retried"]
    client.wait_for_workers(2, timeout=60)  # the nanny restarts it
