"""The HTTP API (FastAPI) over a CommandService, and the live monitor page.

    app = create_app(service, token=None)      # uvicorn.run(app, host="127.0.0.1", port=8080)

Everything under ``/api`` needs the token when one is set (``Authorization: Bearer T``,
``X-Hearth-Token: T`` or ``?token=T`` for EventSource, which cannot set headers). Errors are
``{"error": {"message": ..., ...}}`` with 404 (unknown mission, run, parameter, request),
409 (ended run, reused idempotency key, decided request), 422 (bad parameters; FastAPI's own
body checks answer 422 with ``detail``), 401 (token). The OpenAPI schema is at
``/openapi.json``, the interactive docs at ``/docs``, the monitor page at ``/``.
"""
from __future__ import annotations

import asyncio
import json
import hmac
from contextlib import asynccontextmanager
from importlib import resources
from typing import Any

from fastapi import APIRouter, Depends, FastAPI, Header, Query, Request
from fastapi.responses import HTMLResponse, JSONResponse, StreamingResponse
from pydantic import BaseModel, Field

from executive.command.service import CommandService, Conflict, NotFound
from executive.errors import MissionError, MissionValidationError

Key = Field(default=None, min_length=1, max_length=200,
            description="idempotency key: a retried request with the same key returns the "
                        "same run instead of starting another")


class SubmitRequest(BaseModel):
    mission: str = Field(min_length=1, max_length=200, description="a mission name (GET /api/missions)")
    params: dict[str, Any] = Field(default_factory=dict, description="parameter values")
    priority: int = Field(default=0, ge=-1000, le=1000,
                          description="higher preempts the running mission; equal queues")
    idempotency_key: str | None = Key


class CommandRequest(BaseModel):
    text: str = Field(min_length=1, max_length=500, description='what the user said, e.g. "bring me the blue cup"')
    priority: int = Field(default=0, ge=-1000, le=1000)
    idempotency_key: str | None = Key
    dry_run: bool = Field(default=False, description="interpret only; start nothing")


class CancelRequest(BaseModel):
    reason: str = Field(default="cancelled by a client", max_length=300)


class ParameterValue(BaseModel):
    value: Any = Field(description="the new value (checked against the missions declaring it)")


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


def _check_token(expected: str | None):
    def check(request: Request, authorization: str | None = Header(default=None),
              x_hearth_token: str | None = Header(default=None)) -> None:
        if expected is None:
            return
        given = x_hearth_token or request.query_params.get("token")
        if authorization and authorization.lower().startswith("bearer "):
            given = authorization[7:].strip()
        if not given or not hmac.compare_digest(given.encode(), expected.encode()):
            raise _Unauthorised()
    return check


class _Unauthorised(Exception):
    pass


def monitor_html() -> str:
    return resources.files("executive.command").joinpath("static/monitor.html").read_text("utf-8")


def create_app(service: CommandService, token: str | None = None) -> FastAPI:
    @asynccontextmanager
    async def lifespan(app: FastAPI):
        service.hub.attach_loop(asyncio.get_running_loop())
        yield

    app = FastAPI(title="Hearth command API", version="1",
                  description="Start, watch and cancel missions; what the robot can be asked "
                              "for; operator approvals. See docs/command-layer.md.",
                  lifespan=lifespan)
    api = APIRouter(prefix="/api", dependencies=[Depends(_check_token(token))])

    @app.exception_handler(_Unauthorised)
    async def unauthorised(request: Request, exc: _Unauthorised):
        return _error(401, "a valid token is needed (Authorization: Bearer TOKEN, "
                           "X-Hearth-Token or ?token=)")

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

    # -- monitor ---------------------------------------------------------------------------
    @app.get("/", response_class=HTMLResponse, include_in_schema=False)
    def monitor() -> str:
        return monitor_html()

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
    def submit(body: SubmitRequest,
               idempotency_key: str | None = Header(default=None, max_length=200)):
        rec, created = service.submit(body.mission, body.params, body.priority,
                                      body.idempotency_key or idempotency_key)
        reply = {"run": rec.to_json(), "created": created}
        return reply if created else JSONResponse(status_code=200, content=reply)

    @api.post("/commands", response_model=CommandReply,
              summary="interpret an utterance and start its mission, or answer with a "
                      "clarifying question")
    def command(body: CommandRequest,
                idempotency_key: str | None = Header(default=None, max_length=200)):
        if body.dry_run:
            from executive.command.commands import interpret
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
    def run(run_id: str):
        return service.run(run_id).to_json()

    @api.post("/runs/{run_id}/cancel", status_code=202, response_model=Run,
              summary="ask a run to stop (queued: at once; running: halted, then cancelled)")
    def cancel(run_id: str, body: CancelRequest | None = None):
        return service.cancel(run_id, (body or CancelRequest()).reason).to_json()

    @api.get("/runs/{run_id}/tree", summary="the run's tree with each node's last status")
    def tree(run_id: str) -> dict[str, Any]:
        return service.tree(run_id)

    @api.get("/state", summary="what the monitor page loads first")
    def state() -> dict[str, Any]:
        cur = service.current()
        recent = service.runs(1)
        shown = cur or (recent[0] if recent else None)
        return {"last_event": service.hub.last_seq,
                "run": shown.to_json() if shown else None,
                "tree": service.tree(shown.id) if shown else None,
                "approvals": [r.to_json() for r in service.approvals.list(pending_only=True)],
                "granted_autonomy": service.approvals.granted,
                "map": service.map_view()["recent_changes"][:20],
                "parameters": service.parameters()}

    # -- parameters ---------------------------------------------------------------------------
    @api.get("/parameters", summary="runtime parameters and their values")
    def parameters() -> dict[str, Any]:
        return service.parameters()

    @api.put("/parameters/{name}", summary="set a runtime parameter (running missions react)")
    def set_parameter(name: str, body: ParameterValue) -> dict[str, Any]:
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
    def decide(request_id: str, body: Decision) -> dict[str, Any]:
        return service.decide(request_id, body.approve, body.by, body.reason).to_json()

    # -- events ------------------------------------------------------------------------------
    @api.get("/events", summary="server-sent events: one per status change, feedback, "
                                "blackboard write, map change, approval, vocabulary revision",
             response_class=StreamingResponse,
             responses={200: {"content": {"text/event-stream": {}}}})
    async def events(request: Request,
                     since: int | None = Query(default=None, ge=0,
                                               description="replay events after this number "
                                                           "(default: only new ones)"),
                     run: str | None = Query(default=None, max_length=200,
                                             description="only this run's events (and "
                                                         "map/vocabulary/autonomy ones)"),
                     close_on_end: bool = Query(default=False,
                                                description="end the stream when the run ends"),
                     last_event_id: str | None = Header(default=None)):
        if run is not None:
            service.run(run)   # 404 now, not a stream that never says anything
        cursor = since if since is not None else service.hub.last_seq
        if last_event_id and last_event_id.isdigit():
            cursor = int(last_event_id)
        return StreamingResponse(_stream(service, cursor, run, close_on_end),
                                 media_type="text/event-stream",
                                 headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"})

    app.include_router(api)
    return app


async def _stream(service: CommandService, cursor: int, run: str | None, close_on_end: bool):
    hub = service.hub
    yield f": hearth events after {cursor}\n\n"
    while True:
        waiter = hub.waiter()
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
            yield f"event: end\ndata: {json.dumps(service.run(run).to_json(), default=repr)}\n\n"
            return
        if not items:
            try:
                await asyncio.wait_for(waiter.wait(), timeout=15.0)
            except asyncio.TimeoutError:
                yield ": keep-alive\n\n"
