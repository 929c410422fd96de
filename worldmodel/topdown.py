"""A top-down picture of the home: rooms, large objects, parking positions, small objects,
and overlays (the robot's path, the parking positions visited, where objects were found).

Drawn with OpenCV on a numpy image; ``save_png`` writes it.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence

import cv2
import numpy as np

from worldmodel.geometry import object_meshes
from worldmodel.nodes import LargeArticulatedObject


@dataclass
class Overlay:
    path: Sequence[tuple[float, float]] = ()                 # robot base positions, world x/y
    visited: Sequence[tuple[float, float, float]] = ()       # parking poses visited x, y, yaw
    found: dict[str, tuple[float, float]] = field(default_factory=dict)  # label -> x, y
    title: str = ""


def draw(world, overlay: Optional[Overlay] = None, px_per_m: int = 90, margin_m: float = 0.4) -> np.ndarray:
    """An RGB image of the map seen from above (x right, y up)."""
    rooms = [r for r in world.rooms if r.bounds is not None]
    xs = [b for r in rooms for b in (r.bounds[0] + r.pose.x, r.bounds[2] + r.pose.x)]
    ys = [b for r in rooms for b in (r.bounds[1] + r.pose.y, r.bounds[3] + r.pose.y)]
    x0, x1 = min(xs) - margin_m, max(xs) + margin_m
    y0, y1 = min(ys) - margin_m, max(ys) + margin_m
    title_px = 30
    W, H = int((x1 - x0) * px_per_m), int((y1 - y0) * px_per_m) + title_px
    img = np.full((H, W, 3), 255, np.uint8)

    def px(x, y):
        return int(round((x - x0) * px_per_m)), int(round((y1 - y) * px_per_m)) + title_px

    for r in rooms:
        bx0, by0, bx1, by1 = r.bounds
        cv2.rectangle(img, px(bx0 + r.pose.x, by1 + r.pose.y), px(bx1 + r.pose.x, by0 + r.pose.y),
                      (235, 232, 225), -1)
        cv2.rectangle(img, px(bx0 + r.pose.x, by1 + r.pose.y), px(bx1 + r.pose.x, by0 + r.pose.y),
                      (60, 60, 60), 3)
        cv2.putText(img, r.name, px(bx0 + r.pose.x + 0.1, by0 + r.pose.y + 0.12),
                    cv2.FONT_HERSHEY_SIMPLEX, 0.6, (80, 80, 80), 1, cv2.LINE_AA)
    for obj in world.large_objects():
        pts = []
        for lm in object_meshes(world, obj, children=False):
            pts.append(np.asarray(lm.mesh.vertices)[:, :2])
        if not pts:
            continue
        hull = cv2.convexHull(np.array([px(*p) for p in np.vstack(pts)], np.int32))
        color = (150, 180, 210) if isinstance(obj, LargeArticulatedObject) else (170, 200, 160)
        cv2.fillConvexPoly(img, hull, color)
        cv2.polylines(img, [hull], True, (70, 70, 70), 1, cv2.LINE_AA)
        c = world.T_world(obj.id)[:2, 3]
        cv2.putText(img, obj.name or obj.id, (px(*c)[0] - 25, px(*c)[1]), cv2.FONT_HERSHEY_SIMPLEX,
                    0.35, (20, 20, 20), 1, cv2.LINE_AA)
        for _p, pose in world.parking_positions(obj.id):
            _arrow(img, px, pose.x, pose.y, pose.yaw, (170, 170, 170), 0.18)
    for node in world.small_objects():
        p = world.T_world(node.id)[:2, 3]
        cv2.circle(img, px(*p), 4, (90, 90, 90), -1, cv2.LINE_AA)
    if overlay is not None:
        if len(overlay.path) > 1:
            cv2.polylines(img, [np.array([px(x, y) for x, y in overlay.path], np.int32)], False,
                          (30, 110, 230), 2, cv2.LINE_AA)
        for x, y, yaw in overlay.visited:
            _arrow(img, px, x, y, yaw, (230, 120, 20), 0.3, 2)
        for label, (x, y) in overlay.found.items():
            cv2.circle(img, px(x, y), 9, (20, 170, 40), 2, cv2.LINE_AA)
            cv2.putText(img, label, (px(x, y)[0] + 10, px(x, y)[1] - 8), cv2.FONT_HERSHEY_SIMPLEX,
                        0.45, (20, 130, 30), 1, cv2.LINE_AA)
        if overlay.title:
            cv2.putText(img, overlay.title, (10, 21), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0),
                        1, cv2.LINE_AA)
    return img


def _arrow(img, px, x, y, yaw, color, length, thickness=1):
    tip = (x + length * np.cos(yaw), y + length * np.sin(yaw))
    cv2.arrowedLine(img, px(x, y), px(*tip), color, thickness, cv2.LINE_AA, tipLength=0.35)


def save_png(path, image_rgb: np.ndarray) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), cv2.cvtColor(image_rgb, cv2.COLOR_RGB2BGR)):
        raise OSError(f"could not write {path}")
    return path
