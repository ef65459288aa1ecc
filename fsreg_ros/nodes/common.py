"""What every fsreg node shares: the main runner, parameter helpers, error replies.

``main()`` of each node is ``return run_node(NodeClass, args, ...)``:

* ``rclpy.init(args)`` (so ``--ros-args --params-file F -p x:=y`` work as usual);
* a warning if ``ROS_AUTOMATIC_DISCOVERY_RANGE`` is not ``LOCALHOST`` (the project's
  scripts set it; a node does not refuse to run on a real robot network);
* the node is built; a startup problem (:class:`StartupError`, a bad parameter, or
  one of ``startup_errors``) is logged as one error line and the process exits 2,
  without a traceback;
* a ``SingleThreadedExecutor`` spins it (every node's handlers are async-correct:
  clients live in their own reentrant groups, nothing spins inside a callback); an
  exception escaping a callback is logged as an error and the node keeps running;
* Ctrl-C / SIGTERM (``KeyboardInterrupt``, ``ExternalShutdownException``) end it
  cleanly with exit code 0; the node is destroyed and rclpy shut down.

A node with a ``job`` (the dialogue player) runs ``job(node)`` as a task and exits
when it is done: ``on_done(node, result)`` then exit 0, or exit 1 after logging a
``job_errors`` failure in one line.
"""

from __future__ import annotations

import os
import sys
import traceback
from typing import Any, Awaitable, Callable, Iterable, Optional, Sequence

import rclpy
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.exceptions import ParameterException
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor

from ..carrier import MessageError, parse

#: Exit codes.
EXIT_OK, EXIT_FAILED, EXIT_STARTUP = 0, 1, 2


class StartupError(Exception):
    """The node cannot start (bad configuration); the message says why, in one line."""


# ------------------------------------------------------------------ environment
def check_discovery_range(logger) -> bool:
    """Warn unless DDS discovery is limited to this machine; True when it is."""
    value = os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE")
    if value != "LOCALHOST":
        logger.warning(
            f"ROS_AUTOMATIC_DISCOVERY_RANGE is {value!r}, not 'LOCALHOST': discovery may "
            "reach other machines (scripts/rosenv.sh sets it)"
        )
        return False
    return True


def now_seconds(node) -> float:
    """The node's clock in seconds (sim time when ``use_sim_time`` is set)."""
    return node.get_clock().now().nanoseconds / 1e9


# ------------------------------------------------------------------ parameters
def descriptor(
    description: str,
    *,
    read_only: bool = False,
    dynamic_typing: bool = False,
    additional_constraints: str = "",
) -> ParameterDescriptor:
    """A ParameterDescriptor with the fields fsreg uses."""
    return ParameterDescriptor(
        description=description,
        read_only=read_only,
        dynamic_typing=dynamic_typing,
        additional_constraints=additional_constraints,
    )


def accepted() -> SetParametersResult:
    return SetParametersResult(successful=True)


def rejected(reason: str) -> SetParametersResult:
    return SetParametersResult(successful=False, reason=reason)


def number_value(param, *, name: Optional[str] = None) -> float:
    """The value of an INTEGER or DOUBLE parameter as float; ValueError otherwise.

    Number parameters are declared with ``dynamic_typing`` so ``-p x:=10`` and a YAML
    ``x: 10`` work as well as ``10.0``; this is where the type is enforced instead.
    """
    value = param.value
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"'{name or param.name}' must be a number, got {value!r}")
    return float(value)


def would_be(node, params: Iterable, names: Sequence[str]) -> dict[str, Any]:
    """Values of ``names`` as they would be after setting ``params`` (current otherwise)."""
    values = {name: node.get_parameter(name).value for name in names}
    for param in params:
        if param.name in values:
            values[param.name] = param.value
    return values


# ------------------------------------------------------------------ replies
def error_reply(source: Any, error: str) -> dict:
    """``{"error": error}`` plus the ``id`` of ``source`` (a String message, JSON text or
    a dict) when it has one, so a requester can match the error to its request."""
    reply: dict[str, Any] = {"error": error}
    data = source
    if not isinstance(data, dict):
        try:
            data = parse(getattr(source, "data", source))
        except MessageError:
            data = {}
    if "id" in data:
        reply["id"] = data["id"]
    return reply


# ------------------------------------------------------------------ runner
def spin(executor, logger, until: Optional[Callable[[], bool]] = None) -> None:
    """``executor.spin()`` that survives a failing callback.

    rclpy re-raises an exception escaping a callback (or an async callback's task)
    out of ``spin_once``, which would end the process.  A node must never crash on
    one bad message: log the error and keep serving.  Shutdown still ends the loop.
    """
    while executor.context.ok() and not (until is not None and until()):
        try:
            executor.spin_once()
        except (KeyboardInterrupt, ExternalShutdownException):
            raise
        except Exception as err:  # noqa: BLE001 - see above
            logger.error(f"a callback failed: {type(err).__name__}: {err}")
            logger.debug("".join(traceback.format_exception(err)))


def _node_name(node_cls) -> str:
    return getattr(node_cls, "NODE_NAME", None) or node_cls.__name__


def run_node(
    node_cls: Callable[..., Any],
    args: Optional[list[str]] = None,
    *,
    startup_errors: tuple[type[BaseException], ...] = (),
    job: Optional[Callable[[Any], Awaitable[Any]]] = None,
    on_done: Optional[Callable[[Any, Any], None]] = None,
    job_errors: tuple[type[BaseException], ...] = (),
) -> int:
    """Run one node until Ctrl-C / shutdown (or until its ``job`` is done); exit code."""
    logger = rclpy.logging.get_logger(_node_name(node_cls))
    try:
        rclpy.init(args=args)
    except Exception as err:  # noqa: BLE001 - e.g. a bad --ros-args or params file
        print(f"{_node_name(node_cls)}: cannot initialise ROS: {err}", file=sys.stderr)
        return EXIT_STARTUP
    check_discovery_range(logger)
    node = None
    executor = None
    code = EXIT_OK
    try:
        try:
            node = node_cls()
        except (StartupError, ParameterException, *startup_errors) as err:
            logger.error(f"cannot start: {err}")
            return EXIT_STARTUP
        logger = node.get_logger()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        if job is None:
            spin(executor, logger)
        else:
            # The executor re-raises a failed task's exception from spin; catch it inside.
            async def guarded() -> tuple[bool, Any]:
                try:
                    return True, await job(node)
                except Exception as err:  # noqa: BLE001 - reported below
                    return False, err

            task = executor.create_task(guarded())
            task.add_done_callback(lambda _: executor.wake())
            spin(executor, logger, until=task.done)
            if not task.done():  # shut down before the job finished
                return EXIT_OK
            ok, result = task.result()
            if not ok:
                if isinstance(result, job_errors):
                    logger.error(str(result))
                else:  # report, without dumping a traceback on users (debug level has it)
                    logger.error(f"failed: {type(result).__name__}: {result}")
                    logger.debug("".join(traceback.format_exception(result)))
                return EXIT_FAILED
            if on_done is not None:
                on_done(node, result)
    except (KeyboardInterrupt, ExternalShutdownException):
        code = EXIT_OK
    finally:
        if executor is not None:
            executor.shutdown(timeout_sec=1.0)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return code
