"""Laminar leakage of the actuators: across the piston and to tank on the two-chamber kinds
(``leakage_internal``, ``leakage_external``), the paper's c_l of (56) on the three-way cylinder
(``leakage``), Q = C Δp in m³/(s Pa). Checked against closed forms (a blocked actuator's pressures
relax along exponentials), against (56) as printed, SymPy against numpy, and in a closed loop; a
coefficient of 0 (the default) is structure: the generated code and the hash are those without it."""
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import hydrogen
from hydrogen.actuators import actuator
from hydrogen.errors import HydrogenError

from test_model import FOUR_WAY_ARM, mixed_arm_text
from reference import rk4

KINDS = Path(__file__).parent / "data" / "actuators"
TWO_CHAMBER = ("four_way_cylinder", "rotary", "motor")


def _example(kind, **extra):
    """The kind's example (tests/data/actuators), its parameters with ``extra`` over them, and its range."""
    data = tomllib.loads((KINDS / f"{kind}.toml").read_text())
    mod = actuator(kind)
    return mod, mod.parameters({**data["parameters"], **extra}), data["range"]


# --- closed forms --------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", TWO_CHAMBER)
def test_internal_leakage_equalises_a_blocked_actuators_chambers(kind):
    """Valve closed (u = 0, no underlap), ẋ = 0: Δ = p_A − p_B decays as e^{−t/τ} with
    1/τ = β C_i (1/V_A + 1/V_B), and the oil V_A p_A + V_B p_B is conserved."""
    ci, beta = 3e-12, 1e9
    mod, P, (lo, hi) = _example(kind, underlap=0.0, leakage_internal=ci, bulk_modulus=beta)
    x = 0.5 * (lo + hi)
    va, vb = (float(v) for v in mod.Numeric.volumes(x, P)) if hasattr(mod.Numeric, "volumes") else (None, None)
    tau = 1.0 / (beta * ci * (1 / va + 1 / vb))
    p0 = np.array([15e6, 4e6])

    def rates(p, smooth=True):
        return np.array(mod.Numeric.pressure_rates(x, 0.0, tuple(p), 0.0, beta, P["flow_gain"], P, smooth=smooth))

    for smooth in (True, False):  # the plant's law and the controllers' clipped one alike
        d0 = p0[0] - p0[1]
        np.testing.assert_allclose(rates(p0, smooth), [-beta * ci * d0 / va, beta * ci * d0 / vb], rtol=1e-12)
    t = 0.7 * tau
    p = rk4(rates, p0, t / 2000, 2000)
    np.testing.assert_allclose(p[0] - p[1], (p0[0] - p0[1]) * math.exp(-t / tau), rtol=1e-9)
    np.testing.assert_allclose(va * p[0] + vb * p[1], va * p0[0] + vb * p0[1], rtol=1e-12)


@pytest.mark.parametrize("kind", TWO_CHAMBER)
def test_external_leakage_drains_each_chamber_to_tank(kind):
    """Valve closed, ẋ = 0: each chamber's p − P_t decays with time constant V/(β C_e)."""
    ce, beta = 2e-12, 1.2e9
    mod, P, (lo, hi) = _example(kind, underlap=0.0, leakage_external=ce, bulk_modulus=beta)
    x = lo + 0.3 * (hi - lo)
    va, vb = (float(v) for v in mod.Numeric.volumes(x, P))
    pt, p0 = P["tank_pressure"], np.array([12e6, 6e6])

    def rates(p):
        return np.array(mod.Numeric.pressure_rates(x, 0.0, tuple(p), 0.0, beta, P["flow_gain"], P))

    t = 0.5 * va / (beta * ce)
    p = rk4(rates, p0, t / 2000, 2000)
    np.testing.assert_allclose(p - pt, (p0 - pt) * np.exp(-t * beta * ce / np.array([va, vb])), rtol=1e-9)


def test_the_three_way_cylinders_leakage_is_56():
    """(56) as printed: V_t/β ṗ_c = q_l + c_l (P_s − p_c) − V̇_t, V_t = A (l − L), at any state; and
    blocked with the valve closed, p_c relaxes to P_s with time constant V_t/(β c_l)."""
    cl = 4e-12
    mod, P, (lo, hi) = _example("three_way_cylinder", leakage=cl)
    A, L, ps, beta, c = P["piston_area"], P["chamber_length"], P["supply_pressure"], P["bulk_modulus"], P["flow_gain"]
    rng = np.random.default_rng(5)
    for _ in range(20):
        l, ld, pc, u = rng.uniform(lo, hi), rng.normal(0, 0.1), rng.uniform(0.5e6, 9e6), rng.uniform(-1e-3, 1e-3)
        (rate,) = mod.Numeric.pressure_rates(l, ld, (pc,), u, beta, c, P, smooth=False)
        ql = c * mod.Numeric.valve_flow(u, (pc,), P)
        Vt = A * (l - L)
        np.testing.assert_allclose(Vt / beta * rate, ql + cl * (ps - pc) - A * ld, rtol=1e-10, atol=1e-18)
    P0 = {**P, "underlap": 0.0}
    l = 0.5 * (lo + hi)
    Vt, p0 = A * (l - L), np.array([2e6])

    def rates(p):
        return np.array(mod.Numeric.pressure_rates(l, 0.0, (p[0],), 0.0, beta, c, P0))

    t = 0.8 * Vt / (beta * cl)
    p = rk4(rates, p0, t / 2000, 2000)
    np.testing.assert_allclose(ps - p[0], (ps - p0[0]) * math.exp(-t * beta * cl / Vt), rtol=1e-9)


