"""Queries of a live graph through its services and ``wm/state`` (:class:`GraphQueries`, a part of ``GraphClient``).

The JSON services (``wm_manager/status``, ``wm_manager/sync``, a consultant's ``info``
and debug queries, its manage op ``reset``), working memory as the consultants
publish it (``wm/state``: :meth:`GraphQueries.state`, :meth:`GraphQueries.watch`) and
which domain knows an entity.  The consultants' ops are encoded and decoded by the
protocol's codec (:mod:`fsreg_ros.contract.consultant_codec`).
"""

from __future__ import annotations

from typing import Any, Callable, Mapping, Optional

from .. import contract
from ..contract import consultant_codec as codec
from ..contract.codec import printable
from .carrier import CarrierError, ServiceCaller, subscribe
from .client_base import ClientError, Spinning, describe_graph


#: The client name :meth:`GraphQueries.held` opens its sessions under.
HELD_CLIENT = "fsreg-ctl"


class GraphQueries(Spinning):
    """Service calls and WM reads of one graph (state set up by ``GraphClient``).

    Uses the client's ``_services`` (callers by service name), ``_entities`` (domain ->
    entities its consultant knows, asked once), ``_states`` and ``_state_watcher``
    (``wm/state`` once :meth:`state` subscribed it), ``foreign`` (set when another
    graph's message arrives while watching), and ``domains`` from its readiness.
    """

    def service(self, name: str) -> ServiceCaller:
        if name not in self._services:
            self._services[name] = ServiceCaller(self.node, name)
        return self._services[name]

    def call(self, name: str, payload: Mapping[str, Any], timeout: Optional[float] = None) -> dict:
        """Call one of the graph's JSON services; its reply (ClientError with the service's error kind).

        Every service the client calls is idempotent (status, sync, a consultant's
        queries), so a call that times out is sent again within ``timeout``: a first
        request to a server just discovered can be lost.
        """
        timeout = self.timeout if timeout is None else timeout
        client = self.service(name)
        self.spin_until(client.ready, timeout, f"service {self.node.resolve_service_name(name)} is not available",
                        "not-ready")
        try:
            return self.run(client.wait_ready(payload, timeout), timeout + 1.0, f"service {name}")
        except CarrierError as err:
            raise ClientError(printable(str(err)), err.kind) from None

    def status(self, timeout: Optional[float] = None) -> dict:
        """Return the WM Manager's ``wm_manager/status`` (``ready``, ``memory``, ``running``, ...)."""
        reply = self.call(contract.STATUS.name, {}, timeout)
        graph = reply.get("graph") or ""
        if self.graph is not None and graph != self.graph:
            raise ClientError(f"{contract.STATUS.name} answered by another graph ({describe_graph(graph)}, expected "
                              f"{describe_graph(self.graph)}) in {self.where()}", "foreign")
        return reply

    def reset_state(self, domain: str, timeout: Optional[float] = None) -> dict:
        """Ask ``domain``'s consultant to set its state aside and start from its KB again (manage op ``reset``).

        Sent once (not idempotent: never resent); its reply (``incarnation``, ``moved_aside``,
        ``cleared``, ``state``) or ClientError.  The consultant then serves as a new
        incarnation, ready once the WM Manager configured it (:meth:`wait_ready`).
        """
        timeout = self.timeout if timeout is None else timeout
        name = contract.manage_service(domain)
        client = self.service(name)
        self.spin_until(client.ready, timeout, f"service {self.node.resolve_service_name(name)} is not available",
                        "not-ready")
        future = client.send(codec.reset_request(self.node.get_fully_qualified_name()))
        try:
            return self.run(client.result(future, timeout), timeout + 1.0, f"service {name}")
        except CarrierError as err:
            raise ClientError(printable(str(err)), err.kind) from None

    def sync(self, t: float, timeout: Optional[float] = None) -> dict:
        """Call the WM Manager's barrier: every decay tick due at or before ``t`` applied (docs/design.md)."""
        return self.call(contract.SYNC.name, {"time": t}, timeout)

    def domain_of(self, entity: str, new_ok: bool = False) -> str:
        """Return the domain whose consultant knows ``entity`` (or the only domain, for a new one if ``new_ok``)."""
        domains = self.domains()
        for domain in domains:
            if domain not in self._entities:
                info = self.call(contract.consultant_service(domain), codec.info_request())
                self._entities[domain] = set(codec.entities_of(info))
            if entity in self._entities[domain]:
                return domain
        if new_ok and len(domains) == 1:
            return domains[0]
        raise ClientError(f"no consultant knows entity {entity!r} (domains: {', '.join(domains)})"
                          + ("; name the domain of a new entity" if new_ok else ""), "usage")

    def wm(self, entity: str, domain: Optional[str] = None) -> list[str]:
        """Return ``entity``'s working memory now, least recently used first (reading never refreshes it).

        Asks the consultant's debug service (served when its ``debug`` parameter is true,
        as :mod:`fsreg_ros.testing` starts it); :meth:`state` needs no debug service.
        """
        domain = domain or self.domain_of(entity)
        return codec.queue_of(self.call(contract.debug_service(domain), codec.wm_request(entity)))

    def held(self, entity: str, domain: str, timeout: Optional[float] = None) -> dict:
        """Return how ``entity``'s WM entries are held now: ``queue`` (LRU first), ``origins`` and ``strength``.

        What a consultant's ``open`` reply carries (no debug service needed): a session is
        opened on the entity for client ``fsreg-ctl`` and closed at once without encoding,
        so WM does not change and no reference episode begins.  A session a lost reply
        leaves open is the client's own, dropped when it opens more than the consultant keeps.
        """
        service = contract.consultant_service(domain)
        view = codec.view_of(self.call(service, codec.open_request(entity, None, None, HELD_CLIENT), timeout),
                             first=False)
        self.call(service, codec.close_request(view.handle, (), None, None), timeout)  # time None: the consultant's now
        return {"queue": view.queue, "origins": [{"cause": cause, "turn": turn} for cause, turn in view.origins],
                "strength": [entry.to_json() for entry in view.strength]}

    def snapshot(self, domain: str) -> dict[str, list[str]]:
        """Return every non-empty WM queue of ``domain`` now (the debug service, as :meth:`wm`)."""
        return codec.snapshot_of(self.call(contract.debug_service(domain), codec.snapshot_request()))

    def state(self, domain: str, timeout: Optional[float] = None, current: bool = False) -> dict:
        """Return ``domain``'s latest ``wm/state`` (latched: its non-empty queues as last published).

        A consultant publishes it after each request that changed WM, at most every
        ``state_period`` (0.1 s by default), so it may lag a change by that much.
        ``current``: first ask the consultant (``info``) how many of its calls changed
        WM, and wait for the state that shows them all (what ``fsreg-ctl wm`` prints).
        """
        if self._states is None:
            self._states = {}
            subscribe(self.node, contract.WM_STATE, self._on_state)
        wait = self.timeout if timeout is None else timeout
        if not current:
            self.spin_until(lambda: domain in self._states, wait,
                            f"no {contract.WM_STATE.name} of domain {domain!r} in {self.where()}", "not-ready")
            return self._states[domain]
        info = self.call(contract.consultant_service(domain), codec.info_request(), timeout)
        wanted = codec.wm_as_of(info)

        def caught_up() -> bool:
            state = self._states.get(domain)
            return state is not None and state_version(state) >= wanted

        self.spin_until(caught_up, wait, f"no {contract.WM_STATE.name} of domain {domain!r} as of "
                        f"incarnation {wanted[0]}, WM change {wanted[1]} in {self.where()}", "not-ready")
        return self._states[domain]

    def _on_state(self, data: dict) -> None:
        graph = data.get(contract.GRAPH_FIELD) or ""
        if self.graph is not None and graph != self.graph:
            if self._state_watcher is not None:
                self.foreign = self._foreign(graph)
            return
        self._states[data["domain"]] = data
        if self._state_watcher is not None:
            self._state_watcher(data)

    def _foreign(self, graph: str) -> str:
        return (f"a message from another graph ({describe_graph(graph)}, expected "
                f"{describe_graph(self.graph)}) in {self.where()}")

    def watch(self, on_state: Callable[[dict], None], on_event: Optional[Callable[[dict], None]] = None) -> list:
        """Pass every ``wm/state`` and (with ``on_event``) ``wm/events`` message of this graph on.

        Each domain's current state comes first (:meth:`state` with ``current``), then
        each newer one as it is published (an older latched copy is not passed on); the
        states come through :meth:`state`'s subscription.  Returns the subscriptions made
        (``wm/events``'s, if ``on_event`` is given).

        A message stamped by another graph raises ClientError ``foreign`` out of the spin.
        """
        shown: dict[str, tuple[int, int]] = {}

        def newer(state: dict) -> None:
            version = state_version(state)
            if version > shown.get(state["domain"], (-1, -1)):
                shown[state["domain"]] = version
                on_state(state)

        for domain in self.domains():
            newer(self.state(domain, current=True))
        self.foreign = None
        self._state_watcher = newer  # wm/state keeps coming through state()'s subscription
        if on_event is None:
            return []

        def checked_event(data: dict) -> None:
            graph = data.get(contract.GRAPH_FIELD) or ""
            if self.graph is not None and graph != self.graph:
                self.foreign = self._foreign(graph)
                return
            on_event(data)

        return [subscribe(self.node, contract.WM_EVENTS, checked_event)]


def state_version(state: Mapping[str, Any]) -> tuple[int, int]:
    """Return which state a ``wm/state`` message shows: ``(incarnation, wm_version)``, later compares greater."""
    return state["incarnation"], state["wm_version"]
