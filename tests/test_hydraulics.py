"""Physics sanity of the actuator model and the closed-form valve inverse."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

L6 = np.full(6, 1.84)  # a mid-stroke leg length, m


def _settle(dyn, model, u, p0):
    """Integrate ṗ_c with the piston blocked (l̇ = 0) for 6 s (≈ 30 time constants at the null point) with a stiff solver."""
    u = np.full(6, u)
    sol = solve_ivp(lambda t, p: dyn.pressure_rate(L6, np.zeros(6), p, u, model.gamma),
                    (0, 6.0), np.full(6, p0), method="BDF", rtol=1e-8, atol=1.0)
    assert sol.success
    return sol.y[:, -1]


def test_flow_into_chamber_raises_pressure(dyn, model):
    ps, d = model.supply_pressure, model.underlap
    pc = np.linspace(0.1, 0.9, 6) * ps
    rate_open = dyn.pressure_rate(L6, np.zeros(6), pc, np.full(6, 3 * d), model.gamma)
    rate_drain = dyn.pressure_rate(L6, np.zeros(6), pc, np.full(6, -3 * d), model.gamma)
    assert np.all(rate_open > 0) and np.all(rate_drain < 0)
    # extending the leg with the spool centred at p_s/2 (no net valve flow) lowers p_c
    assert np.all(dyn.pressure_rate(L6, np.full(6, 0.1), np.full(6, ps / 2), np.zeros(6), model.gamma) < 0)


def test_leg_force(dyn, model):
    pc = np.linspace(0, model.supply_pressure, 6)
    np.testing.assert_allclose(dyn.leg_force(pc),
                               pc * model.piston_area - model.supply_pressure * model.rod_area)


@pytest.mark.parametrize("u_over_d,expected", [
    (3.0, "ps"), (-3.0, "zero"), (0.0, "null"), (1 / 3, "null"),
])
def test_blocked_piston_settles(dyn, model, u_over_d, expected):
    ps, d = model.supply_pressure, model.underlap
    p_end = _settle(dyn, model, u_over_d * d, 0.5 * ps if expected != "null" else 0.2 * ps)
    if expected == "ps":
        np.testing.assert_allclose(p_end, ps, rtol=1e-4)
    elif expected == "zero":
        np.testing.assert_allclose(p_end, 0, atol=1e-4 * ps)
    else:
        # (u+d)√(ps−pc) = (d−u)√pc  →  pc = ps (u+d)² / ((u+d)² + (d−u)²)
        u = u_over_d * d
        p_null = ps * (u + d) ** 2 / ((u + d) ** 2 + (d - u) ** 2)
        np.testing.assert_allclose(p_end, p_null, rtol=1e-6)
        np.testing.assert_allclose(dyn.valve_flow(np.full(6, u), p_end), 0, atol=1e-9)


def test_valve_flow_is_continuous_and_increasing_in_u(dyn, model):
    d = model.underlap
    for pc in np.linspace(0.05, 0.95, 5) * model.supply_pressure:
        u = np.linspace(-5 * d, 5 * d, 6000)
        q = np.concatenate([dyn.valve_flow(u[i:i + 6], np.full(6, pc)) for i in range(0, len(u), 6)])
        assert np.all(np.diff(q) > 0)
        assert np.max(np.abs(np.diff(q))) < 1e-3 * np.ptp(q)


@pytest.mark.parametrize("branch", ["below", "underlap", "above"])
def test_valve_inverse_round_trip(dyn, model, rng, branch):
    d, ps = model.underlap, model.supply_pressure
    lo, hi = {"below": (-40, -1.01), "underlap": (-0.99, 0.99), "above": (1.01, 40)}[branch]
    for _ in range(20):
        u = rng.uniform(lo, hi, 6) * d
        pc = rng.uniform(0.01, 0.99, 6) * ps
        np.testing.assert_allclose(dyn.valve_inverse(dyn.valve_flow(u, pc), pc), u, rtol=1e-9, atol=1e-15)


def test_valve_inverse_never_takes_root_of_negative(dyn, model):
    ps = model.supply_pressure
    pc = np.array([0.0, ps, -1e3, ps + 1e3, 0.5 * ps, 1.0])
    u = dyn.valve_inverse(np.array([1.0, -1.0, 0.1, -0.1, 0.0, 2.0]), pc)
    assert np.all(np.isfinite(u))
