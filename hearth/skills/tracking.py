"""TrackObject: follow a small object over frames with hearth.perception.tracking's particle filter.

Each tick captures one frame through ``robot.capture()`` (``depth`` metres, ``color`` uint8
RGB, ``intrinsics`` or ``K``, believed ``T_world_camera``; an optional ``stamp`` in seconds,
else the clock) and folds it into the tracker. The first frame gives the reference cloud:
the points inside the object's box at its start pose (the ``pose`` input, e.g. from
DetectObject, else the map's). After ``frames`` updates the skill succeeds with the last
pose (and moves the object in the map, on its parent, when ``update_map``); it fails when
the tracker reports the object lost for ``max_lost`` frames in a row.
"""
from __future__ import annotations

import numpy as np
import py_trees

from hearth.perception.errors import PerceptionError
from hearth.skills.base import Port, Skill
from hearth.worldmodel.frames import as_matrix
from hearth.worldmodel.pose import Pose

S = py_trees.common.Status


def _matrix(pose) -> np.ndarray:
    return as_matrix(pose)


def object_box(world, object_id: str) -> np.ndarray:
    """Half extents (x, y, z/2) of a small object's box in its own frame, 1 cm margin."""
    from hearth.worldmodel.geometry import small_object_meshes
    obj = world.get(object_id)
    v = np.concatenate([np.asarray(m.mesh.vertices)
                        for m in small_object_meshes(world, obj, np.eye(4))])
    half_xy = np.abs(v[:, :2]).max(axis=0) + 0.01
    return np.array([half_xy[0], half_xy[1], (v[:, 2].max() + 0.01) / 2])


class TrackObject(Skill):
    """Follow a small object that moves (e.g. pushed across a table)."""

    NAME = "TrackObject"
    DESCRIPTION = "track a moving small object over several frames"
    INPUTS = (Port("object", "node_id"),
              Port("pose", "pose", required=False, default=None,
                   description="start pose, world frame (default: the map's)"),
              Port("frames", "integer", required=False, default=30),
              Port("max_lost", "integer", required=False, default=5),
              Port("update_map", "boolean", required=False, default=True))
    OUTPUTS = (Port("pose", "pose", required=False, description="world frame"),
               Port("velocity", "list", required=False, description="m/s, world frame"))

    def initialise(self) -> None:
        self.tracker = None
        self.updates = 0
        self.lost = 0
        self.last_t = None

    def _frame(self):
        f = self.robot.capture()
        K = getattr(f, "intrinsics", None) or getattr(f, "K")
        t = getattr(f, "stamp", None)
        if t is None and self.clock is not None:
            t = self.clock.now()
        return (np.asarray(f.depth, dtype=np.float64), np.asarray(f.color), K,
                np.asarray(f.T_world_camera, dtype=float), t)

    def update(self) -> py_trees.common.Status:
        from hearth.perception.tracking import ParticleTracker, reference_from_view, scene_cloud
        oid = self.input("object")
        try:
            depth, color, K, T_wc, t = self._frame()
            if self.tracker is None:
                pose = self.input("pose")
                T0 = self.world.T_world(oid) if pose is None else _matrix(pose)
                half = object_box(self.world, oid)
                pts, cols = scene_cloud(depth, color, K, T_wc,
                                        np.stack([T0[:3, 3] - half.max() * 2, T0[:3, 3] + half.max() * 2]))
                ref = reference_from_view(pts, cols, T0, half)
                self.tracker = ParticleTracker(ref, T0, rng=np.random.default_rng(0))
                self.last_t = t
                self.feedback_message = f"tracking {oid}"
                return S.RUNNING
            dt = 1 / 30 if t is None or self.last_t is None else max(t - self.last_t, 1e-3)
            self.last_t = t
            est = self.tracker.update(depth, color, K, T_wc, dt)
        except (PerceptionError, KeyError, ValueError) as err:
            self.report_error(err)
            return S.FAILURE
        self.updates += 1
        self.lost = 0 if est.ok else self.lost + 1
        if self.lost >= int(self.input("max_lost")):
            self.feedback_message = f"{oid} lost after {self.updates} frames"
            return S.FAILURE
        pose = Pose.from_matrix(est.T_world_object)
        self.set_output("pose", pose)
        self.set_output("velocity", [round(float(v), 4) for v in est.velocity_world])
        if self.updates < int(self.input("frames")):
            self.feedback_message = f"tracking {oid}: frame {self.updates}, {est.n_particles} particles"
            return S.RUNNING
        if self.input("update_map"):
            parent = self.world.parent(oid)
            local = Pose.from_matrix(np.linalg.inv(self.world.T_world(parent.id)) @ est.T_world_object)
            self.world.move_object(oid, parent.id, local, self.world.get(oid).relation, source=self.NAME)
        self.report(f"{oid} tracked over {self.updates} frames, now at "
                    f"({pose.x:.2f}, {pose.y:.2f}, {pose.z:.2f})", frames=self.updates, pose=pose)
        return S.SUCCESS
