"""``fsreg-ctl view`` / ``fsreg-up --view``: a live web page of a running graph's working memory.

One process: a ROS node (through :class:`~fsreg_ros.ros.client.GraphClient`) hears the
graph's dialogue, REG's expressions and each consultant's ``wm/state`` and ``wm/events``
and feeds them to a :class:`~fsreg_ros.tools.view_model.ViewModel`; a small HTTP server
(the standard library's, in a thread) serves the page and pushes every change to it as
Server-Sent Events (``/events``), so a change shows within one push (tens of
milliseconds).  ``/snapshot`` is the same data as one JSON object, for scripts.

The server binds 127.0.0.1 unless ``--host`` names another address: the page shows what
people said to the robot.  It needs nothing beyond the wheels (no ROS install, no web
framework).  A consultant restart shows as a new incarnation's ``wm/state``; the view
keeps serving throughout.
"""

from __future__ import annotations

import json
import sys
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Optional

from .view_model import ViewModel
from .view_page import PAGE, SNAPSHOT_SLOT

#: Where the page is served by default (``--port 0`` takes a free port).
DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
#: The WM Manager's status (each domain's next decay tick) is asked for when it may have
#: changed (:meth:`ViewModel.status_wanted`), at most once every so many seconds.
STATUS_EVERY = 0.5
#: How long the view waits for its subscriptions to match the graph's publishers before serving, seconds.
MATCH_WAIT = 5.0
#: An idle event stream sends a comment this often, so proxies and browsers keep it open.
HEARTBEAT = 5.0


class ViewServer(ThreadingHTTPServer):
    """The page, its snapshot and its event stream, over one :class:`ViewModel`."""

    daemon_threads = True

    def __init__(self, model: ViewModel, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT) -> None:
        self.model = model
        self.stopping = threading.Event()
        super().__init__((host, port), _Handler)

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
        except (BrokenPipeError, ConnectionResetError):
            pass  # the page was closed


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
    :data:`STATUS_EVERY` seconds; ``stop`` closes the server.  ``fsreg-ctl view`` loops on ``step``; so does
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
