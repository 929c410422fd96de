"""KnobViews: where to read knobs left unread from, on free floor around their appliance.

Candidate base poses stand on a ring around the unread knobs (``DISTANCES`` from them, at
``BEARINGS`` from their panel's normal; all round for knobs on top), facing them, on free floor
(inside a room and ``BASE_CLEARANCE`` clear of every large object's footprint, the appliance's
own included: hearth.worldmodel.viewing); hearth.perception.knob_views ranks them by what the
knob reader would make of each knob from there (its size in pixels and angle off its axis
against the reader's own validation views of that knob), keeping only poses expected to read
more of them than the view from where the robot stands (where they were just left unread).
The places come out best first as search places (x, y, yaw, look_at) for NavigateTo and LookAt
(missions/subtrees/knobs.yaml); with none the skill fails and says what it expects from here.
"""
from __future__ import annotations

import math

import numpy as np
import py_trees

from hearth.perception.errors import PerceptionError
from hearth.skills.base import Port, Skill

S = py_trees.common.Status

#: Metres from the unread knobs' centre (in the floor plane) to the candidate base poses: from
#: nearer than any parking position to further than the straight looks.
DISTANCES = tuple(np.round(np.arange(0.4, 1.65, 0.1), 2))
#: Degrees from the knobs' panel normal (in the floor plane) of the candidate poses.
BEARINGS = tuple(range(-80, 81, 10))
#: Knobs on top (a hob's) are looked at from all round, this many degrees apart.
TOP_BEARING_STEP = 15


class KnobViews(Skill):
    """The best free poses to read the given knobs of ``object`` again from, best first."""

    NAME = "KnobViews"
    DESCRIPTION = "choose free poses around an appliance to read its unread knobs from"
    INPUTS = (Port("object", "node_id", description="the appliance"),
              Port("knobs", "list", required=False, default=None,
                   description="the knobs to read (default: all of the appliance's)"),
              Port("keep", "integer", required=False, default=3,
                   description="how many poses, at least 0.3 m apart"))
    OUTPUTS = (Port("places", "list", required=False,
                    description="search places {x, y, yaw, look_at, expected_read}, best first"),
               Port("count", "integer", required=False))

    def setup(self, **kwargs) -> None:
        super().setup(**kwargs)
        self.reader = kwargs.get("knob_reader")

    def update(self) -> S:
        from hearth.perception.knob_views import (KnobViewConfig, pose_views, rank_views, ring,
                                                  validation_table)
        from hearth.perception.knobs import knob_priors
        from hearth.robot.sim import HEAD, camera_pose, pan_tilt_to
        from hearth.skills.map import robot_pose
        from hearth.worldmodel.pose import Pose
        from hearth.worldmodel.viewing import BASE_CLEARANCE, floor_clear
        obj, ids = self.input("object"), self.input("knobs")
        try:
            priors = knob_priors(self.world, obj)
            unread = [p.knob_id for p in priors if not ids or p.knob_id in set(ids)]
            if not unread:
                raise PerceptionError(f"no knobs to read on {obj}")
            if self.reader is None:     # the same reader ReadKnobs loads (the store's)
                from hearth.skills.knob_models import load_or_train
                self.reader, _ = load_or_train(self.world)
            reader = self.reader
            K = getattr(self.robot, "intrinsics", None)
            if K is None:
                from hearth.perception.camera import Intrinsics
                K = Intrinsics.kinect()
            mount = getattr(self.robot, "mount", None) or HEAD
            own = self.world.large_object_of(obj).id
            want = [p for p in priors if p.knob_id in set(unread)]
            centre = np.mean([p.T_world_face()[:3, 3] for p in want], axis=0)
            axis = np.mean([p.T_world_knob[:3, 2] for p in want], axis=0)
            flat = axis[:2]
            top = float(np.linalg.norm(flat)) < 0.42 * float(np.linalg.norm(axis))  # within 25 deg of up
            bearings = (range(0, 360, TOP_BEARING_STEP) if top else BEARINGS)
            boxes = {o.id: self.world.bounds_world(o.id) for o in self.world.large_objects()}
            free = floor_clear(self.world, BASE_CLEARANCE, boxes)
            candidates = [c for c in ring(centre[:2], None if top else flat, DISTANCES, bearings)
                          if free(c[0], c[1])]
            blockers = [tuple(b) for o, b in boxes.items() if o != own]
            here = robot_pose(self.robot)

            def camera_at(x, y, yaw, point):
                pose = Pose.planar(x, y, yaw)
                return camera_pose(pose, *pan_tilt_to(pose, point, mount), mount)

            table, cfg = validation_table(reader), KnobViewConfig.for_reader(reader)
            # what the view from here (where they were just left unread) gives them
            now, _ = pose_views(want, centre, (here.x, here.y, here.yaw), camera_at, K, table,
                                blockers, cfg)
            ranked, best = rank_views(priors, unread, candidates, camera_at, K, table,
                                      robot_xy=(here.x, here.y), tried=[(here.x, here.y)],
                                      blockers=blockers, cfg=cfg,
                                      keep=int(self.input("keep") or 3), beat=now)
        except (PerceptionError, KeyError, ValueError) as err:
            self.feedback_message = f"{self.NAME}: {err}"
            return S.FAILURE
        places = [r.as_place() for r in ranked]
        self.set_output("places", places)
        self.set_output("count", len(places))
        said = [f"({r.x:.2f}, {r.y:.2f}) {math.hypot(r.x - here.x, r.y - here.y):.1f} m away, "
                f"{r.score:.2f} knob{'s' if r.score != 1 else ''} expected read" for r in ranked]
        limits = [limit(self.world, v) for k, v in sorted(best.items()) if v.p_read < 0.05]
        self.feedback_message = (f"{len(candidates)} free poses around {obj}, {now:.2f} knob"
                                 f"{'s' if now != 1 else ''} expected read from here; "
                                 + ("; ".join(said) if said else "none reads its unread knobs better")
                                 + "".join(f"; {m}" for m in limits))
        return S.SUCCESS if places else S.FAILURE


def limit(world, view) -> str:
    """Why no free pose reads a knob, in numbers: its size in the image at its best view, how
    far off its axis, the chance its reading is given there, and its marker's width in pixels."""
    said = (f"{view.knob_id}: no free pose reads it (at best {view.radius_px:.1f} px radius, "
            f"{view.off_axis:.0f} degrees off its axis: {view.p_read:.2f} of such views read)")
    try:
        from hearth.perception.knobs import knob_shape
        shape = knob_shape(world.get(view.knob_id), world.apartment.library, world.base_dir)
    except (KeyError, ValueError, AttributeError):
        return said
    from hearth.perception.knob_views import marker_width
    width = marker_width(shape)
    if width is None or view.radius_px <= 0:
        return said
    px = width * view.radius_px / shape.radius
    return said[:-1] + f"; its marker, {width * 1000:.1f} mm wide, is {px:.1f} px across there)"
