import re
from pathlib import Path

import numpy as np
import pytest

import hydrogen
from hydrogen.errors import ModelError
from hydrogen.model import default_model_path


def test_default_model_has_table_I_values(model):
    assert model.theta.tolist() == [250.0, 45.0, 45.0, 43.0]
    assert model.theta_names == ("platform.mass", "platform.Ixx", "platform.Iyy", "platform.Izz")
    assert model.piston_area == pytest.approx(np.full(6, 1.14e-3))
    assert model.rod_area == pytest.approx(np.full(6, 6.33e-4))
    assert model.chamber_length == pytest.approx(np.full(6, 1.37))
    assert model.supply_pressure == pytest.approx(np.full(6, 1500 * 6894.757), rel=1e-3)
    assert model.underlap == pytest.approx(np.full(6, 55.4e-6))
    assert model.flow_gain == pytest.approx(np.full(6, 1.5e-4), rel=1e-6)  # from its valve's rating
    assert model.bulk_modulus == pytest.approx(np.full(6, 700e6))
    assert model.neutral_pose[2] == pytest.approx(-2.34)
    np.testing.assert_allclose(model.gamma, [[700e6] * 6, [700e6 * 1.5e-4] * 6], rtol=1e-6)
    assert (model.n, model.n_cylinders, model.n_theta) == (6, 6, 4)
    assert model.coordinate_units == ("m",) * 3 + ("rad",) * 3
    assert model.urdf is None


def test_built_in_models_by_name_and_path():
    names = hydrogen.models()
    assert "ubc_stewart" in names
    for name in names:
        by_name = hydrogen.load_model(name)
        assert by_name.name == name
        from hydrogen.model import model_path
        assert hydrogen.load_model(model_path(name)).baked_hash() == by_name.baked_hash()
    assert hydrogen.load_model().name == "ubc_stewart"


def _write_variant(tmp_path, old, new, source=None):
    text = (source or default_model_path()).read_text()
    assert old in text, old
    path = tmp_path / "my.toml"
    path.write_text(text.replace(old, new, 1))
    return path


@pytest.mark.parametrize("old,new,words", [
    ("mass = 250.0", "mass = -250.0", ["[[links]] 'platform' mass", "> 0"]),
    ("mass = 250.0", "mass = 0", ["[[links]] 'platform' mass", "> 0"]),
    ("mass = 250.0", "mass = nan", ["[[links]] 'platform' mass", "finite"]),
    ("mass = 250.0", 'mass = "heavy"', ["[[links]] 'platform' mass", "expected a number"]),
    ("mass = 250.0", "", ["[[links]] 'platform'", "missing key 'mass'"]),
    ("inertia = [45.0, 45.0, 43.0]", "inertia = [45.0, 45.0]", ["[[links]] 'platform' inertia"]),
    ("inertia = [45.0, 45.0, 43.0]", "inertia = [45.0, 0.0, 43.0]", ["inertia", "positive definite"]),
    ("inertia = [45.0, 45.0, 43.0]", "inertia = [45.0, -45.0, 43.0]", ["inertia", "positive definite"]),
    ("inertia = [45.0, 45.0, 43.0]", "inertia = [1.0, 1.0, 43.0]", ["inertia", "I1 + I2 >= I3"]),
    ("stroke = [1.55, 2.15]", "stroke = [2.5, 2.15]", ["stroke", "shortest < longest"]),
    ("stroke = [1.55, 2.15]", "stroke = [1.9, 2.15]", ["'leg1'", "outside its stroke"]),
    ("gamma2_min = 5.0e4", "gamma2_min = 0.0", ["gamma2_min", "> 0"]),
    ("gamma1_min = 3.5e8", "gamma1_min = 2.0e9", ["gamma1_min", "< gamma1_max"]),
    ("name = \"ubc_stewart\"", "name = \"ubc stewart; rm -rf\"", ["name"]),
    ("name = \"ubc_stewart\"", "name = \"_robot\"", ["name"]),
    ("name = \"ubc_stewart\"", "name = \"robot_\"", ["name"]),
    ("name = \"ubc_stewart\"", "name = \"my__robot\"", ["name"]),
    ("name = \"ubc_stewart\"", "name = \"r\u00f6bot\"", ["name"]),
    ("name = \"ubc_stewart\"", f"name = \"{'a' * 300}\"", ["name"]),
    ("[hydraulics]", "[hydraulix]", ["hydraulix"]),
    ("theta_max = [350.0, 65.0, 65.0, 65.0]", "theta_max = [240.0, 65.0, 65.0, 65.0]", ["contain the true"]),
    ("gamma2_max = 2.2e5", "gamma2_max = 1.0e5", ["gamma2", "contain the true"]),
    ('to = { link = "platform", point = [0.434935, -0.483044, 0.15] }',
     'to = { link = "plateau", point = [0.434935, -0.483044, 0.15] }', ["'leg1'", "'plateau' is not in the tree"]),
    ('to = { link = "platform", point = [0.434935, -0.483044, 0.15] }',
     'to = { link = "base", point = [0.434935, -0.483044, 0.15] }', ["'leg1'", "both ends are on link 'base'"]),
    ('type = "floating"', 'type = "planar"', ["platform_pose", "'planar' is not supported"]),
    ('type = "floating"', 'type = "spherical"', ["platform_pose", "'spherical' is not supported"]),
    ('[[cylinders]]\nname = "leg6"', '[[cylinders_unused]]\nname = "leg6"', ["cylinders_unused"]),
    ('parent = "base"', 'parent = "platform"', ["platform_pose", "itself"]),
    ('parameters = ["platform.mass",', 'parameters = ["platform.weight",', ["platform.weight"]),
    # physical quantities outside the plausible range of any hydraulic machine (QUANTITIES)
    ("supply_pressure = 10.34e6", "supply_pressure = 1e308",
     ["[hydraulics] supply_pressure", "1e+308 Pa", "[100000, 1e+08] Pa"]),
    ("supply_pressure = 10.34e6", "supply_pressure = 10.34e3", ["supply_pressure", "10340 Pa", "plausible range"]),
    ("bulk_modulus = 700e6", "bulk_modulus = 7e12", ["[hydraulics] bulk_modulus", "[1e+07, 1e+10] Pa"]),
    ("piston_area = 1.14e-3", "piston_area = 1140.0", ["piston_area", "1140 m^2", "plausible range"]),
    ("rod_area = 6.33e-4", "rod_area = 1e-12", ["rod_area", "plausible range"]),
    ("chamber_length = 1.37", "chamber_length = 1370.0", ["chamber_length", "[0, 100] m"]),
    ("stroke = [1.55, 2.15]", "stroke = [1.55, 2150.0]", ["[hydraulics] stroke", "2150 m", "[1e-05, 100] m"]),
    ("overlap = -0.01108", "overlap = -1.5", ["[hydraulics] valve.overlap", "-1.5", "plausible range"]),
    ("rated_flow = 5.36206e-4", "rated_flow = 15.0", ["valve.rated_flow", "plausible range"]),
    ("orifice_linear_below = 5.0e4", "orifice_linear_below = 5e9", ["orifice_linear_below", "plausible range"]),
    ("gravity = 9.81", "gravity = 98.1", ["gravity", "98.1 m/s^2", "[0, 30] m/s^2"]),
    ("mass = 250.0", "mass = 2.5e9", ["[[links]] 'platform' mass", "2.5e+09 kg", "plausible range"]),
    ("inertia = [45.0, 45.0, 43.0]", "inertia = [45e12, 45e12, 43e12]",
     ["[[links]] 'platform' inertia", "kg m^2", "plausible range"]),
    ("com = [0.0, 0.0, 0.0]", "com = [0.0, 0.0, 1e6]", ["[[links]] 'platform' com", "1e+06 m", "plausible range"]),
    ("point = [0.978148, -0.207912, -0.45]", "point = [0.978148, -0.207912, -4.5e5]",
     ["[[cylinders]] 'leg1' from.point", "plausible range"]),
    # a typo in a gain or scenario table, refused at load time with the known keys
    ("Kleg = 0.011892071150027212", "Kleg = 0.011892071150027212\nKlegg = 1.0",
     ["[gains.p]", "unknown key 'Klegg'", "known: Kleg, u_max"]),
    ("[gains.p]", "[gains.pp]", ["[gains]", "unknown controller table 'pp'", "adaptive-robust", "common"]),
    ("Ktau = 75.0", "Ktau = 75.0\nKtua = 1.0", ["[gains.backstepping]", "'Ktua'", "Ktau"]),
    ('reference.step = { coordinate = "z"', 'duraton = 3.0\nreference.step = { coordinate = "z"',
     ["[scenarios.z-step]", "unknown key 'duraton'", "duration", "reference"]),
    ("[rig]\nduration = 6.0", "[rig]\nduration = 6.0\nnoise_z = 1.0", ["[rig]", "'noise_z'", "noise_p"]),
    ("[rig]\nduration = 6.0", "[rig]\nduration = 6.0\nlabel = 'rig'", ["[rig]", "unknown key 'label'"]),
    ("gains.backstepping = { Lambda = 30.0,", "gains.backstepping = { Lamda = 30.0,",
     ["[scenarios.paper-sim] gains.backstepping", "'Lamda'", "Lambda"]),
    ("gains.backstepping = { Lambda = 30.0,", "gains.common = { Lambda = 30.0,",
     ["[scenarios.paper-sim] gains", "unknown controller table 'common'", "backstepping"]),
    ("gains.backstepping = { Lambda = 30.0,", "gains.backsteping = { Lambda = 30.0,",
     ["[scenarios.paper-sim] gains", "'backsteping'"]),
    ("[scenarios.z-step]", "[scenarios.rig]", ["[scenarios.rig]", "another name"]),
    # a misspelt parent makes a second root, or (the first joint's) a root of another name
    ('parent = "base"', 'parent = "bas"', ["'leg1' from.link", "'base' is not in the tree", "the root 'bas'",
                                           "platform_pose"]),
])
def test_bad_model_files_name_file_and_key(tmp_path, old, new, words):
    path = _write_variant(tmp_path, old, new)
    with pytest.raises(hydrogen.ModelError) as err:
        hydrogen.load_model(path)
    msg = str(err.value)
    assert str(path) in msg
    for w in words:
        assert w in msg
    assert len(msg) < 2000


