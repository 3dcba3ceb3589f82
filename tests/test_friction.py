"""The plant's seal friction (hydrogen/plant/friction.py): the Stribeck law against its formula, its
SymPy and numpy forms equal, the pressure load per kind; its terms structure (generated only for an
actuator whose description declares them); the description's and the rig's tables; closed-loop runs."""
from __future__ import annotations

import math
import re
import tomllib

import numpy as np
import pytest
import sympy as sp

import hydrogen
from hydrogen.actuators import KINDS, actuator
from hydrogen.model import model_from_dict, model_path
from hydrogen.plant import friction
from hydrogen.simulation.scenarios import actuator_settings, scenario
from hydrogen.simulation.simulator import simulate

from conftest import plain_stewart_data

NAMES = [p.name for p in friction.PARAMETERS]


def _law(v, coulomb=0.0, viscous=0.0, smooth_speed=1e-3, breakaway=None, stribeck_speed=1.0,
         pressure_coefficient=0.0, seal_load=0.0):
    """The numeric twin with the parameters by name (breakaway None: the Coulomb force)."""
    row = friction.row(coulomb, viscous, smooth_speed, breakaway, stribeck_speed, pressure_coefficient)
    return friction.Numeric.force(v, *row, seal_load)


def _formula(v, fc, b, vs, fbrk, vst, kp, s):
    """The docstring's law, written out independently."""
    return (fc + kp * s + (fbrk - fc) * math.exp(-(v / vst) ** 2)) * math.tanh(v / vs) + b * v


ARGS = [(0.03, 500.0, 2e3, 1e-3, 800.0, 0.01, 0.002, 4e4), (-0.2, 80.0, 10.0, 0.05, 80.0, 1.0, 0.0, 0.0),
        (0.0, 1.0, 1.0, 1.0, 2.0, 0.5, 0.1, 3.0), (-4e-3, 300.0, 0.0, 1e-3, 450.0, 2e-2, 1e-3, 1e5)]


@pytest.mark.parametrize("args", ARGS)
def test_the_sympy_and_numpy_laws_agree_with_the_formula(args):
    v, fc, b, vs, fbrk, vst, kp, s = syms = sp.symbols("v fc b vs fbrk vst kp s", real=True)
    law = sp.lambdify(syms, friction.Symbolic.force(v, fc, b, vs, (fbrk, vst), (kp, s)), "math")
    assert friction.Numeric.force(*args) == pytest.approx(law(*args), rel=1e-14, abs=1e-12)
    assert friction.Numeric.force(*args) == pytest.approx(_formula(*args), rel=1e-13, abs=1e-12)


def test_without_its_terms_the_symbolic_law_is_todays_expression():
    """No term declared: F_c tanh(l̇/v_s) + b l̇, the very expression (so the generated plant is too);
    one term declared: that term alone is added."""
    v, fc, b, vs, fbrk, vst, kp, s = sp.symbols("v fc b vs fbrk vst kp s", real=True)
    today = fc * sp.tanh(v / vs) + b * v
    assert friction.Symbolic.force(v, fc, b, vs) == today
    assert sp.simplify(friction.Symbolic.force(v, fc, b, vs, pressure=(kp, s)) - today
                       - kp * s * sp.tanh(v / vs)) == 0
    assert sp.simplify(friction.Symbolic.force(v, fc, b, vs, stribeck=(fbrk, vst)) - today
                       - (fbrk - fc) * sp.exp(-(v / vst) ** 2) * sp.tanh(v / vs)) == 0


def test_with_no_new_keys_the_law_is_todays_bit_for_bit():
    v = np.linspace(-0.3, 0.3, 2001)
    for fc, b, vs in ((100.0, 300.0, 1e-3), (3000.0, 2e4, 1e-3), (0.0, 0.0, 1e-3)):
        today = fc * np.tanh(v / vs) + b * v
        np.testing.assert_array_equal(_law(v, fc, b, vs, seal_load=7e4), today)


def test_the_breakaway_force_is_reached_near_zero_speed():
    fc, fbrk, vs, vst = 100.0, 160.0, 1e-5, 0.02
    v = 20 * vs  # tanh saturated, far below the Stribeck speed
    f = _law(v, fc, 0.0, vs, fbrk, vst)
    assert f == pytest.approx(_formula(v, fc, 0.0, vs, fbrk, vst, 0.0, 0.0), rel=1e-14)
    assert f == pytest.approx(fbrk, rel=1e-4) and _law(-v, fc, 0.0, vs, fbrk, vst) == -f
    assert _law(0.0, fc, 0.0, vs, fbrk, vst) == 0.0  # smooth through zero speed: no force at rest


