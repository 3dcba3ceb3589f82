"""The supply block (hydrogen/plant/supply.py): a pump's supply pressure against closed forms (its
slope (pump flow − demand)/capacitance, the relief's cap, a compensated pump's held pressure, an
accumulator discharging along its gas law p V^n = const), and SymPy against numpy."""
import math

import numpy as np
import pytest
import sympy as sp
from scipy.optimize import brentq

from hydrogen.actuators import actuator
from hydrogen.plant import supply
from reference import rk4

#: A small pump: 1 L/s, relief at 200 bar, 2 L of hose on oil of 1.4 GPa.
PUMP = {"pump_flow": 1e-3, "relief_pressure": 20e6, "hose_volume": 2e-3, "bulk_modulus": 1.4e9,
        "accumulator_volume": 0.0, "polytropic_index": 1.4}
ACCUMULATOR = {**PUMP, "accumulator_volume": 4e-3, "precharge_pressure": 8e6}
COMPENSATED = {**PUMP, "set_pressure": 16e6}


def _rate(kind, S, demand, accumulator=False):
    return lambda ps: supply.Numeric.rate(kind, ps, demand, S, accumulator)


def test_demand_above_the_pump_flow_lowers_the_pressure_at_the_net_flow_over_the_hoses_capacitance():
    """Below the relief, ṗ_s = (Q_p − D)/(V_h/β): a straight line in time."""
    demand = 1.6e-3  # m³/s, above the pump's 1 L/s
    slope = (PUMP["pump_flow"] - demand) * PUMP["bulk_modulus"] / PUMP["hose_volume"]
    p0 = 15e6
    np.testing.assert_allclose(_rate("pump", PUMP, demand)(p0), slope, rtol=1e-12)
    t = 0.5 * (p0 - 5e6) / -slope  # stays well below the relief
    p = rk4(_rate("pump", PUMP, demand), p0, t / 100, 100)
    np.testing.assert_allclose(p, p0 + slope * t, rtol=1e-12)


def test_a_demand_drawn_by_a_valve_is_its_orifice_flow():
    """The demand of a three-way cylinder's open valve, c (u + d) √(p_s − p_c) − a l̇, lowers p_s at
    (Q_p − demand)/C."""
    mod = actuator("three_way_cylinder")
    P = mod.parameters({"piston_area": 1.14e-3, "rod_area": 6.33e-4, "chamber_length": 1.37,
                        "supply_pressure": 15e6, "underlap": 5e-5, "flow_gain": 1.5e-4, "bulk_modulus": 7e8})
    pc, u, ldot = 6e6, 2e-3, 0.05
    demand = float(mod.Numeric.supply_flow(1.8, ldot, (pc,), u, P["flow_gain"], P))
    expected = P["flow_gain"] * (u + P["underlap"]) * math.sqrt(P["supply_pressure"] - pc) - P["rod_area"] * ldot
    np.testing.assert_allclose(demand, expected, rtol=1e-12)
    np.testing.assert_allclose(supply.Numeric.rate("pump", 15e6, demand, PUMP),
                               (PUMP["pump_flow"] - expected) * PUMP["bulk_modulus"] / PUMP["hose_volume"],
                               rtol=1e-12)


def test_the_relief_caps_the_pressure_of_a_pump_with_no_demand():
    """With no demand the pump's flow all goes through the relief: p_s rises to where Q_relief = Q_p,
    p_r + w ln(e^{Q_p/(g_r w)} − 1), within the relief's 1 % override of relief_pressure, and never above."""
    pr = PUMP["relief_pressure"]
    over = supply.RELIEF_OVERRIDE * pr
    width = supply.RELIEF_WIDTH * over
    gain = PUMP["pump_flow"] / over
    cap = pr + width * math.log(math.expm1(PUMP["pump_flow"] / (gain * width)))
    assert pr < cap <= pr * (1 + supply.RELIEF_OVERRIDE)
    np.testing.assert_allclose(supply.Numeric.relief_flow(cap, PUMP), PUMP["pump_flow"], rtol=1e-12)
    f = _rate("pump", PUMP, 0.0)
    p, top = 18e6, 0.0
    for _ in range(400):  # 0.4 s: the hose fills in 0.03 s, the relief settles in ~1 ms
        p = rk4(f, p, 1e-5, 100)
        top = max(top, p)
    np.testing.assert_allclose(p, cap, rtol=1e-9)
    assert top <= cap * (1 + 1e-12)
    # below the relief it passes (almost) nothing: the pump's whole flow fills the hose
    assert supply.Numeric.relief_flow(0.97 * pr, PUMP) < 1e-12 * PUMP["pump_flow"]