def test_fewer_cylinders_than_coordinates(tmp_path):
    text = default_model_path().read_text()
    start = text.index('[[cylinders]]\nname = "leg6"')
    end = text.index("[adaptation]")
    path = tmp_path / "five.toml"
    path.write_text(text[:start] + text[end:])
    with pytest.raises(hydrogen.ModelError, match=r"5 cylinders for 6 coordinates"):
        hydrogen.load_model(path)


def test_singular_geometry_all_platform_joints_at_one_point(tmp_path):
    """All six platform joints at one point: rejected at load time, before any code generation."""
    import re
    text = default_model_path().read_text()
    text = re.sub(r'to = \{ link = "platform", point = \[[^\]]*\] \}',
                  'to = { link = "platform", point = [0.0, 0.0, 0.15] }', text)
    path = tmp_path / "point.toml"
    path.write_text(text)
    with pytest.raises(hydrogen.ModelError, match="singular"):
        hydrogen.load_model(path)


def test_tree_with_a_loop_and_a_second_parent(tmp_path):
    loop = tmp_path / "loop.toml"
    loop.write_text(default_model_path().read_text().replace('parent = "base"', 'parent = "platform2"')
                    + '\n[[links]]\nname = "platform2"\nmass = 1.0\ninertia = [1.0, 1.0, 1.0]\n'
                      '[[joints]]\nname = "back"\ntype = "fixed"\nparent = "platform"\nchild = "platform2"\n')
    with pytest.raises(hydrogen.ModelError, match="loop"):
        hydrogen.load_model(loop)


def test_big_values_are_not_quoted_whole(tmp_path):
    big = "[" + ", ".join(["1.0"] * 200000) + "]"
    path = _write_variant(tmp_path, "inertia = [45.0, 45.0, 43.0]", f"inertia = {big}")
    with pytest.raises(hydrogen.ModelError) as err:
        hydrogen.load_model(path)
    assert len(str(err.value)) < 1000


def test_a_urdf_given_as_the_model_says_a_description_must_load_it():
    from hydrogen.model import model_path
    urdf = model_path("excavator_arm").with_suffix(".urdf")
    with pytest.raises(hydrogen.ModelError, match=r"a URDF, not a robot description: write a description TOML "
                                                  r'that loads it \(urdf = "excavator_arm.urdf"\)'):
        hydrogen.load_model(urdf)


def test_malformed_toml(tmp_path):
    path = _write_variant(tmp_path, "mass = 250.0", "mass = = 250.0")
    with pytest.raises(hydrogen.ModelError, match="malformed TOML"):
        hydrogen.load_model(path)


def test_missing_file(tmp_path):
    with pytest.raises(hydrogen.ModelError, match="not found"):
        hydrogen.load_model(tmp_path / "nope.toml")


def test_not_a_model():
    with pytest.raises(hydrogen.ModelError, match="built-in name"):
        hydrogen.load_model(5)


def test_baked_hash_ignores_runtime_parameters(tmp_path, model):
    heavier = hydrogen.load_model(_write_variant(tmp_path, "mass = 250.0", "mass = 300.0"))
    assert heavier.baked_hash() == model.baked_hash()
    assert heavier.theta[0] == 300.0
    moved = hydrogen.load_model(_write_variant(tmp_path, "overlap = -0.01108", "overlap = -0.012"))
    assert moved.underlap[0] == pytest.approx(60e-6) and moved.baked_hash() != model.baked_hash()


@pytest.mark.parametrize("old,new", [
    ('name = "ubc_stewart"', 'name = "__import__(\'os\').system(\'true\')"'),
    ("mass = 250.0", 'mass = "250.0 * 2"'),
    ("gravity = 9.81", 'gravity = "9.81"'),
])
def test_model_text_is_never_evaluated(tmp_path, old, new):
    with pytest.raises(hydrogen.ModelError):
        hydrogen.load_model(_write_variant(tmp_path, old, new))


def test_link_parameters_are_pinocchios_about_the_origin():
    from hydrogen.model import Link
    lk = Link("l", 2.0, np.array([0.1, 0.0, 0.3]), np.diag([1.0, 2.0, 3.0]))
    p = lk.parameters()
    assert (p["mcx"], p["mcy"], p["mcz"]) == pytest.approx((0.2, 0.0, 0.6))
    assert p["Iyy"] == pytest.approx(2.0 + 2.0 * (0.1 ** 2 + 0.3 ** 2))
    assert p["Ixz"] == pytest.approx(-2.0 * 0.1 * 0.3)


def test_figures_nonlinear_controller_is_the_descriptions(tmp_path):
    assert hydrogen.load_model().figures_nonlinear == "adaptive-robust"  # the default: the paper's experiments'
    assert hydrogen.load_model("excavator_arm").figures_nonlinear == "adaptive-robust"
    text = default_model_path().read_text()
    path = tmp_path / "mine.toml"
    path.write_text(text + '\n[figures]\nnonlinear = "adaptive-observer"\n')
    assert hydrogen.load_model(path).figures_nonlinear == "adaptive-observer"
    path.write_text(text + '\n[figures]\ncontroller = "adaptive-observer"\n')
    with pytest.raises(hydrogen.ModelError, match=r"\[figures\]"):
        hydrogen.load_model(path)


def test_a_duplicate_joint_name_is_named(tmp_path):
    path = _write_variant(tmp_path, "[coordinates]",
                          '[[links]]\nname = "tool"\nmass = 1.0\ninertia = [1.0, 1.0, 1.0]\n\n'
                          '[[joints]]\nname = "platform_pose"\ntype = "fixed"\nparent = "platform"\nchild = "tool"\n\n'
                          "[coordinates]")
    with pytest.raises(hydrogen.ModelError, match=r"joint 'platform_pose' is defined twice") as err:
        hydrogen.load_model(path)
    assert str(path) in str(err.value)


def test_a_second_root_names_the_joints_hanging_from_each(tmp_path):
    path = _write_variant(tmp_path, "[coordinates]",
                          '[[links]]\nname = "tool"\nmass = 1.0\ninertia = [1.0, 1.0, 1.0]\n\n'
                          '[[joints]]\nname = "tool_mount"\ntype = "fixed"\nparent = "platfrom"\nchild = "tool"\n\n'
                          "[coordinates]")
    with pytest.raises(hydrogen.ModelError, match=r"several roots \['base', 'platfrom'\]") as err:
        hydrogen.load_model(path)
    assert "'platfrom' is the parent of joint(s) ['tool_mount']" in str(err.value)