def test_the_stribeck_dip_falls_from_breakaway_to_coulomb():
    fc, fbrk, vs, vst = 100.0, 160.0, 1e-4, 0.02
    v = np.linspace(20 * vs, 5 * vst, 400)
    f = _law(v, fc, 0.0, vs, fbrk, vst)
    assert np.all(np.diff(f) < 0)  # no viscous term: the level only falls
    # at the Stribeck speed the excess is down to 1/e of its value, at 5 v_st it is gone
    assert _law(vst, fc, 0.0, vs, fbrk, vst) == pytest.approx(fc + (fbrk - fc) / math.e, rel=1e-12)
    assert f[-1] == pytest.approx(fc, rel=1e-9)


def test_the_viscous_slope_is_b_beyond_the_dip():
    fc, b, fbrk, vs, vst = 100.0, 300.0, 160.0, 1e-4, 0.02
    v, dv = 0.5, 1e-6  # 25 Stribeck speeds: the level is flat, the slope is b
    slope = (_law(v + dv, fc, b, vs, fbrk, vst) - _law(v - dv, fc, b, vs, fbrk, vst)) / (2 * dv)
    assert slope == pytest.approx(b, rel=1e-6)


def test_the_pressure_term_raises_the_coulomb_level_by_k_p_times_the_seal_load():
    fc, kp, s, vs = 100.0, 2e-3, 5e4, 1e-3
    for v in (-0.1, 3e-4, 0.2):
        extra = _law(v, fc, 0.0, vs, pressure_coefficient=kp, seal_load=s) - _law(v, fc, 0.0, vs)
        assert extra == pytest.approx(kp * s * math.tanh(v / vs), rel=1e-12)


@pytest.mark.parametrize("kind", KINDS)
def test_each_kinds_chamber_forces_sum_to_its_force_and_load_the_seals(kind):
    """The seal load is Σ |chamber force| from the kind's own force law, SymPy and numpy alike."""
    from pathlib import Path
    mod = actuator(kind)  # each kind's example constants, as tests/test_actuators.py reads them
    example = tomllib.loads((Path(__file__).parent / "data" / "actuators" / f"{kind}.toml").read_text())
    P = mod.parameters(example["parameters"])
    p = tuple(0.3e6 + 1e6 * (i + 1) for i in range(len(mod.STATES)))
    parts = mod.Numeric.chamber_forces(p, P)
    assert sum(parts) == pytest.approx(mod.Numeric.force(p, P), rel=1e-12, abs=1e-9)
    load = friction.Numeric.seal_load(parts)
    assert load == pytest.approx(sum(abs(f) for f in parts), rel=1e-15)
    sym = friction.Symbolic.seal_load(mod.Symbolic.chamber_forces(p, P))
    assert float(sym) == pytest.approx(load, rel=1e-12)


def test_the_plant_input_declares_each_parameter_per_actuator():
    from hydrogen.actuators.declarations import ANGLE, LENGTH
    from hydrogen.layout import predictor_model
    pred = predictor_model({"seal_friction": True})
    assert NAMES == ["coulomb", "viscous", "smooth_speed", "breakaway", "stribeck_speed", "pressure_coefficient"]
    assert [p.unit_of(LENGTH) for p in friction.PARAMETERS] == ["N", "N s/m", "m/s", "N", "m/s", ""]
    assert [p.unit_of(ANGLE) for p in friction.PARAMETERS] == ["N m", "N m s/rad", "rad/s", "N m", "rad/s", ""]
    # without seal friction the input is [F_c, b, v_s] per actuator, as it always was
    assert [p.name for p in friction.parameters_of(False)] == NAMES[:3]
    assert len(friction.Symbolic.parameters(3)) == 9 and len(friction.Symbolic.parameters(3, True)) == 18
    assert len(pred["friction"]) == len(NAMES) and set(friction.LOWER) == set(NAMES)
    assert len(predictor_model({})["friction"]) == 3  # without seal friction: [F_c, b, v_s]
    # the predictor's row is no friction at all, whatever terms a plant has
    assert _law(0.37, *pred["friction"], seal_load=1e5) == 0.0


# --- structure: the terms an actuator's description declares ------------------------------------

SEALS = {"coulomb": 100.0, "breakaway": 160.0, "stribeck_speed": 0.02, "viscous": 300.0,
         "pressure_coefficient": 1e-3}


