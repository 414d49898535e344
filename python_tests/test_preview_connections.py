"""`painterly preview` over many connections (README Limits): at most 256
open at once, a connection that sends no request headers within 30 s is
closed, and the requests of a page that has gone are not evaluated."""

import json
import re
import shutil
import socket
import subprocess
import threading
import time
import urllib.parse

import pytest

from conftest import REPO
from preview_helpers import PreviewServer, WebSocket

MAX_CONNECTIONS = 256
HEADER_TIMEOUT = 30
CAMERA = {"position": [0, 0, 50], "target": [0, 0, 0], "up": [0, 1, 0], "fov_y": 30, "near": 0.1, "far": 1000}


@pytest.fixture
def fish(tmp_path):
    p = tmp_path / "blowfish.usda"
    shutil.copy(REPO / "fixtures" / "blowfish.usda", p)
    return p


def address(server):
    u = urllib.parse.urlsplit(server.url)
    return (u.hostname, u.port), u.netloc


def read_response(sock):
    """The status of one HTTP/1.1 response with a Content-Length, read whole."""
    buf = b""
    while b"\r\n\r\n" not in buf:
        chunk = sock.recv(65536)
        assert chunk, f"closed before a response: {buf!r}"
        buf += chunk
    head, body = buf.split(b"\r\n\r\n", 1)
    length = int(re.search(rb"(?i)content-length: *(\d+)", head).group(1))
    while len(body) < length:
        body += sock.recv(65536)
    return int(head.split()[1])


def status_then_closed(sock, seconds):
    """The status of the one response the server sends on `sock` within
    `seconds`, which it then closes; None when it does not."""
    sock.settimeout(seconds)
    buf = b""
    try:
        while chunk := sock.recv(65536):
            buf += chunk
    except socket.timeout:
        return None
    return int(buf.split()[1]) if buf else 0


def server_ss(port, client_port):
    """`ss -o` of the server's end of the connection from `client_port`."""
    return subprocess.run(["ss", "-tnoH", "state", "established", f"( sport = :{port} and dport = :{client_port} )"],
                          capture_output=True, text=True, check=True).stdout


def server_side_closed(port, client_port, seconds):
    """Whether the server closes its end of that connection within `seconds`."""
    deadline = time.monotonic() + seconds
    while server_ss(port, client_port).strip():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.2)
    return True


def closed_within(sock, seconds):
    """Whether the server closes `sock` within `seconds` (it sends nothing)."""
    sock.settimeout(seconds)
    try:
        return sock.recv(1) == b""
    except ConnectionResetError:
        return True
    except socket.timeout:
        return False


def test_idle_connections_are_capped_and_closed_after_the_header_timeout(fish):
    """256 connections that never send a request (one of them kept alive
    after one, four more stalled in a request's body, one pipelining
    requests whose replies it never reads) hold every slot: a new request
    waits, not refused, until the server closes the idle ones 30 s after
    their last request (the stalled ones get 408 first) and the unread one
    30 s after its replies stopped, and is then answered. Before, nothing
    bounded them: a client holding idle, half-sent or unread requests used
    up the server's file descriptors."""
    with PreviewServer(fish) as server:
        addr, host = address(server)
        kept = socket.create_connection(addr)
        kept.sendall(f"GET /api/scene HTTP/1.1\r\nHost: {host}\r\n\r\n".encode())
        assert read_response(kept) == 200
        stalled = []
        for path in ["api/frame", "api/render"] * 2:
            s = socket.create_connection(addr)
            s.sendall(f"POST /{path} HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/json\r\n"
                      "Content-Length: 2000000\r\n\r\n{\"id\": 1, ".encode())
            stalled.append(s)
        # A client that pipelines requests and never reads the replies:
        # the server's writes wait, and no header timer runs then.
        unread = socket.create_connection(addr)
        request = json.dumps({"id": 1, "time": 1}).encode()
        head = (f"POST /api/frame HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/json\r\n"
                f"Content-Length: {len(request)}\r\n\r\n").encode()
        unread.sendall(60 * (head + request))
        idle = [socket.create_connection(addr) for _ in range(MAX_CONNECTIONS - 2 - len(stalled))]
        opened = time.monotonic()
        answered = {}

        def late_request():
            s = socket.create_connection(addr, timeout=120)
            s.sendall(f"GET /api/scene HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n".encode())
            answered["status"] = read_response(s)
            answered["after"] = time.monotonic() - opened
            s.close()

        t = threading.Thread(target=late_request)
        t.start()
        try:
            t.join(10)
            assert "status" not in answered, "a connection past the cap was served at once"
            assert closed_within(kept, HEADER_TIMEOUT + 30)
            assert all(closed_within(s, 30) for s in idle)
            assert [status_then_closed(s, 30) for s in stalled] == [408] * len(stalled)
            assert server_side_closed(addr[1], unread.getsockname()[1], 30), "an unread reply kept its slot"
            t.join(30)
            assert answered.get("status") == 200
            assert HEADER_TIMEOUT - 5 < answered["after"] < HEADER_TIMEOUT + 60
        finally:
            for s in [kept, *idle, *stalled, unread]:
                s.close()
            t.join(120)
        assert server.alive()
        # The server goes on; a page's websocket has TCP keepalive on (a
        # peer that vanished from the network frees its slot).
        ws = WebSocket(server.url)
        ws.send(json.dumps({"id": 1, "time": 1}))
        assert ws.recv()[0] == 2
        local = ws.sock.getsockname()
        # ss shows one timer: a retransmit one while sent bytes await
        # their acknowledgement, the keepalive one once the socket idles.
        for _ in range(50):
            ss = server_ss(addr[1], local[1])
            if "timer:(keepalive," in ss:
                break
            time.sleep(0.1)
        ws.close()
        assert "timer:(keepalive," in ss, ss


