"""``dialogue_player``: plays a scenario's dialogue through the graph, on the clock.

For each turn at time T, in file order:

1. call ``wm_manager/sync`` with T: the WM Manager applies every decay tick due at
   or before T in every domain and replies only when each consultant has acknowledged
   (the race-free hand-off: forgetting due at T is in effect before the event);
2. publish ``/clock`` = T (``drive_clock``; a namespaced graph remaps it, see
   :func:`fsreg_ros.contract.clock_remap`), so every sim-time node agrees on the time
   (the WM Manager's timers then find nothing left to do);
3. publish the human turn on ``dialogue/human`` or the robot turn on
   ``reg/request`` and wait for the answer with the same ``id`` on ``rr/result`` or
   ``reg/expression``.  Delivery is at-least-once: with no answer after
   ``retry_after`` seconds the same message is sent again (RR and REG answer a
   repeated id from their cache, so nothing is encoded twice).

The collected records are exactly those of ``fsreg-sim`` (see
:mod:`fsreg_ros.core.simulation.simulator`), written as JSON to ``output`` or printed as a
table.  Encode/forget events heard on ``wm/events`` go to ``trace`` (JSON lines).

Completeness (issue 20): a consultant publishes ``wm/events`` only while its
publisher is matched with a subscriber, so before turn 1 the player waits until every
consultant reports ``event_listeners >= 1`` (its ``info``) and the player's own
subscription is matched with every consultant.  Every event carries ``seq`` (1, 2, 3,
... per consultant incarnation) and ``incarnation``; the player notes each
consultant's last ``seq`` before turn 1 and, after the last turn, checks that it heard
exactly the events that followed, without a gap, from the incarnation it started with
(:class:`~fsreg_ros.ros.event_sources.EventSources`, :class:`~fsreg_ros.ros.event_audit.EventAudit`).
A gap, a restarted consultant, or anything stamped by another graph (``graph``, the
``graph`` parameter of every node; see :func:`fsreg_ros.ros.carrier.graph_identity`) on
an answer or an event fails the run (exit 1) with one line saying what was missing or
foreign: a result is never written from an incomplete event stream.
"""

from __future__ import annotations

import json
import time as wallclock
from typing import Any, Optional

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.task import Future
from rclpy.node import Node
from rosgraph_msgs.msg import Clock

from .. import contract
from ..ros.carrier import (CarrierError, ServiceCaller, drop_timer, graph_identity, publish, publisher, subscribe,
                           wait_until)
from ..ros.client_base import describe_graph
from ..ros.graph_clock import clock_message
from ..core.lexicon import Lexicon
from ..core.scenario import Scenario, Turn, load_scenario
from ..core.simulation.simulator import dumps, human_record, robot_record, trace_order
from ..ros.node_base import declare_number, run_node
from ..ros.event_audit import EventAudit
from ..ros.event_sources import EventSources, PlayerError

PIPELINE_TOPICS = {  # topic -> (needs a subscriber, needs a publisher)
    contract.HUMAN.name: (True, False),
    contract.REG_REQUEST.name: (True, False),
    contract.RR_RESULT.name: (False, True),
    contract.REG_EXPRESSION.name: (False, True),
}


