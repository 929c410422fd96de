"""Command API on loopback, loaded the way users load it, plus a stress figure and a
schema-driven fuzz.

**As users load it** (``clients_1``, ``clients_50``; the top-level ``submit_p50_ms`` and
``submit_p99_ms`` are those of ``clients_50``; ``load_model`` in the JSON says all of this):
the real app (uvicorn on 127.0.0.1, an ephemeral port, in a thread of this process) over an
Executive ticking on a wall clock at ``--tick-hz`` (default 10 Hz), whose skills are
scripted stand-ins (hearth.executive.testing): a 6-step mission whose steps each run 2 ticks with
feedback. The clients are other processes (``--procs``, default 2; the clients are shared
out between them), each client with its own kept-alive connections (httpx), opened before
the clock starts. Each client submits missions (POST /api/runs, timed) at random moments and
follows the events of the run it asked for last (``run=ID&close_on_end=true``), as a
dialogue system does; one more stream follows every event, as an operator's monitor page
does. The gaps between one client's submits are exponential, drawn from a seeded generator,
with a mean (``mean_think_s`` = clients / rate) that gives Poisson arrivals at ``--rate``
submits per second from all clients together (default 20: each of 50 clients submits every
2.5 s on average), for ``--samples`` / ``--rate`` seconds (default 300 samples: 15 s; --quick
100). Runs queue one after another, as on a robot; what is still queued when the submits are
done is cancelled. ``runs_ok``: every submitted run ended (succeeded, or cancelled by that
clean-up) and none was started twice. ``events_per_s``: events the clients' streams received
per wall second, all together. ``in_app_submit_p50_ms``/``_p99_ms``: the same submits timed
inside the server's app (what the server itself takes; the rest is the network stack,
uvicorn's parsing, the client's event loop and waiting for a CPU);
``server_cpu_ms_per_submit``: the CPU time of the server's process (API, executive, event
streams) over the section, per submit; ``client_late_p99_ms``: how late the clients' submits
started against their drawn moments (their processes waiting for a CPU, their own event loop
busy, or a client's previous submit still running). Target: ``submit_p99_ms`` <= 20 at 50 clients.

**Stress, in one process** (``stress_in_process``; the keys of the earlier figure): the
clients (asyncio, httpx) in this process with the server and the GIL, the executive on a
simulated clock ticking as fast as it can. Each of ``--clients`` clients does ``--missions``
rounds of: submit (timed), then follow that run's events to its end
(``close_on_end=true``); one more client follows every event. All 50 submit at once and
the executive never waits: this saturates the server and measures the benchmark as much as
the server, so it is a stress figure, not what a user sees.

The machine is shared: ``load_avg_1m`` says how busy it was (per section: at its start and
end).
"""
from __future__ import annotations

import asyncio
import itertools
import json
import math
import multiprocessing
import os
import queue as queue_module
import random
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

TARGET_P99_MS = 20.0


def add_arguments(parser) -> None:
    parser.add_argument("--clients", type=int, default=50,
                        help="concurrent API clients of the large section and of the stress "
                             "figure (default 50; a one-client section is always run)")
    parser.add_argument("--samples", type=int, default=None,
                        help="submits expected per section with clients in other "
                             "processes: the section lasts SAMPLES/RATE s "
                             "(default 300; --quick 100)")
    parser.add_argument("--rate", type=float, default=20.0,
                        help="submits per second from all clients together (default 20)")
    parser.add_argument("--procs", type=int, default=2,
                        help="client processes (default 2)")
    parser.add_argument("--tick-hz", type=float, default=10.0,
                        help="the executive's wall-clock tick rate (default 10)")
    parser.add_argument("--missions", type=int, default=None,
                        help="stress figure: missions per client (default 4; --quick 2)")
    parser.add_argument("--fuzz", type=int, default=None,
                        help="fuzz requests (default 500; --quick 100)")
    parser.add_argument("--time-limit", type=float, default=120.0,
                        help="seconds at most per section")


def _percentile(values: list[float], q: float) -> float:
    values = sorted(values)
    if not values:
        return float("nan")
    k = min(len(values) - 1, max(0, int(round(q / 100.0 * (len(values) - 1)))))
    return values[k]


