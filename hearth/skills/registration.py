"""Registration skills: each captures one RGB-D frame through the robot adapter, calls one
perception function and writes what it found (map updates carry the skill's name as source).

The frame comes from ``robot.capture()``: an object with ``depth`` (metres, 0 = none),
``intrinsics`` (hearth.perception.camera.Intrinsics, or ``K``) and ``T_world_camera`` (the believed
camera pose, 4x4). The base pose comes from ``robot.base_pose()`` (a Pose), and a localisation
fix goes back through ``robot.apply_correction(pose)`` with the corrected base Pose.
"""
from __future__ import annotations

import math

import numpy as np
import py_trees

from hearth.perception.errors import PerceptionError
from hearth.skills.base import Feedback, Port, Skill
from hearth.worldmodel.pose import Pose

S = py_trees.common.Status


def capture(robot):
    """(depth, intrinsics, T_world_camera) of a fresh frame from the robot adapter."""
    frame = robot.capture()
    K = getattr(frame, "intrinsics", None) or getattr(frame, "K")
    return np.asarray(frame.depth, dtype=np.float64), K, np.asarray(frame.T_world_camera, dtype=float)


class _PerceptionSkill(Skill):
    """One tick: run ``perceive()``; a PerceptionError (or bad input) fails with its message."""

    def perceive(self) -> str:  # pragma: no cover - abstract
        raise NotImplementedError

    def update(self) -> py_trees.common.Status:
        try:
            self.feedback_message = self.perceive()
        except (PerceptionError, KeyError, ValueError) as err:
            self.report_error(err)
            return S.FAILURE
        return S.SUCCESS


class RegisterLargeObject(_PerceptionSkill):
    """Register a large object's model against the view and write its registered pose to the
    map (it was moved); planar by default (furniture stays on the floor)."""

    NAME = "RegisterLargeObject"
    DESCRIPTION = "register a large object's model against the current view"
    INPUTS = (Port("object", "node_id"),
              Port("mode", "string", required=False, default="planar",
                   description="planar (x, y, yaw) or 6dof"),
              Port("update_map", "boolean", required=False, default=True))
    OUTPUTS = (Port("pose", "pose", required=False), Port("fitness", "number", required=False))

    def perceive(self) -> str:
        from hearth.perception.articulated import ArticulatedConfig, register_base
        oid = self.input("object")
        depth, K, T_wc = capture(self.robot)
        reg = register_base(self.world, oid, depth, K, T_wc,
                            ArticulatedConfig(mode=self.input("mode")), include_parts=True)
        parent = self.world.parent(oid)
        pose = Pose.from_matrix(np.linalg.inv(self.world.T_world(parent.id)) @ reg.T_world_object)
        moved = self.world.get(oid).pose.planar_distance(pose)
        if self.input("update_map"):
            self.world.set_pose(oid, pose, source=self.NAME)
        self.set_output("pose", pose)
        self.set_output("fitness", reg.base.fitness)
        return Feedback(f"{oid} registered {moved * 100:.1f} cm from the map (fitness "
                        f"{reg.base.fitness:.2f})", moved_cm=moved * 100, fitness=reg.base.fitness)


