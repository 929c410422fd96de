"""Soak: missions submitted, cancelled, preempted and re-parameterised at random moments
through the HTTP API, on a simulated robot whose actions are real timed actions.

The server is the real app (uvicorn on 127.0.0.1, an ephemeral port, a thread of this
process) over an Executive on the wall clock (``--tick-hz``, default 50) and a
``SimulatedRobot`` on a copy of the map (``--world``, default the demo home), with real
skills: ``go_to_rest`` (shipped; its watch guard restarts the drive when ``presence``
changes) and a patrol written here (a for-each ``NavigateTo`` over 1-3 places with parking
positions, taken from the map, under a watch on ``presence``). The robot drives fast
(``--speed`` m/s) so a run takes a fraction of a second.

``--clients`` threads, each with its own HTTP connection, share ``--missions`` submissions
and at random moments (a fixed seed picks the actions and the pauses between them):
POST /api/runs (priority 0-2: a higher one preempts the running mission), POST
/api/runs/ID/cancel on a run submitted earlier, PUT /api/parameters/presence. When all are
submitted the queue drains (at most ``--drain`` s); runs still going then are cancelled and
given 10 s.

Counts (targets 0, 0, 0, 0 and < 5):

* ``cancels_not_honoured``: cancels answered 202 whose run did not end ``cancelled``.
* ``robot_left_moving``: runs that ended cancelled or preempted while a timed robot action
  they started was still going: every action the adapter returned during the run (from its
  log's start to its end time) must have stopped by then (its stop time is start + progress x
  duration, on the same clock; one still running counts too).
* ``runs_without_log_end``: submitted runs without a log whose last line is an ``end`` with
  the outcome the API reports.
* ``runs_stuck``: runs not ended 10 s after the final cancel.
* ``rss_mb_per_100_runs``: resident memory growth of the whole process (server, executive,
  clients) from the end of the first tenth of the runs to the end, per 100 runs. It includes
  the bounded buffers (event ring of 50,000 events, 2,000 run records) while they fill.

A shorter run of the same soak is in the test suite (tests/executive/test_soak.py).
"""
from __future__ import annotations

import gc
import os
import random
import resource
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

PATROL = """\
hearth: 1
name: soak_patrol
description: Drive to each place in turn (soak benchmark).
parameters:
  places: {type: list, items: node_id, description: "where to drive, in order"}
  presence: {type: string, enum: [home, away], default: home, runtime: true}
tree:
  watch:
    for_each:
      skill: NavigateTo
      inputs: {target: "{place}"}
    in: $places
    as: place
  params: [presence]
  name: patrol
"""
TERMINAL = ("succeeded", "failed", "cancelled", "preempted")


def add_arguments(parser) -> None:
    parser.add_argument("--missions", type=int, default=None,
                        help="missions submitted (default 300; --quick 40)")
    parser.add_argument("--clients", type=int, default=4, help="API client threads")
    parser.add_argument("--tick-hz", type=float, default=50.0, help="wall-clock tick rate")
    parser.add_argument("--speed", type=float, default=8.0, help="robot speed (m/s)")
    parser.add_argument("--drain", type=float, default=120.0,
                        help="seconds the queue may take to drain after the last submission")
    parser.add_argument("--world", default=None, help="world file (default: the demo home)")


class ActionLog:
    """The robot adapter as the skills see it, keeping every timed action it returns."""

    def __init__(self, robot: Any):
        self._robot = robot
        self.actions: list[Any] = []
        self._lock = threading.Lock()

    def __getattr__(self, name: str) -> Any:
        from hearth.robot.adapter import TimedAction
        attr = getattr(self._robot, name)
        if not callable(attr):
            return attr

        def call(*args: Any, **kwargs: Any) -> Any:
            out = attr(*args, **kwargs)
            if isinstance(out, TimedAction):
                with self._lock:
                    self.actions.append(out)
            return out
        return call


def _rss_mb() -> float:
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE") / 2**20
    except (OSError, ValueError, IndexError):   # not Linux: the peak is what there is
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def _last_line(path: Path) -> dict | None:
    import json
    try:
        lines = [ln for ln in path.read_text(encoding="utf-8").splitlines() if ln.strip()]
        return json.loads(lines[-1]) if lines else None
    except (OSError, ValueError):
        return None


