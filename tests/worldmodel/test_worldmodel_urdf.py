"""URDF import: malformed joints and values are errors with file and line; mesh scales are
honoured per axis, and the world format still reads a single scale."""
from __future__ import annotations

import numpy as np
import pytest

from hearth.worldmodel import (
    LargeObject, Model, ParkingPosition, Pose, Visual, WorldError, load_world, save_world,
)
from hearth.worldmodel.urdf import import_urdf

TEMPLATE = """<?xml version="1.0"?>
<robot name="cab">
  <link name="body">
    <visual><geometry><box size="0.4 0.6 0.8"/></geometry></visual>
  </link>
  <link name="door">
    <visual><geometry>{door_geometry}</geometry></visual>
  </link>
  <joint name="door_hinge" type="revolute">
{joint_body}
    <origin xyz="0.2 0.3 0.4"/>
    <limit lower="0" upper="1.6"/>
  </joint>
</robot>
"""
GOOD_JOINT = '    <parent link="body"/>\n    <child link="door"/>'
BOX = '<box size="0.02 0.6 0.8"/>'


def urdf_file(tmp_path, joint_body=GOOD_JOINT, door_geometry=BOX):
    path = tmp_path / "cab.urdf"
    path.write_text(TEMPLATE.format(joint_body=joint_body, door_geometry=door_geometry))
    return path


def line_of(path, text: str) -> int:
    return next(i for i, line in enumerate(path.read_text().splitlines(), 1) if text in line)


def test_a_good_urdf_still_imports(tmp_path):
    obj = import_urdf(urdf_file(tmp_path), "cab")
    assert [p.id for p in obj.parts] == ["door"]
    assert obj.parts[0].joint.origin.x == pytest.approx(0.2)


def test_a_joint_without_a_child_is_an_error_at_the_joint(tmp_path):
    path = urdf_file(tmp_path, joint_body='    <parent link="body"/>')
    with pytest.raises(WorldError) as err:
        import_urdf(path, "cab")
    assert str(err.value) == (f"{path}:{line_of(path, '<joint')}: bad URDF: joint 'door_hinge' "
                              f'needs <child link="..."/>')


def test_a_joint_without_a_parent_is_an_error_at_the_joint(tmp_path):
    path = urdf_file(tmp_path, joint_body='    <child link="door"/>')
    with pytest.raises(WorldError) as err:
        import_urdf(path, "cab")
    assert str(err.value).startswith(f"{path}:{line_of(path, '<joint')}: bad URDF: joint "
                                     f"'door_hinge' needs <parent")


def test_a_child_element_without_a_link_is_an_error_at_that_element(tmp_path):
    path = urdf_file(tmp_path, joint_body='    <parent link="body"/>\n    <child/>')
    with pytest.raises(WorldError) as err:
        import_urdf(path, "cab")
    assert str(err.value).startswith(f"{path}:{line_of(path, '<child/>')}: bad URDF: ")


def test_a_link_with_two_parent_joints_is_refused(tmp_path):
    path = tmp_path / "loop.urdf"
    path.write_text("""<robot name="loop">
  <link name="base"/><link name="a"/><link name="b"/>
  <joint name="j1" type="fixed"><parent link="base"/><child link="a"/></joint>
  <joint name="j2" type="fixed"><parent link="a"/><child link="b"/></joint>
  <joint name="j3" type="fixed"><parent link="b"/><child link="a"/></joint>
</robot>
""")
    with pytest.raises(WorldError, match=r"loop.urdf:5: bad URDF: link 'a' is the child of two joints"):
        import_urdf(path, "loop")


@pytest.mark.parametrize("geometry, attr", [('<cylinder radius="wide" length="0.1"/>', "radius"),
                                            ('<cylinder radius="0.1"/>', "length"),
                                            ('<box size="0.1 0.2"/>', "size")])
def test_a_bad_number_is_an_error_at_its_element(tmp_path, geometry, attr):
    path = urdf_file(tmp_path, door_geometry=geometry)
    with pytest.raises(WorldError) as err:
        import_urdf(path, "cab")
    line = line_of(path, geometry)
    assert str(err.value).startswith(f"{path}:{line}: bad URDF: ") and attr in str(err.value)


def test_a_mesh_scale_is_kept_per_axis(tmp_path):
    path = urdf_file(tmp_path, door_geometry='<mesh filename="package://cab/door.ply" scale="1 2 3"/>')
    door = import_urdf(path, "cab").parts[0].model.visuals[0]
    assert (door.file, door.scale) == ("door.ply", (1.0, 2.0, 3.0))
    with pytest.raises(WorldError, match="scale must be positive"):
        import_urdf(urdf_file(tmp_path, door_geometry='<mesh filename="d.ply" scale="1 0 1"/>'), "cab")


def crate(object_id, visuals):
    return LargeObject(object_id, "crate", Pose(0.5, 0.5, 0), model=Model(visuals),
                       parking=[ParkingPosition(f"{object_id}_front", Pose(1.2, 0.5, 0))],
                       default_parking=f"{object_id}_front")


def _unit_box_ply(directory):
    import open3d as o3d
    box = o3d.geometry.TriangleMesh.create_box(1.0, 1.0, 1.0)
    box.compute_vertex_normals()
    o3d.io.write_triangle_mesh(str(directory / "box.ply"), box)
    return "box.ply"


def test_a_per_axis_scale_stretches_the_mesh_and_survives_save_and_load(demo_world, tmp_path):
    from hearth.worldmodel.geometry import visual_mesh
    mesh_file = _unit_box_ply(tmp_path)
    stretched = Visual("mesh", file=mesh_file, scale=(1.0, 2.0, 3.0))
    m = visual_mesh(stretched, tmp_path)
    assert np.allclose(m.get_max_bound() - m.get_min_bound(), (1.0, 2.0, 3.0))
    assert np.allclose(np.linalg.norm(np.asarray(m.vertex_normals), axis=1), 1.0)
    uniform = visual_mesh(Visual("mesh", file=mesh_file, scale=0.5), tmp_path)
    assert np.allclose(uniform.get_max_bound() - uniform.get_min_bound(), (0.5, 0.5, 0.5))

    room = demo_world.apartment.rooms[0]
    room.objects.append(crate("stretched", [stretched, Visual("mesh", file=mesh_file, scale=2.0)]))
    save_world(demo_world, tmp_path / "w.xml")
    text = (tmp_path / "w.xml").read_text()
    assert 'scale="1 2 3"' in text and 'scale="2"' in text      # uniform: one number, as before
    again = load_world(tmp_path / "w.xml").get("stretched").model.visuals
    assert [v.scale for v in again] == [(1.0, 2.0, 3.0), (2.0, 2.0, 2.0)]


def test_a_world_file_scale_needs_one_or_three_positive_numbers(demo_world, tmp_path):
    room = demo_world.apartment.rooms[0]
    room.objects.append(crate("crate", [Visual("mesh", file=_unit_box_ply(tmp_path), scale=2.0)]))
    demo_world.base_dir = tmp_path        # meshes live next to the world file (issue 19)
    save_world(demo_world, tmp_path / "w.xml")
    text = (tmp_path / "w.xml").read_text()
    line = next(i for i, l in enumerate(text.splitlines(), 1) if 'scale="2"' in l)
    for bad in ("1 2", "0", "-1 1 1"):
        (tmp_path / "bad.xml").write_text(text.replace('scale="2"', f'scale="{bad}"'))
        with pytest.raises(WorldError) as err:
            load_world(tmp_path / "bad.xml")
        assert str(err.value).startswith(f"{tmp_path / 'bad.xml'}:{line}: "), str(err.value)
