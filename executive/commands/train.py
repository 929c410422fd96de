"""`hearth train knobs|segmentation|all`: train (or check) the perception models ahead of first use.

Prints progress lines on stderr and one summary line on stdout. ``--check`` only says whether
the stored model is current (exit 1 when it is missing or stale); ``--force`` retrains a
current one. Models go to ``--model-dir`` (default ``$HEARTH_MODEL_DIR`` or
``~/.cache/hearth``).
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from executive.cliutil import DEFAULT_WORLD

MODELS = ("knobs", "segmentation", "all")


def register(sub) -> None:
    p = sub.add_parser("train", help="train perception models (knobs, segmentation)",
                       description="Train a perception model for a world and store it.")
    p.add_argument("model", choices=MODELS, help="which model")
    p.add_argument("--world", default=str(DEFAULT_WORLD),
                   help="world file (default: data/demo_home/world.xml)")
    p.add_argument("--model-dir", default=None, help="where models are stored")
    p.add_argument("--force", action="store_true", help="retrain even if the stored model is current")
    p.add_argument("--check", action="store_true", help="only report whether it is current")
    p.add_argument("--tiny", action="store_true", help="a small, quick model (smoke tests)")
    p.set_defaults(func=_run)


def _progress():
    last = {"stage": None, "t": 0.0}
    t0 = time.perf_counter()

    def say(stage: str, done: int, total: int) -> None:
        now = time.perf_counter()
        if stage != last["stage"] or now - last["t"] > 2.0 or done == total:
            print(f"[{now - t0:6.1f} s] {stage}: {done}/{total}", file=sys.stderr, flush=True)
            last["stage"], last["t"] = stage, now
    return say


def _run(args: argparse.Namespace) -> int:
    status = 0
    if args.model in ("knobs", "all"):
        status = max(status, _knobs(args))
    if args.model in ("segmentation", "all"):
        status = max(status, _segmentation(args))
    return status


def _segmentation(args: argparse.Namespace) -> int:
    from skills import segmentation_model as sm

    path = (Path(args.model_dir) if args.model_dir else sm.model_dir()) / sm.MODEL_FILE
    cfg = sm.TrainingConfig()
    if args.check:
        ok = sm.load(path, cfg, sm.SegmentationConfig()) is not None
        print(f"segmentation model: {'current' if ok else 'missing or stale'} ({path})")
        return 0 if ok else 1
    if args.force and path.exists():
        path.unlink()
    if sm.load(path, cfg, sm.SegmentationConfig()) is not None:
        print(f"segmentation model current ({path})")
        return 0
    print("training the segmentation forest on rendered rooms (a few minutes, once)...",
          file=sys.stderr, flush=True)
    sm.load_or_train(cfg, path=path, log=lambda m: print(m, file=sys.stderr, flush=True))
    print(f"segmentation model trained -> {path}")
    return 0


def _knobs(args: argparse.Namespace) -> int:
    from skills import models_store
    from skills.knob_models import MODEL_NAME, TrainingConfig, configuration, load_or_train
    from perception.knobs import KnobConfig
    from worldmodel.io import load_world

    world = load_world(args.world)
    if not world.knobs():
        print(f"{args.world}: the map has no knobs", file=sys.stderr)
        return 2
    directory = Path(args.model_dir) if args.model_dir else None
    cfg = TrainingConfig().tiny() if args.tiny else TrainingConfig()
    if args.check:
        loaded = models_store.load(MODEL_NAME, configuration(world, cfg, KnobConfig()), directory)
        print(f"knob models: {'current' if loaded.ok else loaded.reason} ({loaded.path})")
        return 0 if loaded.ok else 1
    _, info = load_or_train(world, cfg, directory=directory, force=args.force, progress=_progress())
    if info.source == "trained":
        why = f" ({info.reason})" if info.reason else ""
        print(f"knob models trained in {info.seconds:.0f} s{why} -> {info.path}")
    else:
        print(f"knob models current ({info.path})")
    return 0
