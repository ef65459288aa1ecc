"""Recording a live graph as a rosbag2 folder: the subscriptions (this module) over the bag writer (core).

:class:`Recorder` subscribes, on a node of its own in the given node's context, to every
topic of the node's graph (:func:`fsreg_ros.contract.graph_topics`: the dialogue in and out,
RR results, REG requests and expressions, ``ltm/assert`` and its results, ``wm/state``,
``wm/events``, the consultants' announcements, ``wm_manager/ready`` and the graph's clock),
each with the contract's reader QoS made deeper (:data:`RECORD_DEPTH`: a recorder behind by
a burst must not lose it), and writes each message's CDR bytes as they came off the wire (a
*raw* subscription: nothing is decoded or re-encoded) with their DDS receive time (wall
clock, ns), through :class:`fsreg_ros.core.io.recording.BagWriter`, which owns the format.
Nothing is called back per message: a thread of the recorder, at a lower priority than the
graph (:data:`NICE`), drains the readers every :data:`POLL` seconds.  The namespace is the
node's; the clock topic is ``/clock`` as the node resolves it (remapped into a namespaced
graph).

Used by ``fsreg-ctl record`` (which also lowers its whole process: :func:`lower_priority`)
and ``fsreg-up --record`` (on their own node) and by ``fsreg-graph --record``
(:class:`RecorderThread`: a node and context of its own while the graph's processes run).
:func:`graph_knowledge` asks a running graph which knowledge base, lexicon and REG options
it runs with, so a recording made by ``fsreg-ctl record`` carries what a replay needs.
"""

from __future__ import annotations

import json
import os
import threading
import time
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Optional

from rosgraph_msgs.msg import Clock as ClockMsg
from std_msgs.msg import String

from .. import contract
from ..contract import QosSpec
from ..core.io.recording import SEGMENT_SECONDS, TOPICS_KEY, BagWriter, Channel, RecordingError
from .carrier import qos_profile
from .rclpy_internals import take_message
from .recorders import RECORDER_MATCH_WAIT, SUFFIX

#: Reader depth of every recorded topic at least (the contract's writers keep 1 to 10,000): the readers hold
#: what arrived until the drain thread takes it, so a recorder starved of CPU this long does not lose a
#: message (``wm/events`` at ~700 messages/s in the soak: 14 s).
RECORD_DEPTH = 10_000
#: Seconds between two drains of the readers (and checks whether the open segment is due to close).
POLL = 0.05
#: How much lower the recorder runs than the graph (added to the nice value of its thread, or of its whole
#: process for ``fsreg-ctl record``): a recorder must not take the robot's CPU when both want it.
NICE = 10
#: The role each contract topic has in a recording (:data:`fsreg_ros.core.io.recording.ROLES`); ``/clock``: ``clock``.
ROLE_OF = {contract.HUMAN.name: "human", contract.SEMANTICS.name: "semantics", contract.RR_RESULT.name: "rr",
           contract.REG_REQUEST.name: "request", contract.REG_EXPRESSION.name: "expression",
           contract.WM_STATE.name: "state", contract.WM_EVENTS.name: "events", contract.ANNOUNCE.name: "announce",
           contract.READY.name: "ready", contract.LTM_ASSERT.name: "assert",
           contract.LTM_ASSERT_RESULT.name: "assert_result"}


def channels(namespace: str = "", clock: Optional[str] = None) -> list[tuple[contract.GraphTopic, Channel]]:
    """Return every recorded topic of a graph with the bag channel it is written to (its writers' QoS)."""
    return [(t, Channel(t.name, t.msgtype, t.qos.depth, t.qos.latched, t.qos.lease))
            for t in contract.graph_topics(namespace, clock)]


