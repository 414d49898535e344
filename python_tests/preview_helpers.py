"""Helpers for `painterly preview` tests: start/stop the server by pid, speak
its HTTP protocol (docs/preview.md), drive Debian's chromium through
browser_tests/driver.mjs (playwright-core)."""

import base64
import hashlib
import json
import os
import pathlib
import re
import shutil
import signal
import socket
import struct
import subprocess
import time
import urllib.error
import urllib.parse
import urllib.request

from conftest import REPO, painterly_binary

MAGIC = struct.unpack("<I", b"PTLY")[0]
CHROMIUM = pathlib.Path(os.environ.get("CHROMIUM", "/usr/bin/chromium"))
DRIVER = REPO / "browser_tests" / "driver.mjs"


def decode_frame(data: bytes):
    """(header, {name: list of floats}) of a binary reply."""
    import numpy as np

    magic, n = struct.unpack_from("<II", data, 0)
    assert magic == MAGIC, f"bad magic {magic:#x}"
    assert n % 4 == 0
    header = json.loads(data[8 : 8 + n])
    payload = np.frombuffer(data, dtype="<f4", offset=8 + n)
    arrays = {name: payload[off : off + length] for name, (off, length) in header["arrays"].items()}
    return header, arrays


class PreviewServer:
    """`painterly preview IN --port 0 ...`, stopped by its pid on exit."""

    def __init__(self, path, *args):
        self.args = [str(painterly_binary()), "preview", str(path), "--port", "0", *map(str, args)]
        self.proc = None
        self.url = None

    def __enter__(self):
        self.proc = subprocess.Popen(self.args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 120
        line = ""
        while time.monotonic() < deadline:
            line = self.proc.stdout.readline()
            if not line:
                break
            m = re.search(r"(http://\S+/)", line)
            if m:
                self.url = m.group(1)
                return self
        self.stop()
        raise AssertionError(f"preview did not print a URL (last line {line!r}): {self.proc.stderr.read()}")

    def stop(self):
        if self.proc and self.proc.poll() is None:
            os.kill(self.proc.pid, signal.SIGTERM)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                os.kill(self.proc.pid, signal.SIGKILL)
                self.proc.wait()

    def __exit__(self, *exc):
        self.stop()

    def alive(self):
        return self.proc.poll() is None

    def request(self, path, body=None, method=None, headers=None, raw=None):
        """(status, headers, bytes); JSON `body` is sent as application/json."""
        data = raw
        hdrs = dict(headers or {})
        if body is not None:
            data = json.dumps(body).encode()
            hdrs.setdefault("Content-Type", "application/json")
        req = urllib.request.Request(self.url + path.lstrip("/"), data=data, method=method, headers=hdrs)
        try:
            with urllib.request.urlopen(req, timeout=120) as r:
                return r.status, dict(r.headers), r.read()
        except urllib.error.HTTPError as e:
            return e.code, dict(e.headers), e.read()

    def scene(self):
        status, _, data = self.request("api/scene")
        assert status == 200
        return json.loads(data)

    def frame(self, **req):
        status, _, data = self.request("api/frame", body=req)
        assert status == 200, data
        return decode_frame(data)


class WebSocketRefused(Exception):
    """The server answered the handshake with `status` instead of 101."""

    def __init__(self, status, line):
        super().__init__(line)
        self.status = status


class WebSocket:
    """A minimal RFC 6455 client for `GET /api/ws`: masked messages out,
    whole (unfragmented) messages in, handshake checked as the RFC says.
    `origin`: the `Origin` header a browser page would send (none: curl)."""

    GUID = b"258EAFA5-E914-47DA-95CA-C5AB0DC85B11"

    def __init__(self, url, timeout=120, origin=None):
        u = urllib.parse.urlsplit(url)
        self.sock = socket.create_connection((u.hostname, u.port), timeout=timeout)
        self.buf = b""
        key = base64.b64encode(os.urandom(16))
        extra = f"Origin: {origin}\r\n" if origin is not None else ""
        self.sock.sendall(
            (f"GET {u.path}api/ws HTTP/1.1\r\nHost: {u.netloc}\r\nUpgrade: websocket\r\n{extra}"
             f"Connection: Upgrade\r\nSec-WebSocket-Key: {key.decode()}\r\nSec-WebSocket-Version: 13\r\n\r\n").encode())
        while b"\r\n\r\n" not in self.buf:
            self.buf += self._recv_some()
        head, self.buf = self.buf.split(b"\r\n\r\n", 1)
        lines = head.decode().split("\r\n")
        if lines[0].split()[1] != "101":
            self.sock.close()
            raise WebSocketRefused(int(lines[0].split()[1]), lines[0])
        headers = {k.strip().lower(): v.strip() for k, v in (line.split(":", 1) for line in lines[1:])}
        assert headers["sec-websocket-accept"] == base64.b64encode(hashlib.sha1(key + self.GUID).digest()).decode()

    def _recv_some(self):
        chunk = self.sock.recv(65536)
        if not chunk:
            raise EOFError("the server closed the connection")
        return chunk

    def _read(self, n):
        while len(self.buf) < n:
            self.buf += self._recv_some()
        out, self.buf = self.buf[:n], self.buf[n:]
        return out

    def send(self, payload, opcode=1):
        """Sends a text (opcode 1) or binary (2) message."""
        data = payload.encode() if isinstance(payload, str) else bytes(payload)
        n = len(data)
        if n < 126:
            head = bytes([0x80 | opcode, 0x80 | n])
        elif n < 1 << 16:
            head = bytes([0x80 | opcode, 0x80 | 126]) + struct.pack(">H", n)
        else:
            head = bytes([0x80 | opcode, 0x80 | 127]) + struct.pack(">Q", n)
        mask = os.urandom(4)
        masked = bytes(b ^ mask[i % 4] for i, b in enumerate(data))
        self.sock.sendall(head + mask + masked)

    def recv(self):
        """(opcode, payload) of the next message: 1 text, 2 binary, 8 close."""
        b0, b1 = self._read(2)
        assert b0 & 0x80 and not b1 & 0x80, "whole, unmasked server messages"
        n = b1 & 0x7F
        if n == 126:
            n = struct.unpack(">H", self._read(2))[0]
        elif n == 127:
            n = struct.unpack(">Q", self._read(8))[0]
        return b0 & 0x0F, self._read(n)

    def close(self):
        self.sock.close()


def browser_available():
    """Why the browser tests cannot run, or None."""
    if not CHROMIUM.exists():
        return f"{CHROMIUM} is missing (scripts/test installs Debian's chromium)"
    if not (REPO / "node_modules" / "playwright-core").exists():
        return "node_modules/playwright-core is missing (scripts/test runs npm ci)"
    if not shutil.which("node"):
        return "node is missing"
    return None


class Browser:
    """Debian's chromium driven by playwright-core through driver.mjs."""

    def __init__(self):
        self.proc = subprocess.Popen(
            ["node", str(DRIVER)],
            cwd=REPO,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        self.browser_pids = []
        r = self.call("launch")
        self.browser_pids = r["browser_pids"]

    def call(self, cmd, **kw):
        self.proc.stdin.write(json.dumps({"cmd": cmd, **kw}) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            raise AssertionError(f"browser driver died: {self.proc.stderr.read()}")
        reply = json.loads(line)
        if not reply.pop("ok"):
            raise AssertionError(f"browser {cmd} failed: {reply['error']}")
        return reply

    def eval(self, js):
        return self.call("eval", js=js).get("value")

    def wait(self, js, timeout=30000):
        self.call("wait", js=js, timeout=timeout)

    def settle(self, frames_before=None):
        """Waits until no frame request is pending (and a new frame was drawn)."""
        cond = "window.painterly && window.painterly.idle()"
        if frames_before is not None:
            cond += f" && window.painterly.framesDrawn > {frames_before}"
        self.wait(cond)
        # One animation frame so the canvas shows what arrived.
        self.eval("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")

    def close(self):
        try:
            if self.proc.poll() is None:
                self.call("quit")
                self.proc.wait(timeout=20)
        except Exception:
            pass
        finally:
            if self.proc.poll() is None:
                os.kill(self.proc.pid, signal.SIGKILL)
            for pid in self.browser_pids:
                # Only a browser process we started that is still there.
                try:
                    comm = pathlib.Path(f"/proc/{pid}/comm").read_text()
                except OSError:
                    continue
                if "chrom" in comm:
                    try:
                        os.kill(pid, signal.SIGKILL)
                    except ProcessLookupError:
                        pass
            if self.proc.poll() is None:
                self.proc.wait()
