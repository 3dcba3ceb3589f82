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
        assert mode_key() == id(table)
    assert isinstance(s, sp.Symbol) and table.symbols == [s] and table.values == [0.1]
    assert mode_key() is None and baked(0.1) == sp.Float("0.1")


def test_a_shared_table_gives_equal_numbers_one_symbol():
    with numbers_as_symbols(shared=True) as shared:
        assert baked(2.5) is baked(2.5) and baked(1.0) is not baked(2.5)
    with numbers_as_symbols() as per_use:
        assert baked(2.5) is not baked(2.5)
    assert (len(shared.symbols), len(per_use.symbols)) == (2, 2)


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


@pytest.mark.parametrize("shared", [True, False])
def test_the_derivation_with_numbers_as_symbols_equals_the_folded_one(fresh_crane, shared, rng):
    """At the description's numbers the parametric functions give the folded ones' values. The
    parametric derivation runs first: the folded one after it holds no number symbol, so the
    derivation caches keep the two apart."""
    model = hydrogen.load_model(fresh_crane)
    with numbers_as_symbols(shared) as table:
        param = _functions(model)
    base = {f.name: f for f in _functions(model)}
    assert table.symbols and len(table.values) == len(table.symbols)
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
