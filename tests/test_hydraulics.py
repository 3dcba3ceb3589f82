"""Physics sanity of the actuator model and the closed-form valve inverse, for every robot."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp


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
    for _ in range(20):
        u = rng.uniform(lo, hi, m) * d
        pc = rng.uniform(0.01, 0.99, m) * ps
        np.testing.assert_allclose(dyn.valve_inverse(dyn.valve_flow(u, pc), pc), u, rtol=1e-9, atol=1e-15)


def test_valve_inverse_never_takes_root_of_negative(robot_dyn, robot_model):
    m, ps = robot_model.n_cylinders, robot_model.supply_pressure
    cases = [np.zeros(m), ps, np.full(m, -1e3), ps + 1e3, 0.5 * ps, np.ones(m)]
    for pc in cases:
        for w in (1.0, -1.0, 0.1, 0.0):
            assert np.all(np.isfinite(robot_dyn.valve_inverse(np.full(m, w), pc)))
