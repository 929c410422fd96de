"""Training the semantic-segmentation forest (hearth/perception/segmentation.py) on rendered rooms.

Training renders ``TrainingConfig.frames`` noisy 640x480 views of random rooms (random tables,
chairs, cabinets and small objects at random poses and colours, see ``random_world``) and
``TrainingConfig.homes`` x ``views_per_home`` views of generated homes from their parking
positions (``home_views``; homes of seeds ``home_seed``.., which no benchmark uses: they
bring round and pedestal tables, low coffee tables, open shelving, sideboards, hobs and
objects on shelves that the random rooms lack), and fits ``PatchClassifier`` on the patches'
features. Ground truth comes from the map: every rendered pixel knows its node, and the
node's kind and type give its class (``class_of_node``). The rooms are not the user's home:
the forest is the same for every home, and its stored model is keyed by the configuration
only (``configuration``).

Pure: rendering from map objects, arrays out; nothing is read or written here. The sensor
noise is a parameter (``noise(rendering, rng)``, e.g. the simulated robot's); without one,
``noisy`` adds axial depth noise and colour noise of its own. So are the generated homes
(``home(seed) -> World``, e.g. hearth.worldmodel.homegen's): without one, only random rooms.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Callable, Optional

import numpy as np

from hearth.perception.camera import Intrinsics, look_at
from hearth.perception.segmentation import (
    LABELS, PatchClassifier, SegmentationConfig, extract_patches,
)
from hearth.worldmodel.nodes import Apartment, LargeArticulatedObject, LargeObject, Model, Room
from hearth.worldmodel.pose import Pose

#: Bump when the training data or the features change in a way the configuration misses.
CODE_VERSION = 4    # 4: the simulated noise draws changed order (colour levels)

#: Map node types -> segmentation class (anything else large is "unknown").
TYPE_CLASS = {"table": "table", "desk": "table", "counter": "table", "chair": "chair",
              "stool": "chair", "sofa": "chair", "cupboard": "cabinet", "drawers": "cabinet",
              "fridge": "cabinet", "oven": "cabinet", "cabinet": "cabinet", "shelf": "cabinet",
              "wardrobe": "cabinet", "dishwasher": "cabinet", "bookshelf": "cabinet",
              "sideboard": "cabinet", "cooker": "cabinet", "hob": "cabinet"}


@dataclass(frozen=True)
class TrainingConfig:
    """``frames`` random views (seeds ``seed * 1000 + i``) of ``width`` x ``height``, a share
    ``look_up`` of them aimed higher; the forest's size. Every field is part of the stored
    model's configuration."""
    frames: int = 200
    seed: int = 1234
    n_estimators: int = 40
    max_depth: int = 18
    min_samples_leaf: int = 2
    width: int = 640
    height: int = 480
    look_up: float = 0.2      # share of training views aimed higher (more ceiling)
    homes: int = 20           # generated homes (seeds home_seed ..), when a home source is given
    views_per_home: int = 6
    home_seed: int = 700000   # far from the seeds benchmarks and tests use (0 ..)


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

def noisy(rendering, rng: np.random.Generator, noise: Optional[Callable] = None):
    """Kinect-class noise on a rendering, in place: ``noise(rendering, rng)`` when given (the
    simulated robot's model), else axial depth noise sigma = 1.2 mm + 1.9 mm (z - 0.4 m)^2
    (Nguyen et al. 2012) and colour noise."""
    if noise is not None:
        return noise(rendering, rng)
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
    from hearth.worldmodel.demo_home import WOOD, box, carcass, cyl, small, table
    from hearth.worldmodel.world import World

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


def render_random(seed: int, K: Intrinsics | None = None, look_up: float = 0.0,
                  noise: Optional[Callable] = None):
    """(world, rendering with noise, ground truth (H, W), T_world_camera) of one random view
    (``look_up``: see ``random_view``; ``noise``: see ``noisy``)."""
    from hearth.perception.render import Scene
    from hearth.worldmodel.geometry import scene_meshes
    rng = np.random.default_rng(seed)
    K = K or Intrinsics.kinect()
    world = random_world(rng)
    T = random_view(world, rng, look_up)
    r = Scene(scene_meshes(world)).render(K, T)
    gt = ground_truth(world, r)
    return world, noisy(r, rng, noise), gt, T