def _service(tmp: str, clock, hz: float):
    from hearth.executive.command.server import make_service
    from hearth.executive.testing import Script, Substitution, test_skills
    from hearth import demo_world_path
    from hearth.worldmodel.io import load_world

    (Path(tmp) / "chores.yaml").write_text(MISSION)
    world = load_world(demo_world_path())
    # Each step runs two ticks, with feedback.
    sub = Substitution([Script(match="Act", duration=1.5 / hz, feedback="working on it")], None)
    service = make_service(world, None, [tmp], skills=test_skills(), make_skill=sub,
                           clock=clock, tick_hz=hz, runs_dir=None)
    started: dict[str, int] = {}
    lock = threading.Lock()

    def count(ev):
        if ev.kind == "run" and ev.data.get("state") == "running":
            with lock:
                started[ev.run] = started.get(ev.run, 0) + 1
    service.executive.subscribe(count)
    return service, started


# -- clients in other processes -----------------------------------------------------------

def _client_process(url: str, clients: list[int], duration: float, think_s: float, seed: int,
                    tag: str, monitor: bool, limit: float, ready, go, results) -> None:
    """One client process (multiprocessing, spawned): ``clients`` asyncio clients submitting
    missions at random moments for ``duration`` seconds and following their latest run's
    events;
    with ``monitor``, one more stream following every event. Puts one dict on ``results``."""
    try:
        out = asyncio.run(_clients(url, clients, duration, think_s, seed, tag, monitor, limit,
                                   ready, go))
    except Exception as err:  # reported, not raised: the parent reads the queue
        out = {"latencies": [], "run_ids": [], "events": 0, "errors": [repr(err)],
               "timed_out": False}
    results.put(out)


async def _clients(url, clients, duration, think_s, seed, tag, monitor, limit, ready,
                   go) -> dict:
    import httpx

    latencies: list[float] = []
    late: list[float] = []      # how late each submit started: this process waiting for a CPU
    run_ids: list[str] = []
    events = [0]

    async def follow(c, params: dict, opened: asyncio.Event | None = None) -> None:
        async with c.stream("GET", "/api/events", params=params) as s:
            s.raise_for_status()
            if opened is not None:
                opened.set()
            async for line in s.aiter_lines():
                if line.startswith("data: "):
                    events[0] += 1

    async def client(c, idx: int) -> None:
        rng = random.Random(f"{seed}-{idx}")
        following = None
        start = time.perf_counter()
        due = 0.0                   # when the next submit is due, from the start
        try:
            for n in itertools.count():
                # Exponential gaps between due times: Poisson arrivals at the set rate for
                # the whole section, however long a submit takes.
                due += rng.expovariate(1.0 / think_s)
                if due > duration:
                    break
                await asyncio.sleep(max(0.0, start + due - time.perf_counter()))
                t0 = time.perf_counter()
                late.append((t0 - start - due) * 1000.0)
                r = await c.post("/api/runs", json={"mission": "bench_chores",
                                                    "idempotency_key": f"{tag}-c{idx}-{n}"})
                latencies.append((time.perf_counter() - t0) * 1000.0)
                r.raise_for_status()
                rid = r.json()["run"]["id"]
                run_ids.append(rid)
                # As a dialogue client does: follow the run it asked for (the latest).
                if following is not None:
                    following.cancel()
                following = asyncio.create_task(follow(c, {"run": rid, "since": 0,
                                                           "close_on_end": "true"}))
        finally:
            if following is not None:
                following.cancel()

    # Made before the clock starts: an httpx client loads CA certificates when made. Each
    # opens its kept-alive connection before the clock starts too, as a dialogue system or
    # an app that stays connected has it (the submits are timed, not the TCP handshakes).
    made = [httpx.AsyncClient(base_url=url, timeout=60.0,
                              limits=httpx.Limits(max_connections=4)) for _ in clients]
    for c in made:
        (await c.get("/api/health")).raise_for_status()
    watcher = None
    if monitor:
        opened = asyncio.Event()
        mc = httpx.AsyncClient(base_url=url, timeout=None)
        watcher = asyncio.create_task(follow(mc, {}, opened))
        await asyncio.wait([asyncio.create_task(opened.wait()), watcher],
                           return_when=asyncio.FIRST_COMPLETED)
    ready.put(watcher is None or not watcher.done())
    await asyncio.get_running_loop().run_in_executor(None, go.wait)
    tasks = [asyncio.create_task(client(c, idx)) for idx, c in zip(clients, made)]
    finished, pending = await asyncio.wait(tasks, timeout=limit)
    for t in pending:
        t.cancel()
    errors = [repr(t.exception()) for t in finished if t.exception() is not None]
    if watcher is not None:
        if watcher.done() and watcher.exception() is not None:
            errors.append(repr(watcher.exception()))
        watcher.cancel()
        await asyncio.gather(watcher, return_exceptions=True)
        await mc.aclose()
    await asyncio.gather(*pending, return_exceptions=True)
    for c in made:
        await c.aclose()
    return {"latencies": latencies, "late": late, "run_ids": run_ids, "events": events[0],
            "errors": errors[:3], "timed_out": bool(pending)}


