"""A top-down picture of the home: rooms (their floor polygons) and the doorways between
them, large objects, parking positions, small objects,
and overlays (the robot's path, the parking positions visited, where objects were found).

Drawn with OpenCV on a numpy image; ``save_png`` writes it.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional, Sequence

import cv2
import numpy as np

from hearth.worldmodel.frames import T_world_room, room_corners, transform_xy
from hearth.worldmodel.outline import doorway_rect
from hearth.worldmodel.geometry import object_meshes
from hearth.worldmodel.nodes import LargeArticulatedObject


@dataclass
class Overlay:
    path: Sequence[tuple[float, float]] = ()                 # robot base positions, world x/y
    visited: Sequence[tuple[float, float, float]] = ()       # parking poses visited x, y, yaw
    found: dict[str, tuple[float, float]] = field(default_factory=dict)  # label -> x, y
    title: str = ""


def draw(world, overlay: Optional[Overlay] = None, px_per_m: int = 90, margin_m: float = 0.4) -> np.ndarray:
    """An RGB image of the map seen from above (world x right, y up). Rooms are drawn where
    their poses put them (turned and offset rooms included); labels that would overlap an
    earlier one are moved down until they do not; a legend explains the marks."""
    rooms = [r for r in world.rooms if r.bounds is not None]
    corners = [room_corners(r) for r in rooms]
    pts = np.vstack(corners) if corners else np.array([[0.0, 0.0], [1.0, 1.0]])
    x0, y0 = pts.min(0) - margin_m
    x1, y1 = pts.max(0) + margin_m
    title_px, legend_px = 30, 26
    W, H = int((x1 - x0) * px_per_m), int((y1 - y0) * px_per_m) + title_px + legend_px
    W = max(W, 520)
    img = np.full((H, W, 3), 255, np.uint8)
    labels = _Labels(img)

    def px(x, y):
        return int(round((x - x0) * px_per_m)), int(round((y1 - y) * px_per_m)) + title_px

    for r, cs in zip(rooms, corners):
        poly = np.array([px(*c) for c in cs], np.int32)
        cv2.fillPoly(img, [poly], FLOOR)
        cv2.polylines(img, [poly], True, (60, 60, 60), 3, cv2.LINE_AA)
    # Doorways: the passage in floor colour across the walls, its jambs drawn.
    for r in rooms:
        T = T_world_room(r)
        for d in r.doorways:
            rect = transform_xy(T, doorway_rect(d))
            q = np.array([px(*c) for c in rect], np.int32)
            cv2.fillPoly(img, [q], FLOOR)
            for a, b in ((0, 1), (2, 3)):          # the sides along the passage
                cv2.line(img, tuple(int(v) for v in q[a]), tuple(int(v) for v in q[b]),
                         DOORWAY, 2, cv2.LINE_AA)
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
        for _p, pose in world.parking_positions(obj.id):
            _arrow(img, px, pose.x, pose.y, pose.yaw, PARKING, 0.18)
    for node in world.small_objects():
        p = world.T_world(node.id)[:2, 3]
        cv2.circle(img, px(*p), 4, (90, 90, 90), -1, cv2.LINE_AA)
    if overlay is not None:
        if len(overlay.path) > 1:
            cv2.polylines(img, [np.array([px(x, y) for x, y in overlay.path], np.int32)], False,
                          PATH, 2, cv2.LINE_AA)
        for x, y, yaw in overlay.visited:
            _arrow(img, px, x, y, yaw, VISITED, 0.3, 2)
    # Labels last, so none is painted over; rooms first, so they keep their places.
    for r, cs in zip(rooms, corners):
        # Near the room's (xmin, ymin) corner, inside the room whatever its turn.
        inner = room_corners_inset(r, 0.25)
        labels.put(r.name, px(*inner), 0.6, (80, 80, 80))
    for obj in world.large_objects():
        c = world.T_world(obj.id)[:2, 3]
        q = px(*c)
        labels.put(obj.name or obj.id, (q[0] - 25, q[1]), 0.35, (20, 20, 20))
    if overlay is not None:
        for label, (x, y) in overlay.found.items():
            cv2.circle(img, px(x, y), 9, FOUND, 2, cv2.LINE_AA)
            labels.put(label, (px(x, y)[0] + 10, px(x, y)[1] - 8), 0.45, (20, 130, 30))
        if overlay.title:
            cv2.putText(img, overlay.title, (10, 21), cv2.FONT_HERSHEY_SIMPLEX, 0.55, (0, 0, 0),
                        1, cv2.LINE_AA)
    _legend(img, H - legend_px + 6,
            overlay is not None and bool(overlay.path or overlay.visited or overlay.found))
    return img


PARKING = (170, 170, 170)
FLOOR = (235, 232, 225)
DOORWAY = (150, 90, 40)
VISITED = (230, 120, 20)
PATH = (30, 110, 230)
FOUND = (20, 170, 40)


def room_corners_inset(room, inset: float) -> tuple[float, float]:
    """Where a room's name goes: its corner furthest to the left in the picture (the text
    runs to the right), moved ``inset`` metres towards the room's centre along each side."""
    cs = room_corners(room)
    i = int(np.argmin(cs[:, 0] - 1e-3 * cs[:, 1]))
    c = cs[i]
    a, b = cs[(i + 1) % len(cs)] - c, cs[(i - 1) % len(cs)] - c
    p = c + inset * a / np.linalg.norm(a) + inset * b / np.linalg.norm(b)
    # Text sits above its origin: start from the lower of the two ways into the room.
    return float(p[0]), float(p[1])


