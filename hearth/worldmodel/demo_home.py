"""The bundled demo home, generated here and written to data/demo_home/world.xml.

A kitchen (6 m x 5 m) with a kitchen table holding a red cup, a bowl, a sugar container and a
blue cup; a side table; a chair; a cupboard with two hinged doors; a drawer unit with three
drawers; a fridge; an oven with a bottom-hinged door and four knobs; a light switch; a
charging station. A
bathroom with a cabinet holding a pill box. Articulated objects face their local +x.

Run ``python -m hearth.worldmodel.demo_home [OUT]`` to regenerate the file.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

from hearth.worldmodel.io import atomic_write, to_xml
from hearth.worldmodel.nodes import (
    Apartment, Charger, DefaultPosition, GraspPoint, Handle, Joint, Knob, KnobState, LargeArticulatedObject,
    LargeObject, Model, ParkingPosition, Part, Room, SmallObject, Surface, Switch, Visual,
)
from hearth.worldmodel.pose import Pose

WOOD = (0.55, 0.38, 0.22)
WHITE = (0.92, 0.92, 0.9)
STEEL = (0.72, 0.73, 0.75)
DARK = (0.12, 0.12, 0.13)
CREAM = (0.93, 0.89, 0.78)

# The knob frame's axes in its parent's frame when the knob sits on a face whose outward
# normal is the parent's +x: knob x = parent y, knob y (marker at angle 0) = parent z (up),
# knob z (axis) = parent x.
_R = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
_T_KNOB = np.eye(4)
_T_KNOB[:3, :3] = _R
_KNOB_ROT = Pose.from_matrix(_T_KNOB)


def box(sx, sy, sz, x=0.0, y=0.0, z=0.0, color=WHITE, material="matte", name="", yaw=0.0):
    return Visual("box", Pose(x, y, z, 0, 0, yaw), size=(sx, sy, sz), color=color,
                  material=material, name=name)


def cyl(r, h, x=0.0, y=0.0, z=0.0, color=WHITE, material="matte", name=""):
    return Visual("cylinder", Pose(x, y, z), radius=r, length=h, color=color, material=material,
                  name=name)


def front_parking(prefix: str, depth: float, dist: float = 0.75, spread: float = 0.35):
    """Parking positions in front of an object facing +x, looking at it."""
    return [ParkingPosition(f"{prefix}_front", Pose(depth / 2 + dist, 0.0, 0, 0, 0, math.pi)),
            ParkingPosition(f"{prefix}_left", Pose(depth / 2 + dist, spread, 0, 0, 0, math.pi)),
            ParkingPosition(f"{prefix}_right", Pose(depth / 2 + dist, -spread, 0, 0, 0, math.pi))]


def table(oid, name, x, y, sx, sy, h, yaw=0.0, color=WOOD, children=(),
          sides=("south", "north", "west")):
    legs = [box(0.05, 0.05, h - 0.03, sxs * (sx / 2 - 0.05), sys_ * (sy / 2 - 0.05), (h - 0.03) / 2,
                color=color) for sxs in (-1, 1) for sys_ in (-1, 1)]
    top = box(sx, sy, 0.03, 0, 0, h - 0.015, color=color, name="top")
    d = 0.6
    parking = [ParkingPosition(f"{oid}_south", Pose(0, -(sy / 2 + d), 0, 0, 0, math.pi / 2)),
               ParkingPosition(f"{oid}_north", Pose(0, sy / 2 + d, 0, 0, 0, -math.pi / 2)),
               ParkingPosition(f"{oid}_west", Pose(-(sx / 2 + d), 0, 0, 0, 0, 0.0))]
    parking = [p for p in parking if p.id.rsplit("_", 1)[1] in sides]
    return LargeObject(id=oid, type="table", name=name, pose=Pose(x, y, 0, 0, 0, yaw),
                       model=Model([top, *legs]), parking=parking, default_parking=parking[0].id,
                       affordances=["supporting_surface"],
                       surfaces=[Surface("top", Pose(0, 0, h), sx, sy)], children=list(children))


def cup(oid, color_name, rgb, x, y, z, parent):
    return SmallObject(
        id=oid, type="cup", color=color_name, pose=Pose(x, y, z), relation="on",
        description=f"{color_name} ceramic mug",
        grasp_points=[GraspPoint(Pose(0, 0, 0.05))],
        default_positions=[DefaultPosition(parent, "on", Pose(x, y, z))],
        model=Model([cyl(0.04, 0.10, 0, 0, 0.05, color=rgb, name="body"),
                     box(0.035, 0.012, 0.06, 0.055, 0, 0.05, color=rgb, name="handle")]))


def small(oid, type_, color_name, visuals, x, y, z, parent, relation="on", description=""):
    return SmallObject(id=oid, type=type_, color=color_name, pose=Pose(x, y, z), relation=relation,
                       description=description, grasp_points=[GraspPoint(Pose(0, 0, 0.04))],
                       default_positions=[DefaultPosition(parent, relation, Pose(x, y, z))],
                       model=Model(visuals))


def carcass(depth, width, height, color=WHITE, t=0.018, shelves=()):
    """An open-fronted box (back, sides, top, bottom, shelves) with its bottom centre at the
    origin and its open front at x = depth/2."""
    v = [box(t, width, height, -depth / 2 + t / 2, 0, height / 2, color=color, name="back"),
         box(depth, t, height, 0, width / 2 - t / 2, height / 2, color=color, name="side"),
         box(depth, t, height, 0, -width / 2 + t / 2, height / 2, color=color, name="side"),
         box(depth, width, t, 0, 0, height - t / 2, color=color, name="top"),
         box(depth, width, t, 0, 0, t / 2 + 0.06, color=color, name="bottom"),
         box(depth - 0.02, width - 0.02, 0.06, -0.01, 0, 0.03, color=DARK, name="plinth")]
    for z in shelves:
        v.append(box(depth - 2 * t, width - 2 * t, t, 0, 0, z, color=color, name="shelf"))
    return v


def hinged_door(pid, name, depth, width, height, z0, side, handle_id, color=WHITE, t=0.02,
                state=0.0):
    """A door on the front face (x = depth/2) hinged at y = side*width/2 (side +1 or -1)."""
    dw = width - 0.006
    sign = -side
    joint = Joint("revolute", origin=Pose(depth / 2 + t / 2 + 0.002, side * width / 2, z0),
                  axis=(0.0, 0.0, float(side)), lower=0.0, upper=math.radians(100), state=state)
    model = Model([box(t, dw, height, 0, sign * dw / 2, height / 2, color=color, name="face")])
    handle = Handle(handle_id, Pose(t / 2 + 0.035, sign * (dw - 0.06), height * 0.6 if z0 < 0.5 else 0.25 * height),
                    radius=0.008, length=0.16, standoff=0.035)
    return Part(pid, "door", joint, name=name, model=model, handles=[handle])


def drawer(pid, name, depth, width, h, z, handle_id, color=WHITE):
    front = box(0.02, width - 0.01, h - 0.01, 0, 0, 0, color=color, name="face")
    tray = [box(depth - 0.06, width - 0.06, 0.012, -(depth - 0.06) / 2 - 0.01, 0, -h / 2 + 0.03, color=color),
            box(depth - 0.06, 0.012, h * 0.6, -(depth - 0.06) / 2 - 0.01, width / 2 - 0.04, -h / 2 + h * 0.3 + 0.03, color=color),
            box(depth - 0.06, 0.012, h * 0.6, -(depth - 0.06) / 2 - 0.01, -width / 2 + 0.04, -h / 2 + h * 0.3 + 0.03, color=color)]
    joint = Joint("prismatic", origin=Pose(depth / 2 + 0.012, 0, z), axis=(1.0, 0.0, 0.0),
                  lower=0.0, upper=depth * 0.8, state=0.0)
    handle = Handle(handle_id, Pose(0.01 + 0.03, 0, h * 0.2, -math.pi / 2, 0, 0), radius=0.007,
                    length=width * 0.45, standoff=0.03)
    return Part(pid, "drawer", joint, name=name, model=Model([front, *tray]), handles=[handle])


def knob(kid, y, z, n_states, state_index=0):
    step = math.radians(270.0 / (n_states - 1))
    names = ["off"] + [str(i) for i in range(1, n_states)]
    states = [KnobState(nm, -i * step) for i, nm in enumerate(names)]  # clockwise from the front
    pose = Pose(0, y, z, _KNOB_ROT.roll, _KNOB_ROT.pitch, _KNOB_ROT.yaw)
    return Knob(kid, pose, states, names[state_index], angle=states[state_index].angle,
                radius=0.022, depth=0.022)


def cupboard():
    D, W, H = 0.5, 0.9, 0.9
    parts = [hinged_door("cupboard_door_left", "left cupboard door", D, W / 2, H - 0.1, 0.08, +1,
                         "cupboard_handle_left"),
             hinged_door("cupboard_door_right", "right cupboard door", D, W / 2, H - 0.1, 0.08, -1,
                         "cupboard_handle_right")]
    # Each door covers half the front: shift hinge origins to the cupboard's outer edges.
    parts[0].joint.origin = Pose(D / 2 + 0.012, W / 2, 0.08)
    parts[0].model = Model([box(0.02, W / 2 - 0.006, H - 0.1, 0, -(W / 2 - 0.006) / 2, (H - 0.1) / 2, name="face")])
    parts[0].handles[0].pose = Pose(0.01 + 0.035, -(W / 2 - 0.06), 0.55)
    parts[1].joint.origin = Pose(D / 2 + 0.012, -W / 2, 0.08)
    parts[1].model = Model([box(0.02, W / 2 - 0.006, H - 0.1, 0, (W / 2 - 0.006) / 2, (H - 0.1) / 2, name="face")])
    parts[1].handles[0].pose = Pose(0.01 + 0.035, W / 2 - 0.06, 0.55)
    return LargeArticulatedObject(
        id="cupboard", type="cupboard", name="cupboard", pose=Pose(5.72, 1.6, 0, 0, 0, math.pi),
        model=Model(carcass(D, W, H, shelves=(0.45,))), parking=front_parking("cupboard", D),
        default_parking="cupboard_front", affordances=["container", "openable"],
        surfaces=[Surface("shelf_low", Pose(0, 0, 0.08), D - 0.04, W - 0.04, "in"),
                  Surface("shelf_mid", Pose(0, 0, 0.459), D - 0.04, W - 0.04, "in")],
        parts=parts,
        children=[small("glass_jar", "jar", "clear", [cyl(0.045, 0.14, 0, 0, 0.07, color=(0.8, 0.85, 0.85), material="glass")],
                        0.0, 0.15, 0.459, "cupboard", "in", "glass jar")])


def drawer_unit():
    D, W, H = 0.5, 0.5, 0.85
    parts = [drawer(f"drawer_{i}", f"{nm} drawer", D, W, 0.24, 0.2 + i * 0.25, f"drawer_{i}_handle")
             for i, nm in enumerate(("bottom", "middle", "top"))]
    return LargeArticulatedObject(
        id="drawer_unit", type="drawers", name="drawer unit", pose=Pose(5.72, 2.6, 0, 0, 0, math.pi),
        model=Model(carcass(D, W, H)), parking=front_parking("drawer_unit", D, spread=0.3),
        default_parking="drawer_unit_front", affordances=["container", "openable"], parts=parts)


def fridge():
    D, W, H = 0.6, 0.6, 1.75
    door = hinged_door("fridge_door", "fridge door", D, W, H - 0.1, 0.05, +1, "fridge_handle",
                       color=STEEL)
    door.handles[0].pose = Pose(0.01 + 0.04, -(W - 0.07), 0.95)
    door.handles[0].length = 0.35
    door.handles[0].standoff = 0.04
    door.handles[0].radius = 0.011
    return LargeArticulatedObject(
        id="fridge", type="fridge", name="fridge", pose=Pose(0.9, 4.68, 0, 0, 0, -math.pi / 2),
        model=Model(carcass(D, W, H, color=STEEL, shelves=(0.6, 1.0, 1.35))),
        parking=front_parking("fridge", D), default_parking="fridge_front",
        affordances=["container", "openable"], parts=[door])


def oven():
    D, W, H = 0.6, 0.6, 0.9
    body = carcass(D, W, H, color=STEEL, shelves=(0.35,))
    body.append(box(0.02, W, 0.14, D / 2 - 0.01, 0, H - 0.09, color=DARK, name="panel"))
    body.append(box(D, W, 0.03, 0, 0, H + 0.015, color=DARK, name="hob"))
    door_h = 0.6
    door = Part("oven_door", "door",
                Joint("revolute", origin=Pose(D / 2 + 0.012, 0, 0.1), axis=(0.0, 1.0, 0.0),
                      lower=0.0, upper=math.radians(90), state=0.0),
                name="oven door",
                model=Model([box(0.02, W - 0.01, door_h, 0, 0, door_h / 2, color=DARK,
                                 material="shiny", name="face")]),
                handles=[Handle("oven_handle", Pose(0.01 + 0.035, 0, door_h - 0.06, -math.pi / 2, 0, 0),
                                radius=0.01, length=0.45, standoff=0.035)])
    n_states = (6, 7, 8, 9)
    knobs = [knob(f"oven_knob_{i + 1}", y, H - 0.09, n) for i, (y, n) in
             enumerate(zip((0.21, 0.07, -0.07, -0.21), n_states))]
    for k in knobs:
        k.pose = Pose(D / 2, k.pose.y, k.pose.z, k.pose.roll, k.pose.pitch, k.pose.yaw)
    return LargeArticulatedObject(
        id="oven", type="oven", name="oven", pose=Pose(3.0, 4.68, 0, 0, 0, -math.pi / 2),
        model=Model(body), parking=front_parking("oven", D, dist=0.6, spread=0.25),
        default_parking="oven_front", affordances=["appliance", "openable"], parts=[door],
        knobs=knobs)


def bathroom_cabinet():
    D, W, H = 0.35, 0.6, 0.7
    door = hinged_door("cabinet_door", "cabinet door", D, W, H - 0.04, 0.02, -1, "cabinet_handle")
    body = carcass(D, W, H, shelves=(0.35,))
    body = [v for v in body if v.name != "plinth"]
    return LargeArticulatedObject(
        id="bathroom_cabinet", type="cabinet", name="bathroom cabinet",
        pose=Pose(8.8, 1.5, 0.9, 0, 0, math.pi), model=Model(body),
        parking=front_parking("bathroom_cabinet", D, dist=0.6, spread=0.25),
        default_parking="bathroom_cabinet_front", affordances=["container", "openable"],
        surfaces=[Surface("shelf", Pose(0, 0, 0.359), D - 0.04, W - 0.04, "in")], parts=[door],
        children=[small("pill_box", "pill box", "white",
                        [box(0.06, 0.1, 0.03, 0, 0, 0.015, color=(0.95, 0.95, 0.97), name="body"),
                         box(0.062, 0.04, 0.002, 0, 0, 0.031, color=(0.85, 0.1, 0.1), name="label")],
                        0.0, 0.05, 0.359, "bathroom_cabinet", "in", "weekly pill box")])


def build() -> Apartment:
    top = 0.75
    kitchen_table = table(
        "kitchen_table", "kitchen table", 3.0, 2.2, 1.2, 0.8, top,
        children=[cup("red_cup", "red", (0.8, 0.1, 0.1), -0.35, 0.15, top, "kitchen_table"),
                  small("bowl", "bowl", "white", [cyl(0.08, 0.06, 0, 0, 0.03, color=WHITE, name="body")],
                        0.1, 0.2, top, "kitchen_table", description="soup bowl"),
                  small("sugar", "sugar container", "yellow",
                        [box(0.08, 0.08, 0.12, 0, 0, 0.06, color=(0.95, 0.8, 0.2), name="body")],
                        0.35, -0.2, top, "kitchen_table", description="sugar jar"),
                  cup("blue_cup", "blue", (0.1, 0.2, 0.8), -0.1, -0.2, top, "kitchen_table")])
    side_table = table("side_table", "side table", 1.4, 1.3, 0.8, 0.6, 0.72, color=(0.45, 0.3, 0.2))
    # Where go_to_rest rests (hearth/worldmodel/rest.py): by the side table while the user
    # is at home, by the kitchen table while they are out.
    side_table.affordances.append("rest")
    kitchen_table.affordances.append("rest_away")
    chair = LargeObject(
        id="chair", type="chair", name="kitchen chair", pose=Pose(3.9, 2.2, 0, 0, 0, math.pi),
        static=False,
        model=Model([box(0.42, 0.42, 0.03, 0, 0, 0.45, color=WOOD),
                     box(0.03, 0.42, 0.45, -0.2, 0, 0.7, color=WOOD),
                     *[box(0.03, 0.03, 0.44, sx * 0.18, sy * 0.18, 0.22, color=WOOD)
                       for sx in (-1, 1) for sy in (-1, 1)]]),
        parking=[ParkingPosition("chair_back", Pose(-0.75, 0, 0, 0, 0, 0.0))],
        default_parking="chair_back", affordances=["seat"])
    kitchen = Room("kitchen", "kitchen", bounds=(0.0, 0.0, 6.0, 5.0),
                   switches=[Switch("kitchen_light", "rotational", Pose(0.05, 2.5, 1.2, 0, 0, 0),
                                    name="kitchen light")],
                   # in the free south-east corner, facing into the room; the robot docks
                   # backed onto it, 0.4 m out
                   chargers=[Charger("charger", Pose(5.95, 0.5, 0, 0, 0, math.pi),
                                     Pose.planar(0.4, 0.0, 0.0), name="charging station")],
                   objects=[kitchen_table, side_table, chair, cupboard(), drawer_unit(), fridge(),
                            oven()])
    counter = table("bathroom_counter", "bathroom counter", 7.2, 0.3, 0.9, 0.5, 0.85,
                    color=(0.85, 0.85, 0.85), sides=("north",))
    bathroom = Room("bathroom", "bathroom", bounds=(6.2, 0.0, 9.0, 3.0),
                    switches=[Switch("bathroom_light", "prismatic", Pose(6.25, 2.5, 1.2),
                                     name="bathroom light")],
                    objects=[bathroom_cabinet(), counter])
    return Apartment(id="demo_home", name="Hearth demo home", rooms=[kitchen, bathroom])


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    out = Path(argv[0] if argv else Path(__file__).resolve().parents[1] / "data/demo_home/world.xml")
    atomic_write(out, to_xml(build()))
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