# --- URDF ---------------------------------------------------------------------------------------


def _arm_variant(tmp_path, old=None, new=None, urdf_text=None):
    """The excavator arm with its URDF edited (``old`` -> ``new``) or replaced by ``urdf_text``."""
    toml = hydrogen.model.model_path("excavator_arm")
    urdf = toml.parent / "excavator_arm.urdf"
    if urdf_text is None:
        urdf_text = urdf.read_text()
        assert old in urdf_text, old
        urdf_text = urdf_text.replace(old, new, 1)
    (tmp_path / "arm.urdf").write_text(urdf_text)
    path = tmp_path / "arm.toml"
    path.write_text(toml.read_text().replace('urdf = "excavator_arm.urdf"', 'urdf = "arm.urdf"'))
    return path


_BUCKET_ORIGIN = '<origin xyz="2.90 0 0" rpy="0 0 0"/>'


@pytest.mark.parametrize("old,new,words", [
    ('<axis xyz="0 -1 0"/>\n    <limit lower="-2.498"',
     '<axis xyz="0 -1 0"/>\n    <mimic joint="stick_joint" multiplier="1.0"/>\n    <limit lower="-2.498"',
     ["joint 'bucket_joint'", "mimics joint 'stick_joint'", "mimic joints are not supported", "fixed", "remove"]),
    ('<joint name="bucket_joint"', '<joint name="stick_joint"', ["joint 'stick_joint'", "defined twice"]),
    ('<link name="bucket">', '<link name="stick">', ["link 'stick'", "defined twice"]),
    (_BUCKET_ORIGIN, '<origin xyz="nan 0 0" rpy="0 0 0"/>', ["joint 'bucket_joint' <origin xyz>", "finite"]),
    (_BUCKET_ORIGIN, '<origin xyz="2.90 0 0" rpy="0 nan 0"/>', ["joint 'bucket_joint' <origin rpy>", "finite"]),
    (_BUCKET_ORIGIN, '<origin xyz="2.90 0" rpy="0 0 0"/>', ["joint 'bucket_joint' <origin xyz>", "3 numbers"]),
    (_BUCKET_ORIGIN, '<origin xyz="2.90e6 0 0" rpy="0 0 0"/>', ["joint 'bucket_joint' <origin xyz>",
                                                               "plausible range"]),
    ('<mass value="950.0"/>', '<mass value="heavy"/>', ["link 'stick' <inertial><mass value>", "'heavy'"]),
    ('<mass value="950.0"/>', '<mass value="9.5e9"/>', ["link 'stick' <inertial><mass value>", "plausible range"]),
    ('<mass value="950.0"/>', '<mass/>', ["link 'stick' <inertial>", "lacks the attribute 'value'"]),
    ('ixx="40.0" ', '', ["link 'stick' <inertial>", "lacks the attribute(s) ixx"]),
    ('ixx="40.0" ', 'ixx="forty" ', ["link 'stick' <inertial><inertia ixx>", "'forty'"]),
    ('<origin xyz="1.05 0 0.12" rpy="0 0 0"/>', '<origin xyz="1.05 0 0.12" rpy="0 0 x"/>',
     ["link 'stick' <inertial><origin rpy>"]),
    ('effort="179000"', 'effort="lots"', ["joint 'bucket_joint' <limit effort>", "'lots'"]),
    ('<robot name="excavator_arm">', '<robot>', ["root element <robot>", "lacks the attribute 'name'"]),
    ('<parent link="boom"/>', '<parent link="bom"/>',
     ["joint 'stick_joint'", "parent link 'bom' that is not defined", "base, boom, stick, bucket"]),
    ('<child link="bucket"/>', '<child link="bukket"/>', ["joint 'bucket_joint'", "child link 'bukket'"]),
    ('<parent link="boom"/>', '', ["joint 'stick_joint'", "lacks <parent link="]),
    ('<joint name="bucket_joint" type="revolute">', '<joint name="bucket_joint">',
     ["joint 'bucket_joint'", "lacks the attribute 'type'"]),
    ('<link name="bucket">', '<link>', ["<link> #4", "lacks the attribute 'name'"]),
])
def test_bad_urdf_files_name_the_element(tmp_path, old, new, words):
    path = _arm_variant(tmp_path, old, new)
    with pytest.raises(hydrogen.ModelError) as err:
        hydrogen.load_model(path)
    msg = str(err.value)
    assert str(tmp_path / "arm.urdf") in msg
    for w in words:
        assert w in msg, msg
    assert "\n" not in msg and len(msg) < 2000


def test_an_xml_file_that_is_not_a_urdf(tmp_path):
    path = _arm_variant(tmp_path, urdf_text='<?xml version="1.0"?>\n<svg name="drawing"><g/></svg>\n')
    with pytest.raises(hydrogen.ModelError, match=r"arm\.urdf: root element: <svg> is not <robot name=\"...\">: "
                                                  r"this is not a URDF file"):
        hydrogen.load_model(path)


def test_a_urdf_path_that_is_a_folder_or_a_device(tmp_path):
    path = _arm_variant(tmp_path, urdf_text="<robot/>")
    text = path.read_text()
    for target, why in ((".", "is a folder, not a URDF file"), ("/dev/null", "is not a regular file"),
                        ("nope.urdf", "URDF file not found")):
        path.write_text(text.replace('urdf = "arm.urdf"', f'urdf = "{target}"'))
        with pytest.raises(hydrogen.ModelError) as err:
            hydrogen.load_model(path)
        assert str(err.value).startswith(f"{path}: urdf: ") and why in str(err.value), str(err.value)


def test_a_joint_origin_rpy_is_the_files_numbers_exactly(tmp_path):
    """The pitch is not re-derived through arcsin of a rotation matrix (which gives pi/2 exactly)."""
    pitch = "1.57079632679"
    # the bucket frame pitched by p about y and the bucket coordinate shifted by p: the same geometry
    # (its axis is -y), so the model stays valid at the shifted neutral pose
    path = _arm_variant(tmp_path, _BUCKET_ORIGIN, f'<origin xyz="2.90 0 0" rpy="0 {pitch} 0"/>')
    path.write_text(path.read_text().replace("neutral = [0.10, -1.65, -0.90]",
                                             f"neutral = [0.10, -1.65, {-0.90 + float(pitch)!r}]"))
    urdf = path.parent / "arm.urdf"  # its limits shift with the coordinate (the linkage is checked over them)
    urdf.write_text(urdf.read_text().replace('lower="-2.498" upper="0.553"',
                                             f'lower="{-2.498 + float(pitch)!r}" upper="{0.553 + float(pitch)!r}"'))
    model = hydrogen.load_model(path)
    bucket = next(j for j in model.joints if j.name == "bucket_joint")
    assert bucket.origin_rpy.tolist() == [0.0, float(pitch), 0.0]
    assert bucket.origin_rpy[1] != np.pi / 2
    from hydrogen.tree import cylinder_lengths
    ref = hydrogen.load_model("excavator_arm")
    np.testing.assert_allclose(cylinder_lengths(model, model.neutral_pose),
                               cylinder_lengths(ref, ref.neutral_pose), rtol=1e-9)


def test_a_huge_joint_axis_is_normalised_without_overflow(tmp_path):
    path = _arm_variant(tmp_path, '<axis xyz="0 -1 0"/>', '<axis xyz="1e308 -1e308 0"/>')
    boom = next(j for j in hydrogen.load_model(path).joints if j.name == "boom_joint")
    np.testing.assert_allclose(boom.axis, [2 ** -0.5, -(2 ** -0.5), 0.0], rtol=1e-15)


def test_urdf_joint_limits_are_read_per_coordinate():
    m = hydrogen.load_model("excavator_arm")
    lim = m.coordinate_limits()
    assert lim["lower"].tolist() == [-0.795, -2.744, -2.498] and lim["upper"].tolist() == [0.993, -0.555, 0.553]
    assert lim["velocity"].tolist() == [1.0, 1.0, 1.0]
    assert m.joints[0].limit["effort"] == 638000.0
    # the platform's floating joint has none
    s = hydrogen.load_model("ubc_stewart").coordinate_limits()
    assert np.all(np.isinf(s["lower"])) and np.all(np.isinf(s["velocity"]))