class RefineLocalisation(_PerceptionSkill):
    """Correct the robot's base pose on the landmarks in view (x, y, yaw). ``earlier``: what
    the views taken before from the same base pose said (their ``views`` output); a fix
    that one of them contradicts along a direction it pins down is not reported as a
    correction (docs/registration.md, "Never a wrong corrected"). When this view's own fix
    is not one to report (not trusted, loose or contradicted), every view taken so far is
    registered together; a joint fix that is trusted and pinned down is the correction
    (docs/registration.md, "Views registered together")."""

    NAME = "RefineLocalisation"
    AUTONOMY = 0
    DESCRIPTION = "refine the robot's localisation on landmark objects in view"
    INPUTS = (Port("landmarks", "list", required=False, default=None,
                   description="landmark ids (default: fixed large objects in view)"),
              Port("earlier", "list", required=False, default=None,
                   description="the views output of earlier fixes from this base pose"))
    OUTPUTS = (Port("correction", "dict", required=False), Port("quality", "dict", required=False),
               Port("views", "list", required=False,
                    description="earlier plus this view's estimate of the pose"))

    def perceive(self) -> str:
        from hearth.perception.localisation import (LocalisationConfig, refine_localisation,
                                                    visible_landmarks)
        earlier = list(self.input("earlier") or [])
        # written first: a view that raises leaves the earlier ones, never a stale list
        # from another place
        self.set_output("views", earlier)
        depth, K, T_wc = capture(self.robot)
        T_wb = self.robot.base_pose().matrix()
        cfg = LocalisationConfig()
        try:
            fix = refine_localisation(self.world, depth, K, T_wc, T_wb, cfg,
                                      landmarks=self.input("landmarks"))
        except PerceptionError:
            # a look that registered nothing still showed its landmarks: LookAtLandmark
            # passes over them next time
            ids = self.input("landmarks") or visible_landmarks(self.world, K, T_wc, cfg.max_range)
            if ids:
                self.set_output("views", earlier + [{"landmarks": list(ids)}])
            raise
        # every view that was registered is kept, for a joint fix with the later ones; its
        # estimate of the pose (``evidence``) only where it is one
        mine = dict(fix.evidence or {"landmarks": list(fix.landmarks)})
        if fix.views:
            mine["view"] = fix.views[-1]
        self.set_output("views", earlier + [mine])
        self.set_output("quality", fix.quality)
        if not (fix.ok and not fix.loose
                and _contradiction(earlier, fix, cfg)[0] <= cfg.max_contradiction_m):
            joint = _joint_fix(self.world, earlier, fix, cfg)
            if joint is not None:
                self.robot.apply_correction(Pose.from_matrix(joint.T_world_base))
                self.set_output("correction", dict(dx=joint.dx, dy=joint.dy, dyaw=joint.dyaw))
                self.set_output("quality", joint.quality)
                return Feedback(
                    f"localisation corrected by {math.hypot(joint.dx, joint.dy) * 100:.1f} cm, "
                    f"{math.degrees(joint.dyaw):.1f} deg on {', '.join(joint.landmarks)} "
                    f"together ({len(joint.views)} views)",
                    dx_cm=100 * joint.dx, dy_cm=100 * joint.dy, dyaw_deg=math.degrees(joint.dyaw),
                    landmarks=list(joint.landmarks),
                    views=len(joint.views))
        if not fix.ok:
            why = "; ".join(fix.quality.get("doubts") or ()) or "too weak"
            raise PerceptionError(Feedback(f"fix on {', '.join(fix.landmarks)} not trusted: {why} "
                                           f"(fitness {fix.quality['fitness']:.2f}); pose left "
                                           f"unchanged", fix.quality, landmarks=fix.landmarks))
        against = _contradiction(earlier, fix, cfg)
        if against[0] > cfg.max_contradiction_m:
            # Two views of one pose further apart than twice the error a fix may have: one
            # of them is wrong and neither says which (the trusted one was, at home 5; the
            # earlier one, at home 23), so the pose is left as it was.
            raise PerceptionError(Feedback(
                f"fix on {', '.join(fix.landmarks)} not trusted: the view of "
                f"{', '.join(against[1]['landmarks'])} puts the robot {100 * against[0]:.1f} cm "
                f"away along a direction it pins down; pose left unchanged",
                landmarks=fix.landmarks, contradicted_by=against[1]['landmarks'],
                contradiction_cm=100 * against[0]))
        self.robot.apply_correction(Pose.from_matrix(fix.T_world_base))
        corr = dict(dx=fix.dx, dy=fix.dy, dyaw=fix.dyaw)
        self.set_output("correction", corr)
        moved = (f"{math.hypot(fix.dx, fix.dy) * 100:.1f} cm, {math.degrees(fix.dyaw):.1f} deg "
                 f"on {', '.join(fix.landmarks)}")
        corrected = dict(dx_cm=100 * fix.dx, dy_cm=100 * fix.dy, dyaw_deg=math.degrees(fix.dyaw),
                         landmarks=fix.landmarks)
        if fix.loose:
            # the best pose this view gives, so it is applied (the other missions read knobs
            # and grasp better from it than from the pose before), but a pose a few
            # centimetres along the landmarks explains the view nearly as well: the skill
            # fails, so that the missions try other landmarks and never say "corrected" on it
            raise PerceptionError(Feedback(
                f"localisation moved by {moved}, but not pinned down: a pose "
                f"{100 * fix.quality['ring_m']:.0f} cm away explains the view nearly as well "
                f"(drop {fix.quality['ring_drop']:.3f})", fix.quality, **corrected))
        return Feedback(f"localisation corrected by {moved}", **corrected)


def _contradiction(earlier, fix, cfg) -> tuple[float, dict | None]:
    """The largest ``contradiction`` (m) of ``fix`` by an earlier view's estimate, and that
    view; (0, None) without one."""
    from hearth.perception.localisation import contradiction
    return max(((contradiction(e, fix.evidence, cfg.min_weakest), e) for e in earlier
                if fix.evidence is not None and "pose" in e),
               key=lambda t: t[0], default=(0.0, None))


