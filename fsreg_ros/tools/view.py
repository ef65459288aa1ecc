"""``fsreg-ctl view`` / ``fsreg-up --view``: a live web page of a running graph's working memory.

One process: a ROS node (through :class:`~fsreg_ros.ros.client.GraphClient`) hears the
graph's dialogue, REG's expressions and each consultant's ``wm/state`` and ``wm/events``
and feeds them to a :class:`~fsreg_ros.tools.view_model.ViewModel`; a small HTTP server
(the standard library's, in a thread) serves the page and pushes every change to it as
Server-Sent Events (``/events``), so a change shows within one push (tens of
milliseconds).  ``/snapshot`` is the same data as one JSON object, for scripts.

The server binds 127.0.0.1 unless ``--host`` names another address: the page shows what
people said to the robot.  A host that would bind every interface is refused unless the
network is allowed deliberately (``FSREG_ALLOW_NETWORK=1``, as for DDS: :func:`check_host`):
refused are the empty and wildcard hosts ``''``, ``0``, ``0.0.0.0`` and ``::``.  It serves at most
:data:`MAX_CONNECTIONS` connections at once (one thread each; one more is answered 503
and closed) and closes a connection silent for :data:`IDLE_TIMEOUT` seconds (a request
never finished, a page that stopped reading its stream).  A browser that leaves is not
an error: nothing is printed for a connection reset, a broken pipe or a timeout.  It
needs nothing beyond the wheels (no ROS install, no web framework).  A consultant
restart shows as a new incarnation's ``wm/state``; the view keeps serving throughout.
"""

from __future__ import annotations

import ipaddress
import json
import os
import socket
import sys
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Mapping, Optional

from .view_model import ViewModel
from .view_page import PAGE, SNAPSHOT_SLOT

#: Where the page is served by default (``--port 0`` takes a free port).
DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
#: The WM Manager's status (each domain's next decay tick) is asked for when it may have
#: changed (:meth:`ViewModel.status_wanted`), at most once every so many seconds.
STATUS_EVERY = 0.5
#: Entities whose strength the view reads per step (:meth:`ViewModel.strength_wanted`; two service calls each).
HELD_PER_STEP = 8
#: How long the view waits for its subscriptions to match the graph's publishers before serving, seconds.
MATCH_WAIT = 5.0
#: An idle event stream sends a comment this often, so proxies and browsers keep it open.
HEARTBEAT = 5.0
#: Seconds a connection may stay silent (a request not finished, a stream not read) before it is closed.
IDLE_TIMEOUT = 15.0
#: Connections served at once (a thread each); one more is answered 503 and closed.
MAX_CONNECTIONS = 128
#: What a browser that leaves or stalls raises in its connection's thread: not an error of the view.
GONE = (ConnectionError, TimeoutError)


def check_host(host: str, env: Optional[Mapping[str, str]] = None) -> str:
    """Return ``host`` if the view may bind it; ValueError (one line) for an empty or wildcard address.

    A wildcard binds every interface of the machine; it is taken only when the network
    is allowed deliberately (``FSREG_ALLOW_NETWORK=1``, :func:`fsreg_ros.ros.network.network_allowed`).
    A name is resolved: ``0`` or ``0x0`` is the wildcard too.
    """
    from ..ros.network import ALLOW_NETWORK, network_allowed

    if network_allowed(dict(os.environ if env is None else env)):
        return host
    wildcard = not host.strip()
    if not wildcard:
        try:
            found = socket.getaddrinfo(host, None, type=socket.SOCK_STREAM)
        except (OSError, UnicodeError, ValueError):
            found = []  # not an address: binding it fails with its own reason
        for *_, address in found:
            try:
                wildcard = wildcard or ipaddress.ip_address(str(address[0]).split("%")[0]).is_unspecified
            except ValueError:
                continue
    if wildcard:
        raise ValueError(f"--host {host!r} would bind every network interface: name one address (default "
                         f"{DEFAULT_HOST}: this machine only), or set {ALLOW_NETWORK}=1 to serve the network "
                         "deliberately")
    return host


