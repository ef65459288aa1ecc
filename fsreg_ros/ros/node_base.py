"""What every fsreg node shares: the main runner, parameter helpers, the clock watchdog.

``main()`` of each node is ``return run_node(NodeClass, args, ...)``:

* the network policy of :mod:`fsreg_ros.ros.network`, applied to the process's own
  environment before ROS starts (:func:`~fsreg_ros.ros.network.enforce_loopback`): DDS stays on
  this machine (``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` and the loopback profile) however
  the node was started (``ros2 run``, the launch file, a runner), and an environment that would
  widen it is refused with one line and exit 2, unless ``FSREG_ALLOW_NETWORK=1``;
* ``rclpy.init(args)`` (so ``--ros-args --params-file F -p x:=y -r __ns:=/robot1`` work as usual);
* the node is built; any problem while building it (a missing or out-of-range
  parameter, an unreadable file, ...) is logged as one error line and the process
  exits 2, without a traceback;
* a ``SingleThreadedExecutor`` spins it.  Callbacks do not fail the process because the
  wrappers that install them (:func:`fsreg_ros.ros.serving.serve`, :func:`~fsreg_ros.ros.carrier.subscribe`)
  log each failure with its topic or service and request id and answer it; spinning
  itself swallows nothing;
* Ctrl-C / SIGTERM (rclpy's signal handler shuts ROS down: ``ExternalShutdownException``)
  end it cleanly with exit code 0; the node is destroyed and rclpy shut down.  Any number
  of further signals is ignored and the process ends within 1.5 s
  (:mod:`fsreg_ros.ros.process_stop`).

A node with a ``job`` (the dialogue player) runs ``job(node)`` as a task and exits
when it is done: ``on_done(node, result)`` then exit 0, or exit 1 after logging a
``job_errors`` failure in one line.

Numeric parameters are declared with :func:`declare_number`: statically typed (a type
change or NOT_SET is refused by rclpy) with a ``floating_point_range`` /
``integer_range`` that ``ros2 param describe`` shows and rclpy enforces.
"""

from __future__ import annotations

import inspect
import os
import sys
import traceback
import weakref
from dataclasses import dataclass
from typing import Any, Awaitable, Callable, Optional

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult
from rclpy.clock import Clock, ClockType
from rclpy.exceptions import InvalidParameterTypeException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.parameter import Parameter

from ..contract.codec import id_of, printable
from ..contract import CLOCK
from .diagnostics import Diagnostics
from .network import NetworkRefused, enforce_loopback
from .process_stop import StopSignals
from . import rclpy_internals
from .sim_clock import follow_clock, now_ns

#: Exit codes.
EXIT_OK, EXIT_FAILED, EXIT_STARTUP = 0, 1, 2
#: Seconds without ``/clock`` after which a sim-time node warns (once).
CLOCK_SILENCE = 5.0


class StartupError(Exception):
    """The node cannot start (bad configuration); the message says why, in one line."""


# ------------------------------------------------------------------ clock
def now_seconds(node) -> float:
    """Return the node's clock in seconds (sim time when ``use_sim_time`` is set: the latest ``/clock`` received)."""
    return now_ns(node) / 1e9


@dataclass
class ClockGuard:
    """What :func:`guard_clock` did for one node: how many ``/clock`` messages it ignored."""

    ignored: int = 0


_GUARDS: "weakref.WeakKeyDictionary[Any, ClockGuard]" = weakref.WeakKeyDictionary()


def clock_guard(node) -> Optional[ClockGuard]:
    """Return the node's :class:`ClockGuard` (None if its clock is not guarded)."""
    return _GUARDS.get(node)


def guard_clock(node) -> None:
    """Make the node's ``/clock`` subscription survive any ``/clock`` message.

    rclpy's time source turns each message into a ``Time``, which raises for negative
    seconds ("Seconds value must not be negative"); raised out of a callback, that
    would stop the node.  Such a message is ignored (the clock stays where it was) and
    reported as a warning, at most every 10 s.  The guard replaces the node's time
    source's callback, so a clock subscription created later (``use_sim_time`` set at
    run time) is guarded too.
    """
    convert = rclpy_internals.clock_callback(node)
    if convert is None:  # pragma: no cover - every rclpy Node has a time source
        return
    topic = node.resolve_topic_name(CLOCK)
    logger = node.get_logger()
    guard = _GUARDS.setdefault(node, ClockGuard())

    def clock_callback(msg) -> None:
        try:
            convert(msg)
        except (ValueError, OverflowError, TypeError) as err:
            guard.ignored += 1
            stamp = getattr(msg, "clock", None)
            sec, nanosec = getattr(stamp, "sec", "?"), getattr(stamp, "nanosec", "?")
            logger.warning(printable(f"ignored a {topic} message (sec={sec}, nanosec={nanosec}): {err}; "
                                     f"the clock stays at {now_seconds(node):g} s"), throttle_duration_sec=10.0)

    rclpy_internals.set_clock_callback(node, clock_callback)