def test_a_compensated_pump_holds_its_set_pressure_up_to_its_flow():
    """A demand D < Q_p is held at p_set − Δ_c artanh(2D/Q_p − 1), within 2 % of p_set for 2 % ..
    98 % of the pump's flow; a demand above it lowers the pressure."""
    pset = COMPENSATED["set_pressure"]
    droop = supply.COMPENSATOR_DROOP * pset
    for fraction in (0.05, 0.5, 0.9):
        demand = fraction * COMPENSATED["pump_flow"]
        held = pset - droop * math.atanh(2 * fraction - 1)
        assert abs(held - pset) < 2 * droop
        p = rk4(_rate("compensated_pump", COMPENSATED, demand), 12e6, 1e-5, 40000)
        np.testing.assert_allclose(p, held, rtol=1e-9)
    assert _rate("compensated_pump", COMPENSATED, 1.1 * COMPENSATED["pump_flow"])(pset - 5 * droop) < 0


def _gas_oil(ps, S):
    """Oil in the accumulator by Boyle-Poisson: the gas V_a at p̄_0 compressed to p̄_s along p V^n = const."""
    p0, pa = S["precharge_pressure"] + supply.ATMOSPHERE, ps + supply.ATMOSPHERE
    return S["accumulator_volume"] - S["accumulator_volume"] * (p0 / pa) ** (1 / S["polytropic_index"])


@pytest.mark.parametrize("index", [1.0, 1.4])
def test_an_accumulator_discharges_along_its_gas_law(index):
    """No pump flow to speak of, a constant demand D: the oil delivered D t is what the accumulator's gas
    (p V^n = const) and the hose's oil give up, V_oil(p(0)) − V_oil(p(t)) + V_h/β (p(0) − p(t));
    p(t) solved from that closed form against the integrated rate."""
    S = {**ACCUMULATOR, "pump_flow": 1e-9, "polytropic_index": index}
    demand, p_start = 2e-3, 18e6

    def delivered(ps):
        return _gas_oil(p_start, S) - _gas_oil(ps, S) + S["hose_volume"] / S["bulk_modulus"] * (p_start - ps)

    # the relief is far above: Q_p = 1e-9 m³/s besides the demand
    net = demand - S["pump_flow"]
    f = _rate("pump", S, demand, accumulator=True)
    p = p_start
    for t in (0.2, 0.4, 0.6):  # discharges to ~9 MPa, above the precharge
        p = rk4(f, p, 1e-4, 2000)
        exact = brentq(lambda ps: delivered(ps) - net * t, S["precharge_pressure"] + 1.0, p_start)
        np.testing.assert_allclose(p, exact, rtol=1e-9)
    np.testing.assert_allclose(supply.Numeric.accumulator_oil(p, S), _gas_oil(p, S), rtol=1e-12)


def test_an_accumulator_below_its_precharge_holds_no_oil():
    """At or below the precharge the gas fills the accumulator: only the hose's capacitance is left."""
    S = ACCUMULATOR
    for ps in (S["precharge_pressure"], 0.5 * S["precharge_pressure"]):
        assert supply.Numeric.accumulator_oil(ps, S) == 0.0
        assert supply.Numeric.capacitance(ps, S, True) == S["hose_volume"] / S["bulk_modulus"]
    # just above it, its capacitance is the slope of its oil
    ps, h = 1.2 * S["precharge_pressure"], 10.0
    slope = (_gas_oil(ps + h, S) - _gas_oil(ps - h, S)) / (2 * h)
    np.testing.assert_allclose(supply.Numeric.capacitance(ps, S, True) - S["hose_volume"] / S["bulk_modulus"],
                               slope, rtol=1e-7)


