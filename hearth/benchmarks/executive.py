"""Executive tick overhead: a generated 200-node mission ticked through Hearth vs the same
tree built directly in py_trees.

The tree: ``repeat`` forever over a ``parallel`` (all) of 18 groups, each a ``parallel``
(all) of two memory sequences of four leaves (200 nodes). Each leaf is a skill that runs
for 0-3 ticks (fixed seed) and succeeds, so about half the tree is ticked every tick and
statuses keep changing (Hearth has events to track). Hearth ticks it through
``Executive.tick()`` on a simulated clock, with the execution log written (the cost every
run pays); ``tick_ms_subscribed`` is the same with one (empty) subscriber, so every event is
also made an ``Event`` and delivered, as under the HTTP API. The executive ticks the tree by
direct calls (hearth/executive/treetick.py), not py_trees' generators; docs/missions.md,
"Performance", has the profile.

The baseline is the same behaviour classes assembled by hand from py_trees composites and
ticked the way py_trees ticks a tree, ``py_trees.trees.BehaviourTree.tick()``
(``py_trees_tree_tick_ms``); ``tick_overhead_ratio`` = Hearth median / that median (target
<= 1.3). A stricter figure, ``tick_overhead_ratio_bare``, divides by the cheapest possible
py_trees tick, a bare ``for _ in root.tick(): pass`` (``py_trees_tick_ms``), which skips
BehaviourTree's per-tick walk over the whole tree for visitors. ``tick_ms`` is Hearth's
median in milliseconds (target < 1). All figures are medians (means as ``*_mean``) of
per-tick wall times, measured in interleaved blocks of 10 ticks so machine load hits all
three alike.
"""
from __future__ import annotations

import gc
import random
import statistics
import tempfile
import time
from pathlib import Path

import py_trees
from py_trees import common

from hearth.benchmarks import _btcpp
from hearth.skills.base import Bindings, Port, Skill

GROUPS = 18


class Work(Skill):
    """Benchmark-only skill: RUNNING for ``ticks`` ticks, then SUCCESS."""
    NAME = "BenchWork"
    INPUTS = (Port("ticks", "integer"),)
    OUTPUTS = ()

    def initialise(self) -> None:
        self.left = self.input("ticks")

    def update(self) -> common.Status:
        if self.left > 0:
            self.left -= 1
            return common.Status.RUNNING
        return common.Status.SUCCESS


def _durations(seed: int) -> list[int]:
    rng = random.Random(seed)
    return [rng.randint(0, 3) for _ in range(GROUPS * 8)]


def mission_yaml(seed: int) -> str:
    durations = iter(_durations(seed))
    lines = ["name: bench", "tree:", "  repeat:", "    parallel:"]
    for g in range(GROUPS):
        lines += ["      - parallel:", "          - sequence:"]
        for half in range(2):
            if half:
                lines.append("          - sequence:")
            for i in range(4):
                lines.append(f"              - {{skill: BenchWork, name: w{g}_{half}_{i}, "
                             f"inputs: {{ticks: {next(durations)}}}}}")
        lines.append(f"        name: group{g}")
    lines.append("  times: -1")
    return "\n".join(lines) + "\n"


def direct_tree(seed: int) -> py_trees.behaviour.Behaviour:
    from hearth.skills.base import Literal
    durations = iter(_durations(seed))
    groups = []
    for g in range(GROUPS):
        halves = []
        for half in range(2):
            leaves = [Work(name=f"w{g}_{half}_{i}",
                           bindings=Bindings(inputs={"ticks": Literal(next(durations))}))
                      for i in range(4)]
            halves.append(py_trees.composites.Sequence("sequence", memory=True, children=leaves))
        groups.append(py_trees.composites.Parallel(
            f"group{g}", policy=common.ParallelPolicy.SuccessOnAll(synchronise=True),
            children=halves))
    par = py_trees.composites.Parallel(
        "parallel", policy=common.ParallelPolicy.SuccessOnAll(synchronise=True), children=groups)
    return py_trees.decorators.Repeat("repeat", par, num_success=-1)