def _stewart(**tables):
    """ubc_stewart without its datasheet valve and seal friction (conftest.plain_stewart_data), with
    each ``leg=table`` as that leg's own seal friction table."""
    data = plain_stewart_data()
    for cy in data["cylinders"]:
        if cy["name"] in tables:
            cy["friction"] = tables[cy["name"]]
    return model_from_dict(data, "seals.toml")


@pytest.fixture(scope="module")
def model(plain_stewart):
    """The Stewart platform without seal friction: the plant whose structure the terms change."""
    return plain_stewart


@pytest.fixture(scope="module")
def dyn(plain_stewart_dyn):
    return plain_stewart_dyn


def test_the_hydraulics_table_gives_every_actuator_without_its_own_table_its_seal_friction():
    shipped = hydrogen.load_model("ubc_stewart")
    assert all(c.friction == shipped.cylinders[0].friction and c.seal_terms == (True, True) for c in shipped.cylinders)
    m = _stewart(leg2={"coulomb": 50.0})
    assert m.cylinders[1].friction == {"coulomb": 50.0} and all(c.friction is None for c in m.cylinders if c.name != "leg2")
    data = tomllib.loads(model_path("ubc_stewart").read_text())  # as shipped
    data["cylinders"][2]["friction"] = {"pressure_coefficient": 2e-3}
    own = model_from_dict(data, "seals.toml")
    assert own.cylinders[2].friction == {"pressure_coefficient": 2e-3}  # its own replaces the shared one whole
    assert [c.friction for i, c in enumerate(own.cylinders) if i != 2] == [shipped.cylinders[0].friction] * 5
    data["hydraulics"]["friction"] = {"breakaway": 1.0, "coulomb": 2.0}
    with pytest.raises(hydrogen.ModelError, match=r"seals\.toml: \[hydraulics\] friction\.breakaway: must be >= coulomb"):
        model_from_dict(data, "seals.toml")


@pytest.mark.parametrize("table, terms", [
    ({"breakaway": 160.0, "stribeck_speed": 0.02}, (True, False)),
    ({"pressure_coefficient": 1e-3}, (False, True)),
    (SEALS, (True, True)),
    ({"coulomb": 100.0, "breakaway": 100.0, "viscous": 50.0}, (False, False)),  # no excess: no dip
    ({"coulomb": 100.0, "pressure_coefficient": 0.0}, (False, False)),
])
def test_a_description_declares_its_terms_and_only_those_change_the_structure(model, table, terms):
    m = _stewart(leg2=table)
    assert [c.seal_terms for c in m.cylinders] == [(False, False), terms] + [(False, False)] * 4
    assert m.seal_friction == any(terms)
    assert (m.structure() != model.structure()) == any(terms)
    assert "seal_terms" not in str(model.baked())  # a robot without seal friction hashes as before


def _forces(m):
    """The plant's actuator forces less friction (its f_leg intermediate) and its friction input."""
    from hydrogen.symbolic.plant import plant_rhs
    inputs, _, inter = plant_rhs(m)
    f_leg = next(value for sym, value in inter if str(sym[0]).startswith("plant_fleg"))
    return f_leg, dict(inputs)["friction"]


def test_without_seal_friction_the_plant_is_the_term_free_form(model):
    """Each actuator's force less F_c tanh(l̇/v_s) + b l̇ (written here, not by the friction block), the
    input [F_c, b, v_s] per actuator, and no other trace of friction in the plant's forces."""
    f_leg, fric = _forces(model)
    assert fric.shape == (3 * model.n_cylinders, 1)
    for i in range(model.n_cylinders):
        fc, visc, vs = fric[3 * i:3 * i + 3]
        ld = next(s for s in f_leg[i].free_symbols if s.name == f"plant_ldot_{i}")
        pushed = f_leg[i].subs({fc: 0, visc: 0})  # the pressures' force alone
        assert not pushed.has(ld) and not pushed.has(vs)
        assert sp.expand(f_leg[i] - (pushed - (fc * sp.tanh(ld / vs) + visc * ld))) == 0
        assert not f_leg[i].atoms(sp.exp, sp.Abs)