def test_toml_joint_limits_are_read_and_checked(tmp_path):
    path = _write_variant(tmp_path, 'type = "floating"', 'type = "floating"\nlimit = { lower = 1.0, upper = 0.5 }')
    with pytest.raises(hydrogen.errors.ModelError, match=r"\[\[joints\]\] 'platform_pose' limit: lower 1.0 must be < upper"):
        hydrogen.load_model(path)
    path = _write_variant(tmp_path, 'type = "floating"', 'type = "floating"\nlimit = { speed = 1.0 }')
    with pytest.raises(hydrogen.errors.ModelError, match="unknown key 'speed'"):
        hydrogen.load_model(path)


def test_a_reference_beyond_a_joint_limit_is_refused_before_the_run(tmp_path):
    path = _arm_variant(tmp_path, '<limit lower="-0.795" upper="0.993"', '<limit lower="-0.795" upper="0.12"')
    with pytest.raises(hydrogen.errors.KinematicsError,
                       match=r"passes the position limit of joint '\w+' at t = .* limit \[-0.795, 0.12\] rad"):
        hydrogen.simulate("arm-sim", "p", model=hydrogen.load_model(path), duration=2.0)


def test_a_reference_beyond_a_velocity_limit_is_refused_before_the_run(tmp_path):
    path = _arm_variant(tmp_path, 'effort="638000" velocity="1.0"', 'effort="638000" velocity="0.01"')
    with pytest.raises(hydrogen.errors.KinematicsError, match=r"passes the velocity limit .* limit 0.01 rad/s"):
        hydrogen.simulate("arm-sim", "p", model=hydrogen.load_model(path), duration=2.0)


# A two-legged URDF as robots are exported: a world link, a trunk with a placeholder inertia, a
# sensor frame without one, massless foot frames; the description keeps one leg and locks the other.
_LEGS_URDF = """<?xml version="1.0"?>
<robot name="biped">
  <link name="world"/>
  <link name="trunk"><inertial><mass value="0"/><inertia ixx="1" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <link name="imu"/>
  <joint name="world_trunk" type="fixed"><parent link="world"/><child link="trunk"/><origin xyz="0 0 1" rpy="0 0 0"/></joint>
  <joint name="trunk_imu" type="fixed"><parent link="trunk"/><child link="imu"/></joint>
  {legs}
</robot>
"""
_LEG = """
  <link name="thigh_{s}"><inertial><origin xyz="0.2 0 0"/><mass value="4"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.05" iyz="0" izz="0.05"/></inertial></link>
  <link name="shank_{s}"><inertial><origin xyz="0.15 0 0"/><mass value="2"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.02"/></inertial></link>
  <link name="foot_{s}"/>
  <joint name="hip_{s}" type="revolute"><parent link="trunk"/><child link="thigh_{s}"/><origin xyz="0 {y} 0" rpy="0.1 0 0.2"/><axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" effort="100" velocity="5"/></joint>
  <joint name="knee_{s}" type="revolute"><parent link="thigh_{s}"/><child link="shank_{s}"/><origin xyz="0.4 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/><limit lower="-2.5" upper="0.5" effort="100" velocity="5"/></joint>
  <joint name="ankle_{s}" type="fixed"><parent link="shank_{s}"/><child link="foot_{s}"/><origin xyz="0.3 0 0"/></joint>
"""
_LEGS_TOML = """
name = "biped_leg"
gravity = 9.81
urdf = "legs.urdf"
[tree]
base = "trunk"
locked = { hip_R = 0.3, knee_R = -0.5 }
[coordinates]
neutral = [0.2, -0.4]
[hydraulics]
piston_area = 2e-4
rod_area = 1e-4
chamber_length = 0.05
supply_pressure = 2e7
underlap = 1e-5
flow_gain = 1e-5
bulk_modulus = 1e9
orifice_linear_below = 5e4
stroke = [0.1, 1.0]
[[cylinders]]
name = "hip_cyl"
from = { link = "trunk", point = [0.0, 0.1, 0.3] }
to = { link = "thigh_L", point = [0.2, 0.0, 0.05] }
[[cylinders]]
name = "knee_cyl"
from = { link = "thigh_L", point = [0.1, 0.0, 0.1] }
to = { link = "shank_L", point = [0.15, 0.0, 0.0] }
[adaptation]
parameters = ["thigh_L.mcx"]
theta_min = [0.4]
theta_max = [1.2]
gamma1_min = 1e8
gamma1_max = 5e9
gamma2_min = 1e2
gamma2_max = 1e5
"""


def _legs(tmp_path, toml=_LEGS_TOML):
    legs = "".join(_LEG.format(s=s, y=y) for s, y in (("L", 0.1), ("R", -0.1)))
    (tmp_path / "legs.urdf").write_text(_LEGS_URDF.format(legs=legs))
    path = tmp_path / "legs.toml"
    path.write_text(toml)
    return path


def test_a_sub_tree_with_locked_joints_and_placeholder_links_loads_as_pinocchio_reduces_it(tmp_path, rng):
    pin = pytest.importorskip("pinocchio")
    from hydrogen.errors import DescriptionNote
    from hydrogen.tree import link_poses

    path = _legs(tmp_path)
    with pytest.warns(DescriptionNote, match="left out") as notes:
        m = hydrogen.load_model(path)
    assert any("foot_L" in str(w.message) and "no mass" in str(w.message) for w in notes)
    assert m.coordinate_names == ("hip_L", "knee_L") and m.root == "trunk"
    full = pin.buildModelFromUrdf(str(tmp_path / "legs.urdf"))
    q_full = pin.neutral(full)
    q_full[full.joints[full.getJointId("hip_R")].idx_q] = 0.3
    q_full[full.joints[full.getJointId("knee_R")].idx_q] = -0.5
    reduced = pin.buildReducedModel(full, [full.getJointId("hip_R"), full.getJointId("knee_R")], q_full)
    data = reduced.createData()
    for _ in range(5):
        q = m.neutral_pose + rng.uniform(-0.3, 0.3, 2)
        pin.framesForwardKinematics(reduced, data, q)
        poses = link_poses(m, q)
        trunk = data.oMf[reduced.getFrameId("trunk")]
        for link in ("thigh_L", "shank_L", "foot_L", "thigh_R", "shank_R", "foot_R"):
            T = trunk.inverse() * data.oMf[reduced.getFrameId(link)]  # hydrogen's base is the trunk
            R, p = poses[link]
            np.testing.assert_allclose(R, T.rotation, atol=1e-12)
            np.testing.assert_allclose(p, T.translation, atol=1e-12)


def test_a_joint_that_moves_no_mass_is_refused(tmp_path):
    path = _legs(tmp_path)
    urdf = (tmp_path / "legs.urdf").read_text()
    urdf = urdf.replace('<mass value="2"/>', '<mass value="0"/>')  # both shanks massless
    (tmp_path / "legs.urdf").write_text(urdf)
    with pytest.raises(hydrogen.errors.ModelError, match="joint 'knee_L'.* moves no mass"):
        hydrogen.load_model(path)


@pytest.mark.parametrize("old,new,words", [
    ("hip_R = 0.3", "hip_X = 0.3", "no joint 'hip_X'"),
    ("hip_R = 0.3", "hip_R = 3.0", "outside the joint's limits"),
    ('base = "trunk"', 'base = "torso"', "no link 'torso'"),
    ('base = "trunk"', 'root = "trunk"', "unknown key 'root'"),
])
def test_tree_selection_errors_name_the_key(tmp_path, old, new, words):
    path = _legs(tmp_path, _LEGS_TOML.replace(old, new))
    with pytest.raises(hydrogen.errors.ModelError, match=words):
        hydrogen.load_model(path)


def test_the_cli_shows_description_notes_as_one_line(tmp_path, capsys):
    from hydrogen import cli

    path = _legs(tmp_path)
    assert cli.main(["generate", "--check", "--model", str(path), "--out", str(tmp_path / "gen")]) in (0, 1, 2)
    err = capsys.readouterr().err
    assert "hydrogen: note:" in err and "left out" in err and "Warning" not in err


# --- actuator kinds -----------------------------------------------------------------------------

FOUR_WAY_ARM = Path(__file__).parent / "data" / "four_way_arm.toml"