class ViewServer(ThreadingHTTPServer):
    """The page, its snapshot and its event stream, over one :class:`ViewModel`."""

    daemon_threads = True
    request_queue_size = MAX_CONNECTIONS  # the listen backlog (socketserver's default, 5, drops a burst of pages)

    def __init__(self, model: ViewModel, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT) -> None:
        self.model = model
        self.stopping = threading.Event()
        self._active = 0  # connections being served
        self._count = threading.Lock()
        super().__init__((check_host(host), port), _Handler)

    @property
    def connections(self) -> int:
        """Connections being served now."""
        with self._count:
            return self._active

    def process_request(self, request, client_address) -> None:
        """Serve a connection in a thread of its own, unless :data:`MAX_CONNECTIONS` are served (503, closed)."""
        with self._count:
            full = self._active >= MAX_CONNECTIONS
            if not full:
                self._active += 1
        if full:
            try:
                request.settimeout(1.0)
                request.sendall(b"HTTP/1.0 503 Service Unavailable\r\nContent-Length: 0\r\nRetry-After: 5\r\n\r\n")
            except OSError:
                pass
            self.shutdown_request(request)
            return
        try:
            super().process_request(request, client_address)
        except BaseException:
            self._release()
            raise

    def process_request_thread(self, request, client_address) -> None:  # the connection's thread
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._release()

    def _release(self) -> None:
        with self._count:
            self._active -= 1

    def handle_error(self, request, client_address) -> None:
        """Say nothing of a browser that left or stalled; print anything else as one line on stderr."""
        err = sys.exc_info()[1]
        if isinstance(err, GONE):
            return
        from ..contract.codec import printable

        print(printable(f"fsreg view: a request from {client_address[0]} failed: {type(err).__name__}: {err}", 300),
              file=sys.stderr, flush=True)

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        return f"http://{host}:{port}/"

    def start(self) -> threading.Thread:
        """Serve in a daemon thread; return it."""
        thread = threading.Thread(target=self.serve_forever, kwargs={"poll_interval": 0.1}, daemon=True,
                                  name="fsreg-view")
        thread.start()
        return thread

    def stop(self) -> None:
        self.stopping.set()
        with self.model._lock:  # wake every event stream so it sees the stop
            self.model._lock.notify_all()
        self.shutdown()
        self.server_close()


