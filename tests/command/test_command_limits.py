"""What the API refuses before it does any work: a foreign Host (DNS rebinding), bodies and
fields over their limits, one event stream too many; and HTTPS when asked for."""
from __future__ import annotations

import json
import shutil
import socket
import ssl
import subprocess

import httpx
import pytest

from hearth.cli.main import main
from hearth.executive.command.api import (MAX_BODY_BYTES, MAX_PARAMS_BYTES, MAX_VALUE_BYTES,
                                   host_is_served)
from hearth.cli.commands.serve import check_tls


def _raw(url: str, head: str, body: bytes = b"") -> tuple[int, dict, bytes]:
    """Send a hand-written request over a socket; return status, headers, body. The server
    may answer before the request is complete, and closes the connection."""
    host, port = url.split("//")[1].split(":")
    with socket.create_connection((host, int(port)), timeout=30) as s:
        s.sendall(head.replace("\n", "\r\n").encode() + b"\r\n" + body)
        data = b""
        while chunk := s.recv(65536):
            data += chunk
    head_bytes, _, rest = data.partition(b"\r\n\r\n")
    lines = head_bytes.decode("latin-1").split("\r\n")
    headers = dict(line.split(": ", 1) for line in lines[1:])
    return int(lines[0].split()[1]), {k.lower(): v for k, v in headers.items()}, rest


def test_a_foreign_host_header_is_refused_with_one_json_error(server):
    for path in ("/api/health", "/", "/openapi.json"):
        r = server.client.get(path, headers={"Host": "evil.example.com:8080"})
        assert r.status_code == 421
        assert "'evil.example.com'" in r.json()["error"]["message"]
        assert "--allowed-host" in r.json()["error"]["message"]
    # Nothing was started by a refused request.
    r = server.client.post("/api/runs", json={"mission": "fetch_test",
                                              "params": {"object": "blue_cup"}},
                           headers={"Host": "rebind.attacker.test"})
    assert r.status_code == 421
    assert server.client.get("/api/runs").json() == []


def test_the_served_address_and_localhost_are_accepted(server):
    port = server.thread.port
    for host in (f"127.0.0.1:{port}", f"localhost:{port}", "LOCALHOST", f"[::1]:{port}"):
        assert server.client.get("/api/health", headers={"Host": host}).status_code == 200


def test_configured_host_names_are_accepted(demo_world, make_server):
    srv = make_server(allowed_hosts=["robot.local"])
    assert srv.client.get("/api/health", headers={"Host": "robot.local:8080"}).status_code == 200
    assert srv.client.get("/api/health", headers={"Host": "robot.evil"}).status_code == 421


def test_host_check_follows_the_address_a_request_came_in_on():
    # A server bound to 0.0.0.0 serves each connection's own local address.
    assert host_is_served("192.168.1.20:8080", "192.168.1.20")
    assert host_is_served("[fe80::1]:8080", "fe80::1")
    assert host_is_served("192.168.1.20", "::ffff:192.168.1.20")
    assert not host_is_served("10.0.0.9:8080", "192.168.1.20")
    # localhost only on a loopback connection; names only when configured.
    assert host_is_served("localhost:8080", "127.0.0.1")
    assert host_is_served("127.0.0.2", "127.0.0.1")
    assert not host_is_served("localhost", "192.168.1.20")
    assert not host_is_served("robot.local", "192.168.1.20")
    assert host_is_served("Robot.Local.:8080", "192.168.1.20", ["robot.local"])
    assert host_is_served("anything.example", "127.0.0.1", ["*"])


def test_a_huge_body_is_refused_by_its_length_before_it_is_read(server):
    # 100 MB announced, a few bytes sent: the answer comes without reading (or waiting for)
    # the rest.
    status, headers, body = _raw(server.url, (
        f"POST /api/runs HTTP/1.1\nHost: 127.0.0.1\nContent-Type: application/json\n"
        f"Content-Length: {100 * 1024 * 1024}\n"), b'{"mission": "fetch_test", "params": {')
    assert status == 413 and headers["connection"] == "close"
    assert "at most 65536" in json.loads(body)["error"]["message"]
    assert server.client.get("/api/runs").json() == []


def test_a_chunked_body_is_refused_once_its_count_passes_the_limit(server):
    piece = b"x" * 8192
    chunks = b"".join(b"%x\r\n%s\r\n" % (len(piece), piece) for _ in range(10)) + b"0\r\n\r\n"
    status, headers, body = _raw(server.url, (
        "POST /api/runs HTTP/1.1\nHost: 127.0.0.1\nContent-Type: application/json\n"
        "Transfer-Encoding: chunked\n"), chunks)
    assert status == 413
    assert json.loads(body)["error"]["message"].startswith("the request body has more bytes")
    assert server.client.get("/api/health").status_code == 200    # the server is fine


def test_a_five_megabyte_object_parameter_is_refused_and_logs_nothing(server):
    big = json.dumps({"mission": "fetch_test", "params": {"object": "x" * 5_000_000}}).encode()
    status, _, body = _raw(server.url, (
        f"POST /api/runs HTTP/1.1\nHost: 127.0.0.1\nContent-Type: application/json\n"
        f"Content-Length: {len(big)}\n"), big[:1000])
    assert status == 413
    # Under the body limit but over the parameters' limit: 422, naming the size.
    r = server.client.post("/api/runs", json={"mission": "fetch_test",
                                              "params": {"object": "x" * 20_000}})
    assert r.status_code == 422
    assert f"at most {MAX_PARAMS_BYTES}" in json.dumps(r.json()["detail"])
    assert server.client.get("/api/runs").json() == []
    assert MAX_PARAMS_BYTES < 20_000 < MAX_BODY_BYTES


