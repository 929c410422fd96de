"""The semantic-segmentation forest: training data from rendered random rooms, training, and
storage on disk (perception/ stays pure, so files live here).

The model is **trained on first use** and cached: nothing binary is shipped in the
repository. ``load_or_train()`` looks for ``segmentation_forest.joblib`` in
``$HEARTH_MODEL_DIR`` (default ``~/.cache/hearth``); the file holds the fitted classifier
and the training configuration it came from, and a file whose configuration differs from
the current one (``TrainingConfig`` plus ``SegmentationConfig``) is stale and is retrained.
Training renders ``TrainingConfig.frames`` noisy 640x480 views of random rooms (random
tables, chairs, cabinets and small objects, see ``random_world``); about a minute on two
cores.

Ground truth comes from the map: every rendered pixel knows its node, and the node's kind
and type give its class (``class_of_node``).
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from perception.camera import Intrinsics, look_at
from perception.segmentation import (
    LABELS, PatchClassifier, SegmentationConfig, extract_patches,
)
from worldmodel.nodes import Apartment, LargeArticulatedObject, LargeObject, Model, Room
from worldmodel.pose import Pose

MODEL_FILE = "segmentation_forest.joblib"

#: Map node types -> segmentation class (anything else large is "unknown").
TYPE_CLASS = {"table": "table", "desk": "table", "counter": "table", "chair": "chair",
              "stool": "chair", "sofa": "chair", "cupboard": "cabinet", "drawers": "cabinet",
              "fridge": "cabinet", "oven": "cabinet", "cabinet": "cabinet", "shelf": "cabinet",
              "wardrobe": "cabinet", "dishwasher": "cabinet"}


@dataclass(frozen=True)
class TrainingConfig:
    frames: int = 200
    seed: int = 1234
    n_estimators: int = 40
    max_depth: int = 18
    min_samples_leaf: int = 2
    width: int = 640
    height: int = 480
    look_up: float = 0.2      # share of training views aimed higher (more ceiling)


# -- ground truth ----------------------------------------------------------------------------

def class_of_node(world, rendering_index: int, rendering) -> str:
    """The segmentation class of one rendered mesh (index into ``rendering.nodes``)."""
    node_id = rendering.nodes[rendering_index]
    name = rendering.names[rendering_index]
    if name in ("floor", "wall", "ceiling"):
        return name
    owner = rendering.owners[rendering_index]
    try:
        node = world.get(owner)
    except Exception:
        return "unknown"
    if node.kind == "SmallObject":
        return "object"
    if node.kind in ("LargeObject", "LargeArticulatedObject"):
        return TYPE_CLASS.get(node.type, "unknown")
    return "unknown"   # switches and other room fixtures


def ground_truth(world, rendering) -> np.ndarray:
    """(H, W) class indices into ``LABELS`` per pixel; -1 where nothing was rendered."""
    lut = np.array([LABELS.index(class_of_node(world, i, rendering))
                    for i in range(len(rendering.nodes))] + [-1], dtype=np.int16)
    return lut[rendering.labels]   # labels == -1 picks the trailing -1


# -- noisy rendering -------------------------------------------------------------------------

def noisy(rendering, rng: np.random.Generator):
    """Kinect-class noise on a rendering, in place: the simulated robot's model
    (robot.noise.add_kinect_noise) when it exists, else axial depth noise
    sigma = 1.2 mm + 1.9 mm (z - 0.4 m)^2 (Nguyen et al. 2012) and colour noise."""
    try:
        from hearth.robot.noise import add_kinect_noise  # type: ignore
        return add_kinect_noise(rendering, rng)
    except ImportError:
        pass
    d = rendering.depth.astype(np.float64)
    ok = d > 0
    d[ok] += rng.standard_normal(int(ok.sum())) * (0.0012 + 0.0019 * (d[ok] - 0.4) ** 2)
    rendering.depth = d.astype(np.float32)
    c = rendering.color.astype(np.int16) + rng.normal(0, 3.0, rendering.color.shape).astype(np.int16)
    rendering.color = np.clip(c, 0, 255).astype(np.uint8)
    return rendering


# -- random rooms ----------------------------------------------------------------------------

def _color(rng, base=None, spread=0.12):
    if base is None:
        return tuple(float(v) for v in rng.uniform(0.1, 0.95, 3))
    return tuple(float(np.clip(b + rng.uniform(-spread, spread), 0, 1)) for b in base)


def _free(rng, bounds, placed, r, margin=0.15):
    x0, y0, x1, y1 = bounds
    for _ in range(40):
        x, y = rng.uniform(x0 + r + margin, x1 - r - margin), rng.uniform(y0 + r + margin, y1 - r - margin)
        if all(math.hypot(x - px, y - py) > r + pr + 0.1 for px, py, pr in placed):
            placed.append((x, y, r))
            return x, y
    return None


def random_world(rng: np.random.Generator):
    """A World with one room of random size holding 1-3 tables (with small objects), 0-4
    chairs and 1-3 cabinets (cupboards, drawer units, fridges) at random poses and colours."""
    from worldmodel.demo_home import WOOD, box, carcass, cyl, small, table
    from worldmodel.world import World

    w, d = rng.uniform(3.5, 6.5), rng.uniform(3.5, 6.0)
    bounds = (0.0, 0.0, float(w), float(d))
    placed: list = []
    objects = []
    for i in range(int(rng.integers(1, 4))):
        sx, sy = rng.uniform(0.6, 1.6), rng.uniform(0.5, 0.9)
        h = rng.uniform(0.6, 0.95)    # dining, kitchen and side tables (see docs)
        at = _free(rng, bounds, placed, math.hypot(sx, sy) / 2)
        if at is None:
            continue
        kids = []
        for j in range(int(rng.integers(1, 7))):
            ox, oy = rng.uniform(-sx / 2 + 0.08, sx / 2 - 0.08), rng.uniform(-sy / 2 + 0.08, sy / 2 - 0.08)
            col = _color(rng)
            if rng.random() < 0.5:
                r, hh = rng.uniform(0.03, 0.07), rng.uniform(0.05, 0.2)
                vis = [cyl(r, hh, 0, 0, hh / 2, color=col)]
            else:
                a, b, hh = rng.uniform(0.04, 0.15), rng.uniform(0.04, 0.15), rng.uniform(0.03, 0.2)
                vis = [box(a, b, hh, 0, 0, hh / 2, color=col, yaw=float(rng.uniform(0, np.pi)))]
            kids.append(small(f"obj_{i}_{j}", "thing", "", vis, ox, oy, h, f"table_{i}"))
        t = table(f"table_{i}", "table", float(at[0]), float(at[1]), sx, sy, h,
                  yaw=float(rng.uniform(-np.pi, np.pi)), color=_color(rng, WOOD, 0.25),
                  children=kids)
        objects.append(t)
    for i in range(int(rng.integers(0, 5))):
        at = _free(rng, bounds, placed, 0.32)
        if at is None:
            continue
        s, hs = rng.uniform(0.36, 0.48), rng.uniform(0.4, 0.5)
        col = _color(rng, WOOD, 0.3) if rng.random() < 0.7 else _color(rng)
        vis = [box(s, s, 0.03, 0, 0, hs, color=col),
               box(0.03, s, rng.uniform(0.3, 0.5), -s / 2 + 0.015, 0, hs + 0.22, color=col),
               *[box(0.03, 0.03, hs - 0.01, sx * (s / 2 - 0.03), sy * (s / 2 - 0.03), (hs - 0.01) / 2,
                     color=col) for sx in (-1, 1) for sy in (-1, 1)]]
        objects.append(LargeObject(id=f"chair_{i}", type="chair", pose=Pose(float(at[0]), float(at[1]), 0, 0, 0, float(rng.uniform(-np.pi, np.pi))),
                                   model=Model(vis)))
    for i in range(int(rng.integers(1, 4))):
        D, W = rng.uniform(0.35, 0.65), rng.uniform(0.5, 1.2)
        H = rng.choice([rng.uniform(0.7, 1.0), rng.uniform(1.4, 2.0)])
        # against a wall, facing into the room
        side = int(rng.integers(4))
        x0, y0, x1, y1 = bounds
        along = rng.uniform(0.2, 0.8)
        pose = [Pose(x0 + D / 2 + 0.01, y0 + along * (y1 - y0), 0, 0, 0, 0.0),
                Pose(x1 - D / 2 - 0.01, y0 + along * (y1 - y0), 0, 0, 0, np.pi),
                Pose(x0 + along * (x1 - x0), y0 + D / 2 + 0.01, 0, 0, 0, np.pi / 2),
                Pose(x0 + along * (x1 - x0), y1 - D / 2 - 0.01, 0, 0, 0, -np.pi / 2)][side]
        if any(math.hypot(pose.x - px, pose.y - py) < max(D, W) / 2 + pr for px, py, pr in placed):
            continue
        placed.append((pose.x, pose.y, max(D, W) / 2))
        col = _color(rng) if rng.random() < 0.5 else _color(rng, (0.9, 0.9, 0.88), 0.1)
        vis = carcass(D, W, H, color=col, shelves=(H / 2,))
        ndoor = int(rng.integers(1, 3))
        for k in range(ndoor):
            dw = W / ndoor
            vis.append(box(0.02, dw - 0.006, H - 0.1, D / 2 + 0.012, -W / 2 + dw * (k + 0.5), H / 2 + 0.03,
                           color=col, name="face"))
            handle_y = -W / 2 + dw * (k + 0.5) + 0.3 * dw * (1 if k else -1)
            vis.append(box(0.03, 0.015, 0.14, D / 2 + 0.04, handle_y, H * 0.6, color=(0.7, 0.7, 0.72)))
        typ = str(rng.choice(["cupboard", "drawers", "fridge", "cabinet"]))
        objects.append(LargeArticulatedObject(id=f"cab_{i}", type=typ, pose=pose, model=Model(vis)))
    room = Room("room", "room", bounds=bounds, objects=objects)
    return World(Apartment(id="random", rooms=[room]))


def random_view(world, rng: np.random.Generator, look_up: float = 0.0) -> np.ndarray:
    """``T_world_camera`` of a robot head camera (1.1-1.5 m up) standing in the room, looking
    at a random large object (or a random point) from 1.2-3.5 m; with probability ``look_up``
    at a point 1.2-2.2 m high instead (training sees more of the rarely seen ceiling)."""
    room = world.rooms[0]
    x0, y0, x1, y1 = room.bounds
    objs = world.large_objects()
    for _ in range(30):
        if objs and rng.random() < 0.85:
            o = objs[int(rng.integers(len(objs)))]
            tx, ty = o.pose.x, o.pose.y
            tz = rng.uniform(0.2, 0.9)
        else:
            tx, ty, tz = rng.uniform(x0, x1), rng.uniform(y0, y1), rng.uniform(0.0, 1.2)
        if look_up > 0 and rng.random() < look_up:
            tz = rng.uniform(1.2, 2.2)
        r, a = rng.uniform(1.2, 3.5), rng.uniform(-np.pi, np.pi)
        ex, ey = tx + r * math.cos(a), ty + r * math.sin(a)
        if x0 + 0.3 < ex < x1 - 0.3 and y0 + 0.3 < ey < y1 - 0.3:
            if all(math.hypot(ex - o.pose.x, ey - o.pose.y) > 0.6 for o in objs):
                return look_at((ex, ey, rng.uniform(1.1, 1.5)), (tx, ty, tz))
    return look_at(((x0 + x1) / 2, (y0 + y1) / 2, 1.3), (x1, (y0 + y1) / 2, 0.5))


def render_random(seed: int, K: Intrinsics | None = None, look_up: float = 0.0):
    """(world, rendering with noise, ground truth (H, W), T_world_camera) of one random view
    (``look_up``: see ``random_view``)."""
    from perception.render import Scene
    from worldmodel.geometry import scene_meshes
    rng = np.random.default_rng(seed)
    K = K or Intrinsics.kinect()
    world = random_world(rng)
    T = random_view(world, rng, look_up)
    r = Scene(scene_meshes(world)).render(K, T)
    gt = ground_truth(world, r)
    return world, noisy(r, rng), gt, T


# -- training and storage --------------------------------------------------------------------

def training_set(cfg: TrainingConfig, seg: SegmentationConfig):
    """Patch features (N, 14), classes (N,) and sample weights (N,) from ``cfg.frames``
    random views. Accuracy is counted per pixel, so a patch weighs sqrt(its pixels): big
    patches count more without drowning the small classes (objects)."""
    K = Intrinsics.kinect(cfg.width, cfg.height)
    X, y, w = [], [], []
    for f in range(cfg.frames):
        _, r, gt, T = render_random(cfg.seed * 1000 + f, K, cfg.look_up)
        patches = extract_patches(r.depth, r.color, K, T, seg)
        X.append(patches.features)
        y.append(patches.majority(gt))
        w.append(np.sqrt(patches.sizes))
    X, y, w = np.concatenate(X), np.concatenate(y), np.concatenate(w)
    keep = y >= 0
    return X[keep], y[keep], w[keep]


def train(cfg: TrainingConfig | None = None, seg: SegmentationConfig | None = None) -> PatchClassifier:
    cfg, seg = cfg or TrainingConfig(), seg or SegmentationConfig()
    X, y, w = training_set(cfg, seg)
    clf = PatchClassifier(n_estimators=cfg.n_estimators, max_depth=cfg.max_depth,
                          min_samples_leaf=cfg.min_samples_leaf, random_state=cfg.seed)
    return clf.fit(X, y, sample_weight=w)


def _fingerprint(cfg: TrainingConfig, seg: SegmentationConfig) -> str:
    text = json.dumps({"training": asdict(cfg), "segmentation": asdict(seg), "labels": LABELS,
                       "version": 1}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def model_dir() -> Path:
    return Path(os.environ.get("HEARTH_MODEL_DIR", Path.home() / ".cache" / "hearth"))


def save(clf: PatchClassifier, path: Path, cfg: TrainingConfig, seg: SegmentationConfig) -> None:
    import joblib
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    joblib.dump({"fingerprint": _fingerprint(cfg, seg), "training": asdict(cfg),
                 "segmentation": asdict(seg), "model": clf}, tmp)
    os.replace(tmp, path)


def load(path: Path, cfg: TrainingConfig, seg: SegmentationConfig) -> PatchClassifier | None:
    """The stored classifier, or None when there is none or it was trained differently."""
    import joblib
    if not path.exists():
        return None
    try:
        blob = joblib.load(path)
    except Exception:
        return None
    if not isinstance(blob, dict) or blob.get("fingerprint") != _fingerprint(cfg, seg):
        return None
    return blob["model"]


_CACHE: dict = {}


def load_or_train(cfg: TrainingConfig | None = None, seg: SegmentationConfig | None = None,
                  path: Path | None = None, log=None) -> PatchClassifier:
    """The segmentation forest: from memory, from disk, or trained now (and stored)."""
    cfg, seg = cfg or TrainingConfig(), seg or SegmentationConfig()
    path = Path(path) if path is not None else model_dir() / MODEL_FILE
    key = (str(path), _fingerprint(cfg, seg))
    if key in _CACHE:
        return _CACHE[key]
    clf = load(path, cfg, seg)
    if clf is None:
        t0 = time.perf_counter()
        clf = train(cfg, seg)
        if log:
            log(f"trained segmentation forest in {time.perf_counter() - t0:.0f} s -> {path}")
        try:
            save(clf, path, cfg, seg)
        except OSError:
            pass   # read-only home: keep the model in memory only
    _CACHE[key] = clf
    return clf