class _Handler(BaseHTTPRequestHandler):
    server: ViewServer
    timeout = IDLE_TIMEOUT  # the socket's: a silent connection is closed

    def log_message(self, format: str, *args) -> None:  # noqa: A002 - the base class's name
        pass  # a page's requests are not the operator's business

    def _send(self, status: int, body: bytes, kind: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        self.wfile.write(body)

    def do_GET(self) -> None:  # noqa: N802 - the base class's name
        path = self.path.split("?", 1)[0]
        if path in ("/", "/index.html"):
            snapshot = json.dumps(self.server.model.snapshot(), sort_keys=True).replace("</", "<\\/")
            self._send(200, PAGE.replace(SNAPSHOT_SLOT, snapshot).encode("utf-8"), "text/html; charset=utf-8")
        elif path == "/snapshot":
            self._send(200, json.dumps(self.server.model.snapshot(), sort_keys=True).encode(), "application/json")
        elif path == "/events":
            self._stream()
        else:
            self._send(404, b"not found\n", "text/plain")

    def _stream(self) -> None:
        self.send_response(200)
        self.send_header("Content-Type", "text/event-stream")
        self.send_header("Cache-Control", "no-store")
        self.end_headers()
        model, seen, last = self.server.model, -1, time.monotonic()
        try:
            while not self.server.stopping.is_set():
                version = model.wait_change(seen, 0.5)
                if version != seen:
                    seen = version
                    data = json.dumps(model.snapshot(), sort_keys=True)
                    self.wfile.write(f"data: {data}\n\n".encode())
                    self.wfile.flush()
                    last = time.monotonic()
                elif time.monotonic() - last > HEARTBEAT:
                    self.wfile.write(b": alive\n\n")
                    self.wfile.flush()
                    last = time.monotonic()
        except GONE:
            pass  # the page was closed, or stopped reading


def feed(client, model: ViewModel) -> list:
    """Subscribe ``model`` to the graph ``client`` talks to; return the subscriptions (keep them)."""
    from .. import contract
    from ..ros.carrier import subscribe

    client.watch(model.on_state, model.on_event)
    mine = [subscribe(client.node, contract.HUMAN, model.on_human),
            subscribe(client.node, contract.RR_RESULT, model.on_rr),
            subscribe(client.node, contract.REG_EXPRESSION, model.on_expression),
            subscribe(client.node, contract.READY, model.on_ready)]
    for ready in list(client.ready_messages.values()):
        model.on_ready(ready)
    wanted = [contract.RR_RESULT.name, contract.REG_EXPRESSION.name]  # the graph's own publishers: hear them first
    deadline = time.monotonic() + MATCH_WAIT
    while time.monotonic() < deadline and not all(client.node.count_publishers(name) for name in wanted):
        client.executor.spin_once(timeout_sec=0.05)
    return mine


class LiveView:
    """The view of one graph: its model, its server and the client that feeds them.

    ``start`` binds the address (OSError if it cannot) and subscribes; ``step`` spins the
    client's executor once and, when the model wants it (at the start, after a readiness
    message, once a decay tick is reached), asks the WM Manager's status, at most every
    :data:`STATUS_EVERY` seconds, then reads the strength of up to :data:`HELD_PER_STEP`
    entities whose WM changed (the consultant's ``open`` reply, :meth:`GraphClient.held`,
    as ``fsreg-ctl wm`` reads it); ``stop`` closes the server.  ``fsreg-ctl view`` loops on ``step``; so does
    ``fsreg-up --view`` between its supervision of the nodes.
    """

    def __init__(self, client, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT) -> None:
        self.client = client
        self.model = ViewModel()
        self.server = ViewServer(self.model, host, port)
        self._subscriptions: list = []
        self._next_status = 0.0
        self._status_failed = False

    @property
    def url(self) -> str:
        return self.server.url

    def start(self) -> None:
        self._subscriptions = feed(self.client, self.model)
        self.server.start()

    def step(self, timeout: float = 0.05) -> None:
        from ..ros.client import ClientError

        self.client.executor.spin_once(timeout_sec=timeout)
        if self.client.foreign is not None:
            raise ClientError(self.client.foreign, "foreign")
        if self.model.status_wanted() and time.monotonic() >= self._next_status:
            self._next_status = time.monotonic() + STATUS_EVERY
            try:
                self.model.on_status(self.client.status(timeout=2.0))
                self._status_failed = False
            except ClientError as err:  # the manager is restarting or gone: the view keeps what it has
                if not self._status_failed:
                    print(f"fsreg view: status: {err}", file=sys.stderr, flush=True)
                self._status_failed = True
        for domain, entity in self.model.strength_wanted(HELD_PER_STEP):
            try:
                self.model.on_held(domain, entity, self.client.held(entity, domain, timeout=2.0))
            except ClientError:  # gone meanwhile, or its consultant restarting: their next change asks again
                break

    def stop(self) -> None:
        self.server.stop()
        self._subscriptions = []


def serve_view(client, host: str, port: int, *, until=None, announce=print) -> int:
    """Serve the live view of ``client``'s graph until ``until()`` is true (or Ctrl-C); return 0.

    The caller has found the graph (``client.graph`` set).  Raises OSError when the
    address cannot be bound.
    """
    view = LiveView(client, host, port)
    view.start()
    announce(f"fsreg view of {client.where()} at {view.url} (Ctrl-C ends)")
    try:
        while until is None or not until():
            view.step()
    finally:
        view.stop()
    return 0


def check_port(port: Optional[int]) -> int:
    """Return the TCP port of the command line (0 = any free port); ValueError out of range."""
    if port is None:
        return DEFAULT_PORT
    if not 0 <= port <= 65535:
        raise ValueError(f"--port must be between 0 and 65535, got {port}")
    return port