def test_with_seal_friction_only_the_declaring_actuator_gets_its_terms(model):
    f_leg, fric = _forces(_stewart(leg1=SEALS, leg3={"pressure_coefficient": 2e-3}))
    plain, _ = _forces(model)
    assert fric.shape == (6 * 6, 1)  # every actuator's six numbers, the seal's used where declared
    assert f_leg[0].atoms(sp.exp) and f_leg[0].atoms(sp.Abs)  # the Stribeck dip and the pressure load
    assert f_leg[2].atoms(sp.Abs) and not f_leg[2].atoms(sp.exp)  # the pressure load alone
    used = {str(s) for s in f_leg.free_symbols}
    assert {"F_breakaway_0", "v_stribeck_0", "k_pressure_0", "k_pressure_2"} <= used
    assert not {"F_breakaway_1", "k_pressure_1", "F_breakaway_2", "v_stribeck_2"} & used
    for i in (1, 3, 4, 5):  # the others: today's expression, its symbols the same
        assert f_leg[i] == plain[i]


@pytest.mark.parametrize("table, text", [
    ({"coulomb": 100.0, "breakaway": 90.0}, "friction.breakaway: must be >= coulomb"),
    ({"breakaway": 120.0}, "friction.stribeck_speed: must be given"),
    ({"breakaway": 120.0, "stribeck_speed": 0.0}, "friction.stribeck_speed: must be a finite number > 0.0"),
    ({"pressure_coefficient": -1e-3}, "friction.pressure_coefficient: must be a finite number >= 0.0"),
    ({"viscous": "300"}, "friction.viscous: must be a finite number"),
    ({"static": 1.0}, "friction: unknown key(s) ['static']"),
    ([100.0, 300.0, 1e-3], "friction: expected a table"),
])
def test_a_bad_description_table_is_refused_by_name(table, text):
    with pytest.raises(hydrogen.ModelError) as err:
        _stewart(leg2=table)
    assert "seals.toml: [[cylinders]] 'leg2' " in str(err.value) and text in str(err.value)


# --- the rig's per-actuator table: numbers only --------------------------------------------------

def test_the_description_gives_the_actuators_friction_and_the_rig_overrides_it_key_by_key():
    m = _stewart(leg1=SEALS)
    sc = scenario("z-1hz", m)  # the rig's friction [100, 300, 1e-3] for every leg
    rows = actuator_settings(sc, m)["friction"]
    assert rows.shape == (m.n_cylinders, len(NAMES))
    assert dict(zip(NAMES, rows[0])) == {**SEALS, "smooth_speed": sc.friction[2]}
    np.testing.assert_array_equal(rows[1], friction.row(*sc.friction))  # the rig's, no seal numbers used
    ideal = scenario("paper-sim", m)  # friction off: the ideal plant stays frictionless, seals and all
    plain = actuator_settings(ideal, m)["friction"]
    np.testing.assert_array_equal(plain[0], friction.row(0.0, 0.0, ideal.friction[2], None, 1.0, 0.0))
    on = actuator_settings(ideal.with_overrides(friction=(1.0, 0.0, 1e-3)), m)["friction"]
    assert dict(zip(NAMES, on[0])) == {**SEALS, "smooth_speed": 1e-3}  # friction on: the description's numbers
    given = actuator_settings(ideal.with_overrides(actuators={"leg1": {"friction": {"viscous": 7.0}}}), m)
    assert dict(zip(NAMES, given["friction"][0])) == {**SEALS, "smooth_speed": 1e-3, "viscous": 7.0}
    over = sc.with_overrides(actuators={"leg1": {"friction": {"breakaway": 200.0, "pressure_coefficient": 0.0}}})
    row = dict(zip(NAMES, actuator_settings(over, m)["friction"][0]))
    assert row == {**SEALS, "smooth_speed": 1e-3, "breakaway": 200.0, "pressure_coefficient": 0.0}


@pytest.mark.parametrize("seals, match", [
    ({"coulomb": 100.0, "breakaway": 160.0, "stribeck_speed": 0.02}, r"actuators\.leg1\.friction\.breakaway = 160\.0 "
     r"asks for the seal friction's Stribeck dip, which actuator 'leg1''s plant is generated without"),
    ({"pressure_coefficient": 1e-3}, r"actuators\.leg1\.friction\.pressure_coefficient = 0\.001 asks for the seal "
     r"friction's pressure load"),
    ({"breakaway": 160.0}, r"actuators\.leg1\.friction\.stribeck_speed must be given"),
])
def test_a_scenario_may_not_ask_for_a_term_the_plant_is_built_without(model, seals, match):
    sc = scenario("z-1hz", model).with_overrides(actuators={"leg1": {"friction": seals}})
    with pytest.raises(hydrogen.ScenarioError, match=match):
        actuator_settings(sc, model)