@pytest.mark.parametrize("kind, S, accumulator", [("pump", PUMP, False), ("pump", ACCUMULATOR, True),
                                                  ("compensated_pump", COMPENSATED, False)])
def test_symbolic_and_numeric_laws_agree(kind, S, accumulator):
    ps, demand = sp.symbols("ps demand", real=True)
    expr = supply.Symbolic.rate(kind, ps, demand, {k: sp.Float(v) for k, v in S.items()}, accumulator)
    f = sp.lambdify((ps, demand), expr, "mpmath")
    for p in (1e6, 9e6, 15.9e6, 16.1e6, 19.9e6, 20.1e6, 21e6, 40e6):
        for d in (0.0, 5e-4, 3e-3):
            np.testing.assert_allclose(float(f(p, d)), supply.Numeric.rate(kind, p, d, S, accumulator),
                                       rtol=1e-12)


# --- a robot on a pump, built and run --------------------------------------------------------------

#: A small pump with an accumulator (the session fixture ``pump_dyn`` puts it under the mixed arm).
PUMP_TABLE = """
[supply]
kind = "pump"
pump_flow = 2.0e-4
relief_pressure = 11.0e6
hose_volume = 1.0e-3
accumulator_volume = 5.0e-4
precharge_pressure = 6.0e6
"""


def test_the_generated_plant_draws_every_valve_on_the_one_supply(pump_dyn, rng):
    """The generated plant's ṗ_s is the supply law at the demand of every actuator's supply edges, and
    each chamber's rate its kind's law at the supply state's pressure, not the constant's."""
    from hydrogen.plant import plant_layout, slot, state_vector
    from hydrogen.pressures import split
    model = pump_dyn.model
    layout = plant_layout(model)
    q = model.neutral_pose + 0.05 * rng.normal(size=model.n)
    qdot = 0.2 * rng.normal(size=model.n)
    pc, ps, u = rng.uniform(2e6, 7e6, 3), 8.5e6, np.array([3e-4, -2e-4])
    x = state_vector(layout, q=q, qdot=qdot, pc=pc, ps=[ps])
    g1, g2 = model.gamma
    ideal = np.zeros(5 * model.n_cylinders)  # the ideal valve: the chambers see the command
    xdot = np.asarray(pump_dyn.functions["plant_rhs"](x, u, model.theta, g1, g2, np.zeros(3 * model.n_cylinders),
                                                       ideal), float).ravel()
    l, ldot = pump_dyn.leg_lengths(q), pump_dyn.leg_jacobian(q) @ qdot
    demand, rates = 0.0, []
    for i, (c, p) in enumerate(zip(model.cylinders, split(model, pc))):
        mod, P = actuator(c.kind), {**c.table, "supply_pressure": ps}
        demand += float(mod.Numeric.supply_flow(l[i], ldot[i], p, u[i], g2[i] / g1[i], P))
        rates += [float(r) for r in mod.Numeric.pressure_rates(l[i], ldot[i], p, u[i], g1[i], g2[i] / g1[i], P)]
    S = model.supply.values
    np.testing.assert_allclose(xdot[slot(layout, "ps").slice], supply.Numeric.rate("pump", ps, demand, S, True),
                               rtol=1e-9)
    np.testing.assert_allclose(xdot[slot(layout, "pc").slice], rates, rtol=1e-9)


def test_a_pump_run_is_the_same_in_both_loops_and_held_under_the_relief(pump_dyn):
    """The supply pressure, logged by either loop: from the actuators' supply_pressure the pump charges
    the accumulator up to the relief, which holds it within twice its override."""
    import hydrogen
    runs = [hydrogen.simulate("arm-sim", "backstepping", dyn=pump_dyn, duration=0.4, engine=e) for e in ("c", "python")]
    c, py = (r.supply_pressure for r in runs)
    assert c.shape == runs[0].t.shape and c[0] == 10.0e6  # it starts at the actuators' supply_pressure
    np.testing.assert_allclose(c, py, rtol=1e-9)
    relief = pump_dyn.model.supply.values["relief_pressure"]
    assert relief < c.max() <= relief * (1 + 2 * supply.RELIEF_OVERRIDE)


