"""hydrogen.urdf: the URDF reader (links' inertials; joints' type, parent, child, origin, axis,
limit, mimic), strict and without entity expansion, giving the data yourdfpy gave; and how a
description reads a URDF through it (hydrogen.model): the sub-tree [tree] keeps is all that is
checked, placeholder inertias are massless frames, fixed joints can be dropped."""
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


# --- a sub-tree of a URDF (hydrogen.model) ------------------------------------------------------

# A leg on a trunk, as exported: the leg is kept ([tree] base = "hip"); what is outside it has a
# broken inertia (arm) or an all-zero one (imu); the foot carries the exporters' placeholder (every
# entry 1e-6), the tip an all-zero one with a milligram mass; the camera an all-zero inertia with a
# real mass (it enters the dynamics unless dropped).
_TRUNK = """<?xml version="1.0"?>
<robot name="leggy">
  <link name="trunk"><inertial><mass value="30"/><inertia ixx="1" ixy="0" ixz="0" iyy="2" iyz="0" izz="2"/></inertial></link>
  <link name="imu"><inertial><mass value="0.05"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <link name="arm"><inertial><mass value="4"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="5"/></inertial></link>
  <link name="hip"><inertial><origin xyz="0 0 0.1"/><mass value="3"/><inertia ixx="0.05" ixy="0" ixz="0" iyy="0.05" iyz="0" izz="0.01"/></inertial></link>
  <link name="thigh"><inertial><origin xyz="0.15 -0.02 0.01" rpy="0.2 -0.1 0.3"/><mass value="2.5"/>
    <inertia ixx="0.004" ixy="-0.003" ixz="0.0001" iyy="0.027" iyz="2e-05" izz="0.028"/></inertial></link>
  <link name="shank"><inertial><origin xyz="0.12 0 -0.01"/><mass value="0.9"/><inertia ixx="0.0005" ixy="6e-05" ixz="0" iyy="0.0125" iyz="0" izz="0.0123"/></inertial></link>
  <link name="foot"><inertial><mass value="1e-6"/><inertia ixx="1e-6" ixy="1e-6" ixz="1e-6" iyy="1e-6" iyz="1e-6" izz="1e-6"/></inertial></link>
  <link name="tip"><inertial><mass value="2e-4"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  {camera}
  <joint name="imu_joint" type="fixed"><parent link="trunk"/><child link="imu"/><origin xyz="0 0 0.1"/></joint>
  <joint name="arm_joint" type="revolute"><parent link="trunk"/><child link="arm"/><origin xyz="0.4 0 0.2"/><axis xyz="0 1 0"/><limit lower="-1" upper="1" effort="100" velocity="5"/></joint>
  <joint name="haa" type="revolute"><parent link="trunk"/><child link="hip"/><origin xyz="0.37 0.2 0" rpy="0 1.5708 3.1416"/><axis xyz="0 0 1"/><limit lower="-1.2" upper="0.4" effort="150" velocity="12"/></joint>
  <joint name="hfe" type="revolute"><parent link="hip"/><child link="thigh"/><origin xyz="0.08 0 0" rpy="1.5708 0 0.1"/><axis xyz="0 0 1"/><limit lower="-0.8" upper="1.2" effort="150" velocity="12"/></joint>
  <joint name="kfe" type="revolute"><parent link="thigh"/><child link="shank"/><origin xyz="0.35 0 0" rpy="0 0.05 0"/><axis xyz="0 0 1"/><limit lower="-2.4" upper="-0.3" effort="150" velocity="12"/></joint>
  <joint name="foot_joint" type="fixed"><parent link="shank"/><child link="foot"/><origin xyz="0.35 0 0" rpy="1.5708 0 -1.5708"/></joint>
  <joint name="tip_joint" type="fixed"><parent link="foot"/><child link="tip"/><origin xyz="0 0 0.02"/></joint>
</robot>
"""
_CAMERA = """<link name="camera"><inertial><mass value="0.4"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <joint name="camera_joint" type="fixed"><parent link="shank"/><child link="camera"/><origin xyz="0.1 0 0.03" rpy="0 0.3 0"/></joint>"""
_LEG_TOML = """
name = "leg"
gravity = 9.81
urdf = "leggy.urdf"
[tree]
base = "hip"
drop = ["camera_joint"]
[coordinates]
neutral = [0.2, -1.0]
[hydraulics]
piston_area = 2e-4
rod_area = 1e-4
chamber_length = 0.01
supply_pressure = 2e7
underlap = 1e-5
flow_gain = 1e-5
bulk_modulus = 1e9
orifice_linear_below = 5e4
stroke = [0.05, 1.0]
[[cylinders]]
name = "hfe_cyl"
from = { link = "hip", point = [0.0, 0.1, 0.1] }
to = { link = "thigh", point = [0.2, 0.0, 0.05] }
[[cylinders]]
name = "kfe_cyl"
from = { link = "thigh", point = [0.1, 0.0, 0.1] }
to = { link = "shank", point = [0.15, 0.0, 0.0] }
[adaptation]
parameters = ["thigh.mcx"]
theta_min = [0.1]
theta_max = [1.2]
gamma1_min = 1e8
gamma1_max = 5e9
gamma2_min = 1e2
gamma2_max = 1e5
"""


