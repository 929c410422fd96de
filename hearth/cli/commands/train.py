"""`hearth train knobs|segmentation|all --world W`: train (or check) a home's perception models
ahead of first use.

The knob models are trained for the home in ``--world`` (from renderings of its own knobs) and
stored under a key of that home, beside the models of other homes; the segmentation forest is
trained on random rooms and shared by every home. A home without knobs needs no knob models
(``all`` says so and goes on). Prints progress lines on stderr and one summary line per model
on stdout. ``--check`` only says whether the stored models are current (exit 1 when one is
missing or stale); ``--force`` retrains current ones. Models go to ``--model-dir`` (default
``$HEARTH_MODEL_DIR`` or ``~/.cache/hearth``).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from hearth.cli.util import DEFAULT_WORLD

MODELS = ("knobs", "segmentation", "all")


def register(sub) -> None:
    p = sub.add_parser("train", help="train a home's perception models (knobs, segmentation)",
                       description="Train the perception models for a home and store them "
                                   "(per home: training another home keeps this one's).")
    p.add_argument("model", choices=MODELS, help="which model")
    p.add_argument("--world", default=str(DEFAULT_WORLD),
                   help="world file of the home (default: data/demo_home/world.xml)")
    p.add_argument("--model-dir", default=None, help="where models are stored")
    p.add_argument("--force", action="store_true", help="retrain even if the stored model is current")
    p.add_argument("--check", action="store_true", help="only report whether it is current")
    p.add_argument("--tiny", action="store_true", help="a small, quick model (smoke tests)")
    p.set_defaults(func=_run)


def _progress(header: str):
    """Progress lines on stderr, after ``header`` (printed once training starts)."""
    last = {"stage": None, "t": 0.0}
    t0 = time.perf_counter()

    def say(stage: str, done: int, total: int) -> None:
        now = time.perf_counter()
        if last["stage"] is None:
            print(header, file=sys.stderr, flush=True)
        if stage != last["stage"] or now - last["t"] > 2.0 or done == total:
            print(f"[{now - t0:6.1f} s] {stage}: {done}/{total}", file=sys.stderr, flush=True)
            last["stage"], last["t"] = stage, now
    return say


def _run(args: argparse.Namespace) -> int:
    from hearth.worldmodel.io import load_world

    t0 = time.perf_counter()
    world = load_world(args.world)
    status = 0
    if args.model in ("knobs", "all"):
        status = max(status, _knobs(args, world))
    if args.model in ("segmentation", "all"):
        status = max(status, _segmentation(args))
    if args.model == "all" and not args.check:
        print(f"models for {world.apartment.id} ready in {time.perf_counter() - t0:.0f} s")
    return status


def _say(what: str, info) -> None:
    if info.source == "trained":
        why = f" ({info.reason})" if info.reason else ""
        print(f"{what} trained in {info.seconds:.0f} s{why} -> {info.path}")
    else:
        print(f"{what} current ({info.path})")


def _segmentation(args: argparse.Namespace) -> int:
    from hearth.skills import segmentation_model as sm

    directory = Path(args.model_dir) if args.model_dir else None
    cfg = (sm.TrainingConfig(frames=8, n_estimators=8, homes=1, views_per_home=2) if args.tiny
           else sm.TrainingConfig())
    if args.check:
        loaded = sm.check(cfg, directory=directory)
        print(f"segmentation forest: {'current' if loaded.ok else loaded.reason} ({loaded.path})")
        return 0 if loaded.ok else 1
    _, info = sm.get(cfg, directory=directory, force=args.force, progress=_progress(
        "training the segmentation forest on rendered rooms (once, for every home)..."))
    _say("segmentation forest", info)
    return 0


def _knobs(args: argparse.Namespace, world) -> int:
    from hearth.skills import knob_models as km

    home = world.apartment.id
    if not world.knobs():
        if args.model == "all":
            print(f"{home} has no knobs: no knob models needed")
            return 0
        print(f"{args.world}: the map has no knobs", file=sys.stderr)
        return 2
    directory = Path(args.model_dir) if args.model_dir else None
    cfg = km.TrainingConfig().tiny() if args.tiny else km.TrainingConfig()
    if args.check:
        loaded = km.check(world, cfg, directory=directory)
        print(f"knob models for {home}: {'current' if loaded.ok else loaded.reason} "
              f"({loaded.path})")
        return 0 if loaded.ok else 1
    header = (f"training the knob models for {home} ({len(world.knobs())} knobs) from "
              f"renderings of its knobs...")
    _, info = km.load_or_train(world, cfg, directory=directory, force=args.force,
                               progress=_progress(header))
    _say(f"knob models for {home}", info)
    return 0