def test_a_four_way_robot_loads_its_kind_and_parameters():
    m = hydrogen.load_model(FOUR_WAY_ARM)
    assert [c.kind for c in m.cylinders] == ["four_way_cylinder"] * 2
    c = m.cylinders[0]
    assert c.params == {"cap_area": 1.2566e-3, "annulus_area": 7.6576e-4, "dead_volume_A": 5e-5,
                        "dead_volume_B": 5e-5, "tank_pressure": 0.0, "leakage_internal": 0.0,
                        "leakage_external": 0.0}
    assert not {"piston_area", "rod_area", "chamber_length"} & set(c.table)  # no three-way constants anywhere
    from hydrogen.actuators import actuator
    P = actuator(c.kind).parameters(c.table)
    assert P["stroke_min"] == 0.22 and P["stroke_max"] == 0.62 and P["supply_pressure"] == 10e6
    # shipped robots: the Stewart platform on the default kind, its own constants in params as every
    # kind's; the excavator on four-way cylinders, its bucket through a linkage
    assert all(c.kind == "three_way_cylinder" and c.params == {"piston_area": 1.14e-3, "rod_area": 6.33e-4,
                                                               "chamber_length": 1.37, "leakage": 0.0}
               for c in hydrogen.load_model("ubc_stewart").cylinders)
    arm = hydrogen.load_model("excavator_arm")
    assert all(c.kind == "four_way_cylinder" for c in arm.cylinders)
    assert [c.linkage_joint for c in arm.cylinders] == [None, None, "bucket_joint"]


def test_a_kind_given_per_cylinder_overrides_the_hydraulics_default(tmp_path):
    text = FOUR_WAY_ARM.read_text().replace('name = "elbow_cylinder"\n', 'name = "elbow_cylinder"\n'
                                            'kind = "four_way_cylinder"\ncap_area = 2.0e-3\n')
    path = tmp_path / "arm.toml"
    path.write_text(text)
    m = hydrogen.load_model(path)
    assert m.cylinders[1].params["cap_area"] == 2.0e-3 and m.cylinders[0].params["cap_area"] == 1.2566e-3


def test_an_explicit_default_kind_keeps_the_hash(tmp_path, model):
    path = _write_variant(tmp_path, "[hydraulics]                 # the same for every leg (Table I)",
                          '[hydraulics]\nkind = "three_way_cylinder"')
    assert hydrogen.load_model(path).baked_hash() == model.baked_hash()
    assert not any("kind" in map(str, entry) for entry in model.baked()["cylinders"])  # no kind fields appended


def test_a_kind_parameter_changes_the_hash_its_gamma_does_not(tmp_path):
    base = hydrogen.load_model(FOUR_WAY_ARM)

    def variant(old, new):
        path = tmp_path / "arm.toml"
        path.write_text(FOUR_WAY_ARM.read_text().replace(old, new, 1))
        return hydrogen.load_model(path)

    assert variant("dead_volume_B = 5.0e-5", "dead_volume_B = 6.0e-5").baked_hash() != base.baked_hash()
    assert variant("stroke = [0.22, 0.62]", "stroke = [0.21, 0.62]").baked_hash() != base.baked_hash()
    assert variant("bulk_modulus = 1.0e9", "bulk_modulus = 1.1e9").baked_hash() == base.baked_hash()


@pytest.mark.parametrize("old,new,words", [
    ('kind = "four_way_cylinder"', 'kind = "five_way"', ["[hydraulics] kind", "unknown actuator kind 'five_way'",
                                                          "four_way_cylinder", "three_way_cylinder"]),
    ('kind = "four_way_cylinder"', 'kind = "rotary"', ["'shoulder_cylinder' (kind rotary)", "unknown key 'from'"]),
    ('kind = "four_way_cylinder"', "kind = 4", ["[hydraulics] kind", "unknown actuator kind 4"]),
    ("cap_area = 1.2566e-3               # pi/4 x 0.040^2, m^2", "",
     ["[[cylinders]] 'shoulder_cylinder'", "missing key 'cap_area'"]),
    ("annulus_area = 7.6576e-4", "annulus_area = 1.3e-3", ["[[cylinders]] 'shoulder_cylinder' annulus_area",
                                                           "<= cap_area"]),
    ("tank_pressure = 0.0", "tank_pressure = 1.0e7", ["tank_pressure", "< supply_pressure"]),
    ("tank_pressure = 0.0", "tank_pressure = -1.0", ["[hydraulics] tank_pressure", ">= 0"]),
    ("dead_volume_A = 5.0e-5", "dead_volume_A = 0.0", ["[hydraulics] dead_volume_A", "> 0"]),
    ("dead_volume_A = 5.0e-5", "dead_volume_A = 5.0e4", ["[hydraulics] dead_volume_A", "plausible range"]),
    ("cap_area = 1.2566e-3", "cap_area = 1.2566e3", ["[hydraulics] cap_area", "plausible range"]),
    ("cap_area = 1.2566e-3", 'cap_area = "big"', ["[hydraulics] cap_area", "expected a number"]),
    ("stroke = [0.22, 0.62]", "stroke = [0.62, 0.22]", ["'shoulder_cylinder' stroke", "shortest < longest"]),
    # a three-way cylinder's key on a four-way cylinder, and in [hydraulics] with no three-way cylinder
    ("stroke = [0.22, 0.62]", "stroke = [0.22, 0.62]\npiston_area = 1e-3",
     ["'shoulder_cylinder' (kind four_way_cylinder)", "unknown key 'piston_area'", "cap_area"]),
    ("tank_pressure = 0.0", "tank_pressure = 0.0\nchamber_length = 0.1",
     ["[hydraulics] chamber_length", "no cylinder's kind (four_way_cylinder)"]),
    ("underlap = 1.0e-5", "underlap = 1.0e-5\nbore = 0.04", ["[hydraulics]", "unknown key 'bore'"]),
])
def test_bad_four_way_cylinders_are_named(tmp_path, old, new, words):
    text = FOUR_WAY_ARM.read_text()
    assert old in text, old
    path = tmp_path / "arm.toml"
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(hydrogen.ModelError) as err:
        hydrogen.load_model(path)
    for w in [str(path), *words]:
        assert w in str(err.value), (w, str(err.value))


def test_a_four_way_default_fills_an_omitted_tank_pressure(tmp_path):
    path = tmp_path / "arm.toml"
    path.write_text(FOUR_WAY_ARM.read_text().replace("tank_pressure = 0.0 ", "", 1))
    assert hydrogen.load_model(path).cylinders[0].params["tank_pressure"] == 0.0


ROTARY_ELBOW = """[[cylinders]]
name = "elbow_motor"
kind = "rotary"
joint = "elbow"
displacement = 4.0e-5
angle = [-1.9, -0.1]
"""


def rotary_arm_text() -> str:
    """The four-way arm with a rotary vane actuator on its elbow instead of the elbow cylinder."""
    text = FOUR_WAY_ARM.read_text()
    start = text.index('[[cylinders]]\nname = "elbow_cylinder"')
    end = text.index("[adaptation]")
    text = text[:start] + ROTARY_ELBOW + "\n" + text[end:]
    # the vane's force loop in N m/rad: 1e4 N/m times the square of the elbow cylinder's 0.178 m lever
    return text.replace("[gains.common]\n", "[gains.common]\nGtau_inv = [1.0e4, 317.0]\n", 1)


THREE_WAY_SHOULDER = """kind = "three_way_cylinder"
piston_area = 8.0e-4               # A, m^2: pi/4 x 0.032^2
rod_area = 4.0e-4                  # a, the annulus at supply pressure: half of A
chamber_length = 0.2               # L, m: 0.02 m below the shortest length
"""


def mixed_arm_text(elbow: str = "four_way") -> str:
    """The four-way arm with its shoulder on the paper's three-way cylinder, and its elbow on the
    four-way cylinder (``elbow="four_way"``) or the rotary vane actuator (``"rotary"``): every kind in
    one robot, each actuator's own pressure block."""
    text = FOUR_WAY_ARM.read_text() if elbow == "four_way" else rotary_arm_text()
    head = 'name = "shoulder_cylinder"\n'
    text = text.replace(head, head + THREE_WAY_SHOULDER, 1)
    if elbow == "rotary":  # no four-way cylinder is left to take the arm's cylinder areas
        text = "".join(line for line in text.splitlines(keepends=True)
                       if not line.startswith(("cap_area", "annulus_area")))
    return text