def test_requests_of_a_page_that_has_gone_are_not_evaluated(fish):
    """Pages that send a frame request and close (over the websocket or
    HTTP) while the evaluator is busy: their requests are skipped (the
    `-v` log says so), and the next page's frame is the only one computed
    after the busy render. Before, each was evaluated for nobody."""
    with PreviewServer(fish, "-v") as server:
        addr, host = address(server)
        render = {"frame": {"time": 1}, "camera": CAMERA, "width": 4096, "height": 4096}
        busy = [threading.Thread(target=lambda: server.request("api/render", body=render)) for _ in range(3)]
        for b in busy:
            b.start()
        # The renders are queued first; they take about 1 s each, the pages
        # below about 0.3 s in all.
        time.sleep(0.3)
        for i in range(10):
            ws = WebSocket(server.url)
            ws.send(json.dumps({"id": 100 + i, "time": 2}))
            ws.close()
        body = json.dumps({"id": 200, "time": 3}).encode()
        for _ in range(5):
            s = socket.create_connection(addr)
            s.sendall(f"POST /api/frame HTTP/1.1\r\nHost: {host}\r\nContent-Type: application/json\r\n"
                      f"Content-Length: {len(body)}\r\n\r\n".encode() + body)
            s.close()
        for b in busy:
            b.join(120)
        ws = WebSocket(server.url)
        ws.send(json.dumps({"id": 1, "time": 4}))
        assert ws.recv()[0] == 2
        ws.close()
        server.stop()
        log = server.proc.stderr.read()
    frames = re.findall(r"preview: frame request (\d+) at time", log)
    assert frames == ["1"], log
    assert log.count("preview: render of 4096x4096 at time 1 in ") == 3, log
    # The websocket requests reach the evaluator's queue (a request is
    # queued before the socket is watched) and are skipped there; HTTP
    # ones may be dropped before (hyper saw the close first).
    assert 10 <= log.count("preview: a request skipped (its client has gone)") <= 15, log


def cpu_seconds(pid):
    """User + system CPU time of process `pid` so far."""
    import os

    fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def test_out_of_descriptors_the_server_waits_then_serves(fish):
    """With the server's descriptors used up, `accept` fails (EMFILE) while
    the connection stays queued: retrying at once would spin a core until
    one frees. The server waits between tries, and serves once they free."""
    import os
    import resource

    with PreviewServer(fish) as server:
        addr, host = address(server)
        pid = server.proc.pid
        old = resource.prlimit(pid, resource.RLIMIT_NOFILE)
        used = len(os.listdir(f"/proc/{pid}/fd"))
        resource.prlimit(pid, resource.RLIMIT_NOFILE, (used + 8, old[1]))
        socks = [socket.create_connection(addr) for _ in range(24)]
        try:
            time.sleep(0.5)
            before = cpu_seconds(pid)
            time.sleep(2)
            spent = cpu_seconds(pid) - before
            assert spent < 0.5, f"{spent:.2f} s of CPU in 2 s with no descriptor to accept into"
        finally:
            for s in socks:
                s.close()
            resource.prlimit(pid, resource.RLIMIT_NOFILE, old)
        status, _, _ = server.request("api/scene")
        assert status == 200 and server.alive()
