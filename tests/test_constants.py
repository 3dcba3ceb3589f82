"""The description's numbers in the derivation: folded as constants, or left as symbols."""
import numpy as np
import pytest
import sympy as sp

import hydrogen
from hydrogen.codegen.casadi_functions import to_casadi_function
from hydrogen.symbolic.constants import baked, folded, mode_key, numbers_as_symbols
from hydrogen.symbolic.functions import SymbolicFunction, kinematics_functions, rigid_body_functions

from conftest import workspace_poses


def test_baked_is_the_shortest_round_trip_float_outside_the_block():
    assert baked(0.1) == sp.Float("0.1") and isinstance(baked(2), sp.Float)
    with numbers_as_symbols() as table:
        s = baked(0.1)
        with folded():
            assert baked(0.1) == sp.Float("0.1") and mode_key() is None
        assert mode_key() == table.serial
    assert isinstance(s, sp.Symbol) and table.symbols == [s] and table.values == [0.1]
    assert mode_key() is None and baked(0.1) == sp.Float("0.1")
    with numbers_as_symbols() as later:  # a new table never shares the derivation caches' entries
        assert mode_key() == later.serial != table.serial


def test_a_table_gives_symbols_by_name_by_value_or_per_use():
    with numbers_as_symbols("name") as by_name:
        assert baked(2.5, "a.mass") is baked(2.5, "a.mass") and baked(2.5, "b.mass") is not baked(2.5, "a.mass")
        assert baked(1.0) is not baked(1.0)  # a number without a name: one symbol per use
    with numbers_as_symbols("value") as shared:
        assert baked(2.5, "a.mass") is baked(2.5, "b.mass") and baked(1.0) is not baked(2.5)
    with numbers_as_symbols("use") as per_use:
        assert baked(2.5, "a.mass") is not baked(2.5, "a.mass")
    assert (len(by_name.symbols), len(shared.symbols), len(per_use.symbols)) == (4, 2, 2)
    assert by_name.names == ["a.mass", "b.mass", None, None]
    with pytest.raises(ValueError, match="key"):
        numbers_as_symbols("neither").__enter__()


def _functions(model):
    return [f for f in kinematics_functions(model) + rigid_body_functions(model) if isinstance(f, SymbolicFunction)]


@pytest.fixture(scope="module")
def fresh_crane(tmp_path_factory):
    """The loader crane with gravity moved in its 8th digit: a description no other test has
    derived, so the derivation caches hold nothing of it yet."""
    import shutil

    folder = tmp_path_factory.mktemp("crane")
    data = hydrogen.model.model_path("loader_crane").parent
    shutil.copy(data / "loader_crane.urdf", folder)
    text = (data / "loader_crane.toml").read_text()
    assert "gravity = 9.81 " in text
    (folder / "loader_crane.toml").write_text(text.replace("gravity = 9.81 ", "gravity = 9.8100001 ", 1))
    return folder / "loader_crane.toml"


@pytest.mark.parametrize("key", ["name", "use"])
def test_the_derivation_with_numbers_as_symbols_equals_the_folded_one(fresh_crane, key, rng):
    """At the description's numbers the parametric functions give the folded ones' values. The
    parametric derivation runs first: the folded one after it holds no number symbol, so the
    derivation caches keep the two apart."""
    model = hydrogen.load_model(fresh_crane)
    with numbers_as_symbols(key) as table:
        param = _functions(model)
    base = {f.name: f for f in _functions(model)}
    assert table.symbols and len(table.values) == len(table.symbols)
    if key == "name":  # each description number once: a link's mass, a pin point, a joint origin
        named = [n for n in table.names if n is not None]
        assert len(named) == len(set(named)) and {"gravity", "boom.mass", "boom_cylinder.from[0]"} <= set(named)
        assert any(".origin_xyz[" in n for n in named)
    found = set().union(*(sp.Matrix(e).free_symbols for f in base.values() for _, e in f.outputs))
    assert not found & set(table.symbols)
    numbers = sp.Matrix(table.symbols)
    assert set(table.symbols) & set().union(*(sp.Matrix(e).free_symbols for f in param for _, e in f.outputs))
    for f in param:
        g = SymbolicFunction(f.name, [*f.inputs, ("numbers", numbers)], f.outputs, f.doc, f.intermediates)
        a, b = to_casadi_function(base[f.name]), to_casadi_function(g)
        for _ in range(2):
            args = [workspace_poses(model, 1, rng)[0] if name == "q" else
                    model.theta * rng.uniform(0.7, 1.3) if name == "theta" else rng.normal(size=m.shape[0])
                    for name, m in base[f.name].inputs]
            for x, y in zip(a.call(args), b.call([*args, np.asarray(table.values)])):
                np.testing.assert_allclose(np.array(y), np.array(x), rtol=1e-10, atol=1e-10, err_msg=f.name)


# --- runtime parameters: every number by name, an edit of numbers served without a new derivation ---

