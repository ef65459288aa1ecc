"""Where the workbench's embarrassingly parallel jobs run: local processes or a Dask cluster.

This module owns the *execution layer* of the research tools and nothing of what they
compute.  A job is a module-level function and a list of independent tasks;
:func:`run_tasks` runs them on an :class:`Engine` and returns the results in task
order, whatever order they finished in, so a tool's output never depends on where it
ran.  The engines:

* ``local`` (the default): ``workers`` processes on this machine (``--jobs N``; one
  means in this process), through :class:`concurrent.futures.ProcessPoolExecutor`;
* ``cluster`` (``--cluster local:N``): a Dask ``LocalCluster`` of N one-thread worker
  processes started for the job and stopped after it.  Scheduler, workers, nannies and
  the scheduler's HTTP endpoint all bind ``127.0.0.1`` on free ports: nothing listens
  beyond this machine;
* ``scheduler`` (``--scheduler tcp://HOST:PORT``): an existing Dask cluster, the only
  way work reaches another host (see docs/research.md, "Bigger than one machine").

Over Dask the tasks go out with ``Client.map`` and come back through ``as_completed``;
scheduling, queueing and rescheduling a task whose worker died are Dask's own.  The
number of tasks Dask rescheduled because a worker was lost is read from the
scheduler's ``remove-worker`` events and reported (:attr:`TaskRun.retried`).  Worker
processes import only what the job's function imports (the research layer is pure
Python: never rclpy).  Over Dask each task first checks that its worker runs the
same fsreg_ros source as the caller (:func:`code_fingerprint`), so a worker host with
other code fails the job audibly instead of changing results.  A callback sees each result as it arrives, in the calling
process, so a tool can persist finished work before the job ends (``fsreg-sweep
--resume``).  The same tqdm bar (tasks done / total, rate, ETA) is drawn for every engine.
A Dask job stopped early (Ctrl-C, a task's error) tears its client down quietly
(:func:`quiet_teardown`): the tool's one line says what happened, not Dask's tracebacks of
connections its stopping closed.  A ``--jobs`` worker stops the task it runs on Ctrl-C (the
calling process gets the interruption back) and ignores one between tasks, where the
default handler would print a traceback from the worker (:class:`LocalTask`).
"""

from __future__ import annotations

import argparse
import functools
import hashlib
import logging
import multiprocessing
import re
import signal
import socket
import uuid
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Optional, Sequence

#: Most workers an engine may be asked for on one machine (``--jobs``, ``--cluster local:N``).
MAX_LOCAL_WORKERS = 256
#: Seconds to wait for an existing scheduler to answer before giving up.
CONNECT_TIMEOUT = 20
_SCHEDULER = re.compile(r"^tcp://(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9]([A-Za-z0-9.-]*[A-Za-z0-9])?):(\d{1,5})$")


class EngineError(ValueError):
    """An engine cannot be set up or a job cannot finish on it; the message is one line naming why."""


@dataclass(frozen=True)
class Engine:
    """Where a job runs: ``local`` processes, a ``cluster`` of local Dask workers, or an existing ``scheduler``."""

    kind: str = "local"
    workers: int = 1  # local processes or LocalCluster workers (a scheduler's workers are counted when it runs)
    address: Optional[str] = None  # the scheduler's address, kind "scheduler" only

    def __post_init__(self) -> None:
        if self.kind not in ("local", "cluster", "scheduler"):
            raise EngineError(f"unknown engine '{self.kind}' (known: local, cluster, scheduler)")
        if self.kind != "scheduler" and not 1 <= self.workers <= MAX_LOCAL_WORKERS:
            raise EngineError(f"workers must be in [1, {MAX_LOCAL_WORKERS}], got {self.workers}")
        if self.kind == "scheduler":
            parse_scheduler(self.address or "")

    @property
    def dask(self) -> bool:
        """Whether the engine is a Dask cluster."""
        return self.kind != "local"

    def label(self) -> str:
        """Return e.g. ``2 local processes``, ``LocalCluster of 2 workers``, ``scheduler tcp://h:8786``."""
        if self.kind == "local":
            return "1 process" if self.workers == 1 else f"{self.workers} local processes"
        if self.kind == "cluster":
            return f"Dask LocalCluster of {self.workers} worker{'s' if self.workers > 1 else ''} on 127.0.0.1"
        return f"Dask scheduler {self.address}"