def _time_ticks(tick, n: int) -> list[float]:
    times = []
    perf = time.perf_counter
    for _ in range(n):
        t0 = perf()
        tick()
        times.append(perf() - t0)
    return times


def add_arguments(parser) -> None:  # pragma: no cover - argparse wiring
    pass


def run(args) -> dict:
    from hearth.executive.executive import Executive
    from hearth.executive.missionfile import load_mission
    from hearth.robot.clock import SimClock

    seed = getattr(args, "seed", 0)
    ticks = 300 if getattr(args, "quick", False) else 3000
    warmup = 50
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.yaml"
        path.write_text(mission_yaml(seed))
        mission = load_mission(path, {"BenchWork": Work})
        nodes = sum(1 for _ in mission.nodes())

        bare_root = direct_tree(seed)
        for node in bare_root.iterate():
            node.setup()

        def bare_tick() -> None:
            for _ in bare_root.tick():
                pass

        bt = py_trees.trees.BehaviourTree(direct_tree(seed))
        bt.setup()

        ex = Executive(clock=SimClock(), tick_hz=10, runs_dir=Path(tmp) / "runs",
                       skills={"BenchWork": Work}, background=False)
        handle = ex.submit(mission)
        ex_sub = Executive(clock=SimClock(), tick_hz=10, runs_dir=Path(tmp) / "runs_sub",
                           skills={"BenchWork": Work}, background=False)
        ex_sub.subscribe(lambda event: None)
        handle_sub = ex_sub.submit(mission)

        gc.collect()
        _time_ticks(bare_tick, warmup)
        _time_ticks(bt.tick, warmup)
        _time_ticks(ex.tick, warmup)
        _time_ticks(ex_sub.tick, warmup)
        # Interleave blocks so all see the same machine load.
        d_times, t_times, h_times, s_times = [], [], [], []
        block = 10
        for _ in range(ticks // block):
            d_times += _time_ticks(bare_tick, block)
            t_times += _time_ticks(bt.tick, block)
            h_times += _time_ticks(ex.tick, block)
            s_times += _time_ticks(ex_sub.tick, block)
        for h, e in ((handle, ex), (handle_sub, ex_sub)):
            h.cancel("benchmark done")
            e.run_until_idle(100)
            e.shutdown()
        log_lines = sum(1 for _ in open(handle.log_path))
        # The same tree, exported and ticked by BehaviorTree.CPP (hearth/benchmarks/_btcpp.py).
        btcpp_times = _btcpp.tick_times(str(path), {"BenchWork": Work}, len(h_times), warmup)

    d_med, h_med = statistics.median(d_times), statistics.median(h_times)
    d_mean, h_mean = statistics.fmean(d_times), statistics.fmean(h_times)
    t_med, t_mean = statistics.median(t_times), statistics.fmean(t_times)
    return {
        "nodes": nodes,
        "ticks": len(h_times),
        "tick_ms": round(h_med * 1e3, 4),
        "tick_ms_mean": round(h_mean * 1e3, 4),
        "tick_ms_subscribed": round(statistics.median(s_times) * 1e3, 4),
        "py_trees_tick_ms": round(d_med * 1e3, 4),
        "py_trees_tick_ms_mean": round(d_mean * 1e3, 4),
        "py_trees_tree_tick_ms": round(t_med * 1e3, 4),
        "py_trees_tree_tick_ms_mean": round(t_mean * 1e3, 4),
        "tick_overhead_ratio": round(h_med / t_med, 3),
        "tick_overhead_ratio_mean": round(h_mean / t_mean, 3),
        "tick_overhead_ratio_bare": round(h_med / d_med, 3),
        "tick_overhead_ratio_bare_mean": round(h_mean / d_mean, 3),
        "events_per_tick": round(log_lines / (len(h_times) + warmup), 2),
        "log_lines": log_lines,
        **_btcpp.figures(btcpp_times, h_med),
        "targets": {"tick_overhead_ratio": 1.3, "tick_ms": 1.0},
        "seed": seed,
    }
