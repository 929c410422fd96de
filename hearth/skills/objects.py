"""Small-object skills: detect and verify an object in the current view, plan where to look
from next. Each captures one RGB-D frame through the robot adapter (``robot.capture()``:
``depth`` metres, ``color`` uint8 RGB, ``intrinsics``, believed ``T_world_camera``) and calls
one function of hearth/perception/objects.py or hearth/perception/nbv.py.

Hypotheses travel on the blackboard as plain dicts: ``object`` (map id), ``pose`` (world
frame, Pose.as_dict()), ``confidence`` and the verification scores.
"""
from __future__ import annotations

import numpy as np
import py_trees

from hearth.perception.errors import PerceptionError
from hearth.skills.base import Feedback, Port, Skill
from hearth.worldmodel.frames import as_matrix
from hearth.worldmodel.pose import Pose

S = py_trees.common.Status


def capture(robot):
    """(depth, color or None, intrinsics, T_world_camera) of a fresh frame."""
    frame = robot.capture()
    K = getattr(frame, "intrinsics", None) or getattr(frame, "K")
    color = getattr(frame, "color", None)
    return (np.asarray(frame.depth, dtype=np.float64), None if color is None else
            np.asarray(color), K, np.asarray(frame.T_world_camera, dtype=float))


def resolve_object(world, words) -> str:
    """A small object's map id from its id or words ("blue cup"); KeyError when none."""
    if words in world:
        return words
    hits = world.find(str(words), kinds=("SmallObject",))
    if not hits:
        raise KeyError(f'no small object matches "{words}"')
    return hits[0].node.id


def hypothesis_dict(h) -> dict:
    return dict(object=h.object_id, pose=Pose.from_matrix(h.T_world_object).as_dict(),
                confidence=round(h.confidence, 4), inlier_fraction=round(h.inlier_fraction, 4),
                normal_agreement=round(h.normal_agreement, 4),
                color_agreement=round(h.color_agreement, 4),
                unexplained=round(h.unexplained, 4), conflict=round(h.conflict, 4),
                visible_fraction=round(h.visible_fraction, 4),
                worst_part_color=round(h.worst_part_color, 4), taller=round(h.taller, 4))


def _T(pose) -> np.ndarray:
    return as_matrix(pose)


class _PerceptionSkill(Skill):
    """One tick: ``perceive()`` returns (success, message); a PerceptionError or bad input
    fails with its message."""

    def perceive(self) -> tuple[bool, str]:  # pragma: no cover - abstract
        raise NotImplementedError

    def update(self) -> py_trees.common.Status:
        try:
            ok, self.feedback_message = self.perceive()
        except (PerceptionError, KeyError, ValueError) as err:
            self.report_error(err)
            return S.FAILURE
        return S.SUCCESS if ok else S.FAILURE


class DetectObject(_PerceptionSkill):
    """Detect and verify a small object on the supporting surface in view. Succeeds when the
    object's best hypothesis is accepted (and then, with ``update_map``, writes its pose and
    parent to the map); fails otherwise, still writing every hypothesis for
    PlanNextBestView."""

    NAME = "DetectObject"
    DESCRIPTION = "detect and verify a small object in the current view"
    INPUTS = (Port("object", "string|node_id", description="map id or words (\"blue cup\")"),
              Port("candidates", "list", required=False, default=None,
                   description="small-object ids whose models to try (default: all)"),
              Port("surface", "string|dict", required=False, default=None,
                   description="large_object/surface, or a level from PlaceSurfaces "
                               "(default: the nearest surface in view)"),
              Port("previous", "list", required=False, default=None,
                   description="hypotheses of earlier views, kept with this view's"),
              Port("update_map", "boolean", required=False, default=True))
    OUTPUTS = (Port("pose", "pose", required=False, description="world frame"),
               Port("confidence", "number", required=False),
               Port("hypotheses", "list", required=False,
                    description="this view's hypotheses and the previous ones, best first"))

    def perceive(self):
        from hearth.perception.objects import detect_objects
        oid = resolve_object(self.world, self.input("object"))
        surface = self.input("surface")
        if isinstance(surface, dict):
            surface = surface.get("surface")
        depth, color, K, T_wc = capture(self.robot)
        det = detect_objects(self.world, depth, color, K, T_wc,
                             candidates=self.input("candidates"), surface=surface)
        hyps = [hypothesis_dict(h) for h in det.hypotheses[:10]] + list(self.input("previous") or [])
        hyps.sort(key=lambda d: -float(d.get("confidence", 0.0)))
        self.set_output("hypotheses", hyps[:10])
        best = det.best(oid)
        accepted = best is not None and best in det.accepted
        self.set_output("confidence", best.confidence if best else 0.0)
        if not accepted:
            return False, Feedback(f"{oid} not recognised" + (
                f" (best confidence {best.confidence:.2f})" if best else ""),
                confidence=best.confidence if best else None)
        pose = Pose.from_matrix(best.T_world_object)
        self.set_output("pose", pose)
        if self.input("update_map") and det.surface:
            parent = det.surface.split("/")[0]
            local = Pose.from_matrix(np.linalg.inv(self.world.T_world(parent)) @ best.T_world_object)
            self.world.move_object(oid, parent, local, "on", source=self.NAME)
        return True, Feedback(f"{oid} found on {det.surface} (confidence {best.confidence:.2f})",
                              confidence=best.confidence, surface=det.surface, pose=pose)