def test_a_rotary_actuator_on_a_revolute_joint(tmp_path):
    path = tmp_path / "arm.toml"
    path.write_text(rotary_arm_text())
    m = hydrogen.load_model(path)
    c = m.cylinders[1]
    assert (c.kind, c.joint, c.link_from, c.link_to) == ("rotary", "elbow", "upper", "fore")
    assert c.table["angle_min"] == -1.9 and c.table["displacement"] == 4e-5 and c.table["dead_volume_A"] == 5e-5
    from hydrogen.tree import cylinder_jacobian, cylinder_lengths
    assert cylinder_lengths(m, [0.3, -0.8])[1] == -0.8
    np.testing.assert_allclose(cylinder_jacobian(m, [0.3, -0.8])[1], [0.0, 1.0], atol=1e-9)


@pytest.mark.parametrize("old,new,words", [
    ('joint = "elbow"', 'joint = "wrist"', ["'elbow_motor' joint", "'wrist' is not a revolute joint",
                                            "shoulder, elbow"]),
    ('joint = "elbow"\n', '', ["'elbow_motor' (kind rotary)", "missing key 'joint'"]),
    # the cause, not the neutral pose's two numbers for the one coordinate left
    ('name = "elbow"\ntype = "revolute"', 'name = "elbow"\ntype = "fixed"',
     ["'elbow_motor' joint: a rotary actuator needs a revolute joint; 'elbow' is fixed (revolute joints: shoulder)"]),
    ("angle = [-1.9, -0.1]", "angle = [-0.1, -1.9]", ["'elbow_motor' angle", "lowest < highest"]),
    ("angle = [-1.9, -0.1]", "angle = [-0.5, -0.1]", ["'elbow_motor': angle -1.0000 rad at the neutral pose is outside its angle range [-0.5, -0.1] rad"]),
    ("displacement = 4.0e-5", "displacement = 20.0", ["'elbow_motor' displacement", "plausible range"]),
    ("displacement = 4.0e-5", 'displacement = 2.0e-5\nfrom = { link = "upper", point = [0.0, 0.0, 0.0] }',
     ["'elbow_motor' (kind rotary)", "unknown key 'from'"]),
])
def test_bad_rotary_actuators_are_named(tmp_path, old, new, words):
    text = rotary_arm_text()
    assert old in text, old
    path = tmp_path / "arm.toml"
    path.write_text(text.replace(old, new, 1))
    with pytest.raises(hydrogen.ModelError) as err:
        hydrogen.load_model(path)
    for w in [str(path), *words]:
        assert w in str(err.value), (w, str(err.value))


def test_an_actuators_ranges_are_its_kinds_declarations(tmp_path, monkeypatch):
    """The loader and Model.number_ranges hold an actuator's constants to the ranges its kind declares
    (hydrogen.actuators.declarations.Parameter.range), with no table of the loader to extend: a kind's
    new range is checked as declared, and the message names the file, actuator, key, unit, range and
    the declaring module."""
    import dataclasses

    from hydrogen import model as model_module
    from hydrogen.actuators import KINDS, actuator
    from hydrogen.actuators.declarations import Range
    # no actuator constant is a quantity of the loader's own
    for kind in KINDS:
        assert not {p.name for p in actuator(kind).PARAMETERS} & set(model_module.QUANTITIES), kind
    assert not hasattr(model_module, "_QUANTITY_OF")
    path = tmp_path / "arm.toml"
    own = rotary_arm_text().replace("displacement = 4.0e-5", "displacement = 4.0e-5\ndead_volume_A = 5.0e-5", 1)
    path.write_text(own)
    ranges = hydrogen.load_model(path).number_ranges()
    assert ranges["elbow_motor.dead_volume_A"] == (1e-9, 100.0)
    rotary = actuator("rotary")
    narrow = tuple(dataclasses.replace(p, range=Range("positive", 1.0, 2.0)) if p.name == "dead_volume_A" else p
                   for p in rotary.PARAMETERS)
    monkeypatch.setattr(rotary, "PARAMETERS", narrow)
    with pytest.raises(hydrogen.ModelError) as err:
        hydrogen.load_model(path)
    assert str(err.value).startswith(f"{path}: [[cylinders]] 'elbow_motor' dead_volume_A: 5e-05 m^3 is outside the "
                                     "plausible range [1, 2] m^3")
    assert "hydrogen.actuators.rotary" in str(err.value)
    monkeypatch.undo()
    path.write_text(own.replace("dead_volume_A = 5.0e-5\n", "dead_volume_A = -1.5\n", 1))
    with pytest.raises(hydrogen.ModelError, match=r"'elbow_motor' dead_volume_A: must be > 0, got -1.5"):
        hydrogen.load_model(path)


def test_a_kind_of_unlimited_travel_loads_with_no_range(tmp_path, monkeypatch):
    """A kind whose TRAVEL is not limited (ROTATION) takes no range key: its actuator's range is
    (−∞, ∞), the neutral pose check passes any angle, its numbers hold no range ends and the
    description table lists no range row for it. Handled from the declaration, not the kind's name
    (here the rotary kind, declared unlimited for the test)."""
    from hydrogen import schema
    from hydrogen.actuators import actuator
    from hydrogen.actuators.declarations import ROTATION
    rotary = actuator("rotary")
    monkeypatch.setattr(rotary, "TRAVEL", ROTATION)
    monkeypatch.setattr(rotary, "PARAMETERS", tuple(p for p in rotary.PARAMETERS
                                                    if p.name not in ("angle_min", "angle_max")))
    path = tmp_path / "arm.toml"
    path.write_text(rotary_arm_text().replace("angle = [-1.9, -0.1]\n", "", 1))
    m = hydrogen.load_model(path)
    c = m.cylinders[1]
    assert (c.stroke_min, c.stroke_max) == (-np.inf, np.inf) and m.leg_max[1] == np.inf
    assert not [k for k in m.numbers() if k.startswith("elbow_motor.angle")]
    from hydrogen.codegen.generate import structure_hash
    assert len(structure_hash(m)) == 64 and m.baked_hash()
    assert "| `[[cylinders]] kind = rotary` | `angle` |" not in schema.description_table()
    path.write_text(rotary_arm_text())
    with pytest.raises(hydrogen.ModelError, match=r"'elbow_motor' \(kind rotary\): unknown key 'angle'"):
        hydrogen.load_model(path)


@pytest.mark.parametrize("rotary", [False, True])
def test_a_neutral_pose_past_a_joint_limit_names_the_joint_not_the_stroke(tmp_path, rotary):
    """The elbow's neutral -1.0 rad is past its lower limit -0.9 rad and outside the actuator's range
    (a cylinder's stroke, or a vane's angle range [-0.8, -0.1] rad): the joint's limit is named."""
    text = rotary_arm_text().replace("angle = [-1.9, -0.1]", "angle = [-0.8, -0.1]") if rotary else \
        FOUR_WAY_ARM.read_text().replace("stroke = [0.40, 0.80]", "stroke = [0.60, 0.80]")
    path = tmp_path / "arm.toml"
    path.write_text(text.replace('child = "fore"\n', 'child = "fore"\nlimit = { lower = -0.9, upper = 0.5 }\n', 1))
    with pytest.raises(hydrogen.ModelError) as err:
        hydrogen.load_model(path)
    assert str(err.value) == (f"{path}: [coordinates] neutral: elbow = -1 rad is past joint 'elbow''s lower limit "
                              "(limits [-0.9, 0.5] rad)")
    path.write_text(text)  # without the limit: the actuator's own range, in its own unit
    with pytest.raises(hydrogen.ModelError, match="at the neutral pose is outside its "
                                                  + ("angle range" if rotary else "stroke")):
        hydrogen.load_model(path)


def test_a_scenario_name_holding_the_variant_separator_is_refused_at_load(tmp_path):
    """``[scenarios."z-1hz.low-latency"]`` could never run: that name runs z-1hz at the variant
    low-latency. The load names the file and the table."""
    text = default_model_path().read_text()
    path = tmp_path / "my.toml"
    path.write_text(text + '\n[scenarios."z-1hz.low-latency"]\nrig = true\nduration = 1.0\n')
    with pytest.raises(hydrogen.ModelError) as err:
        hydrogen.load_model(path)
    msg = str(err.value)
    assert msg.startswith(f"{path}: [scenarios.\"z-1hz.low-latency\"]: ") and "may not contain '.'" in msg
    path.write_text(text + '\n[scenarios.z-1hz-low-latency]\nrig = true\nduration = 1.0\n')
    assert "z-1hz-low-latency" in hydrogen.load_model(path).scenarios


