"""Readiness and identity of the graph a client talks to (:class:`Readiness`, a part of ``GraphClient``).

The WM Manager's latched ``wm_manager/ready`` (:class:`~fsreg_ros.contract.ManagerReady`)
says when every consultant serves; :meth:`Readiness.wait_ready` waits for it (and for
the dialogue pipeline to be matched with the client) instead of retrying requests.
Every node stamps what it publishes with its graph's identity
(:data:`~fsreg_ros.contract.GRAPH_FIELD`): the client expects one graph (given, or
the one whose WM Manager answers) and refuses to go on when two graphs' WM Managers
share the namespace (kind ``clash``).  While a client waits, the graph leaving (its
WM Manager stopped or died, or its readiness lost) is noticed (:meth:`Readiness.gone`).
The graph's domains and node names are read from its readiness.
"""

from __future__ import annotations

import time
from typing import Optional

from .. import contract
from .client_base import ClientError, Spinning, describe_graph
from .exchange import KIND_TOPICS

#: Seconds to collect every WM Manager's latched readiness once more than one publishes it.
CLASH_WAIT = 2.0
#: Seconds a runner looks for a graph already running where it would start one (discovery on this
#: machine takes 0.1-2.5 s; the wait ends as soon as one is seen).
DISCOVERY_WAIT = 2.5
#: Seconds a waiting client lets its graph stay not ready (after it was ready) before reporting it gone.
GONE_AFTER = 1.5
#: Seconds the ready writer's liveliness must stay lapsed before the graph counts as gone (a stall
#: of the WM Manager's process beyond its 1 s lease, as on a loaded machine, is not a death).
LAPSE_CONFIRM = 0.8
#: The node names of a graph (besides ``consultant_<domain>``).
GRAPH_NODES = ("wm_manager", "parser", "reference_resolution", "reg", "dialogue_player")


