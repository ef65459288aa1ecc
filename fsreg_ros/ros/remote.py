"""A :class:`~fsreg_ros.core.algorithms.port.ConsultantPort` over a consultant node's service.

RR and REG run the core algorithms unchanged; with a :class:`RemotePort` each port
call (a :meth:`~RemotePort.walk` included: the consultant runs it) is one awaited JSON
call to ``consultant/<domain>`` (ops and replies: :mod:`fsreg_ros.contract.consultant`,
encoded and decoded by :mod:`fsreg_ros.contract.consultant_codec`; the preference order and the entity list are
cached while the consultant's LTM ``version`` stays the same).  Await port methods
only from a callback outside ``callback_group`` (give the port a reentrant group of its own).

Errors: a request the consultant rejects because it names an unknown entity or
property (or a session it no longer holds) raises
:class:`~fsreg_ros.core.consultant.consultant.KnowledgeError`, as the in-process
:class:`~fsreg_ros.core.consultant.local_port.LocalPort` would; everything else (timeouts, a
malformed reply, other rejections, an outage) raises :class:`~fsreg_ros.ros.carrier.CarrierError`.

Outages are detected, not waited out.  The port listens to the consultant's latched
``consultant/<domain>/alive`` announcement, whose writer has a DDS liveliness lease of
1 s (kept by the DDS threads across processes, whatever the consultant's Python is
doing; a reader in the consultant's own process needs its writes, every 0.25 s).  When
the process dies its liveliness lapses: the calls it had not answered fail (kind
``unavailable``, after a 0.25 s grace: a lease can lapse and recover under load), and a
new call waits at most ``outage_wait`` seconds for a consultant to come back.  A lapse
alone never fails a new call: a CPU-starved machine can miss a lease while the consultant
lives.  The call is sent with a deadline of ``lapsed_deadline`` seconds instead of
``timeout``; an answer in time is proof of life, no answer fails it the same way.  So a
query during an outage is answered within about 1.5 s, not after ``timeout``, and a
consultant that lives but is slow gets the full ``timeout``.  An ``open`` or ``info`` that
failed only because the consultant restarted under it (its new incarnation is up) is sent
again once, with the catalogue refreshed.  Any answer is proof of life: after one, the port
serves as usual even before its own subscription has seen the new liveliness.

Restarts are known, not guessed.  The WM Manager, which every asking node discovered long
before, reports each consultant's incarnation on ``wm_manager/ready``
(:meth:`RemotePort.reported`).  When it names an incarnation newer than the one this port
was last answered by, the consultant restarted: :meth:`RemotePort.needs_round_trip` turns
true and the node waits, within its ``ready_timeout``, until the manager has configured the
new incarnation and one call to it was answered (:meth:`RemotePort.wait_ready`; a first
request to a server this process has only just discovered can be lost, so it is sent again).
DDS discovers a restarted process in each node separately, seconds apart under load; this
wait is what makes "the WM Manager reports the graph ready" mean "the next request
succeeds" in RR and REG too.  An outage the manager reports no restart for still fails fast.  Each port has a client id
(``open`` carries it: the consultant counts sessions per client) and keeps at most
``max_in_flight`` calls outstanding.
"""

from __future__ import annotations

import secrets
import time
from dataclasses import dataclass, field
from typing import Any, Mapping, Optional, Sequence

from rclpy.callback_groups import CallbackGroup, ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import SubscriptionEventCallbacks

from .. import contract
from ..contract import consultant_codec as codec
from .carrier import DEFAULT_TIMEOUT, CarrierError, ServiceCaller, drop_timer, subscribe, wait_until
from ..contract.codec import MessageError
from ..core.consultant.consultant import KnowledgeError
from ..core.algorithms.port import Narrowed, Reference, Step, View, Walked, WalkStep

#: Seconds a new call waits for a consultant whose liveliness lapsed to come back.
OUTAGE_WAIT = 0.5
#: Seconds a lapsed liveliness must stay lapsed before the calls in flight fail.
LAPSE_GRACE = 0.25
#: Deadline of a call sent while the consultant's liveliness is lapsed, seconds: an answer
#: within it shows the consultant lives (a loaded machine can miss a lease); none fails the call.
LAPSED_DEADLINE = 1.0
#: Calls a port keeps outstanding at most (RR and REG make one at a time).
MAX_IN_FLIGHT = 16
#: Ops sent again once when the consultant restarted under them (they hold no session).
RETRIED_OPS = ("info", "open")