class _Labels:
    """Text placed so that no label overlaps an earlier one (moved down in steps)."""

    def __init__(self, img: np.ndarray):
        self.img = img
        self.boxes: list[tuple[int, int, int, int]] = []

    def put(self, text: str, org: tuple[int, int], scale: float, color) -> None:
        (w, h), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, 1)
        x, y = int(org[0]), int(org[1])
        x = min(max(x, 2), max(self.img.shape[1] - w - 2, 2))
        for _ in range(12):
            box = (x, y - h - 1, x + w, y + base)
            if not any(_overlap(box, b) for b in self.boxes):
                break
            y += h + base + 2
        self.boxes.append((x, y - h - 1, x + w, y + base))
        cv2.putText(self.img, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, scale, color, 1, cv2.LINE_AA)


def _overlap(a, b) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def _legend(img: np.ndarray, y: int, with_overlay: bool) -> None:
    x = 10
    items = [("parking position", PARKING, "arrow"), ("doorway", DOORWAY, "jambs")]
    if with_overlay:
        items += [("pose driven to", VISITED, "arrow"), ("robot path", PATH, "line"),
                  ("object found", FOUND, "circle")]
    for text, color, mark in items:
        if mark == "arrow":
            cv2.arrowedLine(img, (x, y + 6), (x + 22, y + 6), color, 2, cv2.LINE_AA, tipLength=0.4)
        elif mark == "jambs":
            cv2.line(img, (x + 4, y), (x + 4, y + 12), color, 2, cv2.LINE_AA)
            cv2.line(img, (x + 18, y), (x + 18, y + 12), color, 2, cv2.LINE_AA)
        elif mark == "line":
            cv2.line(img, (x, y + 6), (x + 22, y + 6), color, 2, cv2.LINE_AA)
        else:
            cv2.circle(img, (x + 11, y + 6), 7, color, 2, cv2.LINE_AA)
        cv2.putText(img, text, (x + 28, y + 11), cv2.FONT_HERSHEY_SIMPLEX, 0.42, (40, 40, 40), 1,
                    cv2.LINE_AA)
        x += 40 + cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, 0.42, 1)[0][0]


def _arrow(img, px, x, y, yaw, color, length, thickness=1):
    tip = (x + length * np.cos(yaw), y + length * np.sin(yaw))
    cv2.arrowedLine(img, px(x, y), px(*tip), color, thickness, cv2.LINE_AA, tipLength=0.35)


def save_png(path, image_rgb: np.ndarray) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(path), cv2.cvtColor(image_rgb, cv2.COLOR_RGB2BGR)):
        raise OSError(f"could not write {path}")
    return path
