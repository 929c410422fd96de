"""Command API on loopback: 50 concurrent clients submitting missions and following their
events, plus a schema-driven fuzz.

The server is the real app (uvicorn on 127.0.0.1, an ephemeral port, in a thread of this
process) over an Executive on a simulated clock whose skills are scripted stand-ins
(executive.testing): a 6-step mission whose steps each run 2 ticks with feedback, ~30
events per run. The executive queues equal priorities, so runs execute one after another
as fast as it ticks. Each of ``clients`` asyncio clients (httpx, its own connection pool)
does ``missions`` rounds of: POST /api/runs (timed: ``submit_p50_ms``, ``submit_p99_ms``),
then GET /api/events?run=ID&since=0&close_on_end=true, reading to the end. One more client
follows every event, as the monitor page does. ``events_per_s``: SSE events received by all
clients together per wall second. ``runs_ok`` checks no run was lost or run twice (each
submitted run ended succeeded, and was started exactly once). Bounded: at most
``time_limit_s`` seconds.

The clients share this process with the server (and the GIL), and the machine is shared:
figures are pessimistic; ``load_avg_1m`` says how busy the machine was.
"""
from __future__ import annotations

import asyncio
import json
import os
import statistics
import tempfile
import threading
import time
from pathlib import Path

MISSION = """\
hearth: 1
name: bench_chores
description: Six scripted steps (benchmark only).
utterances: ["do the chores"]
tree:
  sequence:
    - {skill: Act, name: s1}
    - {skill: Act, name: s2}
    - {skill: Act, name: s3}
    - {skill: Act, name: s4}
    - {skill: Act, name: s5}
    - {skill: Speak, name: report, inputs: {text: done}}
"""


def add_arguments(parser) -> None:
    parser.add_argument("--clients", type=int, default=50, help="concurrent API clients")
    parser.add_argument("--missions", type=int, default=None,
                        help="missions per client (default 4; --quick 2)")
    parser.add_argument("--fuzz", type=int, default=None,
                        help="fuzz requests (default 500; --quick 100)")
    parser.add_argument("--time-limit", type=float, default=120.0, help="seconds at most")
    parser.add_argument("--tick-hz", type=float, default=0.0,
                        help="tick on a wall clock at this rate (default 0: a simulated clock, "
                             "ticking as fast as it can)")


def _percentile(values: list[float], q: float) -> float:
    values = sorted(values)
    if not values:
        return float("nan")
    k = min(len(values) - 1, max(0, int(round(q / 100.0 * (len(values) - 1)))))
    return values[k]


async def _client(c, rounds: int, idx: int, latencies: list[float],
                  counts: list[int], run_ids: list[str]) -> None:
    async with c:
        for k in range(rounds):
            t0 = time.perf_counter()
            r = await c.post("/api/runs", json={"mission": "bench_chores",
                                                "idempotency_key": f"c{idx}-{k}"})
            latencies.append((time.perf_counter() - t0) * 1000.0)
            r.raise_for_status()
            rid = r.json()["run"]["id"]
            run_ids.append(rid)
            n = 0
            async with c.stream("GET", "/api/events", params={"run": rid, "since": 0,
                                                              "close_on_end": "true"}) as s:
                async for line in s.aiter_lines():
                    if line.startswith("data: "):
                        n += 1
            counts.append(n)


async def _monitor(url: str, stop: asyncio.Event, counts: list[int]) -> None:
    import httpx
    async with httpx.AsyncClient(base_url=url, timeout=None) as c:
        async with c.stream("GET", "/api/events", params={"since": 0}) as s:
            async for line in s.aiter_lines():
                if line.startswith("data: "):
                    counts[0] += 1
                if stop.is_set():
                    return


async def _load(url: str, clients: int, rounds: int, limit: float) -> dict:
    latencies: list[float] = []
    counts: list[int] = []
    run_ids: list[str] = []
    monitor_count = [0]
    stop = asyncio.Event()
    mon = asyncio.create_task(_monitor(url, stop, monitor_count))
    import httpx
    # Made before the clock starts: making an httpx client loads CA certificates (~30 ms of
    # CPU each, under the GIL the server shares), which would be counted as submit latency.
    limits = httpx.Limits(max_connections=2)
    made = [httpx.AsyncClient(base_url=url, timeout=60.0, limits=limits)
            for _ in range(clients)]
    t0 = time.perf_counter()
    tasks = [asyncio.create_task(_client(c, rounds, i, latencies, counts, run_ids))
             for i, c in enumerate(made)]
    done, pending = await asyncio.wait(tasks, timeout=limit)
    wall = time.perf_counter() - t0
    for t in pending:
        t.cancel()
    stop.set()
    mon.cancel()
    errors = [repr(t.exception()) for t in done if t.exception() is not None]
    return {"latencies": latencies, "counts": counts, "run_ids": run_ids, "wall": wall,
            "monitor": monitor_count[0], "timed_out": bool(pending), "errors": errors[:3]}