def lower_priority(nice: int, threads: Optional[Iterable[int]] = None) -> int:
    """Add ``nice`` to the nice value of ``threads`` (native ids; None: every thread of this process); return how many.

    Linux keeps a nice value per thread (``os.nice`` changes the calling thread's only), so
    a whole process -- its DDS threads included -- is lowered thread by thread.  Raising
    one's own nice value needs no privilege; a thread that cannot be changed is left as it is.
    """
    if nice <= 0 or not hasattr(os, "setpriority"):
        return 0
    if threads is None:
        try:
            threads = [int(t) for t in os.listdir("/proc/self/task")]
        except OSError:
            threads = [threading.get_native_id()]
    done = 0
    for tid in threads:
        try:
            os.setpriority(os.PRIO_PROCESS, tid, min(19, os.getpriority(os.PRIO_PROCESS, tid) + nice))
            done += 1
        except OSError:
            pass
    return done


class Recorder:
    """Record every fsreg topic of ``node``'s graph to a new rosbag2 folder ``path`` (see the module docstring).

    ``custom``: ``custom_data`` entries (strings, ``fsreg.`` keys); ``attach``: files to copy
    into the recording (key -> path), e.g. the knowledge base a replay needs.  Call
    :meth:`close` once at the end (a recording that is never closed keeps its closed
    segments: :mod:`fsreg_ros.core.io.recording`).

    The readers live on a node of their own that no executor spins: DDS fills their
    histories (:data:`RECORD_DEPTH` deep) in its own threads, and one thread of this
    object, ``nice`` lower than the caller (:func:`lower_priority`), takes whatever
    arrived every :data:`POLL` seconds and writes it with its DDS receive time.  So
    recording costs no executor wake-up and no callback per message (measured: ~280 us
    of CPU per message that way, in a process competing with the graph for its cores).
    """

    def __init__(self, node, path: Path, *, segment_seconds: float = SEGMENT_SECONDS,
                 custom: Optional[Mapping[str, str]] = None, attach: Optional[Mapping[str, Path]] = None,
                 nice: int = NICE) -> None:
        import rclpy

        self.node = node
        clock = node.resolve_topic_name(contract.CLOCK)
        pairs = channels(node.get_namespace(), clock)
        roles = {t.name: ROLE_OF[t.topic.name] if t.topic is not None else "clock" for t, _ in pairs}
        self.bag = BagWriter(Path(path), [c for _, c in pairs], segment_seconds=segment_seconds,
                             custom={**{k: str(v) for k, v in (custom or {}).items()},
                                     TOPICS_KEY: json.dumps(roles, sort_keys=True)})
        for key, source in (attach or {}).items():
            self.bag.attach(key, Path(source))  # a failure here is the caller's (nothing recorded yet)
        self.topics = [t for t, _ in pairs]
        # Names are absolute (the graph's namespace and clock resolved above): the readers' node needs no remap.
        self._readers = rclpy.create_node(f"{node.get_name()}{SUFFIX}", context=node.context,
                                          start_parameter_services=False, enable_rosout=False)
        self.subscriptions = []
        for topic in self.topics:
            reader = QosSpec(max(topic.reader_qos.depth, RECORD_DEPTH), latched=topic.reader_qos.latched)
            kind = ClockMsg if topic.msgtype == contract.CLOCK_TYPE else String
            self.subscriptions.append(self._readers.create_subscription(
                kind, topic.name, _never_called, qos_profile(reader), raw=True))
        self.closed = False
        self.error: Optional[BaseException] = None  # what stopped the drain thread (writing failed), if anything
        self._lock = threading.Lock()  # the bag: the drain thread's, and close()'s
        self._stop = threading.Event()
        self._nice = nice
        self._thread = threading.Thread(target=self._run, name="fsreg-recorder", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        lower_priority(self._nice, [threading.get_native_id()])
        while not self._stop.wait(POLL):
            with self._lock:
                if self.closed:
                    return
                try:
                    self.drain()
                    self.bag.poll()
                except Exception as err:  # noqa: BLE001 - e.g. a full disk: kept for the owner to report
                    self.error = err
                    return

    def drain(self) -> int:
        """Write every message waiting in any recorded topic's reader, in receive-time order; return how many."""
        taken: list[tuple[int, int, str, bytes]] = []
        for order, (topic, sub) in enumerate(zip(self.topics, self.subscriptions)):
            name = topic.name
            while True:
                message = take_message(sub, raw=True)
                if message is None:
                    break
                raw, info = message
                taken.append((info.get("received_timestamp") or time.time_ns(), order, name, raw))
        taken.sort(key=lambda m: (m[0], m[1]))
        write = self.bag.write
        for stamp, _, name, raw in taken:
            write(name, stamp, raw)
        return len(taken)

    def matched(self) -> dict[str, int]:
        """Return each recorded topic's number of matched writers now."""
        return {t.name: s.get_publisher_count() for t, s in zip(self.topics, self.subscriptions)}

    def unmatched(self, writers: Optional[Mapping[str, int]] = None) -> list[str]:
        """Return the recorded topics with a writer in the graph that no reader of the recording has matched yet.

        A latched topic's reader matched late gets only the writer's *latest* sample: a
        recording that starts with the graph waits for this list to empty
        (:meth:`wait_matched`) before the graph is called ready, so the first samples (e.g.
        each consultant's initial ``wm/state``) are in the bag.  ``writers``: how many
        writers some topics must have (contract names, e.g. ``{contract.WM_STATE.name: 2}``), for a
        recorder that cannot know the graph has been discovered (its own participant).
        """
        count = self._readers.count_publishers
        wanted = {t.name: (writers or {}).get(t.topic.name, 0) if t.topic is not None else 0 for t in self.topics}
        return [t.name for t, s in zip(self.topics, self.subscriptions)
                if s.get_publisher_count() < max(count(t.name), wanted[t.name])]

    def wait_matched(self, timeout: float = RECORDER_MATCH_WAIT, writers: Optional[Mapping[str, int]] = None,
                     between: Optional[Callable[[], None]] = None) -> Optional[str]:
        """Wait until :meth:`unmatched` is empty, at most ``timeout`` s; return None, or one warning line.

        ``between`` runs between two looks (it may raise, e.g. for a node that died), else
        :data:`POLL` s pass.  The line names the topics still unmatched.
        """
        deadline = time.monotonic() + timeout
        while (missing := self.unmatched(writers)) and time.monotonic() < deadline:
            between() if between is not None else time.sleep(POLL)
        if not missing:
            return None
        return (f"not yet matched on {', '.join(missing)} after {timeout:g} s; their first messages may be missing "
                "from the recording")

    @property
    def counts(self) -> dict[str, int]:
        """Messages written so far, per topic."""
        with self._lock:
            return dict(self.bag.counts)

    def attach(self, key: str, source: Path) -> None:
        """Copy ``source`` into the recording (:meth:`BagWriter.attach`); a write that fails stops the recording."""
        with self._lock:
            try:
                self.bag.attach(key, source)
            except RecordingError as err:
                self.error = self.error or err
                self._stop.set()

    def close(self) -> Path:
        """Stop recording and close the bag (its segments merged into one ``.mcap``); return its folder.

        Never raises for a disk that refuses: :attr:`error` says why, and what was closed
        before stays readable (a recording cut short).
        """
        if self.closed:
            return self.bag.path
        self._stop.set()
        self._thread.join(timeout=10.0)
        with self._lock:
            if self.error is None:
                try:
                    self.drain()
                except RecordingError as err:
                    self.error = err
            self.closed = True
            for sub in self.subscriptions:
                self._readers.destroy_subscription(sub)
            self._readers.destroy_node()
            try:
                return self.bag.close()
            except RecordingError as err:
                self.error = self.error or err
                return self.bag.path

    def summary(self) -> str:
        """Return one line: how many messages on how many topics went where."""
        counts = self.bag.counts
        busy = sum(1 for n in counts.values() if n)
        return f"{sum(counts.values())} messages on {busy} of {len(counts)} topics to {self.bag.path}"


def _never_called(_message) -> None:  # the readers' node is never spun: the drain thread takes their messages
    raise AssertionError("a recorder's reader is drained, never called back")


class RecorderThread:
    """A :class:`Recorder` on a node and ROS context of its own (``fsreg-graph --record``).

    ``namespace`` and ``clock`` (None: the graph's own, as the nodes get it) say which
    graph; set the ROS environment before building one.  The recorder's own thread does
    the work (nothing here is spun).
    """

    def __init__(self, path: Path, namespace: str = "", clock: Optional[str] = None, **recorder: Any) -> None:
        import rclpy
        from rclpy.signals import SignalHandlerOptions

        self.context = rclpy.Context()
        rclpy.init(context=self.context, signal_handler_options=SignalHandlerOptions.NO)
        remaps = ["-r", f"__ns:={namespace}"] if namespace else []
        remaps += _clock_remap(namespace, clock)
        self.node = rclpy.create_node("fsreg_recorder", context=self.context,
                                      cli_args=["--ros-args", *remaps] if remaps else None)
        try:
            self.recorder = Recorder(self.node, path, **recorder)
        except BaseException:
            self._shutdown()
            raise

    def close(self) -> Path:
        """Close the bag, end the node; return the recording's folder."""
        try:
            return self.recorder.close()
        finally:
            self._shutdown()

    def _shutdown(self) -> None:
        import rclpy

        self.node.destroy_node()
        rclpy.try_shutdown(context=self.context)


def _clock_remap(namespace: str, clock: Optional[str]) -> list[str]:
    if clock is None:
        return contract.clock_remap(namespace)
    return [] if clock == contract.CLOCK else ["-r", f"{contract.CLOCK}:={clock}"]


def graph_knowledge(client, timeout: float) -> tuple[dict[str, str], dict[str, Path]]:
    """Ask a running graph what it runs with: (custom data, files to attach).

    The parser's ``kb`` and ``lexicon`` (attached when readable here), REG's ``algorithm``
    and ``wm_order``, the graph identity.  What cannot be asked is left out (a replay
    then needs ``--scenario``).
    """
    custom: dict[str, str] = {}
    attach: dict[str, Path] = {}
    if client.graph:
        custom["fsreg.graph"] = client.graph
    values = {**_parameters(client, "parser", ("kb", "lexicon"), timeout),
              **_parameters(client, "reg", ("algorithm", "wm_order"), timeout)}
    for key in ("algorithm", "wm_order"):
        if values.get(key):
            custom[f"fsreg.{key}"] = str(values[key])
    for key, name in (("kb", "scenario"), ("lexicon", "lexicon")):
        path = Path(values[key]) if values.get(key) else None
        if path is not None and path.is_file():
            attach[name] = path
        elif path is not None:
            custom[f"fsreg.{name}_path"] = str(path)  # named, not readable here
    return custom, attach


def _parameters(client, node_name: str, names: tuple[str, ...], timeout: float) -> dict[str, Any]:
    """Return parameters of a graph node (those it has); {} if it does not answer in ``timeout``."""
    from rcl_interfaces.msg import ParameterType
    from rcl_interfaces.srv import GetParameters

    service = client.node.create_client(GetParameters, f"{node_name}/get_parameters")
    try:
        deadline = time.monotonic() + timeout
        while not service.service_is_ready():
            if time.monotonic() > deadline:
                return {}
            client.executor.spin_once(timeout_sec=0.05)
        future = service.call_async(GetParameters.Request(names=list(names)))
        while not future.done():
            if time.monotonic() > deadline:
                service.remove_pending_request(future)
                return {}
            client.executor.spin_once(timeout_sec=0.05)
        out: dict[str, Any] = {}
        for name, value in zip(names, future.result().values):
            if value.type == ParameterType.PARAMETER_STRING:
                out[name] = value.string_value
        return out
    finally:
        client.node.destroy_client(service)