@pytest.mark.parametrize("kind", TWO_CHAMBER + ("three_way_cylinder",))
def test_f0_carries_the_leakage_so_the_force_rate_is_beta_f0_plus_beta_c_g0(kind):
    """ḟ (chain rule of the pressure rates, the controllers' clipped law) = β f0 + βc g0 with leakage:
    the controllers' f0 knows it; and the SymPy laws give the numpy laws' numbers."""
    extra = {"leakage": 3e-12} if kind == "three_way_cylinder" else {"leakage_internal": 3e-12,
                                                                     "leakage_external": 1e-12}
    mod, P, (lo, hi) = _example(kind, **extra)
    beta, c = P["bulk_modulus"], P["flow_gain"]
    top = P["supply_pressure"]
    rng = np.random.default_rng(7)
    syms = sp.symbols("x xd u p0 p1", real=True)
    x_, xd_, u_ = syms[:3]
    ps_ = syms[3:3 + len(mod.STATES)]
    Ps = {k: sp.Float(v) for k, v in P.items()}
    sym_rates = sp.lambdify(syms[:3 + len(ps_)], list(mod.Symbolic.pressure_rates(x_, xd_, ps_, u_, beta, c, Ps)))
    sym_f0 = sp.lambdify(syms[:2] + ps_, mod.Symbolic.f0(x_, xd_, ps_, Ps))
    for _ in range(20):
        x, xd, u = rng.uniform(lo, hi), rng.normal(0, 0.1), rng.uniform(-1e-3, 1e-3)
        p = tuple(rng.uniform(0.1 * top, 0.9 * top, len(mod.STATES)))
        rates = np.array(mod.Numeric.pressure_rates(x, xd, p, u, beta, c, P, smooth=False))
        h = 1.0
        fdot = (mod.Numeric.force(tuple(np.array(p) + h * rates), P) - mod.Numeric.force(p, P)) / h  # f linear in p
        f0, g0 = mod.Numeric.f0(x, xd, p, P), mod.Numeric.g0(x, p, u, P)
        np.testing.assert_allclose(fdot, beta * f0 + beta * c * g0, rtol=1e-9)
        np.testing.assert_allclose(sym_rates(x, xd, u, *p), np.array(mod.Numeric.pressure_rates(x, xd, p, u, beta, c, P)),
                                   rtol=1e-12)
        np.testing.assert_allclose(sym_f0(x, xd, *p), f0, rtol=1e-12)


# --- structure: no leakage, no terms -------------------------------------------------------------

def _arm(tmp_path, extra="", name="arm.toml"):
    text = FOUR_WAY_ARM.read_text().replace("orifice_linear_below = 5.0e4\n", "orifice_linear_below = 5.0e4\n" + extra, 1)
    path = tmp_path / name
    path.write_text(text)
    return hydrogen.load_model(path)


def test_a_zero_leakage_is_structure_and_a_nonzero_one_a_number(tmp_path):
    """A leakage of 0 given (or left out) hashes as no leakage and leaves no number in the derivation
    with the numbers as inputs; a nonzero one changes the hash and enters the plant's and the
    controllers' laws as a number."""
    from hydrogen.codegen.generate import structure_hash
    from hydrogen.symbolic.constants import numbers_as_symbols
    from hydrogen.symbolic.functions import hydraulic_functions
    from hydrogen.symbolic.control_laws import Common

    plain = _arm(tmp_path)
    zero = _arm(tmp_path, "leakage_internal = 0.0\nleakage_external = 0\n", "zero.toml")
    leaky = _arm(tmp_path, "leakage_internal = 2e-12\n", "leaky.toml")
    assert zero.baked_hash() == plain.baked_hash() and structure_hash(zero) == structure_hash(plain)
    assert leaky.baked_hash() != plain.baked_hash() and structure_hash(leaky) != structure_hash(plain)
    assert leaky.numbers()["shoulder_cylinder.leakage_internal"] == 2e-12

    def met(model):
        with numbers_as_symbols() as table:
            hydraulic_functions(model)
            common = Common(model)
            common.laws[0].f0(common.l[0], common.ldot[0], common.pb[0], common.P[0])
        return {n for n in table.names if n and "leakage" in n}

    assert met(zero) == set()
    assert met(leaky) == {"shoulder_cylinder.leakage_internal", "elbow_cylinder.leakage_internal"}


