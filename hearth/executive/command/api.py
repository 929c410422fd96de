"""The HTTP API (FastAPI) over a CommandService, and the live monitor page.

    app = create_app(service, token=None)      # uvicorn.run(app, host="127.0.0.1", port=8080)

Everything under ``/api`` needs the token when one is set (``Authorization: Bearer T`` or
``X-Hearth-Token: T``; ``?token=T`` only on ``/api/events``, for EventSource, which cannot set
headers: a token in a URL lands in access logs). Errors are ``{"error": {"message": ..., ...}}``
with 404 (unknown mission, run, parameter, request), 409 (ended run, reused idempotency key,
decided request), 422 (bad parameters; FastAPI's own body checks answer 422 with ``detail``),
401 (token), 421 (a Host that is not this server's), 413 (body too large), 503 (too many open
event streams). The limits are the ``MAX_*`` constants below (docs/command-layer.md,
"Limits"). The OpenAPI schema is at ``/openapi.json``, the interactive docs at ``/docs``
(Swagger UI served from ``static/swagger-ui/``, so it works offline), the monitor page at
``/`` (its scripts and styles under ``/static``).
"""
from __future__ import annotations

import asyncio
import functools
import ipaddress
import json
import hmac
import math
import re
from collections.abc import AsyncIterator, Iterable
from contextlib import asynccontextmanager
from dataclasses import dataclass
from importlib import resources
from typing import Any

from fastapi import APIRouter, Depends, FastAPI, Header, HTTPException, Path, Query, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.openapi.docs import get_swagger_ui_html
from fastapi.routing import APIRoute
from fastapi.responses import HTMLResponse, JSONResponse, StreamingResponse
from fastapi.staticfiles import StaticFiles
from starlette.concurrency import run_in_threadpool
from pydantic import BaseModel, Field, field_validator

from hearth.executive.command.service import CommandService, Conflict, NotFound
from hearth.executive.errors import MissionError, MissionValidationError
from hearth.executive.events import json_default
from hearth.util.files import BadJSON, load_json

#: A request body, in bytes: refused from its Content-Length before it is read, and by counting
#: as it arrives when it has none (chunked). 413.
MAX_BODY_BYTES = 64 * 1024
#: Mission parameters of one request: how many, and their size as JSON (so one request cannot
#: write megabytes into a run log, or into every later GET /api/runs). 422.
MAX_PARAMS = 32
MAX_PARAMS_BYTES = 4096
#: A runtime parameter's value (PUT /api/parameters/NAME), as JSON. 422.
MAX_VALUE_BYTES = 4096
#: Event streams (GET /api/events) open at once; the next one is answered 503. Each holds a
#: connection and wakes on every event.
MAX_EVENT_STREAMS = 64
#: Ids in a path (runs, approval requests, parameter names).
MAX_ID = 200
#: A run's recent events in one answer (GET /api/runs/{id}/events, GET /api/state).
MAX_RECENT_EVENTS = 5000
#: Where the monitor page's assets and the vendored Swagger UI are served.
STATIC = "/static"

Key = Field(default=None, min_length=1, max_length=200,
            description="idempotency key: a retried request with the same key returns the "
                        "same run instead of starting another")


class SubmitRequest(BaseModel):
    mission: str = Field(min_length=1, max_length=200, description="a mission name (GET /api/missions)")
    params: dict[str, Any] = Field(default_factory=dict, description="parameter values")
    priority: int = Field(default=0, ge=-1000, le=1000,
                          description="higher preempts the running mission; equal queues")
    idempotency_key: str | None = Key

    @field_validator("params")
    @classmethod
    def _bounded(cls, params: dict[str, Any]) -> dict[str, Any]:
        if len(params) > MAX_PARAMS:
            raise ValueError(f"{len(params)} parameters; at most {MAX_PARAMS}")
        _check_json_size(params, MAX_PARAMS_BYTES, "the parameters")
        return params


def _check_json_size(value: Any, limit: int, what: str) -> None:
    size = len(json.dumps(value, default=repr, ensure_ascii=False).encode())
    if size > limit:
        raise ValueError(f"{what} take {size} bytes as JSON; at most {limit}")