def home_views(world, rng: np.random.Generator, n: int) -> list[np.ndarray]:
    """``T_world_camera`` of ``n`` head-camera views (1.2-1.4 m up) of a home: at the parking
    positions of its large objects (drawn at random), sometimes stepped back up to 0.8 m when
    that stays in the room on free floor (not inside a piece of furniture, whose inside
    gives a view with no depth at all: hearth/worldmodel/navigation.py), looking at the object (0.1-1.0 m high) or, one in five, at a
    random point of the room."""
    from hearth.worldmodel.frames import room_contains
    from hearth.worldmodel.navigation import nav_grid
    grid = nav_grid(world)
    objs = [o for o in world.large_objects() if o.parking]
    out = []
    for _ in range(n if objs else 0):
        o = objs[int(rng.integers(len(objs)))]
        _, pose = world.parking_positions(o.id)[int(rng.integers(len(o.parking)))]
        room = world.room_of(o.id)
        back = rng.uniform(0.0, 0.8) if rng.random() < 0.6 else 0.0
        x, y = pose.x - back * math.cos(pose.yaw), pose.y - back * math.sin(pose.yaw)
        if not room_contains(room, x, y, margin=-0.2) or (grid is not None
                                                          and not grid.is_free(x, y)):
            x, y = pose.x, pose.y
        if rng.random() < 0.2 and room.bounds is not None:
            x0, y0, x1, y1 = room.bounds
            q = room.pose.matrix() @ np.array([rng.uniform(x0, x1), rng.uniform(y0, y1), 0, 1])
            target = (q[0], q[1], rng.uniform(0.0, 1.5))
        else:
            c = world.T_world(o.id)[:3, 3]
            target = (c[0], c[1], rng.uniform(0.1, 1.0))
        eye = (x + 0.1 * math.cos(pose.yaw), y + 0.1 * math.sin(pose.yaw), rng.uniform(1.2, 1.4))
        if math.hypot(target[0] - eye[0], target[1] - eye[1]) < 0.3:
            continue
        out.append(look_at(eye, target))
    return out


# -- training --------------------------------------------------------------------

def training_set(cfg: TrainingConfig, seg: SegmentationConfig, noise: Optional[Callable] = None,
                 progress: Optional[Callable[[str, int, int], None]] = None,
                 home: Optional[Callable] = None):
    """Patch features (N, N_FEATURES), classes (N,) and sample weights (N,) from ``cfg.frames``
    random views and, with a ``home(seed) -> World`` source, ``cfg.homes`` x
    ``cfg.views_per_home`` views of generated homes. Accuracy is counted per pixel, so a
    patch weighs sqrt(its pixels): big patches count more without drowning the small classes
    (objects)."""
    from hearth.perception.render import Scene
    from hearth.worldmodel.geometry import scene_meshes
    K = Intrinsics.kinect(cfg.width, cfg.height)
    X, y, w = [], [], []

    def add(r, gt, T):
        patches = extract_patches(r.depth, r.color, K, T, seg)
        X.append(patches.features)
        y.append(patches.majority(gt))
        w.append(np.sqrt(patches.sizes))

    for f in range(cfg.frames):
        if progress and f % 20 == 0:
            progress("rendering random rooms", f, cfg.frames)
        _, r, gt, T = render_random(cfg.seed * 1000 + f, K, cfg.look_up, noise)
        add(r, gt, T)
    for h in range(cfg.homes if home is not None else 0):
        if progress and h % 5 == 0:
            progress("rendering generated homes", h, cfg.homes)
        world = home(cfg.home_seed + h)
        rng = np.random.default_rng(cfg.home_seed + h)
        scene = Scene(scene_meshes(world))
        for T in home_views(world, rng, cfg.views_per_home):
            r = scene.render(K, T)
            add(noisy(r, rng, noise), ground_truth(world, r), T)
    X, y, w = np.concatenate(X), np.concatenate(y), np.concatenate(w)
    keep = y >= 0
    return X[keep], y[keep], w[keep]


def train(cfg: TrainingConfig | None = None, seg: SegmentationConfig | None = None,
          noise: Optional[Callable] = None, jobs: int = -1,
          progress: Optional[Callable[[str, int, int], None]] = None,
          home: Optional[Callable] = None) -> PatchClassifier:
    """The forest fitted on ``training_set``; ``jobs`` threads fit it (-1: every core; the
    result does not depend on it); ``progress(stage, done, total)`` is called now and then;
    ``home``: the generated-home source (see ``training_set``)."""
    cfg, seg = cfg or TrainingConfig(), seg or SegmentationConfig()
    X, y, w = training_set(cfg, seg, noise, progress, home)
    if progress:
        progress(f"fitting the forest ({cfg.n_estimators} trees, {len(y)} patches)", 0, 1)
    clf = PatchClassifier(n_estimators=cfg.n_estimators, max_depth=cfg.max_depth,
                          min_samples_leaf=cfg.min_samples_leaf, random_state=cfg.seed,
                          n_jobs=jobs).fit(X, y, sample_weight=w)
    if progress:
        progress("done", 1, 1)
    return clf.set_params(n_jobs=1)


def configuration(cfg: TrainingConfig, seg: SegmentationConfig,
                  noise: Optional[Callable] = None, home: Optional[Callable] = None,
                  home_version: Optional[int] = None) -> dict:
    """Everything the forest depends on: the training configuration, the over-segmentation's
    trained fields (``SegmentationConfig.trained_fields``), the classes, the noise model and
    the generated-home source (with its generator's version)."""
    return {"code_version": CODE_VERSION, "training": asdict(cfg),
            "segmentation": seg.trained_fields(), "labels": list(LABELS),
            "noise": None if noise is None else f"{noise.__module__}.{noise.__qualname__}",
            "homes": None if home is None else f"{home.__module__}.{home.__qualname__}",
            "home_version": home_version}