def _client(url: str, plan: list[tuple[str, Any, float]], shared: dict) -> None:
    """Carry out ``plan``: (action, argument, pause before it in seconds)."""
    import httpx
    with httpx.Client(base_url=url, timeout=30.0) as c:
        for action, arg, pause in plan:
            time.sleep(pause)
            if action == "submit":
                r = c.post("/api/runs", json=arg)
                if r.status_code == 201:
                    rid = r.json()["run"]["id"]
                    with shared["lock"]:
                        shared["runs"].append(rid)
                else:
                    shared["errors"].append(f"submit {r.status_code}: {r.text[:200]}")
            elif action == "cancel":
                with shared["lock"]:
                    runs = list(shared["runs"])
                if not runs:
                    continue
                where, latest = arg      # the latest run, or one anywhere in the past
                rid = runs[-1] if latest else runs[int(where * len(runs))]
                r = c.post(f"/api/runs/{rid}/cancel", json={"reason": "soak cancel"})
                with shared["lock"]:
                    shared["cancels"].append((rid, r.status_code))
                if r.status_code not in (202, 409):
                    shared["errors"].append(f"cancel {r.status_code}: {r.text[:200]}")
            else:
                r = c.put("/api/parameters/presence", json={"value": arg})
                with shared["lock"]:
                    shared["params"] += 1
                if r.status_code != 200:
                    shared["errors"].append(f"parameter {r.status_code}: {r.text[:200]}")


def _plans(n: int, clients: int, places: list[str], seed: int) -> list[list]:
    """Each client's actions, drawn from ``seed``: ``n`` submissions in all, with cancels and
    parameter changes between them."""
    rng = random.Random(seed)
    plans: list[list] = [[] for _ in range(clients)]
    for i in range(n):
        plan = plans[i % clients]
        if rng.random() < 0.5:
            body = {"mission": "soak_patrol",
                    "params": {"places": rng.sample(places, rng.randint(1, min(3, len(places))))}}
        else:
            near, away = rng.sample(places, 2)
            body = {"mission": "go_to_rest",
                    "params": {"rest_near_user": near, "rest_out_of_the_way": away}}
        body["priority"] = rng.choice([0, 0, 0, 1, 2])
        plan.append(("submit", body, rng.uniform(0.0, 0.3)))
        if rng.random() < 0.45:
            plan.append(("cancel", (rng.random(), rng.random() < 0.6), rng.uniform(0.0, 0.4)))
        if rng.random() < 0.2:
            plan.append(("param", rng.choice(["home", "away"]), rng.uniform(0.0, 0.3)))
    return plans


