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
