import pytest

import hydrogen
from hydrogen.model import default_model_path


def test_default_model_has_table_I_values(model):
    assert model.theta.tolist() == [250.0, 45.0, 45.0, 43.0]
    assert model.piston_area == pytest.approx(1.14e-3)
    assert model.rod_area == pytest.approx(6.33e-4)
    assert model.chamber_length == pytest.approx(1.37)
    assert model.supply_pressure == pytest.approx(1500 * 6894.757, rel=1e-3)
    assert model.underlap == pytest.approx(55.4e-6)
    assert model.flow_gain == pytest.approx(1.5e-4)
    assert model.bulk_modulus == pytest.approx(700e6)
    assert model.neutral_pose[2] == pytest.approx(-2.34)
    assert model.gamma.tolist() == pytest.approx([700e6, 700e6 * 1.5e-4])


def _write_variant(tmp_path, old, new):
    text = default_model_path().read_text()
    assert old in text, old
    path = tmp_path / "my.toml"
    path.write_text(text.replace(old, new, 1))
    return path


@pytest.mark.parametrize("old,new,words", [
    ("mass = 250.0", "mass = -250.0", ["[rigid_body] mass", "> 0"]),
    ("mass = 250.0", "mass = 0", ["[rigid_body] mass", "> 0"]),
    ("mass = 250.0", "mass = nan", ["[rigid_body] mass", "finite"]),
    ("mass = 250.0", 'mass = "heavy"', ["[rigid_body] mass", "expected a number"]),
    ("mass = 250.0", "", ["missing key 'rigid_body.mass'"]),
    ("inertia = [45.0, 45.0, 43.0]", "inertia = [45.0, 45.0]", ["[rigid_body] inertia", "shape"]),
    ("leg_min = 1.55", "leg_min = 2.5", ["leg_min", "< leg_max"]),
    ("gamma2_min = 5.0e4", "gamma2_min = 0.0", ["gamma2_min", "> 0"]),
    ("gamma1_min = 3.5e8", "gamma1_min = 2.0e9", ["gamma1_min", "< gamma1_max"]),
    ("name = \"ubc_stewart\"", "name = \"ubc stewart; rm -rf\"", ["name"]),
    ("[hydraulics]", "[hydraulix]", ["[hydraulics]"]),
    ("theta_max = [350.0, 65.0, 65.0, 65.0]", "theta_max = [240.0, 65.0, 65.0, 65.0]", ["contain the true"]),
    ("gamma2_max = 2.2e5", "gamma2_max = 1.0e5", ["gamma2", "contain the true"]),
])
def test_bad_model_files_name_file_and_key(tmp_path, old, new, words):
    path = _write_variant(tmp_path, old, new)
    with pytest.raises(hydrogen.ModelError) as err:
        hydrogen.load_model(path)
    msg = str(err.value)
    assert str(path) in msg
    for w in words:
        assert w in msg


def test_malformed_toml(tmp_path):
    path = _write_variant(tmp_path, "mass = 250.0", "mass = = 250.0")
    with pytest.raises(hydrogen.ModelError, match="malformed TOML"):
        hydrogen.load_model(path)


def test_missing_file(tmp_path):
    with pytest.raises(hydrogen.ModelError, match="not found"):
        hydrogen.load_model(tmp_path / "nope.toml")


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
