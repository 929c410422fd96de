"""Large objects of a world as the draft's scoring and its classifier's training see them
(issue 47): the closed box's centre in the world's x, y, the front's direction, the size,
and the handles (with part kind and hinge side) and knobs in world coordinates.

``truth_objects(world)`` reads a true (generated or hand-written) world; with ``drafted=True``
a draft world (hearth/worldmodel/draft.py), whose objects face their +x. ``label_of`` gives a
drafted object's training label: the true type under its centre.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np


@dataclass
class TrueObject:
    id: str
    type: str
    centre: np.ndarray          # world x, y
    yaw: Optional[float]        # the front's direction (world); None: no front
    symmetry: int               # 1, 2 (rectangular table), 0 (no yaw scored)
    size: tuple
    handles: list               # (world xyz, part kind, hinge sign or 0)
    knobs: list                 # world xyz


def _body_points(world, obj, T_wo):
    from hearth.worldmodel.geometry import object_meshes
    skip = {h.id for h in getattr(obj, "handles", [])} | {k.id for k in getattr(obj, "knobs", [])}
    for p in getattr(obj, "parts", []):
        skip |= {h.id for h in p.handles} | {k.id for k in p.knobs}
    meshes = [m for m in object_meshes(world, obj, T_world_object=T_wo, children=False)
              if m.node not in skip]
    return np.vstack([np.asarray(m.mesh.vertices) for m in meshes])


def _front_in_object(obj) -> Optional[float]:
    """The direction of the object's front in its own frame (generated homes turn some
    objects' contents inside their frame): away from a carcass's back board, towards an
    appliance's knobs, out along a drawer's axis; None for tables and chairs."""
    from hearth.worldmodel.nodes import LargeArticulatedObject
    if isinstance(obj, LargeArticulatedObject) and obj.knobs:
        m = np.mean([k.pose.position[:2] for k in obj.knobs], axis=0)
        return _snap(math.atan2(m[1], m[0]))
    backs = [v for v in obj.model.visuals if v.name == "back"]
    if backs:
        return _snap(math.atan2(-backs[0].pose.y, -backs[0].pose.x))
    return None


def _snap(a: float) -> float:
    return round(a / (math.pi / 2)) * (math.pi / 2)


def truth_objects(world, drafted: bool = False) -> list[TrueObject]:
    """Every large object of ``world`` as the scoring sees it; ``drafted``: a draft world
    (hearth/worldmodel/draft.py), whose objects face their +x."""
    from hearth.worldmodel.geometry import part_T
    from hearth.worldmodel.nodes import LargeArticulatedObject
    out = []
    for room in world.rooms:
        T_wr = room.pose.matrix()
        for o in room.objects:
            T_wo = T_wr @ o.pose.matrix()
            pts = _body_points(world, o, T_wo)
            yaw_w = math.atan2(T_wo[1, 0], T_wo[0, 0])
            front = 0.0 if drafted else _front_in_object(o)
            if o.type == "table":
                round_top = any(v.shape == "cylinder" and v.name == "top" for v in o.model.visuals)
                sym, front = (0, None) if round_top else (2, 0.0)
            elif o.type == "chair":
                sym, front = 0, None
            else:
                sym = 1
            a = yaw_w + (front or 0.0)
            c, s = math.cos(a), math.sin(a)
            uv = pts[:, :2] @ np.array([[c, -s], [s, c]])
            lo, hi = uv.min(0), uv.max(0)
            mid = (lo + hi) / 2
            centre = np.array([c * mid[0] - s * mid[1], s * mid[0] + c * mid[1]])
            handles, knobs = [], []
            if isinstance(o, LargeArticulatedObject):
                for p in o.parts:
                    T_wp = T_wo @ part_T(p, 0.0)
                    hinge = p.joint.type == "revolute" and abs(p.joint.axis[2]) > 0.9
                    for h in p.handles:
                        hp = (T_wp @ np.append(h.pose.position, 1.0))[:3]
                        sign = 0
                        if hinge:
                            hinge_w = (T_wo @ np.append(p.joint.origin.position, 1.0))[:3]
                            lateral = np.array([-s, c])     # the front's left, seen from behind
                            sign = 1 if float((hinge_w[:2] - hp[:2]) @ lateral) > 0 else -1
                        handles.append((hp, p.type, sign))
                knobs = [(T_wo @ np.append(k.pose.position, 1.0))[:3] for k in o.knobs]
            out.append(TrueObject(o.id, o.type, centre, None if front is None else a, sym,
                            tuple(hi - lo), handles, knobs))
    return out


def label_of(obj, truth: list[TrueObject], within: float = 0.25) -> str:
    """The true type under a drafted object's centre (``obj.x``, ``obj.y``; within
    ``within`` metres), else 'none' (what is not furniture: a leftover of a wall)."""
    c = np.array([obj.x, obj.y])
    best = min(truth, key=lambda t: np.linalg.norm(t.centre - c), default=None)
    if best is None or np.linalg.norm(best.centre - c) > within:
        return "none"
    return best.type