def test_the_measured_supply_pressure_feeds_the_predictor_alike_in_both_loops(pump_dyn):
    """The supply pressure is measured (noise_ps, Pa): the delay predictor starts from the measurement,
    so its noise changes the commands, the same in either loop."""
    import hydrogen
    kw = dict(dyn=pump_dyn, duration=0.2, delay=0.002, predictor=True)
    noisy = [hydrogen.simulate("arm-sim", "backstepping", noise_ps=3e5, engine=e, **kw) for e in ("c", "python")]
    np.testing.assert_allclose(noisy[0].u, noisy[1].u, rtol=1e-9, atol=1e-15)
    quiet = hydrogen.simulate("arm-sim", "backstepping", noise_ps=0.0, **kw)
    assert np.abs(quiet.u - noisy[0].u).max() > 1e-9


# --- controllers that read the supply ------------------------------------------------------------

def test_the_controllers_laws_take_the_measured_supply_pressure(pump_dyn):
    """With a supply state every controller law reads p_s from its ``ps`` input (the loop's measured
    supply pressure) in place of the constant supply_pressure; without one, the constant."""
    import hydrogen
    from hydrogen.symbolic.control_laws import Common
    common = Common(pump_dyn.model)
    assert common.supply is not None and ("ps", common.supply) in common.base_inputs()
    assert all(P["supply_pressure"] == common.supply[0] for P in common.P)
    for name in ("ctrl_backstepping", "ctrl_adaptive_robust"):
        assert "ps" in pump_dyn.functions[name].in_names
    from test_model import FOUR_WAY_ARM
    constant = Common(hydrogen.load_model(FOUR_WAY_ARM))
    assert constant.supply is None and all(P["supply_pressure"] == 10.0e6 for P in constant.P)


@pytest.mark.parametrize("index", [0, 1])  # the three-way shoulder, the four-way elbow
def test_f0_and_g0_at_the_measured_supply_give_the_plants_force_rate(pump_dyn, index):
    """Finite differences of an actuator's force along the generated plant (on a pump, p_s below its
    actuators' supply_pressure) against β f0 + βc g0 at that p_s, plus the force's own dependence on
    p_s times ṗ_s (a three-way cylinder's rod side is at supply: −a ṗ_s; none on a four-way one)."""
    from hydrogen.plant import plant_layout, slot, state_vector
    from hydrogen.pressures import split
    model = pump_dyn.model
    layout = plant_layout(model)
    q, qdot = model.neutral_pose + np.array([0.02, -0.03]), np.array([0.1, -0.15])
    pc, ps, u = np.array([3e6, 6e6, 2.5e6]), 8.5e6, np.array([2e-4, -1.5e-4])
    g1, g2 = model.gamma
    args = (u, model.theta, g1, g2, np.zeros(3 * model.n_cylinders), np.zeros(5 * model.n_cylinders))
    c = model.cylinders[index]
    mod = actuator(c.kind)

    def force(x):
        p = split(model, x[slot(layout, "pc").slice])[index]
        return float(mod.Numeric.force(p, {**c.table, "supply_pressure": x[slot(layout, "ps").slice][0]}))

    x = state_vector(layout, q=q, qdot=qdot, pc=pc, ps=[ps])
    xdot = np.asarray(pump_dyn.functions["plant_rhs"](x, *args), float).ravel()
    eps = 1e-6
    rate = (force(x + eps * xdot) - force(x - eps * xdot)) / (2 * eps)
    l, ldot = pump_dyn.leg_lengths(q)[index], (pump_dyn.leg_jacobian(q) @ qdot)[index]
    P = {**c.table, "supply_pressure": ps}
    p = split(model, pc)[index]
    beta, flow_gain = g1[index], g2[index] / g1[index]
    dps = x.copy()
    dps[slot(layout, "ps").slice] += 1.0
    along_ps = (force(dps) - force(x)) * xdot[slot(layout, "ps").slice][0]
    expected = beta * mod.Numeric.f0(l, ldot, p, P) + beta * flow_gain * mod.Numeric.g0(l, p, u[index], P) + along_ps
    np.testing.assert_allclose(rate, expected, rtol=1e-6)
    assert (along_ps != 0) == (c.kind == "three_way_cylinder")


