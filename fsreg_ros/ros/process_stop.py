"""How a node process stops on SIGINT and SIGTERM: once, quietly, within :data:`STOP_DEADLINE` seconds.

:class:`StopSignals` is installed by :func:`fsreg_ros.ros.node_base.run_node` before
``rclpy.init``, whose own signal handler (installed for SIGINT and SIGTERM) shuts the
ROS context down and then chains to it.  So the executor leaves ``spin`` and the node
is destroyed; this handler only notes the first signal and never raises:

* a second or third signal (a terminal's Ctrl-C reaches every process of the group and
  ``ros2 launch`` forwards its own SIGINT a few ms later, or escalates to SIGTERM) is
  ignored: raising ``KeyboardInterrupt`` there interrupted ``destroy_node`` with a
  traceback and exit code -2;
* it takes no lock: ``rclpy.try_shutdown`` from a signal handler can deadlock on the
  context's lock when the signal lands inside ``Context.ok()``.  A helper thread shuts ROS
  down :data:`SHUTDOWN_AFTER` seconds later if rclpy's handler has not (a process that
  initialised rclpy again after a shutdown, or a signal before ``rclpy.init`` ended);
* none can hang: the first signal arms a watchdog thread that ends the process with
  exit code 0 (and one line on stderr) if it is still running :data:`STOP_DEADLINE`
  seconds later (a callback that never returns).  That thread needs the interpreter, which C
  code can hold for good: a DDS deadlock inside rcl while a node is destroyed (Fast DDS 2.14's
  discovery against a peer leaving, eProsima/Fast-DDS#6502, seen under ``ros2 run``).  So the
  first signal also arms :mod:`faulthandler`'s watchdog, which needs no interpreter: a process
  still running :data:`HELD_AFTER` seconds after that deadline is ended with exit code 1 and
  every thread's stack on stderr;
* a signal before ROS is initialised is remembered (:attr:`StopSignals.heard`): the
  runner then stops instead of starting;
* once a signal has been heard, :meth:`StopSignals.restore` (the run is over) leaves SIGINT and SIGTERM
  ignored while the process exits (a late one must neither raise in the interpreter's
  shutdown nor kill it with -15); otherwise it puts the previous handlers back.
"""

from __future__ import annotations

import atexit
import faulthandler
import gc
import os
import signal
import sys
import threading
from typing import Any, Optional

#: Seconds after the first stop signal by which the process has ended (else the watchdog ends it, exit 0).
STOP_DEADLINE = 1.5
#: Seconds after :data:`STOP_DEADLINE` after which faulthandler ends a process whose interpreter is held (exit 1).
HELD_AFTER = 1.5
#: Seconds after the first stop signal after which ROS is shut down by this module if rclpy has not done it.
SHUTDOWN_AFTER = 0.05
#: The signals that stop a node.
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class StopSignals:
    """SIGINT / SIGTERM handling of one node process run (main thread only; else it does nothing)."""

    def __init__(self, name: str, deadline: float = STOP_DEADLINE) -> None:
        self.name = name
        self.deadline = deadline
        self.heard: Optional[int] = None
        self._previous: dict[int, Any] = {}
        self._watchdog: Optional[threading.Timer] = None

    def install(self) -> "StopSignals":
        """Handle SIGINT and SIGTERM from now on (before ``rclpy.init``, which chains to these handlers)."""
        if threading.current_thread() is threading.main_thread():
            for signum in STOP_SIGNALS:
                self._previous[signum] = signal.signal(signum, self._on_signal)
        return self

    def _on_signal(self, signum: int, frame: Any) -> None:
        if self.heard is not None:
            return  # the process is stopping already: a repeated Ctrl-C, launch's own SIGINT, a SIGTERM
        self.heard = signum
        self._watchdog = threading.Timer(self.deadline, self._force_exit)
        self._watchdog.daemon = True
        self._watchdog.start()
        faulthandler.dump_traceback_later(self.deadline + HELD_AFTER, exit=True)  # kept till the process ends
        threading.Thread(target=self._shut_down_ros, name="stop-signal", daemon=True).start()

    def _shut_down_ros(self) -> None:
        """Run by a helper thread: shut ROS down if rclpy's own handler has not (not installed, or stopped)."""
        import rclpy

        threading.Event().wait(SHUTDOWN_AFTER)
        try:
            if rclpy.ok():
                rclpy.try_shutdown()
        except Exception:  # noqa: BLE001 - shut down meanwhile by rclpy's handler or the runner: nothing to do
            pass

    def _force_exit(self) -> None:
        """Run by the watchdog thread: the process did not end within the deadline; end it now, exit 0."""
        name = signal.Signals(self.heard).name if self.heard is not None else "a signal"
        line = f"[{self.name}]: still stopping {self.deadline:g} s after {name} (a callback that does not return?): " \
               "exiting now\n"
        try:
            os.write(2, line.encode(errors="replace"))
        finally:
            os._exit(0)

    def restore(self, code: int = 0) -> None:
        """End the run's signal handling; ``code`` is the exit code the run returns.

        Without a stop signal the previous handlers are put back.  After one, SIGINT and
        SIGTERM stay ignored, and the process's exit is made short (:meth:`_finish`, the
        last ``atexit`` handler registered, so the first to run).
        """
        if self._watchdog is not None:
            self._watchdog.cancel()
        for signum, previous in self._previous.items():
            signal.signal(signum, signal.SIG_IGN if self.heard is not None else previous)
        self._previous.clear()
        if self.heard is not None:
            atexit.register(self._finish, code)

    @staticmethod
    def _finish(code: int) -> None:
        """End a stopped process at its exit: delete what is left of ROS, flush, and exit with ``code``.

        The interpreter's own finalisation after a stopped node (module teardown, then the
        static destructors of Fast DDS) took 0.3-2.5 s on a loaded machine, past the 2 s a
        node has to stop.  A garbage collection deletes the ROS context left behind and with
        it the DDS participant (its peers see it leave; no shared-memory file stays), then
        the process ends without the rest.
        """
        gc.collect()
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except Exception:  # noqa: BLE001 - a closed stream: nothing to flush
                pass
        os._exit(code)