@pytest.mark.parametrize("flag", ["rig", "tuned"])
def test_a_scenario_flag_that_is_no_boolean_is_refused_by_name(tmp_path, flag):
    """``tuned = "no"`` (or ``rig = 1``) is no true/false: the load names the file, the table and the key
    instead of reading a string as true."""
    path = tmp_path / "my.toml"
    other = "tuned = false" if flag == "rig" else "rig = true"
    path.write_text(default_model_path().read_text() + f'\n[scenarios.fast]\n{other}\n{flag} = "no"\n'
                    'reference.sines = [["z", 0.01, 1.0]]\n')
    with pytest.raises(hydrogen.ModelError, match=rf"my\.toml: \[scenarios\.fast\] {flag}: expected true or false"):
        hydrogen.load_model(path)


def test_an_untuned_rig_scenario_runs_but_the_searches_leave_it_out():
    from hydrogen.simulation.tuning import rig_scenarios
    arm = hydrogen.load_model("excavator_arm")
    assert arm.scenarios["arm-flow"]["tuned"] is False
    assert "arm-flow" not in rig_scenarios(arm) and "arm-flow" in rig_scenarios(arm, untuned=True)
    assert "arm-flow.predictor" in rig_scenarios(arm, "predictor", untuned=True)


@pytest.mark.parametrize("name", hydrogen.models())
def test_every_number_has_the_range_the_loader_holds_it_to(name):
    """Model.number_ranges names the numbers Model.numbers does, each inside its range; the ranges are
    QUANTITIES' (an exported program refuses an edited number outside), and number_orders names the
    loader's CYLINDER_ORDER rules between numbers."""
    from hydrogen.model import CYLINDER_ORDER, QUANTITIES, order_broken

    model = hydrogen.load_model(name)
    numbers, ranges = model.numbers(), model.number_ranges()
    assert numbers.keys() == ranges.keys()
    for k, v in numbers.items():
        lo, hi = ranges[k]
        assert (lo is None or lo <= v) and (hi is None or v <= hi), (k, v, lo, hi)
    q = QUANTITIES["mass"]
    assert all(ranges[f"{lk.name}.mass"] == (q.low, q.high) for lk in model.links if lk.mass > 0)
    assert ranges["gravity"] == (QUANTITIES["gravity"].low, QUANTITIES["gravity"].high)
    orders = model.number_orders()
    assert orders and all(a in numbers and b in numbers for a, b, _, _ in orders)
    for a, b, strict, why in orders:
        assert order_broken({a.rsplit(".", 1)[1]: numbers[a], b.rsplit(".", 1)[1]: numbers[b]}) is None
    assert {(a.rsplit(".", 1)[1], b.rsplit(".", 1)[1]) for a, b, _, _ in orders} <= {r[:2] for r in CYLINDER_ORDER}


def test_three_way_valve_constants_take_the_kinds_shared_defaults(tmp_path):
    """A three-way cylinder without underlap and orifice_linear_below takes the defaults the four-way
    kind takes: one declaration (hydrogen.actuators.declarations) for both."""
    from hydrogen.actuators import actuator
    from hydrogen.actuators.declarations import ORIFICE_LINEAR_BELOW, UNDERLAP
    text = re.sub(r"(?m)^valve = \{[^\n]*\}\n", "flow_gain = 1.5e-4\n", default_model_path().read_text())
    path = tmp_path / "no_valve_constants.toml"
    path.write_text(text.replace("orifice_linear_below = 5.0e4", ""))
    model = hydrogen.load_model(path)
    assert model.underlap == pytest.approx(np.zeros(model.n_cylinders))
    assert model.orifice_linear_below == pytest.approx(np.full(model.n_cylinders, 5.0e4))
    for kind in ("three_way_cylinder", "four_way_cylinder"):
        params = actuator(kind).PARAMETERS
        assert UNDERLAP in params and ORIFICE_LINEAR_BELOW in params


@pytest.mark.parametrize("name", ["ubc_stewart", "excavator_arm", "loader_crane"])
def test_a_shipped_robot_lists_its_controllers_so_a_new_one_is_not_generated_for_it(name):
    """The shipped descriptions name their five controllers: a controller added to hydrogen later
    grows neither their committed generated C nor their builds."""
    assert hydrogen.load_model(name).controllers == ("backstepping", "adaptive-robust", "adaptive-observer", "p",
                                                     "p-task")
    assert "controllers" in hydrogen.load_model(name).raw


# --- [supply] ------------------------------------------------------------------------------------

PUMP_SUPPLY = """
[supply]
kind = "pump"
pump_flow = 2.0e-4
relief_pressure = 11.0e6
hose_volume = 1.0e-3
"""


def _supplied_arm(tmp_path, table, text=None):
    path = tmp_path / "supplied.toml"
    path.write_text((text or FOUR_WAY_ARM.read_text()) + table)
    return hydrogen.load_model(path)


def test_a_constant_supply_is_the_robot_without_one(tmp_path):
    """[supply] kind = "constant" (the default) is nothing new: the same hash, no supply state."""
    from hydrogen.plant import plant_layout
    plain = hydrogen.load_model(FOUR_WAY_ARM)
    constant = _supplied_arm(tmp_path, '\n[supply]\nkind = "constant"\n')
    assert constant.supply.constant and constant.baked_hash() == plain.baked_hash()
    assert plant_layout(constant) == plant_layout(plain)
    assert not any(k.startswith("supply.") for k in constant.numbers())


def test_a_pump_supply_is_a_state_and_its_numbers(tmp_path):
    from hydrogen.plant import plant_layout, slot
    m = _supplied_arm(tmp_path, PUMP_SUPPLY)
    assert m.supply.kind == "pump" and m.baked_hash() != hydrogen.load_model(FOUR_WAY_ARM).baked_hash()
    ps = slot(plant_layout(m), "ps")
    assert (ps.start, ps.size, ps.units, ps.entries) == (12, 1, ("Pa",), ("supply",))
    # the supply's oil is the actuators' by default; its numbers with their declared ranges
    assert m.supply.values["bulk_modulus"] == 1.0e9 and m.supply.values["accumulator_volume"] == 0.0
    assert m.numbers()["supply.pump_flow"] == 2.0e-4
    assert m.number_ranges()["supply.pump_flow"] == (1e-6, 10.0)


@pytest.mark.parametrize("table, match", [
    ('kind = "turbine"', r"\[supply\] kind: unknown supply kind 'turbine'; known kinds: constant, pump, "
                         r"compensated_pump"),
    ('kind = "constant"\npump_flow = 1e-3', r"\[supply\] pump_flow: a 'constant' supply takes no pump_flow"),
    ('kind = "pump"\npump_flow = 1e-3\nrelief_pressure = 11e6\nhose_volume = 1e-3\nset_pressure = 9e6',
     r"\[supply\] set_pressure: a 'pump' supply takes no set_pressure"),
    ('kind = "pump"\nrelief_pressure = 11e6\nhose_volume = 1e-3', r"\[supply\]: missing key 'pump_flow'"),
    ('kind = "compensated_pump"\npump_flow = 1e-3\nrelief_pressure = 11e6\nhose_volume = 1e-3',
     r"\[supply\]: missing key 'set_pressure'"),
    ('kind = "pump"\npump_flow = 100.0\nrelief_pressure = 11e6\nhose_volume = 1e-3',
     r"\[supply\] pump_flow: 100 m\^3/s is outside the plausible range \[1e-06, 10\] m\^3/s.*hydrogen.plant.supply"),
    ('kind = "pump"\npump_flow = -1e-3\nrelief_pressure = 11e6\nhose_volume = 1e-3',
     r"\[supply\] pump_flow: must be > 0"),
    ('kind = "pump"\npump_flow = 1e-3\nrelief_pressure = 11e6\nhose_volume = 1e-3\naccumulator_volume = 2e-3',
     r"\[supply\]: missing key 'precharge_pressure'.*accumulator needs its gas precharge"),
    ('kind = "pump"\npump_flow = 1e-3\nrelief_pressure = 11e6\nhose_volume = 1e-3\nprecharge_pressure = 5e6',
     r"\[supply\] precharge_pressure: given without an accumulator"),
    ('kind = "compensated_pump"\npump_flow = 1e-3\nrelief_pressure = 11e6\nhose_volume = 1e-3\nset_pressure = 12e6',
     r"\[supply\] set_pressure: 1.2e\+07 Pa must be below relief_pressure 1.1e\+07 Pa"),
    ('kind = "pump"\npump_flow = 1e-3\nrelief_pressure = 11e6\nhose_volume = 1e-3\nvolume = 1',
     r"\[supply\]: unknown key 'volume'"),
])
def test_a_bad_supply_is_refused_naming_the_file_and_key(tmp_path, table, match):
    with pytest.raises(ModelError, match=r"supplied.toml: " + match):
        _supplied_arm(tmp_path, f"\n[supply]\n{table}\n")