def test_recorded_forces_take_the_supply_state_in_both_loops(pump_dyn):
    """A three-way cylinder's rod side is at the supply's pressure: the forces both loops record, and
    Dynamics.leg_force given ps, are the kinds' laws at the logged p_s, not at the nominal one (which
    would be off by (p_s - P_s) a as the pump charges)."""
    import hydrogen
    from hydrogen import pressures
    runs = [hydrogen.simulate("arm-sim", "backstepping", dyn=pump_dyn, duration=0.4, engine=e) for e in ("c", "python")]
    for r in runs:
        at_state = pressures.forces(pump_dyn.model, r.pressures, np.reshape(r.supply_pressure, len(r.t)))
        np.testing.assert_allclose(r.leg_forces, at_state, rtol=1e-9, atol=1e-6)
        nominal = pressures.forces(pump_dyn.model, r.pressures)
        assert np.max(np.abs(r.leg_forces - nominal)) > 1.0  # N: the supply moved away from its nominal value
    k = len(runs[0].t) // 2
    f = pump_dyn.leg_force(runs[0].pressures[k], runs[0].supply_pressure[k])
    np.testing.assert_allclose(f, runs[0].leg_forces[k], rtol=1e-12, atol=1e-9)
    with pytest.raises(hydrogen.errors.ScenarioError, match="needs the supply pressure ps"):
        pump_dyn.leg_force(runs[0].pressures[k])


# --- the same controllers assuming a constant supply ------------------------------------------------

@pytest.mark.parametrize("predictor", [False, True])
def test_without_supply_feedback_both_loops_feed_the_controller_the_nominal_supply(pump_dyn, predictor):
    """supply_feedback false: the controller's ps input is the description's supply_pressure (the
    measured or predicted p_s is not read), the same commands in either loop, not those with feedback
    (the pump charges the accumulator above supply_pressure)."""
    import hydrogen
    kw = dict(dyn=pump_dyn, duration=0.2, noise_ps=2e5, **(dict(delay=0.002, predictor=True) if predictor else {}))
    off = [hydrogen.simulate("arm-sim", "backstepping", supply_feedback=False, engine=e, **kw) for e in ("c", "python")]
    np.testing.assert_allclose(off[0].u, off[1].u, rtol=1e-9, atol=1e-15)
    np.testing.assert_allclose(off[0].supply_pressure, off[1].supply_pressure, rtol=1e-9)
    on = hydrogen.simulate("arm-sim", "backstepping", **kw)
    assert np.abs(on.supply_pressure - supply.nominal(pump_dyn.model)).max() > 5e5  # p_s left the nominal
    assert np.abs(on.u - off[0].u).max() > 1e-7


def test_without_supply_feedback_the_commands_are_those_of_a_controller_fed_the_constant(pump_dyn, monkeypatch):
    """With feedback off the commands equal those of the loop with feedback whose supply sensor reads the
    constant supply_pressure (no predictor: the sensor's reading is the controller's ps input)."""
    import hydrogen
    from hydrogen.simulation.simulator import PythonStages
    kw = dict(dyn=pump_dyn, duration=0.2, engine="python")
    off = hydrogen.simulate("arm-sim", "adaptive-robust", supply_feedback=False, **kw)
    sensors = PythonStages.sensors

    def constant_sensor(self, s):
        sensors(self, s)
        s.ps_meas = np.full(1, pump_dyn.model.cylinders[0].supply_pressure)
    monkeypatch.setattr(PythonStages, "sensors", constant_sensor)
    fed = hydrogen.simulate("arm-sim", "adaptive-robust", **kw)
    np.testing.assert_array_equal(off.u, fed.u)
    np.testing.assert_array_equal(off.supply_pressure, fed.supply_pressure)
