"""A :class:`~fsreg_ros.core.consultant.ConsultantPort` over a consultant node's service.

RR and REG run the core algorithms unchanged; with a :class:`RemotePort` each port
call is one awaited JSON call to ``consultant/<domain>`` (see
:mod:`fsreg_ros.nodes.consultant` for the ops).  Await port methods only from a
callback outside ``callback_group`` (give the port a reentrant group of its own).

Errors: a request the consultant rejects because it names an unknown entity or
property raises :class:`~fsreg_ros.core.consultant.KnowledgeError` (as the in-process
:class:`~fsreg_ros.core.consultant.LocalPort` would); everything else (timeouts, a
malformed reply, other rejections) raises :class:`~fsreg_ros.carrier.CarrierError`.

Failing fast: after a call times out the port counts the consultant as down, and every
call in the next ``timeout`` seconds fails at once (kind ``unavailable``) instead of
waiting out its own deadline, so one dead consultant does not hold every request queued
behind it for a full timeout each.  After that pause one call probes it again.
A consultant that announces a new incarnation (``consultant/announce``, passed on by
the node through :meth:`RemotePort.restarted`) ends the pause at once, and the calls
then in flight get :data:`RESTART_GRACE` seconds more before they fail (kind
``restarted``): those sent to the previous incarnation would never be answered, while
one the new incarnation received (an announcement can arrive late) is answered in
milliseconds.
"""

from __future__ import annotations

import time
from typing import Any, Mapping, Optional, Sequence

from rclpy.callback_groups import CallbackGroup
from rclpy.clock import Clock, ClockType

from .carrier import DEFAULT_TIMEOUT, CarrierError, JsonClient, drop_timer
from . import contract
from .codec import MessageError
from .contract import consultant_service
from .core.consultant import KnowledgeError


#: Seconds a call in flight when the consultant announces a new incarnation may still take.
RESTART_GRACE = 1.0


class RemotePort:
    """The consultant of ``domain``, reached through its node's service."""

    def __init__(
        self,
        node,
        domain: str,
        callback_group: Optional[CallbackGroup] = None,
        timeout: float = DEFAULT_TIMEOUT,
    ) -> None:
        self.domain = domain
        self.timeout = timeout
        self.client = JsonClient(node, consultant_service(domain), callback_group, timeout)
        self._preference: Optional[list[str]] = None
        self._down_until = 0.0  # monotonic time before which calls fail fast
        self._inflight: dict = {}  # futures of the calls awaiting a reply
        self.incarnation: Optional[int] = None  # the consultant's, from its announcements

    def restarted(self, incarnation: int) -> None:
        """Note the consultant's announced incarnation; on a new one, fail the calls to the old one now."""
        previous, self.incarnation = self.incarnation, incarnation
        if previous is None or previous == incarnation:
            return
        self._down_until = 0.0
        stale = [future for future in self._inflight if not future.done()]
        if not stale:
            return
        client, timer = self.client, None

        def expire() -> None:
            drop_timer(client.node, timer, client.callback_group)
            for future in stale:
                if not future.done():
                    client.client.remove_pending_request(future)
                    future.set_exception(CarrierError(
                        f"consultant '{self.domain}' restarted (incarnation {incarnation}) before answering; "
                        "try again", kind="restarted", service=client.name))

        timer = client.node.create_timer(RESTART_GRACE, expire, client.callback_group,
                                         clock=Clock(clock_type=ClockType.STEADY_TIME))

    # ------------------------------------------------------------ plumbing
    async def _call(self, payload: Mapping[str, Any]) -> dict:
        now = time.monotonic()
        if now < self._down_until:
            raise CarrierError(
                f"consultant '{self.domain}' is not answering (a call timed out "
                f"{self.timeout - (self._down_until - now):.1f} s ago); failing fast, try again later",
                kind="unavailable", service=self.client.name)
        future = self.client.send(payload)
        self._inflight[future] = None
        try:
            reply = await self.client.result(future, self.timeout)
        except CarrierError as err:
            if err.kind == "KnowledgeError":
                raise KnowledgeError(err.error) from None
            if err.kind == "timeout":
                self._down_until = time.monotonic() + self.timeout
            raise
        finally:
            self._inflight.pop(future, None)
        self._down_until = 0.0
        try:
            return contract.check(contract.CONSULTANT_OPS[payload["op"]][1], reply)
        except MessageError as err:
            raise CarrierError(f"malformed reply to '{payload.get('op')}': {err}", kind="protocol",
                               service=self.client.name) from None

    async def wait_ready(self, timeout: float) -> dict:
        """Make one real round trip (an ``info`` call) within ``timeout`` seconds; return the info reply.

        Retries while the service is not discovered or the first call is lost; raises
        :class:`CarrierError` (kind ``timeout``) when the deadline passes.
        """
        reply = await self.client.wait_ready({"op": "info"}, timeout)
        self._remember(reply)
        return reply

    def _remember(self, info: dict) -> None:
        prefs = info.get("preference")
        if isinstance(prefs, list):
            self._preference = list(prefs)

    # ------------------------------------------------------- ConsultantPort
    async def info(self) -> dict:
        """``{"domain", "entities", "preference", "threshold", "policy", "memory"}``."""
        reply = await self._call({"op": "info"})
        self._remember(reply)
        return reply

    async def entities(self) -> list[str]:
        # Not cached: /ltm/assert can add entities at run time.
        return list((await self.info())["entities"])

    async def preference(self) -> list[str]:
        # Cached: a domain's preference order never changes at run time.
        if self._preference is None:
            await self.info()
        return list(self._preference or [])

    async def holds(self, prop: str, entities: Sequence[str]) -> list[str]:
        reply = await self._call({"op": "holds", "property": prop, "entities": list(entities)})
        return reply["holds"]

    async def affirm(
        self, prop: str, entities: Sequence[str], cause: str, time: float, turn: Optional[int]
    ) -> list[str]:
        reply = await self._call(
            {"op": "affirm", "property": prop, "entities": list(entities), "cause": cause,
             "time": time, "turn": turn},
        )
        return reply["holds"]

    async def wm(self, entity: str) -> list[str]:
        return (await self._call({"op": "wm", "entity": entity}))["queue"]

    async def encode(
        self, entity: str, properties: Sequence[str], cause: str, time: float, turn: Optional[int]
    ) -> None:
        await self._call(
            {"op": "encode", "entity": entity, "properties": list(properties), "cause": cause,
             "time": time, "turn": turn},
        )

    async def snapshot(self) -> dict[str, list[str]]:
        """Every non-empty queue of the domain, LRU first."""
        return (await self._call({"op": "snapshot"}))["queues"]
