"""Physics sanity of the three-way actuator model and the closed-form valve inverse, for every robot
on three-way cylinders (every actuator kind's physics: tests/test_actuators.py; the four-way
excavator arm's loops: tests/test_four_way.py and the robot-wide tests)."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hydrogen.pressures import uniform_three_way

from conftest import plant_inputs


@pytest.fixture(autouse=True)
def _three_way_robots_only(request):
    if "robot_model" in request.fixturenames and not uniform_three_way(request.getfixturevalue("robot_model")):
        pytest.skip("the three-way cylinder's laws (p_c A - P_s a, eq. 57); this robot has other kinds")


def _mid(model):
    """A mid-stroke length per cylinder, m."""
    return 0.5 * (model.leg_min + model.leg_max)


def _settle(dyn, model, u, p0):
    """Integrate ṗ_c with the piston blocked (l̇ = 0) for 60 s (about 30 time constants at the null
    point of the slowest cylinder shipped, the excavator's boom), with a stiff solver."""
    m = model.n_cylinders
    u = np.broadcast_to(u, (m,)).astype(float)
    sol = solve_ivp(lambda t, p: dyn.pressure_rate(_mid(model), np.zeros(m), p, u, model.gamma),
                    (0, 60.0), np.broadcast_to(p0, (m,)).astype(float), method="BDF", rtol=1e-8, atol=1.0)
    assert sol.success
    return sol.y[:, -1]


def test_flow_into_chamber_raises_pressure(robot_dyn, robot_model):
    dyn, model = robot_dyn, robot_model
    m, ps, d, l = model.n_cylinders, model.supply_pressure, model.underlap, _mid(model)
    pc = np.linspace(0.1, 0.9, m) * ps
    rate_open = dyn.pressure_rate(l, np.zeros(m), pc, 3 * d, model.gamma)
    rate_drain = dyn.pressure_rate(l, np.zeros(m), pc, -3 * d, model.gamma)
    assert np.all(rate_open > 0) and np.all(rate_drain < 0)
    # extending the cylinder with the spool centred at p_s/2 (no net valve flow) lowers p_c
    assert np.all(dyn.pressure_rate(l, np.full(m, 0.1), ps / 2, np.zeros(m), model.gamma) < 0)


def test_leg_force(robot_dyn, robot_model):
    model = robot_model
    pc = np.linspace(0, 1, model.n_cylinders) * model.supply_pressure
    np.testing.assert_allclose(robot_dyn.leg_force(pc),
                               pc * model.piston_area - model.supply_pressure * model.rod_area)


@pytest.mark.parametrize("u_over_d,expected", [
    (3.0, "ps"), (-3.0, "zero"), (0.0, "null"), (1 / 3, "null"),
])
def test_blocked_piston_settles(robot_dyn, robot_model, u_over_d, expected):
    dyn, model = robot_dyn, robot_model
    ps, d = model.supply_pressure, model.underlap
    p_end = _settle(dyn, model, u_over_d * d, 0.5 * ps if expected != "null" else 0.2 * ps)
    if expected == "ps":
        np.testing.assert_allclose(p_end, ps, rtol=1e-4)
    elif expected == "zero":
        np.testing.assert_allclose(p_end, 0, atol=1e-4 * ps.max())
    else:
        # (u+d)√(ps−pc) = (d−u)√pc  →  pc = ps (u+d)² / ((u+d)² + (d−u)²)
        u = u_over_d * d
        p_null = ps * (u + d) ** 2 / ((u + d) ** 2 + (d - u) ** 2)
        np.testing.assert_allclose(p_end, p_null, rtol=1e-6)
        np.testing.assert_allclose(dyn.valve_flow(u, p_end), 0, atol=1e-9)


def test_valve_flow_is_continuous_and_increasing_in_u(robot_dyn, robot_model):
    dyn, model = robot_dyn, robot_model
    d = model.underlap
    for frac in np.linspace(0.05, 0.95, 5):
        pc = frac * model.supply_pressure
        u = np.linspace(-5, 5, 6000)[:, None] * d
        q = np.array([dyn.valve_flow(row, pc) for row in u])
        assert np.all(np.diff(q, axis=0) > 0)
        assert np.all(np.max(np.abs(np.diff(q, axis=0)), axis=0) < 1e-3 * np.ptp(q, axis=0))


@pytest.mark.parametrize("branch", ["below", "underlap", "above"])
def test_valve_inverse_round_trip(robot_dyn, robot_model, rng, branch):
    dyn, model = robot_dyn, robot_model
    m, d, ps = model.n_cylinders, model.underlap, model.supply_pressure
    lo, hi = {"below": (-40, -1.01), "underlap": (-0.99, 0.99), "above": (1.01, 40)}[branch]
    l = _mid(model)
    for _ in range(20):
        u = rng.uniform(lo, hi, m) * d
        pc = rng.uniform(0.01, 0.99, m) * ps
        # g0 = (q_l / c) / (l - L) of (59): the inverse gives the spool back at any length
        g0 = dyn.valve_flow(u, pc) / (l - model.chamber_length)
        np.testing.assert_allclose(dyn.valve_inverse(g0, pc, l=l), u, rtol=1e-9, atol=1e-15)


def test_valve_inverse_never_takes_root_of_negative(robot_dyn, robot_model):
    m, ps = robot_model.n_cylinders, robot_model.supply_pressure
    cases = [np.zeros(m), ps, np.full(m, -1e3), ps + 1e3, 0.5 * ps, np.ones(m)]
    for pc in cases:
        for w in (1.0, -1.0, 0.1, 0.0):
            assert np.all(np.isfinite(robot_dyn.valve_inverse(np.full(m, w), pc, l=_mid(robot_model))))


def _orifice_flow(u, pc, ps, d, p_lin=None):
    """(57) in numpy, as printed (three branches by u); with p_lin, the plant's roots, linear below p_lin."""
    if p_lin is None:
        up, down = np.sqrt(ps - pc), np.sqrt(pc)
    else:
        root = lambda x: np.where(np.abs(x) < p_lin, x / np.sqrt(p_lin), np.sign(x) * np.sqrt(np.abs(x)))  # noqa: E731
        up, down = root(ps - pc), root(pc)
    return np.where(u < -d, (u - d) * down, np.where(u <= d, (u + d) * up + (u - d) * down, (u + d) * up))


def test_valve_laws_and_plant_pressure_and_spool_rates_match_numpy(robot_dyn, robot_model, rng):
    """The generated valve law (57), the plant's (roots linear near zero drop) and the plant's spool
    rates for the ideal, first-order and second-order valve, against numpy, with commands on and
    either side of the underlap's ends and pressures inside, near and past [0, p_s]."""
    dyn, model = robot_dyn, robot_model
    n, m = model.n, model.n_cylinders
    ps, d = model.supply_pressure, model.underlap
    A, L = model.piston_area, model.chamber_length
    p_lin = np.array([c.orifice_linear_below for c in model.cylinders])
    g1, g2 = model.gamma
    fric, _ = plant_inputs(model)
    for k in range(60):
        u = np.where(rng.random(m) < 0.3, rng.choice([-1.0, 1.0], m), rng.uniform(-3, 3, m)) * d
        inside = rng.uniform(0.01, 0.99, m) * ps
        np.testing.assert_allclose(dyn.valve_flow(u, inside), _orifice_flow(u, inside, ps, d), rtol=1e-13, atol=0)
        pc = np.where(rng.random(m) < 0.4, rng.choice([0.0, 1.0], m) * ps + rng.uniform(-2, 2, m) * p_lin, inside)
        q = model.neutral_pose + rng.uniform(-0.02, 0.02, n)
        qdot, spool, rate = 0.05 * rng.normal(size=n), rng.uniform(-3, 3, m) * d, 0.01 * rng.normal(size=m)
        lag, w, z = [(0.0, 0.0, 0.7), (2e-3, 0.0, 0.7), (0.0, 300.0, 0.6), (2e-3, 300.0, 0.6)][k % 4]
        x = np.concatenate([q, qdot, pc, spool, rate])
        xdot = dyn.functions["plant_rhs"](x, u, model.theta, g1, g2, fric, plant_inputs(model, valve=(lag, w, z))[1])
        s_eff = spool if (w > 0 or lag > 0) else u
        l, ldot = dyn.leg_lengths(q), dyn.leg_jacobian(q) @ qdot
        pc_dot = g1 * (g2 / g1 * _orifice_flow(s_eff, pc, ps, d, p_lin) - A * ldot) / (A * (l - L))
        np.testing.assert_allclose(xdot[2 * n:2 * n + m], pc_dot, rtol=1e-9, atol=1e-9 * np.abs(pc_dot).max())
        s_dot = rate if w > 0 else ((u - spool) / lag if lag > 0 else np.zeros(m))
        s_ddot = w ** 2 * (u - spool) - 2 * z * w * rate if w > 0 else np.zeros(m)
        np.testing.assert_allclose(xdot[2 * n + m:], np.concatenate([s_dot, s_ddot]), rtol=1e-13, atol=0)