def _joint_fix(world, earlier, fix, cfg):
    """Every view registered so far from this base pose (``earlier``'s and ``fix``'s),
    registered together (``refine_localisation_views``), when that fix is trusted and
    pinned down; else None. Each view alone may leave a direction free (a flat front) that
    another pins down; the joint fix answers to every view at once, ring included."""
    from hearth.perception.localisation import refine_localisation_views
    seen = [e["view"] for e in earlier if isinstance(e, dict) and e.get("view") is not None]
    if not seen or not fix.views:
        return None
    try:
        joint = refine_localisation_views(world, seen + list(fix.views), cfg)
    except PerceptionError:
        return None
    return joint if joint.ok and not joint.loose else None


class RegisterArticulated(_PerceptionSkill):
    """Register an articulated object part by part and write each part's state to the map;
    parts seen edge-on or hidden are reported unknown and left as the map has them. The
    missions look again from another parking position when ``unknown`` is not empty (it is
    written also when no part could be read: then every part is unknown)."""

    NAME = "RegisterArticulated"
    DESCRIPTION = "read the state of an articulated object's doors and drawers"
    INPUTS = (Port("object", "node_id"),
              Port("parts", "list", required=False, default=None,
                   description="only these parts (default: every part)"))
    OUTPUTS = (Port("states", "dict", required=False, description="part id -> deg (doors) / m"),
               Port("unknown", "list", required=False,
                    description="the parts whose state could not be read from here"))

    def perceive(self) -> str:
        from hearth.perception.articulated import register_articulated
        from hearth.worldmodel.validate import all_parts
        oid = self.input("object")
        # Sliding doors on a track are left as the map has them: a flat panel sliding along
        # its own plane gives the 1-DoF registration only its edges to lock on (a hall
        # wardrobe's closed door read 0.232 m open, issue 43), and the search slides the half
        # it needs open whatever the state (docs/missions-end-to-end.md, "Sliding doors").
        parts = self.input("parts")
        sliding = {p.id for p in all_parts(self.world.get(oid)) if p.track}
        if sliding:
            parts = [p.id for p in all_parts(self.world.get(oid))
                     if p.id not in sliding and (parts is None or p.id in parts)]
        if sliding and not parts:
            self.set_output("unknown", [])
            self.set_output("states", {})
            return f"{oid}: only sliding doors, their states kept from the map"
        depth, K, T_wc = capture(self.robot)
        reg = register_articulated(self.world, oid, depth, K, T_wc, parts=parts)
        states, unknown = {}, []
        for pid, st in reg.parts.items():
            if st.known and st.joint_type != "fixed":
                self.world.set_joint_state(pid, st.value, source=self.NAME)
                states[pid] = round(st.state, 3 if st.joint_type == "revolute" else 4)
            elif not st.known:
                unknown.append(pid)
        self.set_output("unknown", unknown)
        if not states:
            why = "; ".join(f"{p}: {st.reason}" for p, st in reg.parts.items())
            raise PerceptionError(f"{oid}: no part state read ({why or reg.base_note})")
        self.set_output("states", states)
        said = ", ".join(f"{p} {v:g} {'deg' if reg.parts[p].joint_type == 'revolute' else 'm'}"
                         for p, v in states.items())
        return Feedback(f"{oid}: {said or 'no part state read'}" + (
            f"; unknown: {', '.join(unknown)}" if unknown else ""), states=states, unknown=unknown)


class EstimateHandle(_PerceptionSkill):
    """The fine world pose of a door or drawer handle, for grasping."""

    NAME = "EstimateHandle"
    DESCRIPTION = "find a handle's exact pose"
    INPUTS = (Port("handle", "node_id"),)
    OUTPUTS = (Port("pose", "pose", required=False),)

    def perceive(self) -> str:
        from hearth.perception.articulated import estimate_handle_pose
        hid = self.input("handle")
        depth, K, T_wc = capture(self.robot)
        est, _ = estimate_handle_pose(self.world, hid, depth, K, T_wc)
        pose = Pose.from_matrix(est.T_world_handle)
        self.set_output("pose", pose)
        prior = " (height from the map)" if est.prior_used else ""
        return Feedback(f"{hid} at {pose.x:.3f}, {pose.y:.3f}, {pose.z:.3f}{prior} from "
                        f"{est.points} points", pose=pose, points=est.points)
