"""hydrogen.urdf: the URDF reader (links' inertials; joints' type, parent, child, origin, axis,
limit, mimic), strict and without entity expansion, giving the data yourdfpy gave."""
from __future__ import annotations

import numpy as np
import pytest

from hydrogen.errors import ModelError
from hydrogen.urdf import load_robot, origin_matrix

URDF = """<?xml version="1.0"?>
<robot name="two">
  <link name="base"/>
  <link name="arm">
    <inertial>
      <origin xyz="0.5 0 0.02" rpy="0.1 -0.2 0.3"/>
      <mass value="100"/>
      <inertia ixx="1" ixy="0.1" ixz="0" iyy="2" iyz="0.05" izz="3"/>
    </inertial>
    <visual><geometry><mesh filename="package://nowhere/arm.stl"/></geometry></visual>
  </link>
  <link name="tip"><inertial><mass value="5"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <joint name="j1" type="revolute">
    <parent link="base"/><child link="arm"/>
    <origin xyz="0 0 1" rpy="0.123456789012345678 0.5 -1.25"/>
    <axis xyz="0 -1 0"/>
    <limit lower="-1" upper="1.5" effort="1000" velocity="2"/>
  </joint>
  <joint name="j2" type="continuous">
    <parent link="arm"/><child link="tip"/>
    <origin xyz="1 0 0"/>
    <mimic joint="j1" multiplier="2" offset="0.1"/>
  </joint>
</robot>
"""


def _write(tmp_path, text, name="r.urdf"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_origin_is_urdfs_fixed_axis_roll_pitch_yaw():
    from scipy.spatial.transform import Rotation
    rng = np.random.default_rng(0)
    for _ in range(20):
        xyz, rpy = rng.normal(size=3), rng.uniform(-3, 3, 3)
        T = origin_matrix(xyz, rpy)
        np.testing.assert_allclose(T[:3, :3], Rotation.from_euler("xyz", rpy).as_matrix(), atol=1e-14)
        np.testing.assert_array_equal(T[:3, 3], xyz)


def test_reads_what_hydrogen_needs(tmp_path):
    robot = load_robot(_write(tmp_path, URDF))
    assert [lk.name for lk in robot.links] == ["base", "arm", "tip"]
    assert robot.links[0].inertial is None
    arm = robot.links[1].inertial
    assert arm.mass == 100.0
    np.testing.assert_array_equal(arm.inertia, [[1, 0.1, 0], [0.1, 2, 0.05], [0, 0.05, 3]])
    np.testing.assert_allclose(arm.origin, origin_matrix((0.5, 0, 0.02), (0.1, -0.2, 0.3)))
    assert robot.links[2].inertial.origin is None
    j1, j2 = robot.joints
    assert (j1.type, j1.parent, j1.child) == ("revolute", "base", "arm")
    np.testing.assert_array_equal(j1.axis, [0, -1, 0])
    # full precision of the text: the rpy is read as Python reads the float
    np.testing.assert_array_equal(j1.origin, origin_matrix((0, 0, 1), (float("0.123456789012345678"), 0.5, -1.25)))
    assert (j1.limit.lower, j1.limit.upper, j1.limit.effort, j1.limit.velocity) == (-1, 1.5, 1000, 2)
    assert j2.axis is None and j2.limit is None
    assert (j2.mimic.joint, j2.mimic.multiplier, j2.mimic.offset) == ("j1", 2.0, 0.1)


def test_gives_the_data_yourdfpy_gave(tmp_path):
    yourdfpy = pytest.importorskip("yourdfpy")
    path = _write(tmp_path, URDF)
    mine = load_robot(path)
    ref = yourdfpy.URDF.load(str(path), build_scene_graph=False, load_meshes=False,
                             build_collision_scene_graph=False, load_collision_meshes=False).robot
    for a, b in zip(mine.links, ref.links):
        assert a.name == b.name and (a.inertial is None) == (b.inertial is None)
        if a.inertial is not None:
            assert a.inertial.mass == b.inertial.mass
            np.testing.assert_allclose(a.inertial.inertia, b.inertial.inertia, rtol=0, atol=0)
            eye = lambda T: np.eye(4) if T is None else np.asarray(T, float)  # noqa: E731 - absent: identity
            np.testing.assert_allclose(eye(a.inertial.origin), eye(b.inertial.origin), atol=1e-15)
    for a, b in zip(mine.joints, ref.joints):
        assert (a.name, a.type, a.parent, a.child) == (b.name, b.type, b.parent, b.child)
        np.testing.assert_allclose(a.origin, b.origin, atol=1e-15)
        if b.mimic is not None:
            assert (a.mimic.joint, a.mimic.multiplier, a.mimic.offset) == (b.mimic.joint, b.mimic.multiplier,
                                                                           b.mimic.offset)


def test_shipped_urdf_model_loads():
    import hydrogen
    model = hydrogen.load_model("excavator_arm")
    assert model.n == 3 and model.coordinate_units == ("rad", "rad", "rad")
    # the reader gives the model the committed C was generated from (same hash: no signed zeros either)
    from hydrogen.codegen.generate import check
    from hydrogen.runtime.build import repo_generated_dir
    assert check(model, repo_generated_dir() / model.name) == []
    assert not np.signbit(origin_matrix((0, 0, 0), (0, 0, 0))).any()


@pytest.mark.parametrize("text, message", [
    ('<robot name="r"><link name="a"><inertial><mass value="heavy"/></inertial></link></robot>',
     "link 'a' <mass>: value='heavy' is not a number"),
    ('<robot name="r"><link name="a"/><joint name="j" type="revolute"><parent link="a"/></joint></robot>',
     "joint 'j': needs <child link="),
    ('<robot name="r"><joint name="j" type="revolute"><parent link="a"/><child link="b"/>'
     '<origin xyz="0 0"/></joint></robot>', "joint 'j' <origin>: xyz='0 0' has 2 numbers, expected 3"),
    ('<robot name="r"><link name="a"></robot>', "URDF does not parse"),
    ('<robt name="r"/>', "root element of a URDF file must be <robot>"),
    ('<?xml version="1.0"?><!DOCTYPE robot [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;">]>'
     '<robot name="&b;"><link name="&b;"/></robot>', "expands no entities"),
])
def test_bad_urdf_gets_one_clear_message(tmp_path, text, message):
    path = _write(tmp_path, text)
    with pytest.raises(ModelError) as exc:
        load_robot(path)
    assert str(path) in str(exc.value) and message in str(exc.value)


def test_missing_file_is_named(tmp_path):
    with pytest.raises(ModelError, match="cannot read URDF file"):
        load_robot(tmp_path / "none.urdf")
