"""A :class:`~fsreg_ros.core.consultant.ConsultantPort` over a consultant node's service.

RR and REG run the core algorithms unchanged; with a :class:`RemotePort` each port
call is one awaited JSON call to ``consultant/<domain>`` (the preference order and
the entity list are cached while the consultant's LTM ``version`` stays the same; see
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
from dataclasses import dataclass, field
from typing import Any, Mapping, Optional, Sequence

from rclpy.callback_groups import CallbackGroup
from rclpy.clock import Clock, ClockType

from .carrier import DEFAULT_TIMEOUT, CarrierError, JsonClient, drop_timer
from . import contract
from .codec import MessageError
from .contract import consultant_service
from .core.consultant import KnowledgeError, Narrowed, Step, View


@dataclass
class Catalogue:
    """What a caller caches of a consultant: preference order, entities, and the LTM version they are from."""

    version: str
    preference: list[str]
    entities: list[str]
    known: set[str] = field(default_factory=set)

    @property
    def incarnation(self) -> str:
        return self.version.split(":", 1)[0]


#: Seconds a call in flight when the consultant announces a new incarnation may still take.
RESTART_GRACE = 1.0


class RemotePort:
    """The consultant of ``domain``, reached through its node's service.

    The preference order and the entity list are cached (:class:`Catalogue`) until a
    reply's ``version`` says LTM changed or the consultant restarted; then the next
    use asks ``info`` for the entities added since (they are only ever appended).
    """

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
        self._catalogue: Optional[Catalogue] = None
        self._latest = ""  # the newest version any reply named
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
            if err.kind in ("KnowledgeError", "SessionError"):
                raise KnowledgeError(err.error) from None
            if err.kind == "timeout":
                self._down_until = time.monotonic() + self.timeout
            raise
        finally:
            self._inflight.pop(future, None)
        self._down_until = 0.0
        try:
            contract.check(contract.CONSULTANT_OPS[payload["op"]][1], reply)
        except MessageError as err:
            raise CarrierError(f"malformed reply to '{payload.get('op')}': {err}", kind="protocol",
                               service=self.client.name) from None
        if "version" in reply:
            self._latest = reply["version"]
        return reply

    async def wait_ready(self, timeout: float) -> dict:
        """Make one real round trip (an ``info`` call) within ``timeout`` seconds; return the info reply.

        Retries while the service is not discovered or the first call is lost; raises
        :class:`CarrierError` (kind ``timeout``) when the deadline passes.
        """
        reply = await self.client.wait_ready({"op": "info"}, timeout)
        try:
            contract.check(contract.InfoReply, reply)
        except MessageError as err:
            raise CarrierError(f"malformed reply to 'info': {err}", kind="protocol", service=self.client.name) from None
        self._latest = reply["version"]
        self._catalogue = Catalogue(reply["version"], list(reply["preference"]), list(reply["entities"]),
                                    set(reply["entities"]))
        return reply

    async def catalogue(self, refresh: bool = False) -> Catalogue:
        """Return the cached preference order and entities, asking ``info`` only if stale (or ``refresh``)."""
        cat = self._catalogue
        if cat is not None and not refresh and cat.version == self._latest:
            return cat
        start = len(cat.entities) if cat is not None else 0
        reply = await self._call({"op": "info", "entities_from": start})
        if cat is None or reply["version"].split(":", 1)[0] != cat.incarnation:
            if start:  # restarted: its entities may differ from the first one on
                reply = await self._call({"op": "info"})
            cat = Catalogue(reply["version"], list(reply["preference"]), [], set())
        cat.entities += reply["entities"]
        cat.known.update(reply["entities"])
        cat.version = reply["version"]
        self._catalogue = cat
        return cat

    # ------------------------------------------------------- ConsultantPort
    async def info(self) -> dict:
        """Return the ``info`` reply (domain, entities, preference, threshold, policy, memory, events, version)."""
        return await self._call({"op": "info"})

    async def knows(self, entity: str, refresh: bool = False) -> bool:
        """Return True if ``entity`` is one of this domain's (entities never leave a domain)."""
        return entity in (await self.catalogue(refresh)).known

    async def preference(self) -> list[str]:
        return list((await self.catalogue()).preference)

    async def open(
        self, target: Optional[str] = None, context: Optional[Sequence[str]] = None, first: Optional[Step] = None
    ) -> View:
        payload: dict[str, Any] = {"op": "open"}
        if target is not None:
            payload["target"] = target
        if context is not None:
            payload["context"] = list(context)
        if first is not None:
            payload["first"] = {"property": first.prop, "cause": first.cause, "time": first.time, "turn": first.turn}
        reply = await self._call(payload)
        holding = reply.get("holding")
        view = View(reply["session"], reply["size"], list(reply["queue"]), reply["retains"],
                    frozenset(holding) if holding is not None else None,
                    origins=[(o["cause"], o["turn"]) for o in reply.get("origins", ())])
        if first is not None:
            if reply.get("first") is None:
                raise CarrierError("malformed reply to 'open': no 'first'", kind="protocol", service=self.client.name)
            view.first = Narrowed(reply["first"]["target_holds"], reply["first"]["size"])
        return view

    async def narrow(self, view: View, prop: str, cause: Optional[str], time: float, turn: Optional[int]) -> Narrowed:
        reply = await self._call({"op": "narrow", "session": view.handle, "property": prop, "cause": cause,
                                  "time": time, "turn": turn})
        return Narrowed(reply["target_holds"], reply["size"])

    async def rule_out(self, view: View) -> tuple[list[str], list[int]]:
        reply = await self._call({"op": "rule_out", "session": view.handle})
        try:
            masks = [int(mask, 16) for mask in reply["masks"]]
        except ValueError:
            raise CarrierError("malformed reply to 'rule_out': a mask is not hexadecimal", kind="protocol",
                               service=self.client.name) from None
        return list(reply["properties"]), masks

    async def close(
        self, view: View, encode: Sequence[str] = (), time: float = 0.0, turn: Optional[int] = None
    ) -> list[str]:
        payload: dict[str, Any] = {"op": "close", "session": view.handle, "time": time, "turn": turn}
        if encode:
            payload["encode"] = list(encode)
        return list((await self._call(payload))["members"])

    async def holds(self, prop: str, entities: Sequence[str]) -> list[str]:
        """Return the given entities ``prop`` holds for, in the given order (no encoding)."""
        reply = await self._call({"op": "holds", "property": prop, "entities": list(entities)})
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