class _AppTimer:
    """ASGI wrapper (this benchmark only) timing each ``POST /api/runs`` in the server: from
    the app receiving the parsed request to the last byte of its answer handed to uvicorn.
    The difference from what the clients measure is the network stack, uvicorn's parsing,
    the client's own event loop and waiting for a CPU."""

    def __init__(self, app):
        self.app = app
        self.submit_ms: list[float] = []

    async def __call__(self, scope, receive, send):
        if scope["type"] != "http" or scope["method"] != "POST" or scope["path"] != "/api/runs":
            await self.app(scope, receive, send)
            return
        t0 = time.perf_counter()
        await self.app(scope, receive, send)
        self.submit_ms.append((time.perf_counter() - t0) * 1000.0)


def _get(q, workers: list, timeout: float, missing):
    """The next item on ``q``; ``missing`` when it does not come and a worker has died (or
    after ``timeout`` seconds)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            return q.get(timeout=0.5)
        except queue_module.Empty:
            if any(w.exitcode not in (None, 0) for w in workers):
                return missing
    return missing


def _as_users(args, clients: int, samples: int) -> dict:
    from hearth.executive.command.api import create_app
    from hearth.executive.command.server import ServerThread
    from hearth.robot.clock import WallClock

    hz = getattr(args, "tick_hz", 10.0) or 10.0
    rate = getattr(args, "rate", 20.0)
    procs = max(1, min(getattr(args, "procs", 2), clients))
    limit = getattr(args, "time_limit", 120.0)
    duration = samples / rate       # samples expected: rate * duration
    think = clients / rate
    ctx = multiprocessing.get_context("spawn")
    with tempfile.TemporaryDirectory() as tmp:
        service, started = _service(tmp, WallClock(), hz)
        timer = _AppTimer(create_app(service))
        try:
            with ServerThread(timer) as srv:
                ready, results, go = ctx.Queue(), ctx.Queue(), ctx.Event()
                shares = [list(range(clients))[p::procs] for p in range(procs)]
                workers = [ctx.Process(target=_client_process, daemon=True,
                                       args=(srv.url, share, duration, think, args.seed,
                                             f"n{clients}", p == 0, limit, ready, go,
                                             results))
                           for p, share in enumerate(shares)]
                for w in workers:
                    w.start()
                ok = all(_get(ready, workers, 120, False) for _ in workers)
                timer.submit_ms.clear()     # the warm-up requests are not submits anyway
                load0 = os.getloadavg()[0]
                t0 = time.perf_counter()
                cpu0 = time.process_time()
                go.set()
                lost = {"latencies": [], "run_ids": [], "events": 0, "timed_out": True,
                        "errors": ["a client process ended without an answer"]}
                outs = [_get(results, workers, limit + 60, lost) for _ in workers]
                wall = time.perf_counter() - t0
                cpu = time.process_time() - cpu0
                load1 = os.getloadavg()[0]
                for w in workers:
                    w.join(10)
                run_ids = [r for o in outs for r in o["run_ids"]]
                cancelled = 0
                for rid in run_ids:
                    if not service.run(rid).handle.done:
                        service.cancel(rid, "benchmark over")
                        cancelled += 1
                for rid in run_ids:
                    service.run(rid).handle.wait(30)
                statuses = [service.run(rid).handle.status for rid in run_ids]
        finally:
            service.executive.shutdown()
            service.close()
    lat = [x for o in outs for x in o["latencies"]]
    late = [x for o in outs for x in o.get("late", ())]
    in_app = timer.submit_ms
    timed_out = any(o["timed_out"] for o in outs)
    return {
        "clients": clients,
        "client_procs": procs,
        "mean_think_s": round(think, 3),
        "submits": len(lat),
        "submit_p50_ms": round(statistics.median(lat), 3) if lat else None,
        "submit_p99_ms": round(_percentile(lat, 99), 3) if lat else None,
        "submit_max_ms": round(max(lat), 3) if lat else None,
        "in_app_submit_p50_ms": round(statistics.median(in_app), 3) if in_app else None,
        "in_app_submit_p99_ms": round(_percentile(in_app, 99), 3) if in_app else None,
        "server_cpu_ms_per_submit": round(cpu * 1000.0 / len(lat), 3) if lat else None,
        "client_late_p99_ms": round(_percentile(late, 99), 3) if late else None,
        "submits_per_s": round(len(lat) / wall, 1),
        "runs_succeeded": statuses.count("succeeded"),
        "runs_cancelled_at_end": cancelled,
        "runs_ok": (ok and not timed_out and len(run_ids) == len(lat) > 0
                    and set(statuses) <= {"succeeded", "cancelled"}
                    and all(started.get(r, 0) <= 1 for r in run_ids)
                    and statuses.count("cancelled") == cancelled),
        "events_received": sum(o["events"] for o in outs),
        "events_per_s": round(sum(o["events"] for o in outs) / wall, 1),
        "wall_s": round(wall, 3),
        "load_avg_1m": [round(load0, 2), round(load1, 2)],
        "timed_out": timed_out,
        "errors": [e for o in outs for e in o["errors"]][:3],
    }


# -- stress: everything in this process, a free-running clock -----------------------------

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


def _stress(args, clients: int, rounds: int, limit: float) -> dict:
    from hearth.executive.command.api import create_app
    from hearth.executive.command.server import ServerThread
    from hearth.robot.clock import SimClock

    with tempfile.TemporaryDirectory() as tmp:
        service, started = _service(tmp, SimClock(), 10.0)
        with ServerThread(create_app(service)) as srv:
            load = asyncio.run(_load(srv.url, clients, rounds, limit))
            statuses = {rid: service.run(rid).handle.status for rid in load["run_ids"]}
        service.executive.shutdown()
        service.close()
    lat = load["latencies"]
    received = sum(load["counts"]) + load["monitor"]
    expected = clients * rounds
    return {
        "what": "stress: clients in the server's process, a simulated clock ticking as fast "
                "as it can, all clients submitting at once",
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
        "clock": "sim",
    }


def _fuzz(n: int, seed: int) -> dict:
    import httpx

    from hearth.executive.command.api import create_app
    from hearth.executive.command.fuzz import run_fuzz
    from hearth.executive.command.server import ServerThread
    from hearth.robot.clock import SimClock

    with tempfile.TemporaryDirectory() as tmp:
        service, _ = _service(tmp, SimClock(), 10.0)
        with ServerThread(create_app(service)) as srv:
            with httpx.Client(base_url=srv.url, timeout=30.0) as c:
                schema = c.get("/openapi.json").json()
                t0 = time.perf_counter()
                small = [o.id for o in service.world.small_objects()][:1]   # a real id
                fuzz = run_fuzz(c, schema, ["bench_chores", "do the chores", "presence", "a1",
                                            *small, "bring me the cup", ""], n, seed=seed)
                fuzz_s = time.perf_counter() - t0
        service.executive.shutdown()
        service.close()
    return {"fuzz_requests": fuzz["requests"], "fuzz_5xx": len(fuzz["failures"]),
            "fuzz_by_class": fuzz["by_class"],
            "fuzz_requests_per_s": round(fuzz["requests"] / fuzz_s, 1)}


def _uvicorn_impl() -> dict:
    """uvicorn's HTTP protocol (always h11, see hearth.executive.command.server.make_server) and
    event loop: uvloop where installed, else asyncio's own."""
    import importlib.util
    return {"http": "h11",
            "loop": "uvloop" if importlib.util.find_spec("uvloop") is not None else "asyncio"}


