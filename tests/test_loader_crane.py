"""The loader crane (hydrogen/data/loader_crane.toml): a rotary vane slew and two four-way cylinders in
one shipped robot; adaptive control on its ideal scenario and the nonlinear controllers against P on
its rig. D, C, G and Y θ + y0 against Pinocchio: tests/test_pinocchio.py (every URDF robot); export
and FMUs: tests/test_export.py, tests/test_fmu.py."""
import numpy as np
import pytest

import hydrogen
from hydrogen import pressures
from hydrogen.actuators import actuator
from hydrogen.simulation.scenarios import scenario_names
from hydrogen.simulation.simulator import equilibrium_pressures, simulate
from hydrogen.simulation.tuning import rig_scenarios

MODEL = "loader_crane"
ADAPTIVE = ("adaptive-robust", "adaptive-observer")
NONLINEAR = ("backstepping", *ADAPTIVE)


@pytest.fixture(scope="module")
def crane(cache):
    return hydrogen.build(hydrogen.load_model(MODEL), cache=cache)


def _ideal(model):
    return next(n for n in scenario_names(model) if not model.scenarios[n].get("rig"))


def _rig(model):
    return next(iter(rig_scenarios(model)))


def test_the_slew_is_a_rotary_actuator_and_the_booms_four_way_cylinders(crane):
    """Each actuator keeps its kind's two chamber pressures; the slew's coordinate is its joint angle
    (its JL row a unit vector), the cylinders' rows their own joints' lever arms."""
    m = crane.model
    kinds = [c.kind for c in m.cylinders]
    assert kinds.count("rotary") == 1 and kinds.count("four_way_cylinder") == m.n_cylinders - 1
    assert pressures.blocks(m) == [(2 * i, 2 * i + 2) for i in range(m.n_cylinders)]
    slew = kinds.index("rotary")
    q = m.neutral_pose
    JL = crane.leg_jacobian(q)
    np.testing.assert_allclose(JL[slew], np.eye(m.n)[slew], atol=1e-12)
    assert crane.leg_lengths(q)[slew] == pytest.approx(q[slew])
    # the slewing axis is vertical: gravity does no work on it, at any pose
    for dq in np.linspace(-1, 1, 5):
        assert crane.gravity(q + dq * np.eye(m.n)[slew], m.theta)[slew] == pytest.approx(0.0, abs=1e-9)
    p = equilibrium_pressures(crane, q, m.theta)
    np.testing.assert_allclose(JL.T @ crane.leg_force(p), crane.gravity(q, m.theta), rtol=1e-9, atol=1e-6)


def test_each_actuator_keeps_its_kinds_laws(crane, rng):
    """The compiled force, plant pressure rates and valve inverse agree block by block with each kind's
    own numpy law (the three-way physics of tests/test_hydraulics.py does not apply to these kinds)."""
    m = crane.model
    lo, hi = pressures.bounds(m)
    for _ in range(5):
        q = m.neutral_pose + rng.uniform(-0.2, 0.2, m.n)
        qd = rng.normal(size=m.n) * 0.1
        p = lo + (hi - lo) * rng.uniform(0.1, 0.9, lo.size)
        u = rng.uniform(-1, 1, m.n_cylinders) * 1e-3
        l, ldot = crane.leg_lengths(q), crane.leg_jacobian(q) @ qd
        rates, forces = crane.pressure_rate(l, ldot, p, u, m.gamma), crane.leg_force(p)
        y = rng.normal(size=m.n_cylinders) * 1e3
        spool = crane.valve_inverse(y, p, l=l)
        for i, ((a, b), c) in enumerate(zip(pressures.blocks(m), m.cylinders)):
            law, P, block = actuator(c.kind).Numeric, actuator(c.kind).parameters(c.table), tuple(p[a:b])
            np.testing.assert_allclose(forces[i], law.force(block, P), rtol=1e-12)
            np.testing.assert_allclose(rates[a:b], law.pressure_rates(l[i], ldot[i], block, u[i], m.gamma[0][i],
                                                                      m.gamma[1][i] / m.gamma[0][i], P), rtol=1e-9)
            np.testing.assert_allclose(law.g0(l[i], block, spool[i], P), y[i], rtol=1e-9)


@pytest.fixture(scope="module")
def ideal_runs(crane):
    name = _ideal(crane.model)
    return {k: simulate(crane, name, k) for k in ADAPTIVE}


@pytest.mark.parametrize("controller", ADAPTIVE)
def test_adaptive_control_shrinks_every_error_20_fold_on_the_ideal_scenario(ideal_runs, controller):
    """Max error per coordinate over the first 2 s against the last 2 s, with wrong initial estimates."""
    res = ideal_runs[controller]
    e, t = np.abs(res.q - res.q_d), res.t
    first, last = e[t < 2.0].max(axis=0), e[t >= t[-1] - 2.0].max(axis=0)
    assert np.all(first > 20 * last), (first, last, first / last)


def test_the_ideal_runs_never_drive_a_chamber_to_its_bounds(ideal_runs, crane):
    """The loops clip every pressure to [P_t, P_s]; on the ideal plant, after the start (the first
    tens of ms, where the slew's chambers touch supply and tank while the wrong initial estimates are
    corrected), no chamber comes within 1 % of either bound: the valves and the reference fit."""
    lo, hi = pressures.bounds(crane.model)
    margin = 0.01 * (hi - lo)
    for name, res in ideal_runs.items():
        p = res.pressures[res.t >= 0.5]
        assert np.all(p > lo + margin) and np.all(p < hi - margin), name


@pytest.fixture(scope="module")
def rig_errors(crane):
    """The worst coordinate's max error (% of its amplitude) of each controller on the rig scenario,
    at the robot's tuned gains."""
    name = _rig(crane.model)
    out = {}
    for k in (*NONLINEAR, "p"):
        pct = simulate(crane, name, k).metrics["max_error_pct"]
        out[k] = max(v for v in pct.values() if v is not None)
    return out


@pytest.mark.parametrize("controller", NONLINEAR)
def test_nonlinear_control_is_at_least_3x_better_than_p_on_the_rig(rig_errors, controller):
    assert rig_errors["p"] > 3 * rig_errors[controller], rig_errors