def test_a_supply_state_needs_one_supply_pressure_and_one_oil(tmp_path):
    """Every actuator draws on the one supply: their supply_pressure (its start) must agree, and where
    their bulk_modulus differ the supply's oil needs its own."""
    text = FOUR_WAY_ARM.read_text()
    head = 'name = "elbow_cylinder"\n'
    with pytest.raises(ModelError, match=r"cylinder 'elbow_cylinder' supply_pressure: 1.2e\+07 Pa differs from "
                                         r"cylinder 'shoulder_cylinder''s 1e\+07 Pa"):
        _supplied_arm(tmp_path, PUMP_SUPPLY, text.replace(head, head + "supply_pressure = 12e6\n", 1))
    stiff = text.replace(head, head + "bulk_modulus = 1.5e9\n", 1)
    with pytest.raises(ModelError, match=r"\[supply\]: missing key 'bulk_modulus' \(Pa\): the actuators' "
                                         r"bulk_modulus differ \(1e\+09, 1.5e\+09 Pa\)"):
        _supplied_arm(tmp_path, PUMP_SUPPLY, stiff)
    assert _supplied_arm(tmp_path, PUMP_SUPPLY + "bulk_modulus = 1.2e9\n", stiff).supply.values["bulk_modulus"] == 1.2e9


@pytest.mark.parametrize("table, line, words", [
    ("[rig]", "noise_ps = -3.0", "[rig] noise_ps: must be >= 0 (Pa), got -3.0"),
    ("[rig]", 'noise_q = "abc"', "[rig] noise_q: must be a finite number (rad or m), got 'abc'"),
    ("[scenarios.z-1hz]", 'duration = "2"', "[scenarios.z-1hz] duration: must be a finite number (s), got '2'"),
    ("[variants.low-latency]", "metric_start = true",
     "[variants.low-latency] metric_start: must be a finite number (s), got True"),
])
def test_a_scenario_setting_of_the_wrong_type_or_sign_stops_the_load(tmp_path, table, line, words):
    """The checks a setting declares (a finite number, not negative) hold at load time, naming the file,
    the table and the key; before, a bad value loaded and stopped only the run that used it."""
    from hydrogen.model import default_model_path
    text = default_model_path().read_text()
    assert table + "\n" in text
    path = tmp_path / "bad.toml"
    path.write_text(text.replace(table + "\n", f"{table}\n{line}\n", 1))
    with pytest.raises(hydrogen.ModelError) as err:
        hydrogen.load_model(path)
    assert str(err.value) == f"{path}: {words}"


def test_a_scenario_without_a_required_setting_names_it(tmp_path):
    """A description's scenario that leaves out a setting without a default is refused naming the
    setting, its meaning and unit (not a Python argument error)."""
    from hydrogen.errors import ScenarioError
    text = FOUR_WAY_ARM.read_text() + ('\n[scenarios.bare]\nduration = 0.1\ncontrol_rate = 1000.0\nsubsteps = 2\n'
                                       'reference.sines = [["shoulder", 0.1, 1.0]]\n')
    path = tmp_path / "bare.toml"
    path.write_text(text)
    model = hydrogen.load_model(path)
    with pytest.raises(ScenarioError) as err:
        hydrogen.simulate("bare", "p", model=model)
    assert str(err.value).endswith("[scenarios.bare]: missing field(s) t_adapt (adaptation switched on from this "
                                   "time, s)")


def test_a_link_fixed_to_the_base_has_no_parameter_to_adapt(tmp_path):
    """A link on a fixed joint from the base (a pedestal) never moves: its parameters are no column of Y;
    adapting one is refused naming it, as the base's are (a link fixed to a moving one is adaptable)."""
    pedestal = ('[[links]]\nname = "pedestal"\nmass = 100.0\ncom = [0.0, 0.0, 0.1]\ninertia = [2.0, 2.0, 3.0]\n\n'
                '[[joints]]\nname = "pedestal_mount"\ntype = "fixed"\nparent = "base"\nchild = "pedestal"\n\n')
    text = default_model_path().read_text().replace("[[links]]\n", pedestal + "[[links]]\n", 1)
    source = tmp_path / "with_pedestal.toml"
    source.write_text(text)
    assert "pedestal" in {lk.name for lk in hydrogen.load_model(source).links}
    path = _write_variant(tmp_path, 'parameters = ["platform.mass",', 'parameters = ["pedestal.mass",', source=source)
    with pytest.raises(ModelError, match=r"\[adaptation\] parameters: 'pedestal.mass' is not '<moving link>.*link "
                                         r"'pedestal' is fixed to the base, its inertia never enters the dynamics"):
        hydrogen.load_model(path)


def test_a_toml_link_of_mass_0_is_a_frame(tmp_path):
    """As a URDF link without an inertial: a [[links]] table of mass 0 (no com, no inertia, or zeros) is
    a massless frame (a sensor fixed to the platform adds nothing to the dynamics); with an inertia it is
    refused naming the key, and a joint that then moves no mass is refused as before."""
    frame = ('[[links]]\nname = "imu"\nmass = 0.0\n\n[[joints]]\nname = "imu_mount"\ntype = "fixed"\n'
             'parent = "platform"\nchild = "imu"\norigin_xyz = [0.1, 0.0, 0.2]\n\n')
    path = tmp_path / "with_imu.toml"
    path.write_text(default_model_path().read_text().replace("[[joints]]\n", frame + "[[joints]]\n", 1))
    model, plain = hydrogen.load_model(path), hydrogen.load_model()
    assert model.link("imu").mass == 0.0 and np.array_equal(model.theta, plain.theta)
    bad = _write_variant(tmp_path, 'name = "imu"\nmass = 0.0\n', 'name = "imu"\nmass = 0.0\ninertia = [1.0, 1.0, 1.0]\n',
                         source=path)
    with pytest.raises(ModelError, match=r"\[\[links\]\] 'imu' mass: must be > 0, or 0 for a massless frame with no "
                                         r"inertia \(got inertia = \[1.0, 1.0, 1.0\]\)"):
        hydrogen.load_model(bad)
    zeros = _write_variant(tmp_path, 'name = "imu"\nmass = 0.0\n', 'name = "imu"\nmass = 0.0\ncom = [0.0, 0.0, 0.0]\n'
                           'inertia = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]\n', source=path)
    assert hydrogen.load_model(zeros).link("imu").mass == 0.0  # zeros written out: the same frame
    short = _write_variant(tmp_path, 'name = "imu"\nmass = 0.0\n', 'name = "imu"\nmass = 0.0\ncom = [0.0]\n', source=path)
    with pytest.raises(ModelError, match=r"'imu' mass: must be > 0, or 0 for a massless frame with no com"):
        hydrogen.load_model(short)
    empty = _write_variant(tmp_path, "mass = 250.0", "mass = 0", source=path)
    empty.write_text(empty.read_text().replace("inertia = [45.0, 45.0, 43.0]", "", 1).replace(
        "com = [0.0, 0.0, 0.0]", "", 1))
    with pytest.raises(ModelError, match="moves no mass"):
        hydrogen.load_model(empty)


def test_a_description_made_in_python_takes_numpy_numbers_and_must_be_a_table():
    """numpy's integers load as numbers (its floats did already); anything but a dict at the top is
    refused naming what it got (a TypeError, or "unknown key 'u'" for a string, before)."""
    import tomllib

    import numpy as np

    from hydrogen.model import model_from_dict, model_path

    data = tomllib.loads(model_path("ubc_stewart").read_text())
    data["links"][0]["mass"] = np.int64(250)
    assert model_from_dict(data).links[0].mass == 250.0
    data["links"][0]["mass"] = np.bool_(True)
    with pytest.raises(hydrogen.ModelError, match="mass: expected a number"):
        model_from_dict(data)
    for bad, shown in ((None, "NoneType None"), ("ubc_stewart", "str 'ubc_stewart'")):
        with pytest.raises(hydrogen.ModelError, match=rf"top level: a description is a table of keys \(a dict\), "
                                                      rf"got {shown}"):
            model_from_dict(bad)