def parse_cluster(text: str) -> int:
    """Parse ``--cluster local:N`` into N (one line naming what is wrong otherwise)."""
    kind, sep, count = text.partition(":")
    if kind != "local" or not sep or not count.isdigit():
        raise EngineError(f"--cluster: expected local:N (N Dask workers on this machine), got '{text}'; "
                          "for another machine's cluster give --scheduler tcp://HOST:PORT")
    workers = int(count)
    if not 1 <= workers <= MAX_LOCAL_WORKERS:
        raise EngineError(f"--cluster local:N: N must be in [1, {MAX_LOCAL_WORKERS}], got {workers}")
    return workers


def parse_scheduler(text: str) -> str:
    """Check ``--scheduler tcp://HOST:PORT`` (host name, IPv4 or [IPv6], port 1-65535); return it."""
    match = _SCHEDULER.match(text)
    if match is None:
        raise EngineError(f"--scheduler: expected tcp://HOST:PORT (a running Dask scheduler), got '{text}'")
    port = int(match.group(3))
    if not 1 <= port <= 65535:
        raise EngineError(f"--scheduler {text}: port must be in [1, 65535], got {port}")
    return text


def add_engine_arguments(parser: argparse.ArgumentParser, what: str = "tasks") -> None:
    """Add ``--jobs``, ``--cluster`` and ``--scheduler`` to a tool's parser (read back by :func:`engine_from_args`)."""
    group = parser.add_argument_group("where it runs (results do not depend on it)")
    group.add_argument("--jobs", type=int, default=None, metavar="N",
                       help=f"run the {what} in N local processes (default 1)")
    group.add_argument("--cluster", metavar="local:N",
                       help="run on a Dask LocalCluster of N worker processes bound to 127.0.0.1")
    group.add_argument("--scheduler", metavar="tcp://HOST:PORT",
                       help="run on an existing Dask cluster (see docs/research.md, 'Bigger than one machine')")


def engine_from_args(args: argparse.Namespace) -> Engine:
    """Return the engine named by ``--jobs``/``--cluster``/``--scheduler`` (at most one of them)."""
    given = [name for name in ("jobs", "cluster", "scheduler") if getattr(args, name) is not None]
    if len(given) > 1:
        raise EngineError(f"give one of --jobs, --cluster, --scheduler, not {' and '.join('--' + g for g in given)}")
    if args.cluster is not None:
        return Engine("cluster", parse_cluster(args.cluster))
    if args.scheduler is not None:
        return Engine("scheduler", 0, parse_scheduler(args.scheduler))
    jobs = 1 if args.jobs is None else args.jobs
    if not 1 <= jobs <= MAX_LOCAL_WORKERS:
        raise EngineError(f"--jobs must be in [1, {MAX_LOCAL_WORKERS}], got {jobs}")
    return Engine("local", jobs)


#: True while this ``--jobs`` worker process runs a task (:class:`LocalTask`).
_RUNNING = False


def _interrupt_a_running_task(signum: int, frame: Any) -> None:
    """Stop the task this ``--jobs`` worker runs (its Ctrl-C handler); between tasks, do nothing."""
    if _RUNNING:
        raise KeyboardInterrupt


def _local_worker_start() -> None:
    """Set up a ``--jobs`` worker (its initializer): Ctrl-C stops a running task only; then unblock Ctrl-C."""
    signal.signal(signal.SIGINT, _interrupt_a_running_task)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


@dataclass(frozen=True)
class LocalTask:
    """A task function as a ``--jobs`` worker runs it: marked running, so Ctrl-C stops it (and only it).

    A worker waiting for its next task when Ctrl-C reaches the process group ignores it
    (the default handler would print a traceback from the worker's queue); the calling
    process stops the pool.
    """

    fn: Callable[[Any], Any]

    def __call__(self, task: Any) -> Any:
        global _RUNNING
        _RUNNING = True
        try:
            return self.fn(task)
        finally:
            _RUNNING = False


def dask_setup(worker: Any) -> None:
    """Dask preload hook of a LocalCluster's workers: Ctrl-C is the calling process's to handle.

    A terminal's Ctrl-C reaches every process of its group; the worker processes ignore
    it (no traceback from each), and the calling process stops the cluster.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """Return the SHA-256 of the installed fsreg_ros package's files (paths and contents, caches left out)."""
    root = Path(__file__).resolve().parents[1]
    digest = hashlib.sha256()
    for path in sorted(p for p in root.rglob("*") if p.is_file() and "__pycache__" not in p.parts):
        digest.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


@dataclass(frozen=True)
class SameCode:
    """A task function that first checks its worker runs the caller's fsreg_ros (:func:`code_fingerprint`)."""

    fn: Callable[[Any], Any]
    fingerprint: str

    def __call__(self, task: Any) -> Any:
        mine = code_fingerprint()
        if mine != self.fingerprint:
            raise EngineError(f"worker {socket.gethostname()} runs other fsreg_ros code (files {mine[:12]}, the "
                              f"caller's {self.fingerprint[:12]}): install the same commit on every worker")
        return self.fn(task)