def _leg(tmp_path, toml=_LEG_TOML, camera=_CAMERA):
    _write(tmp_path, _TRUNK.format(camera=camera), "leggy.urdf")
    return _write(tmp_path, toml, "leg.toml")


def _load_with_notes(path):
    import warnings

    import hydrogen
    from hydrogen.errors import DescriptionNote
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        model = hydrogen.load_model(path)
    return model, [str(w.message) for w in caught if issubclass(w.category, DescriptionNote)]


def test_only_the_selected_sub_tree_is_checked_and_placeholders_are_frames(tmp_path):
    model, notes = _load_with_notes(_leg(tmp_path))
    assert model.root == "hip" and model.coordinate_names == ("hfe", "kfe")
    masses = {lk.name: lk.mass for lk in model.links}
    assert masses == {"thigh": 2.5, "shank": 0.9, "foot": 0.0, "tip": 0.0}  # no arm, imu, trunk, camera
    for link in ("foot", "tip"):
        assert any(f"link '{link}' has a placeholder inertial" in n and "leggy.urdf" in n for n in notes), notes
    assert any("left out" in n and "'arm'" in n and "'trunk'" in n for n in notes), notes
    assert any("drop" in n and "['camera']" in n for n in notes), notes
    # the camera's whole sub-tree left out: the model is the one of the file without it
    same = _load_with_notes(_leg(tmp_path, _LEG_TOML.replace('drop = ["camera_joint"]', ""), camera=""))[0]
    assert [(lk.name, lk.mass) for lk in same.links] == [(lk.name, lk.mass) for lk in model.links]
    assert [j.name for j in same.joints] == [j.name for j in model.joints]


def test_the_whole_file_is_checked_when_no_sub_tree_is_selected(tmp_path):
    toml = _LEG_TOML.replace('base = "hip"', "").replace('drop = ["camera_joint"]', 'drop = ["camera_joint"]\n'
                                                                                   'locked = { haa = 0.0 }')
    with pytest.raises(ModelError) as exc:
        _load_with_notes(_leg(tmp_path, toml))
    assert str(tmp_path / "leggy.urdf") in str(exc.value) and "link 'arm' inertia" in str(exc.value)
    assert "I1 + I2 >= I3" in str(exc.value) and "moves with joint 'arm_joint'" in str(exc.value)


@pytest.mark.parametrize("old, new, words", [
    # a link that enters the dynamics: a placeholder's inertia with a real mass, or a real mass with
    # an all-zero inertia (the camera, kept)
    ('<mass value="2.5"/>\n    <inertia ixx="0.004" ixy="-0.003" ixz="0.0001" iyy="0.027" iyz="2e-05" izz="0.028"/>',
     '<mass value="2.5"/><inertia ixx="1e-6" ixy="1e-6" ixz="1e-6" iyy="1e-6" iyz="1e-6" izz="1e-6"/>',
     ["link 'thigh' inertia", "positive definite", "moves with joint 'hfe'", "[tree] drop"]),
    ('drop = ["camera_joint"]', "", ["link 'camera' inertia", "positive definite", "moves with joint 'kfe'"]),
    # a tiny mass with a real body's inertia is no placeholder: refused by the range of masses
    ('<mass value="1e-6"/><inertia ixx="1e-6" ixy="1e-6" ixz="1e-6" iyy="1e-6" iyz="1e-6" izz="1e-6"/>',
     '<mass value="1e-9"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/>',
     ["link 'foot' <inertial><mass value>", "plausible range"]),
])
def test_a_bad_inertia_that_enters_the_dynamics_is_refused(tmp_path, old, new, words):
    text = _TRUNK.format(camera=_CAMERA)
    toml = _LEG_TOML
    if old in toml:
        toml = toml.replace(old, new)
    else:
        assert old in text
        text = text.replace(old, new)
    _write(tmp_path, text, "leggy.urdf")
    with pytest.raises(ModelError) as exc:
        _load_with_notes(_write(tmp_path, toml, "leg.toml"))
    msg = str(exc.value)
    assert msg.startswith(str(tmp_path / "leggy.urdf")) and "\n" not in msg
    for w in words:
        assert w in msg, msg