def run(args) -> dict:
    try:
        import httpx  # noqa: F401  (the clients)
    except ImportError:
        import sys
        print("hearth bench api: the clients need httpx: pip install 'hearth[http]'",
              file=sys.stderr)
        raise SystemExit(2) from None
    clients = getattr(args, "clients", 50)
    samples = getattr(args, "samples", None) or (100 if args.quick else 300)
    for name, value in (("--clients", clients), ("--samples", samples),
                        ("--rate", getattr(args, "rate", 20.0)),
                        ("--procs", getattr(args, "procs", 2)),
                        ("--tick-hz", getattr(args, "tick_hz", 10.0))):
        if not (math.isfinite(value) and value > 0):
            import sys
            print(f"hearth bench api: {name} must be a positive number (got {value})",
                  file=sys.stderr)
            raise SystemExit(2)
    rounds = getattr(args, "missions", None) or (2 if args.quick else 4)
    fuzz_n = getattr(args, "fuzz", None) or (100 if args.quick else 500)
    limit = getattr(args, "time_limit", 120.0)
    one = _as_users(args, 1, samples)
    many = _as_users(args, clients, samples)
    stress = _stress(args, clients, rounds, limit)
    fuzz = _fuzz(fuzz_n, args.seed)
    hz = getattr(args, "tick_hz", 10.0)
    rate = getattr(args, "rate", 20.0)
    return {
        "setup": (f"clients in {many['client_procs']} other processes, the server on "
                  f"127.0.0.1, the executive on a wall clock at {hz} Hz, "
                  f"{rate} submits/s from all clients together"),
        "load_model": {
            "what": "as users load it: clients_1 and clients_N; submit_p50_ms/submit_p99_ms "
                    "are clients_N's",
            "clients": [1, clients],
            "client_processes": many["client_procs"],
            "submits_per_s_all_clients": rate,
            "arrivals": "each client waits an exponential time (seeded) before each submit, "
                        "mean clients/rate s (mean_think_s): Poisson arrivals at the rate "
                        "from all clients together",
            "per_client": "POST /api/runs (timed, kept-alive connection opened before the "
                          "clock starts), then follow that run's events "
                          "(GET /api/events?run=ID&close_on_end=true) until its next submit",
            "monitor_streams": 1,
            "executive": f"wall clock, {hz} Hz; runs queue one after another",
            "samples_per_section": samples,
            "server": "uvicorn on 127.0.0.1 in a thread of the benchmark's process, with the "
                      "executive; in_app_submit_*: the same submits timed inside the app",
            "uvicorn": _uvicorn_impl(),
        },
        "clients_1": one,
        f"clients_{clients}": many,
        "submit_p50_ms": many["submit_p50_ms"],
        "submit_p99_ms": many["submit_p99_ms"],
        "target_submit_p99_ms": TARGET_P99_MS,
        "runs_ok": one["runs_ok"] and many["runs_ok"] and stress["runs_ok"],
        # Stress: all clients in the server's process, submitting back to back on a free-
        # running clock (a saturation figure, not a user's load).
        "stress_in_process": stress,
        **fuzz,
        "load_avg_1m": round(os.getloadavg()[0], 2),
        "cpu_count": os.cpu_count(),
    }


if __name__ == "__main__":  # pragma: no cover
    import argparse
    p = argparse.ArgumentParser()
    p.add_argument("--quick", action="store_true")
    p.add_argument("--seed", type=int, default=0)
    add_arguments(p)
    print(json.dumps(run(p.parse_args())))
