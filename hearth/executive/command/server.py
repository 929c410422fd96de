"""Putting the pieces together: an Executive with approval gates, the CommandService, the
FastAPI app, and uvicorn (in this thread, or in a background thread for tests and
benchmarks).

    service = make_service(world, robot, ["missions"])
    with ServerThread(create_app(service)) as srv:     # 127.0.0.1, an ephemeral port
        httpx.get(srv.url + "/api/vocabulary")
"""
from __future__ import annotations

import ipaddress
import socket
import threading
from typing import Any

import uvicorn

from hearth.executive.autonomy import Approvals, gated_factory
from hearth.executive.command.service import CommandService
from hearth.executive.executive import Executive


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def make_service(world: Any, robot: Any, missions: list[str], *, skills: dict | None = None,
                 make_skill: Any = None, clock: Any = None, tick_hz: float = 10.0,
                 runs_dir: str | None = "runs", granted: int = 3,
                 approval_timeout: float = 120.0, equal_priority: str = "queue",
                 setup_kwargs: dict | None = None) -> CommandService:
    """An Executive (tick thread running) whose skills above ``granted`` ask for approval,
    and the CommandService over it. ``make_skill``: the inner skill factory (e.g. an
    hearth.executive.testing.Substitution); ``skills``: the registry (default: the skills package)."""
    approvals = Approvals(granted=granted, timeout=approval_timeout)
    kwargs = dict(setup_kwargs or {})
    kwargs["approvals"] = approvals
    ex = Executive(world=world, robot=robot, clock=clock, tick_hz=tick_hz, runs_dir=runs_dir,
                   skills=skills, equal_priority=equal_priority,
                   make_skill=gated_factory(make_skill), setup_kwargs=kwargs)
    return CommandService(ex, world, missions, approvals=approvals)


#: A client gone without closing (network lost, laptop lid shut) is dropped after this many
#: seconds of unacknowledged data or unanswered keep-alive probes, so that its event stream
#: gives its slot back (docs/command-layer.md, "Limits"); without it the kernel retries a
#: dead peer for about 15 minutes.
DEAD_PEER_S = 30


def bind_socket(host: str, port: int) -> socket.socket:
    """A listening TCP socket with TCP_NODELAY, which accepted connections inherit: without
    it the event loop's small writes wait for delayed ACKs and every request on a kept-alive
    connection takes ~40 ms on loopback (measured; 0.3 ms with it). Accepted connections
    also inherit TCP keep-alive probes and, on Linux, TCP_USER_TIMEOUT (``DEAD_PEER_S``)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    sock = socket.socket(family, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
    # Idle 10 s, then a probe every 5 s, dropped after 4 unanswered; where the platform has
    # the options (Linux; macOS has TCP_KEEPALIVE for the idle time and no user timeout).
    for name, value in (("TCP_KEEPIDLE", 10), ("TCP_KEEPINTVL", 5), ("TCP_KEEPCNT", 4),
                        ("TCP_USER_TIMEOUT", DEAD_PEER_S * 1000)):
        if hasattr(socket, name):
            sock.setsockopt(socket.IPPROTO_TCP, getattr(socket, name), value)
    sock.bind((host, port))
    sock.listen(2048)
    return sock


class _Server(uvicorn.Server):
    """uvicorn's server, calling ``on_started`` once it has started: its signal handlers are
    in place and it accepts connections."""

    on_started: Any = None

    async def startup(self, sockets: Any = None) -> None:
        await super().startup(sockets=sockets)
        if self.started and self.on_started is not None:
            self.on_started()


def make_server(app: Any, log_level: str = "warning", *, tls_cert: str | None = None,
                tls_key: str | None = None, on_started: Any = None) -> uvicorn.Server:
    """uvicorn for ``app``; with ``tls_cert`` and ``tls_key`` (PEM files) it serves HTTPS.
    ``on_started()`` is called once it serves (``hearth serve`` prints its address then: a
    Ctrl-C before that moment would meet no handler of uvicorn's, and one inherited as
    ignored would leave the server running)."""
    # http="h11" whatever is installed: the head-size limit in docs/command-layer.md
    # ("Limits") is h11's, and uvicorn's httptools protocol (about 0.3 ms less CPU per
    # request here) has none. uvloop (loop "auto") made no difference with h11 here. No
    # access log: a line per request is CPU on every submit.
    config = uvicorn.Config(app, log_level=log_level, access_log=False, http="h11",
                            timeout_graceful_shutdown=1, lifespan="on", backlog=2048,
                            ssl_certfile=tls_cert, ssl_keyfile=tls_key)
    server = _Server(config)
    server.on_started = on_started
    return server


class ServerThread:
    """uvicorn serving ``app`` on ``host`` in a daemon thread (port 0: an ephemeral port;
    ``tls_cert``/``tls_key``: HTTPS). ``url`` once started; ``stop()`` (or leaving the
    ``with``) shuts it down."""

    def __init__(self, app: Any, host: str = "127.0.0.1", port: int = 0,
                 log_level: str = "warning", *, tls_cert: str | None = None,
                 tls_key: str | None = None):
        self.sock = bind_socket(host, port)
        self.host, self.port = self.sock.getsockname()[:2]
        scheme = "https" if tls_cert else "http"
        self.url = f"{scheme}://{self.host}:{self.port}" if ":" not in self.host else \
            f"{scheme}://[{self.host}]:{self.port}"
        self.server = make_server(app, log_level, tls_cert=tls_cert, tls_key=tls_key)
        self.thread = threading.Thread(target=self.server.run, kwargs={"sockets": [self.sock]},
                                       name="hearth-api", daemon=True)

    def start(self, timeout: float = 30.0) -> "ServerThread":
        self.thread.start()
        ready = threading.Event()
        # uvicorn has no start callback; poll its flag (start-up, not a timed assertion).
        for _ in range(int(timeout / 0.01)):
            if self.server.started or not self.thread.is_alive():
                break
            ready.wait(0.01)
        if not self.server.started:
            raise RuntimeError("the API server did not start")
        return self

    def stop(self) -> None:
        self.server.should_exit = True
        self.thread.join(10)
        self.sock.close()

    def __enter__(self) -> "ServerThread":
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.stop()