class VerifyObject(_PerceptionSkill):
    """Check in a new view that the object is where a hypothesis (or the map) puts it."""

    NAME = "VerifyObject"
    DESCRIPTION = "verify a small object hypothesis in the current view"
    INPUTS = (Port("object", "string|node_id"),
              Port("pose", "pose", required=False, default=None,
                   description="world frame (default: the map's pose)"),
              Port("min_confidence", "number", required=False, default=0.45),
              Port("tolerance", "number", required=False, default=0.03,
                   description="metres"))
    OUTPUTS = (Port("confidence", "number", required=False),
               Port("pose", "pose", required=False))

    def perceive(self):
        from hearth.perception.objects import DetectionConfig, verify_object
        oid = resolve_object(self.world, self.input("object"))
        pose = self.input("pose")
        T = self.world.T_world(oid) if pose is None else _T(pose)
        depth, color, K, T_wc = capture(self.robot)
        h = verify_object(self.world, oid, T, depth, color, K, T_wc,
                          tolerance=float(self.input("tolerance")))
        conf = h.confidence if h else 0.0
        self.set_output("confidence", conf)
        if h is None or conf < float(self.input("min_confidence")):
            return False, Feedback(f"{oid} not verified (confidence {conf:.2f})", confidence=conf)
        if h.mostly_hidden_by_furniture(DetectionConfig().min_visible_fraction):
            return False, Feedback(f"{oid} not verified: only {h.visible_fraction:.0%} of it in "
                                   f"sight, the rest hidden by the furniture (confidence "
                                   f"{conf:.2f})", confidence=conf,
                                   visible_fraction=h.visible_fraction)
        self.set_output("pose", Pose.from_matrix(h.T_world_object))
        return True, Feedback(f"{oid} verified (confidence {conf:.2f})", confidence=conf)


class PlanNextBestView(_PerceptionSkill):
    """Plan the base pose from which the object (its hypotheses, else its map pose) is seen
    best and its hypotheses told apart; outputs the pose and the point to look at."""

    NAME = "PlanNextBestView"
    DESCRIPTION = "plan where to stand to see a small object better"
    INPUTS = (Port("object", "string|node_id"),
              Port("hypotheses", "list", required=False, default=None,
                   description="DetectObject's hypotheses (default: the place, else the map's pose)"),
              Port("place", "any", required=False, default=None,
                   description="the place being searched: without hypotheses of the object, "
                               "plan around it (not around the map's pose, which may be elsewhere)"))
    OUTPUTS = (Port("pose", "pose", required=False, description="base pose (x, y, yaw)"),
               Port("look_at", "list", required=False, description="world point [x, y, z]"),
               Port("visible_fraction", "number", required=False))

    def perceive(self):
        from hearth.perception.nbv import ObjectHypothesis, plan_next_best_view
        oid = resolve_object(self.world, self.input("object"))
        hs = [ObjectHypothesis(d["object"], _T(d["pose"]), max(float(d.get("confidence", 1)), 1e-3))
              for d in (self.input("hypotheses") or []) if d.get("confidence", 1) >= 0.05]
        if not any(h.object_id == oid for h in hs):
            hs = self._at_place(oid) + hs
        hs = hs[:4]
        depth, _, K, T_wc = capture(self.robot)
        base = None
        if hasattr(self.robot, "base_pose"):
            b = self.robot.base_pose()
            base = (b.x, b.y, b.yaw)
        views = plan_next_best_view(self.world, hs, depth, K, T_wc, current_base=base)
        best = views[0]
        x, y, yaw = best.base_pose
        self.set_output("pose", Pose.planar(x, y, yaw))
        target = np.average([h.T_world_object[:3, 3] for h in hs], axis=0,
                            weights=[h.weight for h in hs])
        self.set_output("look_at", [float(v) for v in target + (0, 0, 0.05)])
        self.set_output("visible_fraction", best.visible_fraction)
        return True, Feedback(f"view of {oid} from ({x:.2f}, {y:.2f}): "
                              f"{best.visible_fraction:.0%} of its facing surface unoccluded, "
                              f"{len(views)} candidates", pose=Pose.planar(x, y, yaw),
                              visible_fraction=best.visible_fraction, candidates=len(views))

    def _at_place(self, oid: str) -> list:
        """Hypotheses of the object standing at the place being searched, for a view of the
        whole place: where the map believes it when the place is its parent, and at the
        middle of each of the place's surface levels, lowest first (the levels a shelf or a
        cupboard's front hides from the first view; PlanNextBestView keeps four); the map's
        pose when no place is given. Not only the believed pose: the object was not seen
        there, and a view chosen for a cupboard's top may not see into it at all."""
        from hearth.perception.nbv import ObjectHypothesis, from_map
        from hearth.skills.map import place_id
        place = self.input("place")
        if place is None:
            return from_map(self.world, oid)
        pid = place_id(place)
        parent = self.world.parent(oid)
        if isinstance(place, dict) and place.get("look_at") is not None \
                and (parent is None or parent.id != pid):
            T = np.eye(4)
            T[:3, 3] = np.asarray(place["look_at"], dtype=float)[:3]
            return [ObjectHypothesis(oid, T, 1.0)]
        out = from_map(self.world, oid) if parent is not None and parent.id == pid else []
        levels = self.world.surfaces_of(pid)
        if not levels and not out:
            T = np.eye(4)
            T[:3, 3] = self.world.aim_point(pid, "top")
            return [ObjectHypothesis(oid, T, 1.0)]
        believed = out[0].T_world_object[:3, 3] if out else None
        for lv in reversed(levels):
            if believed is not None and \
                    abs(lv.T_world_surface[2, 3] - believed[2]) < 0.05 and len(levels) > 1:
                continue            # the believed pose stands for its own level
            out.append(ObjectHypothesis(oid, lv.T_world_surface, 1.0))
        return out