class DialoguePlayer(Node):
    """Plays one scenario and collects the robot's and RR's answers."""

    def __init__(self, node_name: str = "dialogue_player", *, namespace: Optional[str] = None, **kwargs) -> None:
        super().__init__(node_name, namespace=namespace, **kwargs)
        describe = ParameterDescriptor
        self.declare_parameter("scenario", "", describe(description="scenario YAML to play", read_only=True))
        self.declare_parameter(
            "output", "", describe(description="write the docs/semantics.md section 6 JSON here ('' = print a table)")
        )
        self.declare_parameter("trace", "", describe(description="write wm/events as JSON lines here ('' = off)"))
        self.declare_parameter("drive_clock", True, describe(description="publish /clock at each turn's time"))
        declare_number(self, "turn_timeout", 30.0, 0.1, 3600.0, "seconds to wait for one turn's answer")
        declare_number(self, "retry_after", 2.0, 0.05, 600.0, "resend a turn unanswered for this long, s")
        declare_number(self, "ready_timeout", 60.0, 0.1, 3600.0, "seconds to wait for the graph to come up")
        self.listeners = declare_number(self, "listeners", 0, 0, 100, "other subscribers (a recorder) to wait for "
                                        "on the requests and wm/events before turn 1", integer=True, read_only=True)
        self.declare_parameter(
            "lexicon", "", describe(description="lexicon YAML ('' = package default)", read_only=True)
        )
        path = self.get_parameter("scenario").value
        if not path:
            raise ValueError("parameter 'scenario' is required")
        self.scenario: Scenario = load_scenario(path, Lexicon.load(self.get_parameter("lexicon").value or None))
        self.run_id = f"{self.scenario.name}-{wallclock.time_ns() % 10**9}"
        group = self._group = ReentrantCallbackGroup()
        self._clock_pub = self.create_publisher(Clock, contract.CLOCK, 10)
        self._human = publisher(self, contract.HUMAN)
        self._request = publisher(self, contract.REG_REQUEST)
        self.graph = graph_identity(self)
        self._sync = ServiceCaller(self, contract.SYNC.name, group)
        self._status = ServiceCaller(self, contract.STATUS.name, group)
        self._pending: dict[str, Future] = {}
        self.audit = EventAudit(self.graph, tuple(self.scenario.domains))
        self.memory: dict[str, Any] = {}
        subscribe(self, contract.RR_RESULT, self._on_answer, callback_group=group)
        subscribe(self, contract.REG_EXPRESSION, self._on_answer, callback_group=group)
        self.sources = EventSources(self, list(self.scenario.domains), self.audit, self._on_event, group,
                                    self.listeners)

    # ------------------------------------------------------------ callbacks
    def _on_answer(self, data: dict) -> None:
        future = self._pending.get(str(data.get("id")))
        if future is None or future.done():
            return
        graph = data.get(contract.GRAPH_FIELD) or ""
        if graph != self.graph:
            future.set_exception(PlayerError(
                f"the answer to {data.get('id')!r} came from another graph ({describe_graph(graph)}, this run is "
                f"{describe_graph(self.graph)}): another graph answers in this namespace"))
            return
        future.set_result(data)

    def _on_event(self, data: dict) -> None:
        self.audit.hear(data)  # subscribe() has checked it against contract.WMEventMessage

    @property
    def events(self) -> list[dict]:
        """The run's events heard so far (without transport fields), in arrival order."""
        return self.audit.trace_events()

    def _check_fault(self) -> None:
        self.sources.check_fault()

    # -------------------------------------------------------------- waiting
    def _missing_peers(self) -> list[str]:
        return [
            topic
            for topic, (sub, pub) in PIPELINE_TOPICS.items()
            if (sub and self.count_subscribers(topic) < 1 + self.listeners)
            or (pub and self.count_publishers(topic) == 0)
        ]

    async def wait_ready(self) -> None:
        """Wait until the graph is up.

        Every pipeline topic has its peers and the WM Manager answers a sync (which
        it does only once every consultant is configured).
        """
        timeout = self.get_parameter("ready_timeout").value
        started = wallclock.monotonic()
        if not await wait_until(self, lambda: not self._missing_peers(), timeout):
            raise PlayerError(f"graph not ready within {timeout} s: no peers on {', '.join(self._missing_peers())}")
        remaining = max(1.0, timeout - (wallclock.monotonic() - started))
        try:
            # wait_ready: a first request to a server just discovered can be lost, so it is sent again
            reply = await self._sync.wait_ready({"time": 0.0}, remaining)
            status = await self._status.wait_ready({}, remaining)
        except CarrierError as err:
            raise PlayerError(f"graph not ready: {err}") from None
        self.memory = reply.get("memory", {})
        graph = status.get("graph") or ""
        if graph != self.graph:
            raise PlayerError(f"{contract.STATUS.name} is answered by another graph ({describe_graph(graph)}, this "
                              f"run is {describe_graph(self.graph)}): another graph runs in this namespace")
        await self.sources.wait(status, max(1.0, timeout - (wallclock.monotonic() - started)))

    async def exchange(self, publisher, message: dict) -> dict:
        """Publish ``message`` and return the answer with its id.

        The message is resent every ``retry_after`` seconds until ``turn_timeout``.
        """
        key = str(message["id"])
        future = Future()
        self._pending[key] = future
        started = wallclock.monotonic()
        timeout = self.get_parameter("turn_timeout").value

        def resend() -> None:
            if future.done():
                return
            if wallclock.monotonic() - started > timeout:
                future.set_exception(PlayerError(f"no answer to {key} within {timeout} s"))
                return
            publish(publisher, message)

        publish(publisher, message)
        timer = self.create_timer(self.get_parameter("retry_after").value, resend)
        try:
            return await future
        finally:
            drop_timer(self, timer, self.default_callback_group)
            del self._pending[key]

    # ---------------------------------------------------------------- play
    async def play(self) -> dict:
        """Play every turn; return the docs/semantics.md section 6 result object.

        Raises :class:`PlayerError` if the run's event stream is incomplete or foreign.
        """
        await self.wait_ready()
        records = []
        for turn in self.scenario.dialogue:
            records.append(await self.play_turn(turn))
            self._check_fault()
        await self.sources.drain(self.get_parameter("turn_timeout").value)
        return {"scenario": self.scenario.name, "memory": self.memory, "turns": records}

    async def play_turn(self, turn: Turn) -> dict:
        self._check_fault()
        reply = await self._sync.call({"time": turn.time}, self.get_parameter("turn_timeout").value)
        self.memory = reply.get("memory", self.memory)
        if self.get_parameter("drive_clock").value:
            self._clock_pub.publish(clock_message(turn.time))
        message: dict[str, Any] = {"id": f"{self.run_id}/{turn.index}", "time": turn.time, "turn": turn.index}
        if turn.speaker == "human":
            if turn.text is not None:
                message["text"] = turn.text
            else:
                message["description"] = list(turn.description or ())
            if turn.domain is not None:
                message["domain"] = turn.domain
            answer = await self.exchange(self._human, message)
            _raise_error(answer, turn)
            unknown = answer.get("unknown_words") if turn.text is not None else None
            return human_record(turn, answer, unknown)
        message["target"] = turn.target
        if turn.context is not None:
            message["context"] = list(turn.context)
        answer = await self.exchange(self._request, message)
        _raise_error(answer, turn)
        return robot_record(turn, answer)

    def trace(self) -> list[dict]:
        """Events heard, in the simulator's canonical trace order."""
        return trace_order(self.scenario, self.events)


def _raise_error(answer: dict, turn: Turn) -> None:
    if "error" in answer or answer.get("status") == "error":
        raise PlayerError(f"turn {turn.index} (t={turn.time}): {answer.get('error')}")


def write_outputs(player: DialoguePlayer, result: dict) -> None:
    output = player.get_parameter("output").value
    if output:
        with open(output, "w", encoding="utf-8") as out:
            out.write(dumps(result))
    else:
        from ..core.simulation.report import render_table

        print(render_table(result), end="", flush=True)
    trace = player.get_parameter("trace").value
    if trace:
        with open(trace, "w", encoding="utf-8") as out:
            for event in player.trace():
                out.write(json.dumps(event, sort_keys=True) + "\n")


def main(args=None) -> int:
    return run_node(
        DialoguePlayer,
        args,
        job=lambda node: node.play(),
        on_done=write_outputs,
        job_errors=(PlayerError, CarrierError),
    )


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