@pytest.fixture(scope="module")
def parametric_arm():
    from hydrogen.symbolic.functions import derive_parametric

    model = hydrogen.load_model("excavator_arm")
    return model, derive_parametric(model)


@pytest.mark.parametrize("name", ["ubc_stewart", "loader_crane", "excavator_arm"])
def test_every_number_the_derivation_meets_is_a_description_number_by_name(name, parametric_arm):
    """Each symbol of a parametric derivation has a name of ``model.numbers()`` and its value: the
    runtime fills the numbers vector from the description alone (no SymPy)."""
    from hydrogen.symbolic.functions import NUMBERS, derive_parametric

    model, (funcs, names, values) = parametric_arm if name == "excavator_arm" else \
        (lambda m: (m, derive_parametric(m)))(hydrogen.load_model(name))
    numbers = model.numbers()
    assert names and None not in names and len(set(names)) == len(names)
    assert [numbers[n] for n in names] == values
    assert all(f.inputs[-1][0] == NUMBERS for f in funcs if hasattr(f, "inputs"))
    if name == "excavator_arm":  # the linkage's derived lengths have names too
        assert any(".linkage.crank" in n for n in names)


def _edited_arm(folder, edits: dict):
    import shutil

    data = hydrogen.model.model_path("excavator_arm").parent
    for ext, file_edits in edits.items():
        text = (data / f"excavator_arm.{ext}").read_text()
        for old, new in file_edits:
            assert text.count(old) == 1, old
            text = text.replace(old, new)
        (folder / f"excavator_arm.{ext}").write_text(text)
    if "urdf" not in edits:
        shutil.copy(data / "excavator_arm.urdf", folder)
    return hydrogen.load_model(folder / "excavator_arm.toml")


#: An edit of numbers only: a pin point, the linkage's crank pin (its derived lengths move), a cap
#: area, gravity, a known link mass.
NUMERIC_EDIT = {"toml": [("point = [0.489, 0.0, 1.219]", "point = [0.495, 0.0, 1.225]"),
                         ("crank_pin = [-0.011, 0.0, 0.370]", "crank_pin = [-0.010, 0.0, 0.369]"),
                         ("cap_area = 2.2619e-2", "cap_area = 2.3e-2"), ("gravity = 9.81 ", "gravity = 9.80 "),
                         ("supply_pressure = 35.0e6 ", "supply_pressure = 34.0e6 ")],
                "urdf": [('<mass value="2000.0"/>', '<mass value="2100.0"/>')]}


def test_a_numeric_edit_keeps_the_structure_and_the_parametric_functions_serve_it(tmp_path, parametric_arm, rng):
    """The parametric functions of the shipped arm, given the edited description's numbers, equal
    the folded functions derived from the edited description: such an edit needs no new library."""
    from hydrogen.codegen.generate import structure_hash
    from test_codegen import _random_input

    model, (funcs, names, _) = parametric_arm
    edited = _edited_arm(tmp_path, NUMERIC_EDIT)
    assert edited.baked_hash() != model.baked_hash()
    assert edited.structure() == model.structure() and structure_hash(edited) == structure_hash(model)
    numbers = edited.numbers()
    changed = [n for n in names if numbers[n] != model.numbers()[n]]
    assert {"gravity", "boom_cylinder.from[0]", "boom_cylinder.cap_area", "boom.mass",
            "boom_cylinder.supply_pressure"} <= set(changed)
    assert any(".linkage.crank" in n for n in changed)
    vector = np.array([numbers[n] for n in names])
    folded_edit = {f.name: f for f in derive_functions_of(edited)}
    for f in funcs:
        if f.name not in folded_edit:
            continue
        a, b = to_casadi_function(folded_edit[f.name]), to_casadi_function(f)
        args = [_random_input(n, m.shape, edited, rng, f.name) for n, m in folded_edit[f.name].inputs]
        for x, y in zip(a.call(args), b.call([*args, vector])):
            assert np.all(np.isfinite(np.array(x))), f.name
            np.testing.assert_allclose(np.array(y), np.array(x), rtol=1e-9, atol=1e-9, err_msg=f.name)


def derive_functions_of(model):
    from hydrogen.symbolic.functions import derive_functions

    return [f for f in derive_functions(model, controllers=False) if isinstance(f, SymbolicFunction)]


@pytest.mark.parametrize("edit, why", [
    ({"toml": [("point = [0.489, 0.0, 1.219]", "point = [0.489, 0.1, 1.219]")]}, "a zero coordinate becomes a number"),
    ({"toml": [('parameters = ["boom.mcx", ', 'parameters = ['), ("theta_min = [3060.0, ", "theta_min = ["),
               ("theta_max = [7140.0, ", "theta_max = [")]}, "one parameter fewer adapted"),
])
def test_an_edit_of_structure_changes_the_structure_hash(tmp_path, edit, why):
    from hydrogen.codegen.generate import structure_hash

    model, edited = hydrogen.load_model("excavator_arm"), _edited_arm(tmp_path, edit)
    assert structure_hash(edited) != structure_hash(model), why