@dataclass
class TaskRun:
    """A finished job: the results in task order, how many tasks Dask rescheduled, the workers it ran on."""

    results: list
    engine: Engine
    workers: int
    retried: int = 0  # tasks Dask rescheduled at least once because a worker was lost
    address: Optional[str] = None  # the scheduler's address (Dask engines)
    attempts: dict = field(default_factory=dict)  # task index -> times rescheduled (those rescheduled only)

    def describe(self) -> dict:
        """Return the manifest's record of where the job ran."""
        out: dict[str, Any] = {"engine": self.engine.kind, "label": self.engine.label(), "workers": self.workers,
                               "tasks": len(self.results), "retried": self.retried}
        if self.engine.kind == "scheduler":
            out["address"] = self.address
        return out


def run_tasks(
    fn: Callable[[Any], Any],
    tasks: Sequence[Any],
    engine: Engine = Engine(),
    *,
    progress: bool = True,
    desc: str = "tasks",
    unit: str = "task",
    done: int = 0,
    on_result: Optional[Callable[[int, Any], None]] = None,
    client: Any = None,
) -> TaskRun:
    """Run ``fn(task)`` for every task on ``engine``; return the results in task order.

    ``fn`` must be a module-level function (it is pickled by reference) and every task
    independent of the others.  ``on_result(index, result)`` is called in this process
    as each task finishes (completion order).  The tqdm bar counts ``done`` tasks
    finished before this job (a resumed one) out of ``done + len(tasks)``.  ``client``:
    an existing ``distributed.Client`` to use instead of the engine's own.  A task's
    exception is raised here; a job Dask gives up on (a task whose workers kept dying)
    raises :class:`EngineError`.
    """
    from tqdm import tqdm

    bar = tqdm(total=done + len(tasks), initial=done, desc=desc, unit=unit, disable=not progress)
    results: list = [None] * len(tasks)

    def finish(index: int, result: Any) -> None:
        results[index] = result
        if on_result is not None:
            on_result(index, result)
        bar.update(1)

    try:
        if not tasks:
            return TaskRun(results, engine, engine.workers)
        if engine.dask or client is not None:
            with quiet_teardown() as quieten:
                return _run_dask(fn, tasks, engine, finish, results, client, quieten)
        return _run_local(fn, tasks, engine, finish, results)
    finally:
        bar.close()


def _run_local(fn: Callable, tasks: Sequence, engine: Engine, finish: Callable, results: list) -> TaskRun:
    if engine.workers == 1:
        for index, task in enumerate(tasks):
            finish(index, fn(task))
        return TaskRun(results, engine, 1)
    workers = min(engine.workers, len(tasks))
    # fork: the workers start at once with this process's modules (the research layer is pure Python), every
    # one at the first submit.  They are forked with Ctrl-C held (a Ctrl-C then reaches this process when the
    # mask is restored), and take it up once their handler is in place (_local_worker_start).
    task_fn = LocalTask(fn)
    held = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    pool = ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("fork"), initializer=_local_worker_start)
    try:
        try:
            pending = {pool.submit(task_fn, tasks[0]): 0}
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, held)
        pending.update((pool.submit(task_fn, task), index) for index, task in enumerate(tasks) if index)
        while pending:
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in finished:
                finish(pending.pop(future), future.result())
    except BrokenProcessPool:
        raise EngineError(f"a worker process of --jobs {engine.workers} died (killed or out of memory); "
                          "results finished so far are kept where the tool keeps them") from None
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    return TaskRun(results, engine, workers)


#: The loggers of Dask's and tornado's background threads, quietened while a failed or interrupted job is torn down.
DASK_LOGGERS = ("distributed", "tornado")


class _ClosedComms(logging.Filter):
    """Drops tornado's "Exception in callback" records of a Dask connection that closed (the job's own end says why)."""

    def filter(self, record: logging.LogRecord) -> bool:
        error = record.exc_info[1] if record.exc_info else None
        return type(error).__name__ not in ("CommClosedError", "StreamClosedError")


