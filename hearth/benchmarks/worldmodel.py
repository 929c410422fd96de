"""World model: load time of a map with 10,000 small objects, and find-by-words speed.

Targets: ``load_10k_s`` under 2 s, ``find_by_words_ms`` under 1 ms (medians).
"""
from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

import numpy as np

from hearth.worldmodel.demo_home import build, small, box
from hearth.worldmodel.io import load_world, to_xml

COLORS = ["red", "blue", "green", "yellow", "white", "black", "orange", "purple"]
TYPES = ["cup", "plate", "bowl", "box", "bottle", "jar", "spoon", "book"]


def big_apartment(n_small: int, seed: int = 0):
    """The demo home with ``n_small`` extra small objects spread over its tables."""
    rng = np.random.default_rng(seed)
    apt = build()
    tables = [o for r in apt.rooms for o in r.objects if o.type == "table"]
    for i in range(n_small):
        t = tables[i % len(tables)]
        color = COLORS[rng.integers(len(COLORS))]
        typ = TYPES[rng.integers(len(TYPES))]
        x, y = rng.uniform(-0.3, 0.3, 2)
        obj = small(f"obj_{i}", typ, color, [box(0.05, 0.05, 0.1, 0, 0, 0.05, color=(0.5, 0.5, 0.5))],
                    float(x), float(y), 0.75, t.id, description=f"{color} {typ} number {i}")
        t.children.append(obj)
    return apt


def run(args) -> dict:
    n = 10_000
    reps = 1 if getattr(args, "quick", False) else 3
    apt = big_apartment(n, getattr(args, "seed", 0))
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "world.xml"
        path.write_bytes(to_xml(apt))
        size_mb = round(path.stat().st_size / 1e6, 2)
        loads = []
        for _ in range(reps):
            t0 = time.perf_counter()
            world = load_world(path)
            loads.append(time.perf_counter() - t0)
    tables = [o.name for o in world.large_objects() if o.type == "table" and o.name]
    queries = ["blue cup", "red bottle", (tables or ["table"])[0], "pill box",
               "green jar number 77", "purple spoon", "oven", "white bowl"]
    times = []
    for _ in range(50):
        for q in queries:
            t0 = time.perf_counter()
            world.find(q)
            times.append((time.perf_counter() - t0) * 1000)
    return {
        "small_objects": n,
        "file_mb": size_mb,
        "load_10k_s": round(statistics.median(loads), 3),
        "find_by_words_ms": round(statistics.median(times), 4),
        "find_by_words_ms_p95": round(float(np.percentile(times, 95)), 4),
        "targets": {"load_10k_s": 2.0, "find_by_words_ms": 1.0},
    }