class Readiness(Spinning):
    """The graph's readiness, identity and presence, heard on ``wm_manager/ready`` (state set up by ``GraphClient``).

    Uses the client's ``graph`` (the identity expected), ``ready_messages`` and
    ``_ready_heard`` (what each WM Manager announced, and when), ``_ready_sub`` (the
    subscription, with its liveliness events) and the ``_was_ready`` /
    ``_unready_since`` / ``_lapsed_since`` / ``_gone_checked`` bookkeeping of :meth:`gone`.
    """

    def _on_ready(self, data: dict) -> None:  # subscribe() has checked it against contract.ManagerReady
        key = (data.get(contract.GRAPH_FIELD) or "", data.get("pid"), data.get("host"))
        self.ready_messages[key] = data
        self._ready_heard[key] = time.monotonic()

    def _on_liveliness(self, info) -> None:
        self._ready_alive = info.alive_count
        if info.alive_count == 0:
            self._lapsed_since = self._lapsed_since or time.monotonic()
        else:
            self._lapsed_since = None

    def gone(self) -> Optional[str]:
        """Return why this client's graph has left (None while it is there, or before it was found).

        Gone: its WM Manager's ``wm_manager/ready`` writer is no longer matched (the
        process stopped), or its liveliness lapsed for :data:`LAPSE_CONFIRM` s (the process
        died: within the topic's 1 s lease and that; a process that only stalled for a
        moment, as on a loaded machine, comes back within it), or the graph said ``ready``
        and then not for :data:`GONE_AFTER` s.
        """
        message = self.readiness()
        if message is None:
            return None
        who = f"graph {describe_graph(self.graph or message.get(contract.GRAPH_FIELD))} in {self.where()}"
        if self._ready_sub.get_publisher_count() == 0:
            return f"{who} left: its WM Manager stopped"
        now = time.monotonic()
        if self._ready_alive == 0 and self._lapsed_since is not None and now - self._lapsed_since >= LAPSE_CONFIRM:
            return f"{who} left: its WM Manager's liveliness lapsed (the process died)"
        if message["ready"]:
            self._was_ready, self._unready_since = True, None
        elif self._was_ready:
            self._unready_since = self._unready_since or now
            if now - self._unready_since >= GONE_AFTER:
                waiting = [d for d, st in (message.get("domains") or {}).items() if not st.get("configured")]
                return (f"{who} lost its readiness for {GONE_AFTER:g} s (consultants not configured: "
                        f"{', '.join(waiting) or 'none'})")
        return None

    def check_gone(self) -> None:
        """Raise ClientError ``gone`` if :attr:`notice_leaving` is set and the graph left (checked every 0.1 s)."""
        now = time.monotonic()
        if not self.notice_leaving or now - self._gone_checked < 0.1:
            return
        self._gone_checked = now
        reason = self.gone()
        if reason is not None:
            raise ClientError(reason, "gone")

    def readiness(self) -> Optional[dict]:
        """Return the latest ``wm_manager/ready`` of this client's graph (None before one arrived)."""
        mine = [k for k in self.ready_messages if self.graph is None or k[0] == self.graph]
        return self.ready_messages[max(mine, key=self._ready_heard.__getitem__)] if mine else None

    def _graphs(self) -> list[tuple]:
        return sorted(self.ready_messages, key=str)

    def check_clash(self) -> None:
        """Raise ClientError(``clash``) if two WM Managers announce readiness on this client's names.

        Two messages from WM Managers that are not both matched now (one was restarted)
        are not a clash: the latest heard stands.
        """
        def others() -> bool:  # another WM Manager is known (matched, or a node of that name): hear it
            managers = sum(1 for name, ns in self.node.get_node_names_and_namespaces()
                           if name == "wm_manager" and ns == self.namespace)
            return max(self._ready_sub.get_publisher_count(), managers) > len(self.ready_messages)

        if others():  # collect its latched message (or let a dead one's entity go)
            deadline = time.monotonic() + CLASH_WAIT
            while time.monotonic() < deadline and others():
                self.executor.spin_once(timeout_sec=0.01)
        if len(self.ready_messages) > 1 and self._ready_sub.get_publisher_count() <= 1:
            latest = max(self.ready_messages, key=self._ready_heard.__getitem__)
            self.ready_messages = {latest: self.ready_messages[latest]}
        if len(self.ready_messages) > 1:
            graphs = "; ".join(f"graph {describe_graph(g)} (wm_manager pid {pid} on {host})"
                               for g, pid, host in self._graphs())
            raise ClientError(f"two graphs in {self.where()}: {graphs}; give each its own --namespace or "
                              "ROS_DOMAIN_ID", "clash")

    def wait_ready(self, timeout: float = 30.0, pipeline: bool = True) -> dict:
        """Wait until the graph serves: its WM Manager says ``ready`` (and, with ``pipeline``, every topic matched).

        Learns the graph identity if none was given.  Raises ClientError: ``not-ready``
        (no WM Manager, or not ready in time), ``clash`` (two graphs on these names).
        """
        deadline = time.monotonic() + timeout
        self.spin_until(lambda: self.ready_messages, timeout,
                        f"no fsreg graph answers in {self.where()} (is fsreg-up running there?)", "not-ready")
        self.check_clash()
        if self.graph is None:
            (self.graph, _, _), = self.ready_messages
        if not any(graph == self.graph for graph, _, _ in self.ready_messages):
            found = ", ".join(describe_graph(g) for g, _, _ in self._graphs())
            raise ClientError(f"graph {describe_graph(self.graph)} is not in {self.where()} (found {found})",
                              "not-ready")

        def serving() -> bool:
            message = self.readiness()
            return bool(message and message["ready"])

        remaining = max(0.0, deadline - time.monotonic())
        try:
            self.spin_until(serving, remaining, f"graph {describe_graph(self.graph)} in {self.where()} did not "
                            "become ready", "not-ready")
        except ClientError as err:
            message = self.readiness() or {}
            waiting = [d for d, state in (message.get("domains") or {}).items() if not state.get("configured")]
            raise ClientError(f"{err} (consultants not configured: {', '.join(waiting) or 'none'})",
                              "not-ready") from None
        if pipeline:
            for kind in KIND_TOPICS:
                self.wait_matched(kind, max(0.0, deadline - time.monotonic()))
        return self.readiness() or {}

    def find_running(self, wait: float) -> Optional[str]:
        """Look for a graph in this client's namespace for up to ``wait`` s; describe it in one line (None: none).

        A graph is a node of a graph's name (:data:`GRAPH_NODES`, ``consultant_<domain>``)
        in the namespace, or a WM Manager's readiness there.
        """
        deadline = time.monotonic() + wait
        while True:
            found = sorted(f"{ns.rstrip('/')}/{name}" for name, ns in self.node.get_node_names_and_namespaces()
                           if ns == self.namespace and (name in GRAPH_NODES or name.startswith("consultant_")))
            if found or self.ready_messages:
                if not self.ready_messages:  # its WM Manager's latched readiness names its owner
                    try:
                        self.spin_until(lambda: self.ready_messages, CLASH_WAIT, "readiness")
                    except ClientError:
                        pass
                owners = "; ".join(f"graph {describe_graph(g)}, wm_manager pid {pid} on {host}"
                                   for g, pid, host in self._graphs())
                nodes = f"nodes {', '.join(found)}" if found else "a WM Manager"
                return f"{self.where()} already has a graph: {nodes}" + (f" ({owners})" if owners else "")
            if time.monotonic() >= deadline:
                return None
            self.executor.spin_once(timeout_sec=0.05)

    def domains(self) -> list[str]:
        """Return the names of the graph's domains, as its readiness lists them."""
        message = self.readiness()
        if message is None:
            raise ClientError(f"no fsreg graph answers in {self.where()}", "not-ready")
        return list(message["domains"])

    def graph_nodes(self) -> list[str]:
        """Return the names of the graph's nodes seen in this client's namespace (discovery; may lag)."""
        return sorted(name for name, ns in self.node.get_node_names_and_namespaces()
                      if ns == self.namespace and (name in GRAPH_NODES or name.startswith("consultant_")))

    def node_names(self) -> list[str]:
        """Return the names of the graph's nodes, from its readiness (its domains' consultants and the rest)."""
        return sorted([*GRAPH_NODES[:-1], *(f"consultant_{d}" for d in self.domains())])
