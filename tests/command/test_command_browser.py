"""The monitor page in headless Chromium: it shows the running tree and a node changing
state as the executive ticks.

Needs /usr/bin/chromium (Debian: ``apt-get install -y chromium``); skipped without it, as
this test installs nothing. Chromium is driven through the DevTools protocol over a
WebSocket (a minimal client below: the standard library has none, and this keeps the test
free of extra packages).
"""
from __future__ import annotations

import base64
import json
import os
import shutil
import socket
import struct
import subprocess
import threading
import urllib.request

import pytest

CHROMIUM = "/usr/bin/chromium"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync",
         "--disable-dev-shm-usage", "--remote-debugging-address=127.0.0.1",
         "--remote-debugging-port=0"]

pytestmark = pytest.mark.skipif(not os.path.exists(CHROMIUM),
                                reason=f"{CHROMIUM} is not installed (apt-get install -y "
                                       "chromium; see docs/command-layer.md)")


class DevTools:
    """Just enough of RFC 6455 for the DevTools protocol: text frames, client-masked."""

    def __init__(self, ws_url: str):
        rest = ws_url.split("://", 1)[1]
        hostport, path = rest.split("/", 1)
        host, port = hostport.rsplit(":", 1)
        self.sock = socket.create_connection((host, int(port)), timeout=60)
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((f"GET /{path} HTTP/1.1\r\nHost: {hostport}\r\nUpgrade: websocket\r\n"
                           f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\n"
                           "Sec-WebSocket-Version: 13\r\n\r\n").encode())
        head = b""
        while b"\r\n\r\n" not in head:
            head += self.sock.recv(1)
        assert b" 101 " in head.split(b"\r\n")[0], head
        self.next_id = 0

    def _recv_exact(self, n: int) -> bytes:
        out = b""
        while len(out) < n:
            chunk = self.sock.recv(n - len(out))
            if not chunk:
                raise ConnectionError("DevTools closed the connection")
            out += chunk
        return out

    def _send(self, text: str) -> None:
        data = text.encode()
        mask = os.urandom(4)
        n = len(data)
        head = bytes([0x81]) + (bytes([0x80 | n]) if n < 126 else
                                bytes([0x80 | 126]) + struct.pack(">H", n) if n < 65536 else
                                bytes([0x80 | 127]) + struct.pack(">Q", n))
        self.sock.sendall(head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(data)))

    def _recv(self) -> str:
        parts = []
        while True:
            b0, b1 = self._recv_exact(2)
            n = b1 & 0x7F
            if n == 126:
                n = struct.unpack(">H", self._recv_exact(2))[0]
            elif n == 127:
                n = struct.unpack(">Q", self._recv_exact(8))[0]
            payload = self._recv_exact(n)
            if b0 & 0x0F in (0x1, 0x0):
                parts.append(payload)
                if b0 & 0x80:
                    return b"".join(parts).decode()

    def call(self, method: str, **params):
        self.next_id += 1
        self._send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            msg = json.loads(self._recv())
            if msg.get("id") == self.next_id:
                if "error" in msg:
                    raise RuntimeError(msg["error"])
                return msg["result"]

    def wait_for(self, expression: str, want: str, limit_ms: int = 30000) -> str:
        """Evaluate ``expression`` in the page until it gives ``want`` (or the limit, in the
        browser's time, runs out); returns its last value."""
        js = f"""new Promise(resolve => {{
            const t0 = Date.now();
            (function check() {{
                let v; try {{ v = String({expression}); }} catch (e) {{ v = "error: " + e; }}
                if (v === {json.dumps(want)} || Date.now() - t0 > {limit_ms}) resolve(v);
                else setTimeout(check, 25);
            }})();
        }})"""
        for _ in range(50):   # the page may still be navigating from about:blank
            try:
                res = self.call("Runtime.evaluate", expression=js, awaitPromise=True,
                                returnByValue=True)
            except RuntimeError as err:
                if "context" not in str(err):
                    raise
                continue
            return res["result"].get("value")
        raise RuntimeError("the page never settled")

    def close(self) -> None:
        self.sock.close()


@pytest.fixture
def chromium(tmp_path):
    procs = []

    def launch(url: str) -> DevTools:
        profile = tmp_path / "profile"
        proc = subprocess.Popen([CHROMIUM, *FLAGS, f"--user-data-dir={profile}", url],
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        procs.append(proc)
        port_file = profile / "DevToolsActivePort"
        # Chromium writes the port once it listens; waiting on the file is start-up, bounded.
        for _ in range(600):
            if port_file.exists() and port_file.read_text().strip():
                break
            if proc.poll() is not None:
                pytest.fail(f"chromium exited with {proc.returncode}")
            threading.Event().wait(0.1)
        port = int(port_file.read_text().split()[0])
        targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list"))
        page = next(t for t in targets if t["type"] == "page")
        return DevTools(page["webSocketDebuggerUrl"])
    yield launch
    for p in procs:
        p.terminate()
        p.wait(10)
    shutil.rmtree(tmp_path / "profile", ignore_errors=True)


def test_monitor_page_shows_a_node_change_state(make_server, chromium):
    srv = make_server(granted=1)
    # The knob step waits for an operator's approval: RUNNING until someone decides.
    run_id = srv.client.post("/api/runs", json={"mission": "oven_test"}).json()["run"]["id"]
    events = list(srv.events(run=run_id, close_on_end=False,
                             until=lambda k, d: k == "approval" and d["state"] == "pending"))
    pending = events[-1][1]["id"]
    page = chromium(srv.url + "/")
    node = 'document.querySelector(\'li.node[data-path="/oven_test/turn"]\')?.getAttribute("data-status")'
    assert page.wait_for(node, "RUNNING") == "RUNNING"
    assert page.wait_for('document.getElementById("run-id").textContent', run_id) == run_id
    assert page.wait_for('document.body.getAttribute("data-live")', "1") == "1"
    # The page lists the pending approval; approving it there lets the skill run.
    button = f'document.querySelector(\'[data-request="{pending}"] [data-action="approve"]\')'
    assert page.wait_for(f"{button} !== null", "true") == "true"
    page.call("Runtime.evaluate", expression=f"{button}.click()")
    assert page.wait_for(node, "SUCCESS") == "SUCCESS"
    assert page.wait_for('document.getElementById("run-status").textContent', "succeeded") == "succeeded"
    assert srv.client.get(f"/api/runs/{run_id}").json()["status"] == "succeeded"
    # A run started after the page loaded replaces the tree as it starts.
    second = srv.client.post("/api/runs", json={"mission": "fetch_test",
                                                "params": {"object": "bowl"}}).json()["run"]["id"]
    assert page.wait_for('document.getElementById("run-id").textContent', second) == second
    tell = 'document.querySelector(\'li.node[data-path="/fetch_test/tell"]\')?.getAttribute("data-status")'
    assert page.wait_for(tell, "SUCCESS") == "SUCCESS"
    page.close()