@pytest.mark.parametrize("drop, words", [
    ('["kfe"]', "joint 'kfe' is revolute: only a fixed joint can be dropped"),
    ('["camera"]', "no joint 'camera' in the tree kept"),
    ('["imu_joint"]', "no joint 'imu_joint' in the tree kept"),  # above the base: left out already
    ('"camera_joint"', "expected a list of joint names"),
])
def test_only_a_fixed_joint_of_the_kept_tree_can_be_dropped(tmp_path, drop, words):
    path = _leg(tmp_path, _LEG_TOML.replace('drop = ["camera_joint"]', f"drop = {drop}"))
    with pytest.raises(ModelError) as exc:
        _load_with_notes(path)
    assert str(exc.value).startswith(f"{path}: [tree] drop: ") and words in str(exc.value), str(exc.value)
    assert "fixed joints: camera_joint, foot_joint, tip_joint" in str(exc.value) or "expected" in words


def test_the_sub_tree_has_pinocchios_mass_matrix(tmp_path, rng):
    """D of the kept leg against Pinocchio's on the same file, every joint outside the leg locked:
    equal to round-off with the placeholders' masses made 0 in Pinocchio's file, and within what
    hydrogen's massless placeholders may change (PLACEHOLDER_MASS r² + 3 PLACEHOLDER_INERTIA) of
    Pinocchio's on the file as it is."""
    pin = pytest.importorskip("pinocchio")
    from hydrogen.codegen.casadi_functions import to_casadi_function
    from hydrogen.model import PLACEHOLDER_INERTIA, PLACEHOLDER_MASS
    from hydrogen.symbolic.functions import rigid_body_functions

    model, _ = _load_with_notes(_leg(tmp_path, _LEG_TOML.replace('drop = ["camera_joint"]', ""), camera=""))
    D = next(to_casadi_function(f) for f in rigid_body_functions(model) if f.name == "mass_matrix")
    as_is = tmp_path / "leggy.urdf"
    frames = as_is.read_text().replace('<mass value="1e-6"/>', '<mass value="0"/>').replace('"1e-6"', '"0"')
    frames = _write(tmp_path, frames.replace('<mass value="2e-4"/>', '<mass value="0"/>'), "frames.urdf")
    bound = 1e-6 * 0.8 ** 2 + 2e-4 * 0.8 ** 2 + 3 * 1e-6  # the foot's and tip's, within 0.8 m of a joint axis
    assert bound < PLACEHOLDER_MASS * 0.8 ** 2 + 3 * PLACEHOLDER_INERTIA
    for path, atol in ((frames, 1e-12), (as_is, bound)):
        full = pin.buildModelFromUrdf(str(path))
        outside = [full.getJointId(n) for n in ("haa", "arm_joint")]
        for _ in range(5):
            q_full = pin.randomConfiguration(full)
            leg = pin.buildReducedModel(full, outside, q_full)
            assert list(leg.names)[1:] == ["hfe", "kfe"]
            q = q_full[[full.joints[full.getJointId(n)].idx_q for n in ("hfe", "kfe")]]
            M = pin.crba(leg, leg.createData(), q)
            M = np.triu(M) + np.triu(M, 1).T
            np.testing.assert_allclose(np.asarray(D(q, model.theta)), M, rtol=0, atol=atol)


def test_drop_takes_a_fixed_joint_of_a_toml_tree_too(tmp_path):
    from hydrogen.model import default_model_path
    text = default_model_path().read_text().replace(
        "[coordinates]", '[[links]]\nname = "tool"\nmass = 1.0\ninertia = [1.0, 1.0, 1.0]\n\n'
                         '[[joints]]\nname = "tool_mount"\ntype = "fixed"\nparent = "platform"\nchild = "tool"\n\n'
                         "[coordinates]")
    with_tool = _load_with_notes(_write(tmp_path, text, "tool.toml"))[0]
    model, notes = _load_with_notes(_write(tmp_path, text + '\n[tree]\ndrop = ["tool_mount"]\n', "drop.toml"))
    plain = _load_with_notes(default_model_path())[0]
    assert [lk.name for lk in with_tool.links] == ["platform", "tool"]
    assert [(lk.name, lk.mass) for lk in model.links] == [(lk.name, lk.mass) for lk in plain.links]
    assert [j.name for j in model.joints] == [j.name for j in plain.joints]
    assert any("['tool'] are left out" in n for n in notes), notes