@dataclass
class Catalogue:
    """What a caller caches of a consultant: preference order, entities, and the LTM version they are from."""

    version: str
    preference: list[str]
    entities: list[str]
    known: set[str] = field(default_factory=set)

    @property
    def incarnation(self) -> int:
        return contract.version_incarnation(self.version)


class RemotePort:
    """The consultant of ``domain``, reached through its node's service.

    The preference order and the entity list are cached (:class:`Catalogue`) until a
    reply's ``version`` says an entity was added or the consultant restarted; then the next
    use asks ``info`` for the entities added since (they are only ever appended).
    """

    def __init__(
        self,
        node,
        domain: str,
        callback_group: Optional[CallbackGroup] = None,
        timeout: float = DEFAULT_TIMEOUT,
        *,
        outage_wait: float = OUTAGE_WAIT,
        lapsed_deadline: float = LAPSED_DEADLINE,
        max_in_flight: int = MAX_IN_FLIGHT,
    ) -> None:
        self.domain = domain
        self.timeout = timeout
        self.outage_wait = outage_wait
        self.lapsed_deadline = lapsed_deadline
        self.max_in_flight = max(1, max_in_flight)
        self.caller = ServiceCaller(node, contract.consultant_service(domain), callback_group, timeout)
        self.client_id = f"{node.get_fully_qualified_name()}#{secrets.token_hex(3)}"
        self._catalogue: Optional[Catalogue] = None
        self._latest = ""  # the newest version any reply named
        self._inflight: dict[Any, float] = {}  # future -> monotonic time sent
        self.incarnation: Optional[int] = None  # the consultant's, from its announcements
        self.ready: Optional[bool] = None  # whether it said it serves
        self.alive: Optional[bool] = None  # its liveliness (None: not heard of yet)
        self._appeared_at = 0.0  # monotonic time the newest writer of the alive topic appeared
        self._down_since = time.monotonic()  # when it was last seen to go (or the port started)
        self._answered_at = 0.0  # monotonic time of the latest answer (proof of life)
        self._answered_by: Optional[int] = None  # the incarnation that gave it
        #: The consultant's incarnation and whether it is configured, as the WM Manager reports it (None: no report).
        self.manager_report: Optional[tuple[int, bool]] = None
        self._waited_for: Optional[int] = None  # a reported incarnation waited for in vain (not waited for again)
        topic = contract.alive_topic(domain)
        self._alive_sub = subscribe(node, topic, self._on_alive,
                                    callback_group=callback_group or ReentrantCallbackGroup(),
                                    event_callbacks=SubscriptionEventCallbacks(liveliness=self._on_liveliness))

    # ------------------------------------------------------------ liveness
    def restarted(self, incarnation: int) -> None:
        """Note the consultant's announced incarnation (from ``consultant/announce`` or its alive topic)."""
        self.incarnation = incarnation

    def _on_alive(self, data: dict) -> None:  # subscribe() checked it (a malformed one changes nothing)
        self.restarted(data["incarnation"])
        self.ready = data["ready"]
        self.alive = True

    def _on_liveliness(self, info) -> None:
        """Follow the alive topic's writers; when one lapsed, fail the calls it will never answer."""
        now = time.monotonic()
        if info.alive_count_change > 0:
            self._appeared_at = now  # a consultant (perhaps a new incarnation) appeared
        self.alive = info.alive_count > 0
        if info.alive_count_change >= 0 and info.not_alive_count_change <= 0:
            return
        if not self.alive:
            self._down_since = now
        # Confirm after a short grace (a lease can lapse under heavy load and recover).
        caller, incarnation, timer = self.caller, self.incarnation, None

        def confirm() -> None:
            drop_timer(caller.node, timer, caller.callback_group)
            if self.alive and self.incarnation == incarnation and self._appeared_at > now:
                return  # the same consultant again: its calls are answered
            # A call sent while a live consultant was matched was answered by it; those
            # sent before the newest appeared (all of them, if none lives) went to the dead one.
            before = self._appeared_at if self.alive else now
            error = f"consultant '{self.domain}' stopped (its liveliness lapsed) before answering; try again"
            for future, sent in list(self._inflight.items()):
                if sent <= before and not future.done():
                    caller.client.remove_pending_request(future)
                    future.set_exception(CarrierError(error, kind="unavailable", service=caller.name))

        timer = caller.node.create_timer(LAPSE_GRACE, confirm, caller.callback_group,
                                         clock=Clock(clock_type=ClockType.STEADY_TIME))

    def reported(self, incarnation: Optional[int], configured: bool) -> None:
        """Note what the WM Manager reports of this consultant (``wm_manager/ready``)."""
        if incarnation is not None:
            self.manager_report = (incarnation, configured)

    def needs_round_trip(self) -> bool:
        """Return True until a call was answered, and again when the manager reports a newer incarnation."""
        if self._answered_by is None:
            return True
        report = self.manager_report
        return report is not None and report[0] > self._answered_by and report[0] != self._waited_for

    def _answered(self, version: str) -> None:
        self._answered_at = time.monotonic()
        self._answered_by = contract.version_incarnation(version)

    def _available(self) -> bool:
        proven = self._answered_at > self._down_since  # answered since its liveliness was last seen to go
        return (self.alive is not False or proven) and self.caller.ready()

    # ------------------------------------------------------------ plumbing
    async def _call(self, payload: Mapping[str, Any], retry: bool = True) -> dict:
        deadline = self.timeout
        if not self._available():
            # Wait for a restart only within ``outage_wait`` of the outage's start: requests
            # queued behind a dead consultant are answered at once.
            wait = self._down_since + self.outage_wait - time.monotonic()
            if wait > 0:
                await wait_until(self.caller.node, self._available, wait, callback_group=self.caller.callback_group)
            if not self.caller.ready():
                raise CarrierError(f"consultant '{self.domain}' is not running (no server is matched); try again "
                                   "later", kind="unavailable", service=self.caller.name)
            if self.alive is False:  # a lapse alone is no proof of death: ask, briefly
                deadline = min(self.timeout, self.lapsed_deadline)
        if len(self._inflight) >= self.max_in_flight:
            await wait_until(self.caller.node, lambda: len(self._inflight) < self.max_in_flight, self.timeout,
                             callback_group=self.caller.callback_group)
        future = self.caller.send(payload)
        self._inflight[future] = time.monotonic()
        try:
            reply = await self.caller.result(future, deadline)
        except CarrierError as err:
            if err.kind in ("KnowledgeError", "SessionError"):
                detail = err.reply.get("detail") if isinstance(err.reply, dict) else None
                raise KnowledgeError(err.error, kind=detail if isinstance(detail, str) else None) from None
            if err.kind == "timeout" and deadline < self.timeout:  # asked briefly after a lapse: no answer
                err = CarrierError(f"consultant '{self.domain}' is not running (its liveliness lapsed and it did not "
                                   f"answer within {deadline:g} s); try again later", kind="unavailable",
                                   service=self.caller.name)
            # Alive again (a restart: a request to a server just matched can be lost): ask the new one once.
            if retry and err.kind == "unavailable" and payload["op"] in RETRIED_OPS and self.alive:
                self._latest = ""  # the new incarnation's catalogue may differ
                return await self._call(payload, retry=False)
            raise err from None
        finally:
            self._inflight.pop(future, None)
        try:
            contract.check(contract.CONSULTANT_OPS[payload["op"]][1], reply)
        except MessageError as err:
            raise CarrierError(f"malformed reply to '{payload.get('op')}': {err}", kind="protocol",
                               service=self.caller.name) from None
        version = codec.version_of(reply)
        if version is not None:
            self._latest = version
            self._answered(version)
        return reply

    async def wait_ready(self, timeout: float) -> dict:
        """Make one real round trip (an ``info`` call) within ``timeout`` seconds; return the info reply.

        When the WM Manager reports an incarnation it has not configured yet, first wait
        until it has; then ask until the reply comes from that incarnation (or a newer
        one).  Retries while the service is not discovered or the first call is lost;
        raises :class:`CarrierError` (kind ``timeout``) when the deadline passes.  A
        restart waited for in vain is not waited for again: the requests after it
        fail fast (e.g. ``not-ready``) instead of each waiting ``timeout``.
        """
        try:
            return await self._wait_ready(timeout)
        except CarrierError:
            if self._answered_by is not None and self.manager_report is not None:
                self._waited_for = self.manager_report[0]  # once: later requests fail fast as in an outage
            raise

    async def _wait_ready(self, timeout: float) -> dict:
        deadline = time.monotonic() + timeout
        node, group = self.caller.node, self.caller.callback_group

        def configured() -> bool:
            return self.manager_report is None or self.manager_report[1]

        if not await wait_until(node, configured, timeout, callback_group=group):
            raise CarrierError(f"consultant '{self.domain}' restarted (incarnation {self.manager_report[0]}) and the "
                               f"WM Manager did not configure it within {timeout:g} s", kind="timeout",
                               service=self.caller.name)
        while True:
            reply = await self.caller.wait_ready(codec.info_request(), max(deadline - time.monotonic(), 1e-3))
            try:
                contract.check(contract.InfoReply, reply)
            except MessageError as err:
                raise CarrierError(f"malformed reply to 'info': {err}", kind="protocol",
                                   service=self.caller.name) from None
            version, preference, entities = codec.catalogue_of(reply)
            wanted = self.manager_report[0] if self.manager_report is not None else 0
            if contract.version_incarnation(version) >= wanted:
                break
            await wait_until(node, lambda: False, min(0.1, max(deadline - time.monotonic(), 0.0)),
                             callback_group=group)  # an older incarnation answered: ask again shortly
        self._latest = version
        self._answered(version)
        self._catalogue = Catalogue(version, preference, entities, set(entities))
        return reply

    async def catalogue(self, refresh: bool = False) -> Catalogue:
        """Return the cached preference order and entities, asking ``info`` only if stale (or ``refresh``)."""
        cat = self._catalogue
        if cat is not None and not refresh and cat.version == self._latest:
            return cat
        start = len(cat.entities) if cat is not None else 0
        version, preference, entities = codec.catalogue_of(await self._call(codec.info_request(start)))
        if cat is None or contract.version_incarnation(version) != cat.incarnation:
            if start:  # restarted: its entities may differ from the first one on
                version, preference, entities = codec.catalogue_of(await self._call(codec.info_request()))
            cat = Catalogue(version, preference, [], set())
        cat.entities += entities
        cat.known.update(entities)
        cat.version = version
        self._catalogue = cat
        return cat

    # ------------------------------------------------------- ConsultantPort
    async def info(self) -> dict:
        """Return the ``info`` reply (entities, preference, policy, events, event listeners, stored state, ...)."""
        return await self._call(codec.info_request())

    async def knows(self, entity: str, refresh: bool = False) -> bool:
        """Return True if ``entity`` is one of this domain's (entities never leave a domain)."""
        return entity in (await self.catalogue(refresh)).known

    async def preference(self) -> list[str]:
        return list((await self.catalogue()).preference)

    async def open(
        self, target: Optional[str] = None, context: Optional[Sequence[str]] = None, first: Optional[Step] = None,
        refer: Optional[Reference] = None,
    ) -> View:
        reply = await self._call(codec.open_request(target, context, first, self.client_id, refer))
        return self._decoded("open", codec.view_of, reply, first is not None)

    async def narrow(self, view: View, prop: str, cause: Optional[str], time: float, turn: Optional[int]) -> Narrowed:
        return codec.narrowed_of(await self._call(codec.narrow_request(view.handle, prop, cause, time, turn)))

    async def walk(self, view: View, steps: Sequence[WalkStep], cause: Optional[str], time: float,
                   turn: Optional[int], size: Optional[int] = None) -> Walked:
        """Send the steps in one call; the consultant walks them, knowing ``size`` itself."""
        reply = await self._call(codec.walk_request(view.handle, steps, cause, time, turn))
        return self._decoded("walk", codec.walked_of, reply, len(steps))

    async def rule_out(self, view: View) -> tuple[list[str], list[int]]:
        return self._decoded("rule_out", codec.rule_out_of, await self._call(codec.rule_out_request(view.handle)))

    async def close(
        self, view: View, encode: Sequence[str] = (), time: float = 0.0, turn: Optional[int] = None
    ) -> list[str]:
        return codec.members_of(await self._call(codec.close_request(view.handle, encode, time, turn)))

    def _decoded(self, op: str, decode, reply: dict, *args: Any) -> Any:
        """Decode ``reply`` to ``op``; a reply the schema admits but that is unusable is a ``protocol`` error."""
        try:
            return decode(reply, *args)
        except codec.ReplyError as err:
            raise CarrierError(f"malformed reply to '{op}': {err}", kind="protocol", service=self.caller.name) from None