def watch_clock(node, silence: float = CLOCK_SILENCE):
    """Guard the clock, read it on demand, and warn once if a sim-time node's clock stands still; return the timer.

    The guard is :func:`guard_clock`; the reading :func:`~fsreg_ros.ros.sim_clock.follow_clock`:
    the node does not wake for every ``/clock`` message: it reads the latest one when it
    asks the time (:func:`now_seconds`) and every ``sim_clock.FOLLOW_PERIOD`` seconds.

    The warning comes when the clock has not moved for ``silence`` seconds and names the
    clock topic as this node resolves it (``/clock``, or the namespaced clock a
    remapping gave it).  It re-arms when the clock moves again.  Nothing is watched on
    the wall clock.
    """
    guard_clock(node)
    follow_clock(node)  # the node keeps its timer
    state = {"last": None, "since": None, "warned": False}
    steady = Clock(clock_type=ClockType.STEADY_TIME)
    topic = node.resolve_topic_name(CLOCK)

    def check() -> None:
        if not node.get_parameter("use_sim_time").value:
            return
        now = now_ns(node)
        wall = steady.now().nanoseconds / 1e9
        if now != state["last"]:
            state.update(last=now, since=wall, warned=False)
        elif not state["warned"] and wall - state["since"] >= silence:
            state["warned"] = True
            node.get_logger().warning(
                f"use_sim_time is true but nothing has moved {topic} for {silence:g} s: "
                "timers and decay wait for the clock (start a player or set use_sim_time:=false)"
            )

    return node.create_timer(min(1.0, silence / 3), check, clock=steady)


# ------------------------------------------------------------------ parameters
def descriptor(description: str, *, read_only: bool = False, dynamic_typing: bool = False) -> ParameterDescriptor:
    """Return a ParameterDescriptor for a non-numeric parameter (numbers: :func:`declare_number`)."""
    return ParameterDescriptor(description=description, read_only=read_only, dynamic_typing=dynamic_typing)


def declare_number(
    node,
    name: str,
    default: float,
    low: float,
    high: float,
    description: str,
    *,
    integer: bool = False,
    read_only: bool = False,
) -> Any:
    """Declare a numeric parameter with a range in its descriptor; return its value.

    The type is static (rclpy refuses a type change or NOT_SET); a whole number given
    for a DOUBLE parameter on the command line or in a params file (``-p x:=10``) is
    taken as that number.  A value outside ``[low, high]`` is refused by rclpy, at start
    as a start-up error and later as a failed SetParameters with the range as reason.
    """
    kind = Parameter.Type.INTEGER if integer else Parameter.Type.DOUBLE
    desc = ParameterDescriptor(
        description=f"{description} [{low:g}, {high:g}]", read_only=read_only, type=kind.value
    )
    if integer:
        desc.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=0)]
        return node.declare_parameter(name, int(default), desc).value
    desc.floating_point_range = [FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)]
    try:
        return node.declare_parameter(name, float(default), desc).value
    except InvalidParameterTypeException:
        given = _given_value(node, name, float(default))
        if isinstance(given, bool) or not isinstance(given, int):
            raise
    # A whole number for a DOUBLE parameter (``-p x:=10``): declare it as that number.
    return node.declare_parameter(name, float(given), desc, ignore_override=True).value


def _given_value(node, name: str, default: float) -> Any:
    """Return the value given for ``name`` (override or default), whatever its type.

    Public API only: declare it dynamically typed (which takes any override), read it,
    and undeclare it again, so that the caller can declare it statically typed.
    """
    value = node.declare_parameter(name, default, ParameterDescriptor(dynamic_typing=True)).value
    node.undeclare_parameter(name)
    return value


def accepted() -> SetParametersResult:
    return SetParametersResult(successful=True)


def rejected(reason: str) -> SetParametersResult:
    return SetParametersResult(successful=False, reason=reason)


# ------------------------------------------------------------------ replies
def error_reply(source: Any, error: str) -> dict:
    """Return ``{"error": error}`` plus the usable ``id`` of ``source`` (a String, JSON text or a dict).

    The id lets a requester match the error to its request.
    """
    reply: dict[str, Any] = {"error": printable(error)}
    rid = source.get("id") if isinstance(source, dict) else id_of(source)
    if rid is not None:
        reply["id"] = rid
    return reply


# ------------------------------------------------------------------ runner
def _node_name(node_cls) -> str:
    """Return the default name of a node class: ``NODE_NAME``, else its ``node_name`` argument's default."""
    named = getattr(node_cls, "NODE_NAME", None)
    if named:
        return named
    try:
        default = inspect.signature(node_cls).parameters["node_name"].default
    except (KeyError, TypeError, ValueError):
        default = None
    return default if isinstance(default, str) and default else node_cls.__name__


