import numpy as np
import pytest

import hydrogen
from hydrogen.model import default_model_path


def test_default_model_has_table_I_values(model):
    assert model.theta.tolist() == [250.0, 45.0, 45.0, 43.0]
    assert model.theta_names == ("platform.mass", "platform.Ixx", "platform.Iyy", "platform.Izz")
    assert model.piston_area == pytest.approx(np.full(6, 1.14e-3))
    assert model.rod_area == pytest.approx(np.full(6, 6.33e-4))
    assert model.chamber_length == pytest.approx(np.full(6, 1.37))
    assert model.supply_pressure == pytest.approx(np.full(6, 1500 * 6894.757), rel=1e-3)
    assert model.underlap == pytest.approx(np.full(6, 55.4e-6))
    assert model.flow_gain == pytest.approx(np.full(6, 1.5e-4))
    assert model.bulk_modulus == pytest.approx(np.full(6, 700e6))
    assert model.neutral_pose[2] == pytest.approx(-2.34)
    np.testing.assert_allclose(model.gamma, [[700e6] * 6, [700e6 * 1.5e-4] * 6])
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
    moved = hydrogen.load_model(_write_variant(tmp_path, "underlap = 55.4e-6", "underlap = 60e-6"))
    assert moved.baked_hash() != model.baked_hash()


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