def test_a_runtime_parameter_value_over_its_limit_is_refused(server):
    r = server.client.put("/api/parameters/presence", json={"value": ["away"] * 2000})
    assert r.status_code == 422
    assert f"at most {MAX_VALUE_BYTES}" in json.dumps(r.json()["detail"])
    assert server.client.get("/api/parameters").json().get("presence") != ["away"] * 2000


def test_one_event_stream_more_than_the_limit_is_refused(make_server):
    srv = make_server(max_streams=2)
    run = srv.client.post("/api/runs", json={"mission": "wait_test"}).json()["run"]
    with httpx.Client(base_url=srv.url, timeout=30.0) as other:
        with srv.client.stream("GET", "/api/events", params={"run": run["id"], "since": 0,
                                                             "close_on_end": "true"}) as one, \
                other.stream("GET", "/api/events") as two:
            assert one.status_code == 200 and two.status_code == 200
            third = httpx.get(srv.url + "/api/events")
            assert third.status_code == 503 and third.headers["retry-after"] == "5"
            assert third.json()["error"]["message"].startswith("2 event streams are open")
            # The run's stream ends with the run, and its place is free again.
            assert srv.client.post(f"/api/runs/{run['id']}/cancel").status_code == 202
            kinds = [line[7:] for line in one.iter_lines() if line.startswith("event: ")]
            assert kinds[-1] == "end"
        with httpx.stream("GET", srv.url + "/api/events", params={
                "run": run["id"], "since": 0, "close_on_end": "true"}) as again:
            assert again.status_code == 200
            assert [line for line in again.iter_lines() if line.startswith("event: ")][-1] \
                == "event: end"


@pytest.fixture
def tls_files(tmp_path):
    if shutil.which("openssl") is None:
        pytest.skip("openssl is not installed (needed to make a test certificate)")
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1",
                    "-subj", "/CN=127.0.0.1", "-addext", "subjectAltName=IP:127.0.0.1",
                    "-keyout", str(key), "-out", str(cert)],
                   check=True, capture_output=True)
    return str(cert), str(key)


def test_the_api_serves_https_with_a_certificate_and_key(demo_world, make_server, tls_files):
    cert, key = tls_files
    srv = make_server(tls_cert=cert, tls_key=key)
    assert srv.url.startswith("https://127.0.0.1:")
    ctx = ssl.create_default_context(cafile=cert)
    r = httpx.get(srv.url + "/api/health", verify=ctx)
    assert r.status_code == 200 and r.json()["ok"] is True
    with pytest.raises(httpx.HTTPError):
        httpx.get(srv.url.replace("https", "http") + "/api/health")


def test_serve_refuses_unusable_tls_files_in_one_line(tmp_path, capsys, tls_files):
    cert, key = tls_files
    assert check_tls(cert, key) is None
    assert "go together" in check_tls(cert, None)
    bad = tmp_path / "bad.pem"
    bad.write_text("not a certificate\n")
    for args in (["--tls-cert", cert], ["--tls-cert", str(bad), "--tls-key", key],
                 ["--tls-cert", str(tmp_path / "missing.pem"), "--tls-key", key]):
        assert main(["serve", *args]) == 2
        err = capsys.readouterr().err.strip()
        assert err.startswith("hearth serve: ") and len(err.splitlines()) == 1


def test_a_client_leaving_a_busy_stream_logs_no_server_error(server, caplog):
    # A reader that stops reading and leaves while the stream has events in flight: the
    # server must neither log "Exception in ASGI application" nor keep the stream's place.
    import logging
    caplog.set_level(logging.ERROR, logger="uvicorn.error")
    hub = server.service.hub
    for _ in range(3):
        with httpx.Client(base_url=server.url, timeout=30.0) as c:
            with c.stream("GET", "/api/events") as r:
                assert r.status_code == 200
                for _ in range(400):
                    hub.publish("map", {"e": "map", "pad": "x" * 20_000})
        # the next request is served after the server has noticed the leaver
    assert server.client.get("/api/health").status_code == 200
    with server.client.stream("GET", "/api/events", params={"since": hub.last_seq}) as r:
        assert r.status_code == 200
    assert not [rec for rec in caplog.records if "Exception in ASGI" in rec.getMessage()]


@pytest.mark.skipif(not hasattr(socket, "TCP_USER_TIMEOUT"), reason="Linux socket options")
def test_connections_of_a_client_gone_without_closing_are_dropped_within_the_documented_time():
    """What the server accepts carries TCP keep-alive probes and a user timeout, so that an
    event stream whose client lost its network gives its place back (docs: Limits)."""
    from hearth.executive.command.server import DEAD_PEER_S, bind_socket
    listener = bind_socket("127.0.0.1", 0)
    with listener, socket.create_connection(listener.getsockname()):
        accepted, _ = listener.accept()
        with accepted:
            assert accepted.getsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE) == 1
            idle = accepted.getsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPIDLE)
            every = accepted.getsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPINTVL)
            count = accepted.getsockopt(socket.IPPROTO_TCP, socket.TCP_KEEPCNT)
            assert idle + every * count <= DEAD_PEER_S <= 30
            assert accepted.getsockopt(socket.IPPROTO_TCP, socket.TCP_USER_TIMEOUT) == DEAD_PEER_S * 1000