class CommandRequest(BaseModel):
    text: str = Field(min_length=1, max_length=500, description='what the user said, e.g. "bring me the blue cup"')
    priority: int = Field(default=0, ge=-1000, le=1000)
    idempotency_key: str | None = Key
    dry_run: bool = Field(default=False, description="interpret only; start nothing")


class CancelRequest(BaseModel):
    reason: str = Field(default="cancelled by a client", max_length=300)


class ParameterValue(BaseModel):
    value: Any = Field(description="the new value (checked against the missions declaring it)")

    @field_validator("value")
    @classmethod
    def _bounded(cls, value: Any) -> Any:
        _check_json_size(value, MAX_VALUE_BYTES, "the value")
        return value


class Decision(BaseModel):
    approve: bool
    by: str = Field(default="operator", max_length=100)
    reason: str = Field(default="", max_length=300)


class AutonomyLevel(BaseModel):
    level: int = Field(ge=0, le=3, description="0 observe, 1 move the base, 2 act on the home, 3 handle objects near the user")


class Result(BaseModel):
    outcome: str
    reason: str
    outputs: dict[str, Any]
    ticks: int
    duration: float
    robot_stopped: bool = Field(
        default=True, description="false only when a cancelled or preempted run's robot "
        "actions were not confirmed stopped within the halt timeout")


class Run(BaseModel):
    id: str
    mission: str
    status: str = Field(description="queued, running, halting, succeeded, failed, cancelled or preempted")
    priority: int
    params: dict[str, Any]
    submitted: float
    source: str
    result: Result | None


class SubmitReply(BaseModel):
    run: Run
    created: bool = Field(description="false: an earlier request with this idempotency key made it")


class CommandReply(BaseModel):
    outcome: str = Field(description="run, clarify or not_understood")
    say: str = Field(description="an answer for the user, in English")
    text_id: str = Field(description="HOBBIT-style text identifier for the dialogue layer")
    args: dict[str, Any]
    mission: str | None
    params: dict[str, Any]
    template: str | None
    slot: str | None
    words: str | None
    candidates: list[dict[str, Any]]
    run: Run | None = None
    created: bool = False


def _error(status: int, message: str, **extra: Any) -> JSONResponse:
    return JSONResponse(status_code=status, content={"error": {"message": message, **extra}})


def _check_token(expected: str | None, in_query: bool = False):
    """A dependency: the token from a header (and, with ``in_query``, from ``?token=``).
    Async, so that FastAPI runs it on the event loop instead of handing it to a thread."""
    async def check(request: Request, authorization: str | None = Header(default=None),
                    x_hearth_token: str | None = Header(default=None)) -> None:
        if expected is None:
            return
        given = x_hearth_token or (request.query_params.get("token") if in_query else None)
        if authorization and authorization.lower().startswith("bearer "):
            given = authorization[7:].strip()
        if not given or not hmac.compare_digest(given.encode(), expected.encode()):
            raise _Unauthorised()
    return check


class _Unauthorised(Exception):
    pass


class _BadBody(HTTPException):
    """A body that is not strict JSON; an HTTPException so that FastAPI passes it on (any
    other exception while it reads a body becomes its own 400 without a reason)."""

    def __init__(self, message: str):
        super().__init__(status_code=422, detail=message)
        self.message = message


class _StrictJSONRequest(Request):
    """A request whose JSON body is read by ``hearth.util.files.load_json``: NaN and Infinity,
    integers of thousands of digits, a key given twice and strings with lone surrogates are
    refused (422) instead of reaching the models, the runs and the logs, where they ended as
    500s (a reply holding Infinity is not JSON; "\\ud800" cannot be encoded)."""

    async def json(self) -> Any:
        if not hasattr(self, "_json"):
            try:
                self._json = load_json(await self.body(), finite=True, unique_keys=True)
            except BadJSON as err:
                if err.syntax is not None:
                    raise err.syntax from None      # not JSON: FastAPI's own 422 (json_invalid)
                raise _BadBody(f"the request body is not strict JSON: {err.message}") from None
        return self._json


class _StrictJSONRoute(APIRoute):
    def get_route_handler(self) -> Any:
        handler = super().get_route_handler()

        async def strict(request: Request) -> Any:
            return await handler(_StrictJSONRequest(request.scope, request.receive))
        return strict