def test_a_three_way_cylinders_zero_leakage_keeps_its_hash(tmp_path):
    text = mixed_arm_text("four_way")
    head = 'chamber_length = 0.2               # L, m: 0.02 m below the shortest length\n'
    assert head in text
    models = []
    for i, extra in enumerate(("", "leakage = 0.0\n", "leakage = 1e-12\n")):
        path = tmp_path / f"mixed{i}.toml"
        path.write_text(text.replace(head, head + extra, 1))
        models.append(hydrogen.load_model(path))
    plain, zero, leaky = models
    assert zero.baked_hash() == plain.baked_hash()
    assert leaky.baked_hash() != plain.baked_hash()
    assert leaky.cylinders[0].table["leakage"] == 1e-12 and plain.cylinders[0].table["leakage"] == 0.0


@pytest.mark.parametrize("key", ["leakage_internal", "leakage_external"])
def test_a_negative_leakage_is_refused_by_name(tmp_path, key):
    with pytest.raises(HydrogenError, match=rf"\[hydraulics\] {key}.*-1e-12"):
        _arm(tmp_path, f"{key} = -1e-12\n")


def test_a_negative_three_way_leakage_is_refused_by_name(tmp_path):
    text = mixed_arm_text("four_way").replace('rod_area = 4.0e-4', 'rod_area = 4.0e-4\nleakage = -2e-12', 1)
    path = tmp_path / "neg.toml"
    path.write_text(text)
    with pytest.raises(HydrogenError, match=r"'shoulder_cylinder' leakage.*-2e-12"):
        hydrogen.load_model(path)


# --- a robot with leakage, built and run ---------------------------------------------------------

@pytest.fixture(scope="module")
def leaky_dyn(cache, tmp_path_factory):
    """The mixed arm (three-way shoulder, four-way elbow), both leaking."""
    text = mixed_arm_text("four_way")
    text = text.replace('rod_area = 4.0e-4', 'rod_area = 4.0e-4\nleakage = 1e-12', 1)
    text = text.replace("orifice_linear_below = 5.0e4\n",
                        "orifice_linear_below = 5.0e4\nleakage_internal = 2e-12\nleakage_external = 5e-13\n", 1)
    path = tmp_path_factory.mktemp("leaky") / "leaky_arm.toml"
    path.write_text(text)
    return hydrogen.build(hydrogen.load_model(path), cache=cache)


def test_the_generated_plant_leaks_as_the_laws_say(leaky_dyn, rng):
    model = leaky_dyn.model
    q = model.neutral_pose
    l, ldot = leaky_dyn.leg_lengths(q), leaky_dyn.leg_jacobian(q) @ (0.1 * rng.normal(size=model.n))
    p, u = rng.uniform(2e6, 8e6, 3), rng.uniform(-1e-4, 1e-4, 2)
    got = leaky_dyn.pressure_rate(l, ldot, p, u, model.gamma)
    (g1, g2), want = model.gamma, []
    for i, (c, block) in enumerate(zip(model.cylinders, ((p[0],), (p[1], p[2])))):
        want += list(actuator(c.kind).Numeric.pressure_rates(l[i], ldot[i], block, u[i], g1[i], g2[i] / g1[i], c.table))
    np.testing.assert_allclose(got, want, rtol=1e-10)
    # and the leakage is in them: without it the rates differ by β Q / V
    dry = [dict(c.table, leakage=0.0, leakage_internal=0.0, leakage_external=0.0) for c in model.cylinders]
    (rate0,) = actuator("three_way_cylinder").Numeric.pressure_rates(l[0], ldot[0], (p[0],), u[0], g1[0], g2[0] / g1[0],
                                                                     dry[0])
    P0 = model.cylinders[0].table
    np.testing.assert_allclose(got[0] - rate0, g1[0] * 1e-12 * (P0["supply_pressure"] - p[0])
                               / (P0["piston_area"] * (l[0] - P0["chamber_length"])), rtol=1e-6)


def test_a_leaking_robot_tracks_under_backstepping(leaky_dyn):
    res = hydrogen.simulate("arm-sim", "backstepping", dyn=leaky_dyn, duration=3.0)
    err = np.abs(res.q - res.q_d)[res.t > 2.0].max(axis=0)
    assert np.all(err < 5e-4), err
    assert res.pressures.min() > 0 and res.pressures.max() < 10e6
