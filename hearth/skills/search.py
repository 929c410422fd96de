"""ProposeSearchPositions: when every known place failed, look at the room and propose new
places to search ("Where to look first?", HOBBIT).

One frame from ``robot.capture()`` (``depth``, ``color``, ``intrinsics`` or ``K``, believed
``T_world_camera``) is segmented (hearth.perception.segmentation, forest from
hearth/skills/segmentation_model.py, trained on first use unless ``setup`` gets a ready
``segmentation_model``); the table tops become base poses on their second principal axis at
the safety distance (hearth.perception.search_positions), kept when inside the room and free in an
occupancy grid made of the map's large objects and the obstacles the view shows. The room's
bounds and the grid are in the room's own frame (rooms may be turned and offset).
"""
from __future__ import annotations

import numpy as np
import py_trees

from hearth.perception.errors import PerceptionError
from hearth.skills.base import Port, Skill
from hearth.worldmodel.frames import T_world_room, room_at, to_room
from hearth.worldmodel.pose import Pose

S = py_trees.common.Status


class ProposeSearchPositions(Skill):
    """Base poses from which to search tables seen in the current view, nearest first."""

    NAME = "ProposeSearchPositions"
    DESCRIPTION = "propose search positions at tables found by semantic segmentation"
    INPUTS = (Port("room", "node_id", required=False, default=None,
                   description="room to stay in (default: the robot's)"),
              Port("safety_distance", "number", required=False, default=0.45,
                   description="metres from the table edge to the base centre"))
    OUTPUTS = (Port("positions", "list", required=False, description="base Poses, world frame"),
               Port("tables", "list", required=False,
                    description="table tops: centre x, y, height, half extents"))

    def setup(self, **kwargs) -> None:
        super().setup(**kwargs)
        self.model = kwargs.get("segmentation_model")

    def update(self) -> py_trees.common.Status:
        from hearth.perception.search_positions import OccupancyGrid, SearchConfig, propose_search_positions
        from hearth.perception.segmentation import LABELS, segment
        from hearth.worldmodel.geometry import node_mesh
        try:
            if self.model is None:
                from hearth.skills.segmentation_model import load_or_train
                self.model = load_or_train()
            frame = self.robot.capture()
            K = getattr(frame, "intrinsics", None) or getattr(frame, "K")
            T_wc = np.asarray(frame.T_world_camera, dtype=float)
            seg = segment(np.asarray(frame.depth), np.asarray(frame.color), K, T_wc, self.model)
            base = self.robot.base_pose() if hasattr(self.robot, "base_pose") else None
            robot_xy = (base.x, base.y) if base is not None else (T_wc[0, 3], T_wc[1, 3])
            rid = self.input("room")
            room = self.world.get(rid) if rid else room_at(self.world, *robot_xy)
            if room is None or room.bounds is None:
                raise PerceptionError("the robot's room (with bounds) is not known")
            occ = OccupancyGrid.empty(room.bounds)
            occ.mark_footprints([to_room(room, np.asarray(node_mesh(self.world, o.id).vertices)[:, :2])
                                 for o in room.objects])
            solid = [LABELS.index(n) for n in ("wall", "table", "chair", "cabinet", "object")]
            obstacles = seg.patches.points_world[np.isin(seg.labels, solid)]
            if len(obstacles):
                occ.mark_points(to_room(room, obstacles))
            cfg = SearchConfig(safety_distance_m=float(self.input("safety_distance")))
            found = propose_search_positions(seg.points("table"), room.bounds, occ, robot_xy, cfg,
                                             T_world_room=T_world_room(room))
        except (PerceptionError, KeyError, ValueError) as err:
            self.report_error(err)
            return S.FAILURE
        poses = [Pose(sp.x, sp.y, 0.0, 0.0, 0.0, sp.yaw) for sp in found]
        tables = {id(sp.table): sp.table for sp in found}
        self.set_output("positions", poses)
        self.set_output("tables", [dict(x=round(float(t.center[0]), 3), y=round(float(t.center[1]), 3),
                                        height=round(t.height, 3),
                                        half_extents=[round(float(h), 3) for h in t.half_extents])
                                   for t in tables.values()])
        if not poses:
            self.feedback_message = "no table with a free search position in view"
            return S.FAILURE
        self.feedback_message = f"{len(poses)} search positions at {len(tables)} tables"
        return S.SUCCESS