@contextmanager
def quiet_teardown() -> Iterator[Callable[[], None]]:
    """Yield ``quieten()``: after it, Dask's and tornado's loggers say nothing until the block ends.

    A job that stops early (Ctrl-C, which also stops the LocalCluster's processes, or a
    task's error) tears down a client whose scheduler may already be gone: its background
    thread then logs ``CommClosedError`` tracebacks ("Exception in callback ...") that are
    not the user's error; the tool's own one line says what happened.  Their levels (the
    loggers' own, as Dask configures them) are restored when the block ends.  For the whole
    block, tornado's traceback of a closed Dask connection is dropped even before
    ``quieten()`` (its thread can log before the interrupted thread gets there); Dask
    reschedules what such a connection carried, or the job fails with its own error.
    """
    saved: dict[str, int] = {}
    closed, callbacks = _ClosedComms(), logging.getLogger("tornado.application")
    callbacks.addFilter(closed)

    def quieten() -> None:
        names = [n for n in logging.root.manager.loggerDict if n.split(".")[0] in DASK_LOGGERS]
        for name in [*DASK_LOGGERS, *names]:
            logger = logging.getLogger(name)
            saved.setdefault(name, logger.level)
            logger.setLevel(logging.CRITICAL + 1)

    try:
        yield quieten
    finally:
        callbacks.removeFilter(closed)
        for name, level in saved.items():
            logging.getLogger(name).setLevel(level)


@contextmanager
def dask_client(engine: Engine) -> Iterator[Any]:
    """Yield a ``distributed.Client`` on the engine's cluster (a LocalCluster is started and stopped here).

    A LocalCluster binds 127.0.0.1 only: scheduler, workers and nannies on free ports
    (port 0), the scheduler's HTTP endpoint too (``127.0.0.1:0``), one thread per worker
    process.  A scheduler that does not answer within :data:`CONNECT_TIMEOUT` seconds
    raises :class:`EngineError`.
    """
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise EngineError("a Dask engine needs dask.distributed: pip install 'fsreg_ros[cluster]' "
                          "(or the pinned version in requirements.txt)") from None
    if engine.kind == "cluster":
        cluster = LocalCluster(n_workers=engine.workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                               scheduler_port=0, dashboard_address="127.0.0.1:0", worker_dashboard_address=None,
                               silence_logs=logging.ERROR, preload=[__name__])
        try:
            with Client(cluster) as client:
                yield client
        finally:
            cluster.close()
        return
    try:
        client = Client(engine.address, timeout=CONNECT_TIMEOUT)
    except (OSError, TimeoutError) as err:
        first = str(err).splitlines()[0] if str(err) else type(err).__name__
        raise EngineError(f"--scheduler {engine.address}: cannot connect ({first})") from None
    with client:
        yield client


def _run_dask(fn: Callable, tasks: Sequence, engine: Engine, finish: Callable, results: list,
              client: Any = None, quieten: Callable[[], None] = lambda: None) -> TaskRun:
    if client is None:
        with dask_client(engine) as own:
            return _run_dask(fn, tasks, engine, finish, results, own, quieten)
    from distributed import as_completed

    # Keys of our own (a shared scheduler may run other jobs); pure=False: every task runs.
    prefix = f"{getattr(fn, '__name__', 'task')}-{uuid.uuid4().hex[:12]}"
    keys = [f"{prefix}-{i}" for i in range(len(tasks))]
    index_of = {key: i for i, key in enumerate(keys)}
    workers = len(client.scheduler_info(n_workers=-1).get("workers", {}))
    futures = client.map(SameCode(fn, code_fingerprint()), tasks, key=keys, pure=False)
    try:
        for future, result in as_completed(futures, with_results=True, raise_errors=False):
            if future.status == "error":
                _raise_task_error(future)
            finish(index_of[future.key], result)
            future.release()
    except BaseException:  # interrupted or failed: tearing down a cluster already stopping is not the user's error
        quieten()
        raise
    finally:
        client.cancel([f for f in futures if not f.done()])
    attempts = retried_tasks(client, index_of)
    return TaskRun(results, engine, workers, len(attempts), client.scheduler.address, attempts)


def _raise_task_error(future: Any) -> None:
    from distributed.scheduler import KilledWorker

    error = future.exception()
    if isinstance(error, KilledWorker):
        raise EngineError(f"Dask gave up on a task after its workers died {error.allowed_failures + 1} times "
                          "(distributed.scheduler.allowed-failures); is it running out of memory?") from None
    raise error


def retried_tasks(client: Any, index_of: dict) -> dict:
    """Return task index -> how often Dask rescheduled it because its worker was lost (``remove-worker`` events).

    A task counts when it was processing on, or finished and held by, a worker that died.
    """
    attempts: dict[int, int] = {}
    for _, event in client.get_events("all"):
        if not isinstance(event, dict) or event.get("action") != "remove-worker":
            continue
        lost = set(event.get("processing-tasks", ())) | set(event.get("lost-computed-tasks", ()))
        for key in lost:
            if key in index_of:
                attempts[index_of[key]] = attempts.get(index_of[key], 0) + 1
    return attempts
