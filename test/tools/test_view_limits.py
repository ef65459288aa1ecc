"""The live view under hostile or careless clients (issues 37.8 and 38.7).

A wildcard host is refused unless the network is allowed; browsers that leave mid-stream
or mid-request print nothing; a silent connection is closed after the idle timeout; no
more than the cap of connections are served (one more gets 503); the model's memory stays
bounded however many utterances pass.
"""

from __future__ import annotations

import socket
import struct
import threading

import pytest

from fsreg_ros.tools import ctl, view
from fsreg_ros.tools.view import ViewServer, check_host
from fsreg_ros.tools.view_model import DIALOGUE_LINES, MAX_HELD, MAX_ORIGINS, ViewModel

WILDCARD = ("would bind every network interface: name one address (default 127.0.0.1: this machine only), or set "
            "FSREG_ALLOW_NETWORK=1 to serve the network deliberately")


@pytest.mark.parametrize("host", ["", " ", "0", "0.0.0.0", "::", "0x0"])
def test_an_empty_or_wildcard_host_is_refused_unless_the_network_is_allowed(host, capsys, monkeypatch):
    monkeypatch.delenv("FSREG_ALLOW_NETWORK", raising=False)
    with pytest.raises(ValueError) as err:
        check_host(host)
    assert str(err.value) == f"--host {host!r} {WILDCARD}"
    with pytest.raises(ValueError):
        ViewServer(ViewModel(), host, 0)  # the server itself never binds it
    assert ctl.main(["view", "--host", host, "--port", "0"]) == 2
    assert capsys.readouterr().err == f"fsreg-ctl: error: view: --host {host!r} {WILDCARD}\n"
    assert check_host(host, {"FSREG_ALLOW_NETWORK": "1"}) == host
    assert check_host("127.0.0.1") == "127.0.0.1" and check_host("localhost") == "localhost"


def rst(sock: socket.socket) -> None:
    """Close ``sock`` with a TCP reset, as a browser tab that is killed does."""
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    sock.close()


@pytest.fixture
def served(monkeypatch):
    model = ViewModel()
    server = ViewServer(model, "127.0.0.1", 0)
    server.start()
    try:
        yield model, server
    finally:
        server.stop()


def connect(server: ViewServer) -> socket.socket:
    sock = socket.create_connection(server.server_address[:2], timeout=10)
    return sock


def test_browsers_that_leave_mid_stream_or_mid_request_print_nothing(served, capfd):
    model, server = served
    for i in range(30):  # coming and going
        stream = connect(server)
        stream.sendall(b"GET /events HTTP/1.1\r\nHost: x\r\n\r\n")
        assert stream.recv(4096).startswith(b"HTTP/1.0 200 OK")
        model.on_human({"id": f"u{i}", "text": "male", "time": float(i)})  # a push to a page that is going
        rst(stream)
        half = connect(server)
        half.sendall(b"GET /snapsh")  # the browser leaves before its request ends
        rst(half)
        page = connect(server)
        page.sendall(b"GET / HTTP/1.1\r\n\r\n")
        rst(page)  # before the page was read
    probe = connect(server)
    probe.sendall(b"GET /snapshot HTTP/1.1\r\n\r\n")
    answer = b""
    while chunk := probe.recv(65536):
        answer += chunk
    assert answer.startswith(b"HTTP/1.0 200 OK") and b'"u29"' in answer
    server.stop()
    out, err = capfd.readouterr()
    assert (out, err) == ("", "")


def test_a_silent_connection_is_closed_after_the_idle_timeout(monkeypatch):
    monkeypatch.setattr(view._Handler, "timeout", 0.3)
    server = ViewServer(ViewModel(), "127.0.0.1", 0)
    server.start()
    try:
        idle = connect(server)  # sends nothing
        assert idle.recv(1) == b""  # closed by the server (the client waits up to 10 s)
        half = connect(server)
        half.sendall(b"GET /snapshot HTTP/1.1\r\n")  # a request never finished
        assert half.recv(1) == b""
    finally:
        server.stop()


def test_connections_beyond_the_cap_get_503_and_the_rest_are_served(monkeypatch, served):
    monkeypatch.setattr(view, "MAX_CONNECTIONS", 3)
    model, server = served
    held = [connect(server) for _ in range(3)]
    for sock in held:
        sock.sendall(b"GET /events HTTP/1.1\r\n\r\n")
        assert sock.recv(64).startswith(b"HTTP/1.0 200")
    assert server.connections == 3
    extra = connect(server)
    assert extra.recv(4096).startswith(b"HTTP/1.0 503 Service Unavailable")
    for sock in held:
        sock.close()
    done = threading.Event()
    for _ in range(1000):  # each change wakes every stream: it finds its page gone and ends
        if not server.connections:
            break
        model.on_human({"id": "x", "text": "male"})
        done.wait(0.01)
    assert server.connections == 0
    again = connect(server)
    again.sendall(b"GET /snapshot HTTP/1.1\r\n\r\n")
    assert again.recv(64).startswith(b"HTTP/1.0 200")


def test_the_model_stays_bounded_however_many_utterances_and_encodings_pass():
    model = ViewModel()
    for i in range(5 * DIALOGUE_LINES):
        model.on_human({"id": f"u{i}", "text": "male", "time": float(i)})
        model.on_rr({"id": f"u{i}", "resolved": "face1", "status": "resolved"})
        model.on_expression({"id": f"r{i}", "target": "face1", "text": "the man", "description": ["male"]})
    for i in range(MAX_ORIGINS + 10):
        model.on_event({"domain": "faces", "entity": f"e{i}", "property": "male", "op": "encode", "time": 1.0})
    sizes = model.sizes()
    assert sizes == {"dialogue": DIALOGUE_LINES, "ids": DIALOGUE_LINES, "origins": MAX_ORIGINS, "domains": 0,
                     "held": 0, "unread": MAX_HELD}  # every entity with an event waits to be read: bounded too
    lines = model.snapshot()["dialogue"]
    assert [line["id"] for line in lines[-2:]] == [f"u{5 * DIALOGUE_LINES - 1}", f"r{5 * DIALOGUE_LINES - 1}"]
    assert lines[-2]["resolved"] == "face1"  # an answer still joins its utterance