def soak(missions: int = 300, clients: int = 4, seed: int = 0, tick_hz: float = 50.0,
         speed: float = 8.0, drain_s: float = 120.0, world_path: str | None = None,
         runs_dir: str | None = None) -> dict:
    """Run the soak (see the module docstring); its figures."""
    from hearth.executive.command.api import create_app
    from hearth.executive.command.server import ServerThread, make_service
    from hearth import demo_world_path, missions_dir
    from hearth.robot.clock import WallClock
    from hearth.robot.simulated import SimulatedRobot
    from hearth.worldmodel.io import load_world

    with tempfile.TemporaryDirectory() as tmp:
        runs_path = Path(runs_dir) if runs_dir else Path(tmp) / "runs"
        (Path(tmp) / "soak_patrol.yaml").write_text(PATROL)
        clock = WallClock()
        world = load_world(world_path or demo_world_path(), clock=clock)
        places = [o.id for o in world.large_objects() if world.parking_positions(o.id)]
        if len(places) < 2:
            raise ValueError("the soak needs a world with two places to park at")
        robot = ActionLog(SimulatedRobot(world.copy(), clock=clock, noise=None, seed=seed,
                                         speed=speed, turn_speed=4 * speed,
                                         approach_time=0.05))
        service = make_service(world, robot, [str(Path(tmp) / "soak_patrol.yaml"),
                                              str(missions_dir() / "go_to_rest.yaml")],
                               clock=clock, tick_hz=tick_hz, runs_dir=str(runs_path))
        if service.catalogue_problems:
            raise RuntimeError("; ".join(service.catalogue_problems))
        ex = service.executive
        shared: dict[str, Any] = {"lock": threading.Lock(), "runs": [], "cancels": [],
                                  "params": 0, "errors": [],
                                  "warmup_at": max(1, missions // 10)}
        t0 = time.perf_counter()
        with ServerThread(create_app(service)) as srv:
            threads = [threading.Thread(target=_client, args=(srv.url, plan, shared),
                                        name=f"soak-client-{i}", daemon=True)
                       for i, plan in enumerate(_plans(missions, clients, places, seed))]
            for t in threads:
                t.start()
            # Memory is sampled once the first tenth of the runs have ended (warmed up) and
            # at the end; the queue drains for at most drain_s after the last submission.
            rss_start, ended_at_start, deadline = None, 0, None
            while True:
                with shared["lock"]:
                    runs = list(shared["runs"])
                ended = sum(1 for r in runs if service.run(r).handle.done)
                if rss_start is None and ended >= shared["warmup_at"]:
                    gc.collect()
                    rss_start, ended_at_start = _rss_mb(), ended
                clients_done = not any(t.is_alive() for t in threads)
                if clients_done and deadline is None:
                    deadline = time.monotonic() + drain_s
                if clients_done and (ended == len(runs) or time.monotonic() > deadline):
                    break
                time.sleep(0.05)
            submitted = list(shared["runs"])
            handles = {rid: service.run(rid).handle for rid in submitted}
            if rss_start is None:
                gc.collect()
                rss_start, ended_at_start = _rss_mb(), ended
            final_cancels = [rid for rid, h in handles.items() if not h.done]
            for rid in final_cancels:
                handles[rid].cancel("soak over")
            stuck_deadline = time.monotonic() + 10.0
            for h in handles.values():
                h.wait(max(0.0, stuck_deadline - time.monotonic()))
            wall = time.perf_counter() - t0
            gc.collect()
            rss_end = _rss_mb()
        ex.shutdown()
        service.close()

        outcomes: dict[str, int] = {}
        for h in handles.values():
            key = h.result.outcome if h.result is not None else "not ended"
            outcomes[key] = outcomes.get(key, 0) + 1
        accepted = {rid for rid, code in shared["cancels"] if code == 202}
        not_honoured = sum(1 for rid in accepted
                           if handles[rid].result is None
                           or handles[rid].result.outcome != "cancelled")
        stuck = sum(1 for h in handles.values() if not h.done)
        without_end, left_moving, not_confirmed = 0, 0, 0
        actions = sorted(robot.actions, key=lambda a: a.start)
        for rid, h in handles.items():
            end = _last_line(runs_path / f"{rid}.jsonl")
            if (h.result is None or end is None or end.get("e") != "end"
                    or end.get("outcome") != h.result.outcome):
                without_end += 1
                continue
            if not h.result.robot_stopped:
                not_confirmed += 1
            if h.result.outcome not in ("cancelled", "preempted"):
                continue
            header = _first_line(runs_path / f"{rid}.jsonl")
            if header.get("started") is False:
                continue
            t_start, t_end = float(header["t"]), float(end["t"])
            for a in actions:
                if t_start <= a.start <= t_end:
                    status = a.status()
                    stopped_at = (float("inf") if status == "running"
                                  else a.start + a.progress * a.duration)
                    if stopped_at > t_end + 1e-6:
                        left_moving += 1
                        break
    ended_runs = sum(1 for h in handles.values() if h.done) - ended_at_start
    return {
        "missions": len(submitted),
        "clients": clients,
        "tick_hz": tick_hz,
        "cancels_sent": len(shared["cancels"]),
        "cancels_accepted": len(accepted),
        "cancels_refused_ended": sum(1 for _, code in shared["cancels"] if code == 409),
        "parameter_changes": shared["params"],
        "final_cancels": len(final_cancels),
        "outcomes": outcomes,
        "robot_actions": len(actions),
        "robot_not_confirmed_stopped": not_confirmed,
        "cancels_not_honoured": not_honoured,
        "robot_left_moving": left_moving,
        "runs_without_log_end": without_end,
        "runs_stuck": stuck,
        "rss_mb_start": round(rss_start, 1),
        "rss_mb_end": round(rss_end, 1),
        "rss_runs_measured": ended_runs,
        "rss_mb_per_100_runs": round((rss_end - rss_start) / max(ended_runs, 1) * 100, 3),
        "wall_s": round(wall, 2),
        "runs_per_s": round(len(submitted) / wall, 2) if wall > 0 else None,
        "errors": shared["errors"][:5],
        "targets": {"cancels_not_honoured": 0, "robot_left_moving": 0,
                    "runs_without_log_end": 0, "runs_stuck": 0, "rss_mb_per_100_runs": 5.0},
        "seed": seed,
        "load_avg_1m": round(os.getloadavg()[0], 2),
    }


def _first_line(path: Path) -> dict:
    import json
    with open(path, encoding="utf-8") as f:
        return json.loads(f.readline())


def run(args) -> dict:
    n = getattr(args, "missions", None) or (40 if getattr(args, "quick", False) else 300)
    return soak(missions=n, clients=getattr(args, "clients", 4), seed=getattr(args, "seed", 0),
                tick_hz=getattr(args, "tick_hz", 50.0), speed=getattr(args, "speed", 8.0),
                drain_s=getattr(args, "drain", 120.0), world_path=getattr(args, "world", None))