def run(args) -> dict:
    import httpx

    from executive.command.api import create_app
    from executive.command.fuzz import run_fuzz
    from executive.command.server import ServerThread, make_service
    from executive.testing import Script, Substitution, test_skills
    from hearth.robot.clock import SimClock, WallClock
    from hearth import demo_world_path
    from worldmodel.io import load_world

    clients = getattr(args, "clients", 50)
    rounds = getattr(args, "missions", None) or (2 if args.quick else 4)
    fuzz_n = getattr(args, "fuzz", None) or (100 if args.quick else 500)
    limit = getattr(args, "time_limit", 120.0)
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "chores.yaml").write_text(MISSION)
        world = load_world(demo_world_path())
        hz = getattr(args, "tick_hz", 0.0) or 0.0
        clock = WallClock() if hz > 0 else SimClock()
        hz = hz if hz > 0 else 10.0
        # Each step runs two ticks, with feedback.
        sub = Substitution([Script(match="Act", duration=1.5 / hz, feedback="working on it")],
                           None)
        service = make_service(world, None, [tmp], skills=test_skills(), make_skill=sub,
                               clock=clock, tick_hz=hz, runs_dir=None)
        started: dict[str, int] = {}
        lock = threading.Lock()

        def count(ev):
            if ev.kind == "run" and ev.data.get("state") == "running":
                with lock:
                    started[ev.run] = started.get(ev.run, 0) + 1
        service.executive.subscribe(count)
        with ServerThread(create_app(service)) as srv:
            load = asyncio.run(_load(srv.url, clients, rounds, limit))
            statuses = {rid: service.run(rid).handle.status for rid in load["run_ids"]}
            with httpx.Client(base_url=srv.url, timeout=30.0) as c:
                schema = c.get("/openapi.json").json()
                t0 = time.perf_counter()
                fuzz = run_fuzz(c, schema, ["bench_chores", "do the chores", "presence", "a1",
                                            "blue_cup", "bring me the cup", ""], fuzz_n)
                fuzz_s = time.perf_counter() - t0
        service.executive.shutdown()
        service.close()
    lat = load["latencies"]
    received = sum(load["counts"]) + load["monitor"]
    expected = clients * rounds
    return {
        "clients": clients,
        "missions_per_client": rounds,
        "runs": len(load["run_ids"]),
        "runs_ok": (len(load["run_ids"]) == expected and not load["timed_out"]
                    and set(statuses.values()) == {"succeeded"}
                    and all(started.get(r) == 1 for r in load["run_ids"])),
        "submit_p50_ms": round(statistics.median(lat), 3) if lat else None,
        "submit_p99_ms": round(_percentile(lat, 99), 3) if lat else None,
        "submit_max_ms": round(max(lat), 3) if lat else None,
        "events_received": received,
        "events_per_run": round(statistics.mean(load["counts"]), 1) if load["counts"] else None,
        "events_per_s": round(received / load["wall"], 1),
        "wall_s": round(load["wall"], 3),
        "timed_out": load["timed_out"],
        "errors": load["errors"],
        "fuzz_requests": fuzz["requests"],
        "fuzz_5xx": len(fuzz["failures"]),
        "fuzz_by_class": fuzz["by_class"],
        "fuzz_requests_per_s": round(fuzz["requests"] / fuzz_s, 1),
        "clock": "wall" if getattr(args, "tick_hz", 0.0) else "sim",
        "load_avg_1m": round(os.getloadavg()[0], 2),
        "cpu_count": os.cpu_count(),
    }


if __name__ == "__main__":  # pragma: no cover
    import argparse
    p = argparse.ArgumentParser()
    p.add_argument("--quick", action="store_true")
    add_arguments(p)
    print(json.dumps(run(p.parse_args())))
