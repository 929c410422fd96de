"""Learn a new object from views: "this is my pill organiser" (HOBBIT section 4).

``LearnObject`` finds the object the map does not know on the surface in front of the robot
(or the one named), drives round it to the views hearth.perception.object_learning plans, captures
and segments a view at each, builds the model and writes it into the map
(hearth.worldmodel.learned): mesh files beside the world file and a SmallObject with the name and
words a person gave. Nothing is written into the map before the model is complete; halted
half-way, the skill cancels the drive and leaves the map as it was.
"""
from __future__ import annotations

from typing import Optional

import numpy as np
import py_trees

from hearth.skills.base import Port, Skill
from hearth.skills.map import robot_pose
from hearth.skills.objects import capture

S = py_trees.common.Status


class LearnObject(Skill):
    """Drive round an object the map does not know, learn its model from the views, add it
    to the map under the name given."""

    NAME = "LearnObject"
    AUTONOMY = 1
    DESCRIPTION = "learn a new object from views around it and add it to the map"
    # (not "name": BehaviorTree.CPP's own attribute of every node)
    INPUTS = (Port("object_name", "string",
                   description="what the person calls it (\"pill organiser\")"),
              Port("words", "string", required=False, default="",
                   description="more words for it: colour, kind (\"white plastic\")"),
              Port("kind", "string", required=False, default="",
                   description="its type (default: the name's last word)"),
              Port("surface", "string", required=False, default="",
                   description="the furniture it stands on (default: the one in front)"),
              Port("views", "integer", required=False, default=6,
                   description="views to take around it (2-12)"))
    OUTPUTS = (Port("object_id", "node_id", required=False),
               Port("summary", "string", required=False,
                    description="what was learned, in a sentence for the person"),
               Port("problem", "string", required=False,
                    description="why it could not learn the object, for a person"))

    def initialise(self) -> None:
        self.plan: list = []
        self.views: list = []
        self.action = None
        self.step = "start"
        self.problem: Optional[str] = None
        self._halted = None
        try:
            self._start()
        except Exception as err:  # noqa: BLE001 - a bad name or surface: fail with the reason
            self.problem = str(err)

    def _start(self) -> None:
        from hearth.worldmodel.learned import check_name
        check_name(self.world, str(self.input("object_name")))
        n = int(self.input("views") or 6)
        if not 2 <= n <= 12:
            raise ValueError(f"views must be 2-12, not {n}")
        self.parent, self.level = self._surface()
        self.centre = self._find_on(self.level)
        from hearth.perception.object_learning import spread, views_around
        room = self.world.room_of(self.parent).id
        here = robot_pose(self.robot)
        around = views_around(self.world, self.centre, room, start_xy=(here.x, here.y))
        if len(around) < 2:
            raise ValueError(f"there is no free floor round the {self.world.label(self.parent)} "
                             "to look at it from two sides")
        self.plan = spread(around, n, self.centre)

    def _surface(self):
        """(furniture id, surface level) the object stands on: the named furniture's surface
        nearest what the camera looks at, else the surface the camera looks at."""
        depth, _, K, T = capture(self.robot)
        seen = depth[np.isfinite(depth) & (depth > 0)]
        if not len(seen):
            raise ValueError("my camera sees nothing")
        aim = T[:3, 3] + T[:3, 2] * float(np.median(seen))
        name = str(self.input("surface") or "")
        if not name:
            found = self.world.support_at(aim, margin=0.15)
            if found is None:
                raise ValueError("there is no surface in front of me: say which one it "
                                 "stands on")
            name = found[0].id
        level = self.world.surface_near(name, aim)
        if level is None:
            raise ValueError(f"the {self.world.label(name)} has no surface to stand things on")
        return self.world.large_object_of(name).id, level

    def _find_on(self, level) -> np.ndarray:
        """The world point (x, y, support z) of the object on ``level`` in the current view
        that the map does not know (hearth.perception.object_learning.find_new_object)."""
        from hearth.perception.object_learning import find_new_object
        depth, _, K, T = capture(self.robot)
        known = [self.world.T_world(o.id)[:2, 3] for o in self.world.small_objects()]
        point, why = find_new_object(depth, K, T, level.T_world_surface,
                                     (level.size_x, level.size_y), known)
        if why == "nothing":
            raise ValueError(f"I see nothing standing on the {self.world.label(level.place)}")
        if why == "known":
            raise ValueError("everything I see there is already in my map")
        return point

    def update(self) -> S:
        if self.problem is not None:
            return self._fail(self.problem)
        from hearth.worldmodel.pose import Pose
        if self.action is not None:
            status = self.action.status()
            if status == "running":
                self.feedback_message = f"view {len(self.views) + 1} of {len(self.plan)}: driving"
                return S.RUNNING
            self.action = None
            if status == "succeeded":
                self._take_view()
        if self.plan:
            x, y, yaw = self.plan.pop(0)
            self.action = self.robot.navigate_to(Pose.planar(x, y, yaw))
            self.feedback_message = f"driving to a view of the object ({len(self.plan)} more)"
            return S.RUNNING
        return self._finish()

    def _take_view(self) -> None:
        from hearth.perception.object_learning import segment_view
        self.robot.look_at(self.centre + np.array([0.0, 0.0, 0.05]))
        depth, color, K, T = capture(self.robot)
        known = [tuple(self.world.bounds_world(o.id)) for o in self.world.small_objects()
                 if np.hypot(*(self.world.T_world(o.id)[:2, 3] - self.centre[:2])) < 0.5]
        self.views.append(segment_view(depth, color, K, T, float(self.centre[2]),
                                       self.centre[:2], known=known))

    def _finish(self) -> S:
        from hearth.perception.errors import PerceptionError
        from hearth.perception.object_learning import build_model, hue_name
        from hearth.worldmodel.errors import WorldError
        from hearth.worldmodel.homegen_palette import COLOURS
        from hearth.worldmodel.learned import add_learned_object
        name = str(self.input("object_name"))
        try:
            from hearth.worldmodel.learned import support_colour
            model = build_model(self.views, given=len(self.views),
                                reference_rgb=support_colour(self.world, self.parent, self.centre))
            colour = hue_name(model.colours[0][0], COLOURS) if model.colours else ""
            obj = add_learned_object(self.world, model, name, self.parent,
                                     kind=str(self.input("kind") or ""),
                                     words=str(self.input("words") or ""), colour=colour,
                                     source="LearnObject")
        except (PerceptionError, WorldError) as err:
            return self._fail(str(err))
        self.set_output("object_id", obj.id)
        a, b, h = (100 * v for v in model.size)
        self.set_output("summary", f"I know your {name} now: {a:.0f} by {b:.0f} cm and "
                                   f"{h:.0f} cm high, mostly {colour or 'white, grey or black'}. Ask me to "
                                   "bring it to you.")
        self.feedback_message = (f"learned the {name}: {a:.0f} x {b:.0f} x {h:.0f} cm, mostly "
                                 f"{colour or 'one colour'}, from {model.views_used} of "
                                 f"{model.views_given} views")
        return S.SUCCESS

    def _fail(self, why: str) -> S:
        self.set_output("problem", why)
        self.feedback_message = why
        return S.FAILURE

    def terminate(self, new_status: S) -> None:
        if new_status == S.INVALID and self.action is not None \
                and self.action.status() == "running":
            self.action.cancel()
            self._halted = self.action
            self.feedback_message = "learning cancelled: nothing was added to the map"

    def is_halting(self) -> bool:
        halted = getattr(self, "_halted", None)
        return halted is not None and halted.status() == "running"