def run_node(
    node_cls: Callable[..., Any],
    args: Optional[list[str]] = None,
    *,
    job: Optional[Callable[[Any], Awaitable[Any]]] = None,
    on_done: Optional[Callable[[Any, Any], None]] = None,
    job_errors: tuple[type[BaseException], ...] = (),
) -> int:
    """Run one node until Ctrl-C / shutdown (or until its ``job`` is done); return the exit code."""
    logger = rclpy.logging.get_logger(_node_name(node_cls))
    try:
        enforce_loopback(os.environ)  # before ROS reads the environment (docs/deployment.md)
    except NetworkRefused as err:
        print(printable(f"{_node_name(node_cls)}: error: {err}"), file=sys.stderr)
        return EXIT_STARTUP
    stop = StopSignals(_node_name(node_cls)).install()  # before rclpy.init, which chains to it
    code = EXIT_FAILED
    try:
        code = _run(node_cls, args, logger, job, on_done, job_errors, stop)
        return code
    finally:
        stop.restore(code)


def _run(node_cls: Callable[..., Any], args: Optional[list[str]], logger: Any,
         job: Optional[Callable[[Any], Awaitable[Any]]], on_done: Optional[Callable[[Any, Any], None]],
         job_errors: tuple[type[BaseException], ...], stop: StopSignals) -> int:
    """:func:`run_node` once the network is checked and Ctrl-C handled: initialise ROS, run, shut down."""
    early = _init_ros(node_cls, args, stop)
    if early is not None:
        return early
    node = None
    executor = None
    code = EXIT_OK
    try:
        node, failed = _start_node(node_cls, logger)
        if node is None:
            return failed
        logger = node.get_logger()
        diagnostics = Diagnostics(node)  # noqa: F841 - publishes on /diagnostics while the node runs
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        if job is None:
            executor.spin()
        else:
            code = _spin_job(executor, node, job, on_done, job_errors, logger)
    except (KeyboardInterrupt, ExternalShutdownException):
        code = EXIT_OK
    except Exception as err:  # noqa: BLE001 - a callback outside the wrappers failed: stop, in one line
        if not rclpy.ok():  # Ctrl-C or SIGTERM shut ROS down between the executor's check and its wait
            return EXIT_OK
        _log_failure(logger, f"stopped by a failing callback: {type(err).__name__}: {err}", err)
        code = EXIT_FAILED
    finally:
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return code


def _init_ros(node_cls: Callable[..., Any], args: Optional[list[str]], stop: StopSignals) -> Optional[int]:
    """Initialise ROS; return None to go on, or the exit code (a stop heard meanwhile, or ROS refused to start)."""
    try:
        rclpy.init(args=args)
    except Exception as err:  # noqa: BLE001 - e.g. a bad --ros-args or params file
        if stop.heard is not None:  # stopped while initialising
            return EXIT_OK
        print(printable(f"{_node_name(node_cls)}: cannot initialise ROS: {err}"), file=sys.stderr)
        return EXIT_STARTUP
    if stop.heard is not None:  # Ctrl-C or SIGTERM before rclpy's own handler was in place
        rclpy.try_shutdown()
        return EXIT_OK
    return None


def _start_node(node_cls: Callable[..., Any], logger: Any) -> tuple[Any, int]:
    """Build the node: ``(node, EXIT_OK)``, or ``(None, exit code)`` after one line saying why it cannot start."""
    try:
        return node_cls(), EXIT_OK
    except (KeyboardInterrupt, ExternalShutdownException):
        raise
    except Exception as err:  # noqa: BLE001 - any start-up problem: one line, exit 2
        if not rclpy.ok():  # Ctrl-C or SIGTERM while starting: ROS is shut down, nothing to report
            return None, EXIT_OK
        text = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        _log_failure(logger, f"cannot start: {text}", err)
        return None, EXIT_STARTUP


def _spin_job(executor, node, job: Callable[[Any], Awaitable[Any]], on_done: Optional[Callable[[Any, Any], None]],
              job_errors: tuple[type[BaseException], ...], logger: Any) -> int:
    """Spin until the node's ``job`` is done (or ROS shut down); report how it ended; return the exit code."""
    # The executor re-raises a failed task's exception from spin; catch it inside.
    async def guarded() -> tuple[bool, Any]:
        try:
            return True, await job(node)
        except Exception as err:  # noqa: BLE001 - reported below
            return False, err

    task = executor.create_task(guarded())
    task.add_done_callback(lambda _: executor.wake())
    while executor.context.ok() and not task.done():
        executor.spin_once()
    if not task.done():  # shut down before the job finished
        return EXIT_OK
    ok, result = task.result()
    if not ok:
        if isinstance(result, job_errors):
            logger.error(printable(result))
        else:  # report, without dumping a traceback on users (debug level has it)
            _log_failure(logger, f"failed: {type(result).__name__}: {result}", result)
        return EXIT_FAILED
    if on_done is not None:
        on_done(node, result)
    return EXIT_OK


def _log_failure(logger: Any, line: str, err: BaseException) -> None:
    """Log one error line (no traceback for users); the traceback at debug level."""
    logger.error(printable(line))
    logger.debug(printable("".join(traceback.format_exception(err)), 20000))
