"""The plant's blocks (hydrogen/plant/): the state layout read off their declarations is the generated
plant's x, a new block's states join it, and each block's SymPy and numpy laws agree."""
from __future__ import annotations

import types
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import hydrogen
from hydrogen.plant import (BLOCKS, PlantState, block, describe_entries, entry_names, plant_layout, slot,
                            state_size)
from hydrogen.plant import friction, supply, valve
from hydrogen.pressures import bounds, n_pressures
from test_motor import motor_arm_text

ARM = Path(__file__).parent / "data" / "four_way_arm.toml"


#: The shipped plant blocks, in their order.
SHIPPED = ("mechanics", "chambers", "friction", "valve", "supply")


def _robots(tmp_path):
    """Every shipped robot and the test robots (four-way arm, the arm with a motor elbow)."""
    motor = tmp_path / "motor_arm.toml"
    motor.write_text(motor_arm_text())
    return [hydrogen.load_model(m) for m in hydrogen.models()] + [hydrogen.load_model(ARM),
                                                                  hydrogen.load_model(motor)]


def test_the_layout_is_the_generated_plants_x_in_order_and_size(tmp_path):
    from hydrogen.symbolic.plant import plant_rhs
    for model in _robots(tmp_path):
        layout = plant_layout(model)
        inputs, xdot, _ = plant_rhs(model)
        x = dict(inputs)["x"]
        pumped = bool(supply.entries(model))  # a supply that is not constant: one more state, p_s
        shipped = [s for s in layout if s.block in SHIPPED]  # (a block added since comes after them)
        assert state_size(layout) == x.shape[0] == xdot.shape[0]
        assert sum(s.size for s in shipped) == 2 * model.n + n_pressures(model) + 2 * model.n_cylinders + pumped
        assert [s.name for s in shipped] == ["q", "qdot", "pc", "spool", "spool_rate"] + ["ps"] * pumped
        assert layout[:len(shipped)] == tuple(shipped)
        for s in layout:  # each part's symbols sit at its slice: the generated function's x input
            prefix = "q_" if s.name == "q" else f"{s.name}_"
            got = [str(v) for v in x[s.start:s.stop]]
            assert all(g.startswith(prefix) and not g[len(prefix):].startswith("rate") for g in got), (model.name, s, got)
            assert len(got) == s.size
        assert list(slot(layout, "q").entries) == list(model.coordinate_names)
        lo, hi = bounds(model)  # the kind's; a supply state lifts the top to its ceiling
        assert np.array_equal(slot(layout, "pc").lower, lo)
        assert np.array_equal(slot(layout, "pc").upper, np.maximum(hi, supply.ceiling(model)) if pumped else hi)


def test_the_layout_matches_each_shipped_manifests_plant_input():
    """The committed generated code's plant_rhs takes x of the layout's size, and the manifest records
    the layout the C loop is rendered from."""
    import json
    root = Path(__file__).resolve().parent.parent / "generated"
    for name in hydrogen.models():
        manifest = json.loads((root / name / "manifest.json").read_text())
        (fn,) = [f for f in manifest["functions"] if f["name"] == "plant_rhs"]
        layout = plant_layout(hydrogen.load_model(name))
        assert dict((i[0], i[1]) for i in fn["inputs"])["x"] == state_size(layout)
        assert manifest["model"]["plant"] == [{"name": s.name, "size": s.size_name, "start": s.start,
                                               "entries": s.size, "output": s.output} for s in layout]


def test_a_new_blocks_states_appear_in_the_layout(model):
    extra = types.ModuleType("hydrogen.plant.supply")
    extra.STATES = (PlantState("p_supply", "m", "Pa", "supply pressure at each valve", lower=0.0, upper=3e7),
                    PlantState("flow", "n", "m3/s", "a flow per coordinate"))
    mods = [block(b) for b in BLOCKS] + [extra]
    layout = plant_layout(model, mods)
    base = state_size(plant_layout(model))
    new = slot(layout, "p_supply")
    assert (new.block, new.start, new.size, new.units[0], new.upper[0]) == ("supply", base, model.n_cylinders,
                                                                            "Pa", 3e7)
    assert slot(layout, "flow").start == base + model.n_cylinders
    assert state_size(layout) == base + model.n_cylinders + model.n
    assert entry_names(layout)[base] == f"p_supply[{model.cylinders[0].name}]"
    with pytest.raises(KeyError, match="no part 'nope'"):
        slot(layout, "nope")


def test_entries_are_named_by_their_part(model):
    layout = plant_layout(model)
    pc = slot(layout, "pc")
    text = describe_entries(layout, [0, pc.start + 1, slot(layout, "spool_rate").stop - 1])
    assert text == (f"q[{model.coordinate_names[0]}], pc[{model.cylinders[1].name}.pc], "
                    f"spool_rate[{model.cylinders[-1].name}]")


@pytest.mark.parametrize("par", [(0.0, 0.0, 0.0, 0.0, 0.0), (0.02, 0.0, 0.0, 0.0, 0.0), (0.02, 300.0, 0.7, 0.0, 0.0),
                                 (0.0, 150.0, 1.1, 0.0, 0.0), (0.0, 150.0, 1.1, 4e-4, 1.5e-3), (0.0, 0.0, 0.0, 0.0, 5e-4)])
def test_the_valves_sympy_and_numpy_laws_agree(par):
    rng = np.random.default_rng(3)
    m = 4
    s, r, u = (rng.normal(size=m) * 1e-3 for _ in range(3))
    sy = [sp.Matrix(sp.symbols(f"{k}0:{m}", real=True)) for k in ("s", "r", "u")]
    vs = valve.Symbolic.parameters(m)
    par = np.tile(par, m)
    subs = {**dict(zip(sy[0], s)), **dict(zip(sy[1], r)), **dict(zip(sy[2], u)), **dict(zip(vs, par))}
    rates_s = valve.Symbolic.rates(*sy, vs)
    rates_n = valve.Numeric.rates(s, r, u, par)
    for k in ("spool", "spool_rate"):
        assert np.allclose(np.array(rates_s[k].subs(subs), float).ravel(), rates_n[k], rtol=1e-12, atol=0)
    # with both terms (a datasheet valve's; o = 0 or S = 0 takes away exactly 0), as numpy always has them
    eff = np.array(valve.Symbolic.effective(sy[0], sy[2], vs, [(True, True)] * m).subs(subs), float).ravel()
    assert np.array_equal(eff, valve.Numeric.effective(s, u, par))
    plain = valve.Symbolic.effective(sy[0], sy[2], vs)  # no datasheet valve: no saturation, no dead band
    assert not plain.atoms(sp.Min, sp.Max)
    if not par[3] and not par[4]:  # no dead band, no saturation: the spool state, or the command
        assert np.array_equal(eff, u if tuple(par[:2]) == (0.0, 0.0) else s)
        assert np.array_equal(np.array(plain.subs(subs), float).ravel(), eff)


def test_each_block_declares_its_states_and_parameters():
    for name in BLOCKS + ("friction",):
        mod = block(name)
        assert isinstance(mod.STATES, tuple) and isinstance(mod.PARAMETERS, tuple)
        assert hasattr(mod, "Symbolic")
    from hydrogen.actuators.declarations import ANGLE
    assert [p.unit_of(ANGLE) for p in friction.PARAMETERS][:3] == ["N m", "N m s/rad", "rad/s"]