def test_a_description_breakaway_below_the_scenarios_coulomb_is_named():
    m = _stewart(leg1={"breakaway": 80.0, "stribeck_speed": 0.02})
    actuator_settings(scenario("paper-sim", m), m)  # no Coulomb friction there: fine
    with pytest.raises(hydrogen.ScenarioError, match=r"scenario 'z-1hz': actuators\.leg1\.friction\.breakaway must "
                       r"be >= coulomb \(100\.0\), got 80\.0 .*\(breakaway from its description\)"):
        actuator_settings(scenario("z-1hz", m), m)


@pytest.mark.parametrize("seals, match", [
    ({"coulomb": 100.0, "breakaway": 90.0}, r"actuators\.leg1\.friction\.breakaway must be >= coulomb"),
    ({"coulomb": 100.0, "breakaway": 120.0, "stribeck_speed": -0.01}, r"friction\.stribeck_speed must be .*> 0"),
    ({"coulomb": 100.0, "smooth_speed": -1e-3}, r"friction\.smooth_speed must be .*> 0"),
    ({"coulomb": -1.0}, r"friction\.coulomb must be .*>= 0"),
    ({"viscous": float("nan")}, r"friction\.viscous must be a finite number"),
    ({"pressure_coefficient": -1e-3}, r"friction\.pressure_coefficient must be .*>= 0"),
    ({"static": 1.0}, r"actuators\.leg1\.friction: unknown key\(s\) \['static'\]"),
])
def test_bad_seal_friction_is_refused_by_name(model, seals, match):
    with pytest.raises(hydrogen.ScenarioError, match=match):
        scenario("z-1hz", model).with_overrides(actuators={"leg1": {"friction": seals}})


def test_todays_friction_as_a_table_runs_bit_for_bit_as_the_list(dyn):
    """The table with only today's keys is today's law: the whole run is unchanged."""
    listed = {c.name: {"friction": [100.0, 300.0, 1e-3]} for c in dyn.model.cylinders}
    table = {c.name: {"friction": {"coulomb": 100.0, "viscous": 300.0, "smooth_speed": 1e-3}}
             for c in dyn.model.cylinders}
    a = simulate(dyn, "z-1hz", "backstepping", duration=0.3, actuators=listed)
    b = simulate(dyn, "z-1hz", "backstepping", duration=0.3, actuators=table)
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.u, b.u)


def test_seal_friction_builds_runs_closed_loop_and_the_two_loops_agree(dyn):
    m = _stewart(leg1=SEALS, leg4={"pressure_coefficient": 2e-3})
    d = hydrogen.build(m)
    fn = {f["name"]: f for f in d.library.manifest["functions"]}["plant_rhs"]
    shipped = {f["name"]: f for f in dyn.library.manifest["functions"]}["plant_rhs"]
    assert dict((k, n) for k, n, _ in fn["inputs"])["friction"] == 36
    assert dict((k, n) for k, n, _ in shipped["inputs"])["friction"] == 18
    assert fn["instructions"] > shipped["instructions"]  # the terms, on two legs
    c = simulate(d, "z-1hz", "backstepping", duration=0.3)
    py = simulate(d, "z-1hz", "backstepping", duration=0.3, engine="python")
    plain = simulate(dyn, "z-1hz", "backstepping", duration=0.3)
    assert np.all(np.isfinite(c.q)) and c.t[-1] >= 0.3 - 2 / c.scenario.control_rate
    np.testing.assert_allclose(c.q, py.q, atol=1e-10)
    assert not np.array_equal(c.q, plain.q)  # the seals act


def test_the_description_reference_lists_the_tables_keys():
    from hydrogen import schema
    assert schema.keys("[[cylinders]] friction") == set(friction.KEYS)
    assert "friction" in schema.keys("[[cylinders]]")


def test_the_cli_names_a_scenarios_seal_term_the_plant_lacks_without_a_traceback(dyn, tmp_path, capsys):
    from hydrogen import cli
    from hydrogen.model import default_model_path
    path = tmp_path / "seals.toml"
    text = re.sub(r"(?m)^friction = \{[^\n]*\}\n", "", default_model_path().read_text())  # [hydraulics]' table
    assert "stribeck_speed" not in text
    path.write_text(text + "\n[variants.seals]\n"
                    "actuators.leg2.friction = { breakaway = 160.0, stribeck_speed = 0.02 }\n")
    assert cli.main(["simulate", "--model", str(path), "--scenario", "z-1hz.seals", "--controller", "p",
                     "--duration", "0.05"]) == 2
    err = capsys.readouterr().err
    assert "actuators.leg2.friction.breakaway = 160.0 asks for the seal friction's Stribeck dip" in err
    assert "Traceback" not in err
