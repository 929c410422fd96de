"""Knob skills: read every knob of an appliance (and write the states to the map), turn one.

ReadKnobs captures one frame through ``robot.capture()`` (``color``, ``intrinsics`` or ``K``,
``T_world_camera``), reads the knobs with hearth.perception.knobs in regions projected from the map
(the registered pose when RegisterLargeObject ran before), and writes each knob it could read
with ``world.set_knob_state(knob, state, angle, source="ReadKnobs")``; knobs it could not
find or was unsure of are listed as unknown and left as the map has them. The models are the
ones trained for this home, asked of hearth/skills/knob_models.py in ``setup`` (loaded, or trained
on first use for this home), unless the executive passes a ready ``knob_reader`` to
``setup``.
"""
from __future__ import annotations

import math

import numpy as np
import py_trees

from hearth.perception.errors import PerceptionError
from hearth.skills.actions import RobotActionSkill
from hearth.skills.base import Port, Skill
from hearth.worldmodel.nodes import Knob

S = py_trees.common.Status


class ReadKnobs(Skill):
    """Read the angle and discrete state of every knob of ``object`` (or the given knobs)."""

    NAME = "ReadKnobs"
    DESCRIPTION = "read the state of an appliance's knobs"
    INPUTS = (Port("object", "node_id", required=False, default=None,
                   description="appliance whose knobs to read"),
              Port("knobs", "list", required=False, default=None, description="knob ids"),
              Port("update_map", "boolean", required=False, default=True))
    OUTPUTS = (Port("states", "dict", required=False, description="knob id -> state name"),
               Port("angles", "dict", required=False, description="knob id -> degrees"),
               Port("on", "list", required=False, description="knobs read as not off"),
               Port("unknown", "list", required=False))

    def setup(self, **kwargs) -> None:
        """Loads the knob models of this home (makes them on first use: a few seconds, once
        per home)."""
        super().setup(**kwargs)
        self.reader = kwargs.get("knob_reader")
        if self.reader is None and self.world is not None:
            from hearth.skills.knob_models import load_or_train
            try:
                self.reader, _ = load_or_train(self.world)
            except PerceptionError:
                self.reader = None   # update() tries again and reports why

    def _reader(self):
        if self.reader is None:
            from hearth.skills.knob_models import load_or_train
            self.reader, _ = load_or_train(self.world)
        return self.reader

    def update(self) -> py_trees.common.Status:
        from hearth.perception.knob_panel import WHERE_THE_MAP_SAYS, read_panel
        from hearth.perception.knobs import knob_priors
        try:
            obj, ids = self.input("object"), self.input("knobs")
            priors = knob_priors(self.world, obj)
            if not priors:
                raise PerceptionError(f"no knobs to read on {obj or 'the map'}")
            frame = self.robot.capture()
            K = getattr(frame, "intrinsics", None) or getattr(frame, "K")
            depth = getattr(frame, "depth", None)
            T_wc = np.asarray(frame.T_world_camera, dtype=float)
            depth = None if depth is None else np.asarray(depth)
            if ids and not any(p.knob_id in set(ids) for p in priors):
                raise PerceptionError(f"no knobs to read on {obj or 'the map'}")
            # the knobs where the depth image shows their panel, when the reader finds them
            # there (the robot's pose may be centimetres off: hearth/perception/knob_panel.py); the
            # panel is found with all its knobs though only some are to be read
            readings, fixes = read_panel(self._reader(), np.asarray(frame.color), K, T_wc, priors,
                                         depth=depth, only=set(ids) if ids else None)
        except (PerceptionError, KeyError, ValueError) as err:
            self.report_error(err)
            return S.FAILURE
        states, angles, on, unknown, twice = {}, {}, [], [], []
        off_views = off_views_of(self)
        for r in readings:
            off = self.world.get(r.knob_id).off
            if off_views.add(r, off, T_wc[:3, 3]):
                # off from this place and another (hearth.perception.knobs.OffViews)
                r.state = off
                twice.append(r.knob_id)
            if r.state == "unknown":
                unknown.append(r.knob_id)
                continue
            states[r.knob_id] = r.state
            angles[r.knob_id] = round(math.degrees(r.angle), 1)
            if r.state != off:
                on.append(r.knob_id)
            if self.input("update_map"):
                self.world.set_knob_state(r.knob_id, r.state, r.angle, source=self.NAME)
        for name, value in (("states", states), ("angles", angles), ("on", on), ("unknown", unknown)):
            self.set_output(name, value)
        said = ", ".join(f"{k} {v}" for k, v in states.items())
        if unknown:
            why = "; ".join(f"{r.knob_id}: {r.reason}" for r in readings if r.state == "unknown")
            said += f"; unknown: {why}"
        moved = [f"panel of {len(f.knob_ids)} knob{'s' if len(f.knob_ids) != 1 else ''} found "
                 f"{f.shift_m * 100:.1f} cm from where the map puts it" if f.used else
                 f"panel of {len(f.knob_ids)} knob{'s' if len(f.knob_ids) != 1 else ''} not "
                 f"moved: {f.why}" for f in fixes if f.used or f.why != WHERE_THE_MAP_SAYS]
        if twice:
            moved.append(f"{', '.join(twice)} read off from two places")
        self.report(f"knobs: {said}" + "".join(f"; {m}" for m in moved), states=states,
                    angles_deg=angles, unknown=unknown)
        return S.SUCCESS if states else S.FAILURE


def off_views_of(skill):
    """The mission run's ``OffViews`` (one per run, in the ``run_memory`` the executive gives
    every skill of a run at setup; a skill set up without one keeps its own)."""
    from hearth.perception.knobs import OffViews
    memory = skill.context.get("run_memory")
    if memory is None:
        memory = skill.__dict__.setdefault("_own_memory", {})
    return memory.setdefault("knob_off_views", OffViews())


class TurnKnob(RobotActionSkill):
    """Turn a knob to a state (default: off) or an angle (degrees) through the robot adapter;
    the map gets the new state when the robot reports success (read again to verify)."""

    NAME = "TurnKnob"
    AUTONOMY = 2
    DESCRIPTION = "turn an appliance knob to a state (default off)"
    INPUTS = (Port("knob", "node_id"),
              Port("state", "string", required=False, default=None),
              Port("angle", "number", required=False, default=None, description="degrees"))
    OUTPUTS = (Port("state", "string", required=False),)

    def start(self):
        knob = self.world.get(self.input("knob"))
        if not isinstance(knob, Knob):
            raise ValueError(f"{knob.id} is not a knob")
        state, angle = self.input("state"), self.input("angle")
        if angle is not None:
            a = math.radians(float(angle))
            d = [abs(math.remainder(s.angle - a, 2 * math.pi)) for s in knob.states]
            state = knob.states[int(np.argmin(d))].name
        else:
            state = state or knob.off
            if state not in [s.name for s in knob.states]:
                raise ValueError(f'{knob.id} has no state "{state}"; its states are '
                                 + ", ".join(s.name for s in knob.states))
            a = knob.state_angle(state)
        self._knob, self._state, self._angle = knob.id, state, a
        return self.robot.turn_knob(knob.id, a)

    def describe(self) -> str:
        return f"turning {getattr(self, '_knob', '')} to {getattr(self, '_state', '')}"

    def succeeded(self, action) -> None:
        # what was seen of its knobs before the turn is old (a turn can nudge a neighbour)
        views = off_views_of(self)
        for k in self.world.knobs(self.world.large_object_of(self._knob).id):
            views.forget(k.id)
        self.world.set_knob_state(self._knob, self._state, self._angle, source=self.NAME)
        self.set_output("state", self._state)