def _json_safe(value: Any) -> Any:
    """``value`` with non-finite floats and unencodable strings made printable (what
    FastAPI's validation errors echo back of a request must itself be JSON)."""
    if isinstance(value, float) and not math.isfinite(value):
        return repr(value)
    if isinstance(value, str):
        return value.encode("utf-8", "backslashreplace").decode("utf-8")
    if isinstance(value, dict):
        return {_json_safe(k): _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    return value


class _TooManyStreams(Exception):
    pass


#: A Host header (RFC 9110 7.2): a name of letters, digits, dots, hyphens (and underscores,
#: which some local names carry), or an IPv4 address, or an IPv6 address in brackets;
#: optionally ":" and a port. Nothing else: no userinfo ("localhost:80@evil.com"), no path,
#: no second host, no spaces.
_HOST_RE = re.compile(r"(?:\[(?P<v6>[0-9a-f:.]+)\]|(?P<name>[a-z0-9._-]+))(?::(?P<port>[0-9]{1,5}))?")


def parse_host(value: str) -> tuple[str, int | None] | None:
    """(name, port) of a Host header, lower case, without brackets or a trailing dot; None
    when it is not a host (then nothing is served)."""
    m = _HOST_RE.fullmatch(value.strip().lower())
    if m is None:
        return None
    port = int(m["port"]) if m["port"] is not None else None
    if port is not None and not 0 < port < 65536:
        return None
    name = m["v6"] if m["v6"] is not None else m["name"].rstrip(".")
    return (name, port) if name else None


def _host_name(value: str) -> str:
    """The name in a Host header, without port, brackets, case or a trailing dot (the header
    itself, shortened, when it is no host: for messages)."""
    parsed = parse_host(value)
    return parsed[0] if parsed is not None else value.strip()[:80]


def _ip(name: str | None) -> ipaddress.IPv4Address | ipaddress.IPv6Address | None:
    try:
        ip = ipaddress.ip_address(name or "")
    except ValueError:
        return None
    mapped = getattr(ip, "ipv4_mapped", None)
    return mapped or ip


def host_is_served(host: str, local: str | None, allowed: Iterable[str] = (),
                   local_port: int | None = None) -> bool:
    """Whether a request whose Host header is ``host``, arriving on the local address
    ``local`` and port ``local_port`` (the connection's own, ``scope["server"]``), is for
    this server: that address itself, ``localhost`` and loopback addresses when the
    connection is on loopback (with the connection's port, when the header names one), or a
    configured name (``*``: any). A header that does not parse as a host is never served."""
    allowed = {_host_name(a) if a != "*" else a for a in allowed}
    if "*" in allowed:
        return True
    parsed = parse_host(host)
    if parsed is None:
        return False
    name, port = parsed
    if name in allowed:
        return True
    if port is not None and local_port is not None and port != local_port:
        return False
    ip, here = _ip(name), _ip(local)
    if ip is not None and here is not None and ip == here:
        return True
    on_loopback = here is None or here.is_loopback
    return on_loopback and (name == "localhost" or (ip is not None and ip.is_loopback))


#: Methods that change state: refused when a browser says another site's page sent them.
_UNSAFE = frozenset({"POST", "PUT", "PATCH", "DELETE"})


def cross_site(method: str, host: str | None, origin: str | None, fetch_site: str | None,
               allowed: Iterable[str] = ()) -> str | None:
    """Why a request is a cross-site request that may not change state (None: it may).

    A page on any site can make its visitor's browser POST here without a preflight (a body
    of no type, or a "simple" one), so ``/api/stop`` worked from every web page. Browsers
    say where a request comes from: ``Sec-Fetch-Site`` (anything but ``same-origin`` or
    ``none``, a typed address or a bookmark, is another site) and ``Origin`` (its host and
    port must be this request's Host, or a name given with ``--allowed-host``). Clients that
    send neither (curl, httpx, the Python client, other programs) are not browsers and are
    not asked; the token, when set, is what guards against them."""
    if method not in _UNSAFE:
        return None
    if fetch_site is not None and fetch_site.strip().lower() not in ("same-origin", "none"):
        return f"Sec-Fetch-Site is {fetch_site.strip()[:40]!r}"
    if origin is None:
        return None
    origin = origin.strip()
    m = re.fullmatch(r"(?i)(https?)://([^/?#]+)", origin)
    if m is None:
        return f"the page's origin {origin[:80]!r} is not this server"
    scheme, authority = m[1].lower(), m[2]
    page, here = parse_host(authority), parse_host(host or "")
    if page is None or here is None:
        return f"the page's origin {origin[:80]!r} is not this server"
    default = 443 if scheme == "https" else 80
    if (page[0], page[1] or default) == (here[0], here[1] or default):
        return None
    if page[0] in {_host_name(a) for a in allowed if a != "*"}:
        return None
    return f"the page at {origin[:80]} is another site"


class Guard:
    """ASGI middleware in front of everything the app serves.

    Host: a page on another site whose DNS name has been rebound to this machine (DNS
    rebinding) reaches the server from the owner's browser with its own name in Host; only
    the names :func:`host_is_served` accepts are served, others get 421. Body size: a body
    larger than ``max_body`` bytes is refused from its Content-Length before anything is
    read, or once the bytes counted as they arrive pass the limit (a chunked body): 413, and
    the connection is closed rather than drained.

    Written here rather than with Starlette's TrustedHostMiddleware and body-limit middleware:
    the first takes a fixed list of names (a server bound to 0.0.0.0 serves the address each
    connection came in on), and both answer in plain text, not with the API's JSON errors.
    """

    def __init__(self, app: Any, allowed_hosts: Iterable[str] = (),
                 max_body: int = MAX_BODY_BYTES):
        self.app = app
        self.allowed_hosts = tuple(allowed_hosts)
        self.max_body = max_body
        # Every request asks; the answer depends on the Host and the local address only
        # (parsing both as IP addresses was ~3% of a submit's CPU). Bounded: hosts are
        # whatever clients send.
        self._served = functools.lru_cache(maxsize=256)(
            lambda host, local, port: host_is_served(host, local, self.allowed_hosts, port))

    async def __call__(self, scope: dict, receive: Any, send: Any) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        host = length = origin = fetch_site = None
        for key, value in scope.get("headers", ()):
            if key == b"host":
                host = value.decode("latin-1")
            elif key == b"content-length":
                length = value.decode("latin-1")
            elif key == b"origin":
                origin = value.decode("latin-1")
            elif key == b"sec-fetch-site":
                fetch_site = value.decode("latin-1")
        server = tuple(scope.get("server") or (None, None)) + (None,)
        local, local_port = server[0], server[1]
        if host is not None and not self._served(host, local, local_port):
            here = _ip(local)
            names = [str(here)] if here is not None else []
            names += ["localhost"] if here is None or here.is_loopback else []
            names += [a for a in self.allowed_hosts if a not in names]
            await _refuse(scope, receive, send, 421,
                          f"this server does not serve the host {_host_name(host)!r} (it "
                          f"serves {', '.join(names)}); add a name with hearth serve "
                          f"--allowed-host NAME")
            return
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        why = cross_site(scope.get("method", "GET"), host, origin, fetch_site,
                         self.allowed_hosts)
        if why is not None:
            await _refuse(scope, receive, send, 403,
                          f"a cross-site request may not change this server's state ({why}); "
                          f"use the monitor page this server serves, or a client that is not "
                          f"a browser")
            return
        if length is not None and length.strip().isdigit() and int(length) > self.max_body:
            await _refuse(scope, receive, send, 413, self._too_large(int(length)))
            return
        seen = 0
        refused = started = False

        async def counted() -> dict:
            nonlocal seen, refused
            if refused:
                return {"type": "http.disconnect"}
            message = await receive()
            if message["type"] == "http.request":
                seen += len(message.get("body", b""))
                if seen > self.max_body:
                    refused = True
                    if not started:
                        await _refuse(scope, receive, send, 413, self._too_large(None))
                    return {"type": "http.disconnect"}
            return message

        async def sent(message: dict) -> None:
            nonlocal started
            if refused:
                return          # the 413 has been sent; the app's own answer is dropped
            started = started or message["type"] == "http.response.start"
            await send(message)

        try:
            await self.app(scope, counted, sent)
        except Exception:
            if not refused:     # the app saw a disconnect after the 413: nothing to report
                raise

    def _too_large(self, length: int | None) -> str:
        size = f"{length} bytes" if length is not None else "more bytes"
        return f"the request body has {size}; at most {self.max_body} are read"


async def _refuse(scope: dict, receive: Any, send: Any, status: int, message: str) -> None:
    if scope["type"] == "websocket":
        await send({"type": "websocket.close", "code": 1008})
        return
    response = _error(status, message)
    response.headers["Connection"] = "close"
    await response(scope, receive, send)


@dataclass
class _Slot:
    """One open event stream; released once (when the stream ends or the client leaves)."""
    owner: "_Streams"
    held: bool = True

    def release(self) -> None:
        if self.held:
            self.held = False
            self.owner.open -= 1


@dataclass
class _Streams:
    """Event streams open at once (touched only on the event loop: no lock)."""
    limit: int
    open: int = 0

    def take(self) -> _Slot:
        if self.open >= self.limit:
            raise _TooManyStreams()
        self.open += 1
        return _Slot(self)


@dataclass
class _StreamArgs:
    """What an event stream was asked for, and its slot."""
    cursor: int
    run: str | None
    close_on_end: bool
    slot: _Slot


def monitor_html() -> str:
    return resources.files("hearth.executive.command").joinpath("static/monitor.html").read_text("utf-8")


def recent_events(service: CommandService, run_id: str, limit: int
                  ) -> tuple[int, list[dict[str, Any]]]:
    """The newest ``limit`` events of one run, oldest first, as the stream sends them
    (``id``, ``event``, ``data``), and the last event number they are cut at: a client that
    follows the stream from that number misses nothing and sees nothing twice."""
    last = service.hub.last_seq
    items, _ = service.hub.since(0, limit=10 ** 9, run=run_id)
    mine = [it for it in items if it[2] == run_id and it[0] <= last][-limit:]
    return last, [{"id": seq, "event": kind, "data": json.loads(text)}
                  for seq, kind, _run, text, _ends in mine]


def stop_all(service: CommandService, reason: str) -> list[str]:
    """Cancel every run that has not ended: the queued ones first (so none starts when the
    running one stops), then the running one. The ids cancelled."""
    live = [r for r in reversed(service.runs(10 ** 9))       # oldest first
            if r.handle.status in ("queued", "running", "halting")]
    live.sort(key=lambda r: r.handle.status != "queued")
    return [r.id for r in live if r.handle.cancel(reason)]


def create_app(service: CommandService, token: str | None = None, *,
               allowed_hosts: Iterable[str] = (), max_streams: int = MAX_EVENT_STREAMS,
               max_body: int = MAX_BODY_BYTES) -> FastAPI:
    """The app. ``allowed_hosts``: Host names served besides the address a connection came in
    on (and localhost on loopback); ``*`` turns the check off (behind a proxy that checks Host
    itself)."""
    @asynccontextmanager
    async def lifespan(app: FastAPI):
        service.hub.attach_loop(asyncio.get_running_loop())
        yield

    # /docs is served below from vendored Swagger UI files (FastAPI's own page loads them
    # from a CDN, which an offline robot cannot reach); ReDoc has no local copy: off.
    app = FastAPI(title="Hearth command API", version="1",
                  description="Start, watch and cancel missions; what the robot can be asked "
                              "for; operator approvals. See docs/command-layer.md.",
                  lifespan=lifespan, docs_url=None, redoc_url=None)
    app.add_middleware(Guard, allowed_hosts=tuple(allowed_hosts), max_body=max_body)
    api = APIRouter(prefix="/api", dependencies=[Depends(_check_token(token))],
                    route_class=_StrictJSONRoute)
    # EventSource cannot set headers: the stream alone also takes ?token=.
    stream = APIRouter(prefix="/api", dependencies=[Depends(_check_token(token, in_query=True))])
    streams = _Streams(max_streams)

    @app.exception_handler(_Unauthorised)
    async def unauthorised(request: Request, exc: _Unauthorised):
        return _error(401, "a valid token is needed (Authorization: Bearer TOKEN or "
                           "X-Hearth-Token; ?token= on /api/events only)")

    @app.exception_handler(_TooManyStreams)
    async def too_many_streams(request: Request, exc: _TooManyStreams):
        response = _error(503, f"{streams.limit} event streams are open, the most this server "
                               f"keeps; close one or retry later")
        response.headers["Retry-After"] = "5"
        return response

    @app.exception_handler(_BadBody)
    async def bad_body(request: Request, exc: _BadBody):
        return _error(422, exc.message)

    @app.exception_handler(RequestValidationError)
    async def invalid(request: Request, exc: RequestValidationError):
        # FastAPI's own answer, its echo of the request made JSON whatever was sent
        return JSONResponse(status_code=422,
                            content={"detail": _json_safe(jsonable_encoder(exc.errors()))})

    @app.exception_handler(NotFound)
    async def not_found(request: Request, exc: NotFound):
        return _error(404, str(exc))

    @app.exception_handler(Conflict)
    async def conflict(request: Request, exc: Conflict):
        return _error(409, str(exc))

    @app.exception_handler(MissionError)
    async def mission_error(request: Request, exc: MissionError):
        problems = ([str(p) for p in exc.problems] if isinstance(exc, MissionValidationError)
                    else [str(exc)])
        return _error(422, str(exc).splitlines()[0], param=exc.param, problems=problems)

    # -- monitor and docs ----------------------------------------------------------------------
    @app.get("/", response_class=HTMLResponse, include_in_schema=False)
    def monitor() -> str:
        return monitor_html()

    app.mount(STATIC, StaticFiles(packages=[("hearth.executive.command", "static")]), name="static")

    @app.get("/docs", response_class=HTMLResponse, include_in_schema=False)
    def docs() -> HTMLResponse:
        return get_swagger_ui_html(
            openapi_url=app.openapi_url, title=f"{app.title} - Swagger UI",
            swagger_js_url=f"{STATIC}/swagger-ui/swagger-ui-bundle.js",
            swagger_css_url=f"{STATIC}/swagger-ui/swagger-ui.css",
            swagger_favicon_url=f"{STATIC}/swagger-ui/favicon-32x32.png",
            # validatorUrl: no badge fetched from validator.swagger.io
            swagger_ui_parameters={"validatorUrl": None})

    # -- what can be asked -----------------------------------------------------------------
    @api.get("/health", summary="liveness and counters")
    def health() -> dict[str, Any]:
        cur = service.current()
        return {"ok": True, "current": cur.id if cur else None,
                "queued": [h.id for h in service.executive.queued],
                "last_event": service.hub.last_seq,
                "vocabulary_revision": service.vocabulary.revision,
                "granted_autonomy": service.approvals.granted,
                "catalogue_problems": service.catalogue_problems}

    @api.get("/missions", summary="missions that can be asked for, with parameters and utterances")
    def missions() -> list[dict[str, Any]]:
        return service.missions()

    @api.get("/vocabulary", summary="missions, objects, places and rooms; revision goes up "
                                    "with every map change")
    def vocabulary() -> dict[str, Any]:
        return service.vocabulary.snapshot()

    @api.get("/map", summary="rooms, objects, part and knob states, recent map changes")
    def map_view() -> dict[str, Any]:
        return service.map_view()

    # -- runs -------------------------------------------------------------------------------
    @api.post("/runs", status_code=201, response_model=SubmitReply,
              summary="submit a mission by name",
              responses={404: {"description": "unknown mission"},
                         409: {"description": "idempotency key reused for another request"},
                         422: {"description": "bad parameters"}})
    async def submit(body: SubmitRequest,
                     idempotency_key: str | None = Header(default=None, max_length=200)):
        args = (body.mission, body.params, body.priority,
                body.idempotency_key or idempotency_key)
        # On the event loop when no lock it needs is held (nearly always: a submit is
        # ~0.05 ms of work), else from a worker thread: the loop never waits on a tick. A
        # trip to the thread pool costs two thread wake-ups, which on a busy machine were
        # most of a submit's time in the server (its p99 in the app 18-89 ms against 9-19
        # ms on the loop: hearth bench api, 50 clients, load 8).
        got = service.try_submit(*args)
        rec, created = got if got is not None else await run_in_threadpool(service.submit,
                                                                           *args)
        # A Response is sent as it is: FastAPI would otherwise validate the reply against
        # SubmitReply in a second trip to its thread pool (the model still documents it).
        return JSONResponse(status_code=201 if created else 200,
                            content={"run": rec.to_json(), "created": created})

    @api.post("/commands", response_model=CommandReply,
              summary="interpret an utterance and start its mission, or answer with a "
                      "clarifying question")
    def command(body: CommandRequest,
                idempotency_key: str | None = Header(default=None, max_length=200)):
        if body.dry_run:
            from hearth.executive.command.commands import interpret
            it = interpret(body.text, service.vocabulary.templates, service.world,
                           {n: e.mission for n, e in service.vocabulary.catalogue.items()})
            return {**it.to_json(), "run": None, "created": False}
        it, rec, created = service.command(body.text, body.priority,
                                           body.idempotency_key or idempotency_key)
        return {**it.to_json(), "run": rec.to_json() if rec else None, "created": created}

    @api.get("/runs", response_model=list[Run], summary="recent runs, newest first")
    def runs(limit: int = Query(default=50, ge=1, le=1000)):
        return [r.to_json() for r in service.runs(limit)]

    @api.get("/runs/{run_id}", response_model=Run, summary="a run's status and result")
    def run(run_id: str = Path(max_length=MAX_ID)):
        return service.run(run_id).to_json()

    @api.post("/runs/{run_id}/cancel", status_code=202, response_model=Run,
              summary="ask a run to stop (queued: at once; running: halted, then cancelled)")
    def cancel(body: CancelRequest | None = None, run_id: str = Path(max_length=MAX_ID)):
        rec = service.cancel(run_id, (body or CancelRequest()).reason)
        return JSONResponse(status_code=202, content=rec.to_json())   # as submit's reply

    @api.get("/runs/{run_id}/tree", summary="the run's tree with each node's last status")
    def tree(run_id: str = Path(max_length=MAX_ID)) -> dict[str, Any]:
        return service.tree(run_id)

    @api.get("/runs/{run_id}/events",
             summary="the run's most recent events, oldest first (as the stream sends them); "
                     "follow the stream from last_event for what comes next")
    def run_events(run_id: str = Path(max_length=MAX_ID),
                   limit: int = Query(default=2000, ge=1, le=MAX_RECENT_EVENTS)
                   ) -> dict[str, Any]:
        service.run(run_id)    # 404
        last, events = recent_events(service, run_id, limit)
        return {"run": run_id, "last_event": last, "events": events}

    @api.post("/stop", summary="stop everything: cancel the queued runs, then the running one",
              responses={200: {"description": "the ids of the runs cancelled"}})
    def stop(body: CancelRequest | None = None) -> dict[str, Any]:
        reason = (body or CancelRequest(reason="stopped by a client")).reason
        return {"cancelled": stop_all(service, reason)}

    @api.get("/state", summary="what the monitor page loads first: the shown run with its "
                               "tree and recent events, approvals, parameters, map changes")
    def state(events: int = Query(default=2000, ge=0, le=MAX_RECENT_EVENTS)) -> dict[str, Any]:
        cur = service.current()
        recent = service.runs(1)
        shown = cur or (recent[0] if recent else None)
        if shown is not None:
            last, shown_events = recent_events(service, shown.id, events) if events else \
                (service.hub.last_seq, [])
        else:
            last, shown_events = service.hub.last_seq, []
        return {"last_event": last,
                "run": shown.to_json() if shown else None,
                "tree": service.tree(shown.id) if shown else None,
                "events": shown_events,
                "runs": [r.to_json() for r in service.runs(20)],
                "approvals": [r.to_json() for r in service.approvals.list(pending_only=True)],
                "granted_autonomy": service.approvals.granted,
                "map": service.map_view()["recent_changes"][:20],
                "parameters": service.parameters()}

    # -- parameters ---------------------------------------------------------------------------
    @api.get("/parameters", summary="runtime parameters and their values")
    def parameters() -> dict[str, Any]:
        return service.parameters()

    @api.put("/parameters/{name}", summary="set a runtime parameter (running missions react)")
    def set_parameter(body: ParameterValue, name: str = Path(max_length=MAX_ID)) -> dict[str, Any]:
        value = service.set_parameter(name, body.value)
        return {"name": name, "value": value}

    # -- approvals ---------------------------------------------------------------------------
    @api.get("/autonomy", summary="the granted autonomy level")
    def autonomy() -> dict[str, Any]:
        return {"granted": service.approvals.granted, "timeout_s": service.approvals.timeout}

    @api.put("/autonomy", summary="grant an autonomy level (pending requests at or below it "
                                  "are approved)")
    def set_autonomy(body: AutonomyLevel) -> dict[str, Any]:
        service.approvals.set_granted(body.level)
        return {"granted": service.approvals.granted, "timeout_s": service.approvals.timeout}

    @api.get("/approvals", summary="approval requests (pending first)")
    def approvals(pending: bool = False) -> list[dict[str, Any]]:
        reqs = service.approvals.list(pending_only=pending)
        reqs.sort(key=lambda r: (r.state != "pending", r.asked_at))
        return [r.to_json() for r in reqs]

    @api.post("/approvals/{request_id}", summary="approve or refuse a pending request")
    def decide(body: Decision, request_id: str = Path(max_length=MAX_ID)) -> dict[str, Any]:
        return service.decide(request_id, body.approve, body.by, body.reason).to_json()

    # -- events ------------------------------------------------------------------------------
    async def open_stream(
            since: int | None = Query(default=None, ge=0,
                                      description="replay events after this number "
                                                  "(default: only new ones)"),
            run: str | None = Query(default=None, max_length=MAX_ID,
                                    description="only this run's events (and "
                                                "map/vocabulary/autonomy ones)"),
            close_on_end: bool = Query(default=False,
                                       description="end the stream when the run ends"),
            last_event_id: str | None = Header(default=None, max_length=40)
    ) -> AsyncIterator[_StreamArgs]:
        if run is not None:
            service.run(run)   # 404 now, not a stream that never says anything
        cursor = since if since is not None else service.hub.last_seq
        if last_event_id and last_event_id.isdigit():
            cursor = int(last_event_id)
        slot = streams.take()  # 503 when MAX_EVENT_STREAMS are open
        try:
            yield _StreamArgs(cursor, run, close_on_end, slot)
        finally:
            slot.release()

    @stream.get("/events", summary="server-sent events: one per status change, feedback, "
                                   "blackboard write, map change, approval, vocabulary revision",
                response_class=StreamingResponse,
                responses={200: {"content": {"text/event-stream": {}}},
                           404: {"description": "unknown run"},
                           503: {"description": "too many event streams open"}})
    async def events(args: _StreamArgs = Depends(open_stream)):
        return StreamingResponse(_held(args.slot, _stream(service, args.cursor, args.run,
                                                          args.close_on_end)),
                                 media_type="text/event-stream",
                                 headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"})

    app.include_router(api)
    app.include_router(stream)
    return app



async def _held(slot: _Slot, stream: AsyncIterator[str]) -> AsyncIterator[str]:
    """``stream``, giving its slot back when it ends or its client leaves (the stream's
    dependency gives it back too, after the response, should the stream never start)."""
    try:
        async for chunk in stream:
            yield chunk
    finally:
        slot.release()


# The stream is written here rather than with FastAPI's EventSourceResponse (>= 0.135), which
# was tried: it sends every event as its own write through two memory streams, 90-100 us of
# server CPU per delivered event against 4-6 us here, where what has accumulated since the
# last wake goes out in one write (10 streams, 3000 events in bursts of 20); the stress
# figure of `hearth bench api` fell from ~2000 to ~700 events/s. It also logs a traceback
# when a client leaves while an event is in flight (fastapi/fastapi discussion #15725).
async def _stream(service: CommandService, cursor: int, run: str | None, close_on_end: bool):
    hub = service.hub
    yield f": hearth events after {cursor}\n\n"
    while True:
        waiter = hub.waiter(run)
        items, gap = hub.since(cursor, run=run)
        if gap:
            yield f"event: gap\ndata: {{\"e\": \"gap\", \"after\": {cursor}}}\n\n"
        chunk = []
        ended = False
        for seq, kind, ev_run, text, ends_run in items:
            cursor = seq
            chunk.append(f"id: {seq}\nevent: {kind}\ndata: {text}\n\n")
            if close_on_end and run is not None and ev_run == run and ends_run:
                ended = True
                break
        if chunk:
            yield "".join(chunk)
        if close_on_end and run is not None and not items and not ended:
            if service.run(run).handle.done:
                ended = True    # its last event was read (or had already been dropped)
        if ended:
            yield f"event: end\ndata: {json.dumps(service.run(run).to_json(), default=json_default)}\n\n"
            return
        if not items:
            try:
                await asyncio.wait_for(waiter.wait(), timeout=15.0)
            except asyncio.TimeoutError:
                yield ": keep-alive\n\n"
