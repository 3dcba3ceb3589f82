"""The loader crane (hydrogen/data/loader_crane.toml): a rotary vane slew and two four-way cylinders in
one shipped robot; adaptive control on its ideal scenario and the nonlinear controllers against P on
its rig. D, C, G and Y θ + y0 against Pinocchio: tests/test_pinocchio.py (every URDF robot); export
and FMUs: tests/test_export.py, tests/test_fmu.py."""
import re

import numpy as np
import pytest

import hydrogen
from hydrogen import pressures
from hydrogen.actuators import actuator
from hydrogen.plant import supply
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
    ps = [supply.nominal(m)]  # the pump's pressure: a four-way cylinder's force does not depend on it
    np.testing.assert_allclose(JL.T @ crane.leg_force(p, ps=ps), crane.gravity(q, m.theta), rtol=1e-9, atol=1e-6)


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
        rates, forces = crane.pressure_rate(l, ldot, p, u, m.gamma), crane.leg_force(p, ps=[supply.nominal(m)])
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


def _crane_load_with(model, **fields):
    """The crane's rig scenario with some fields replaced (its per-actuator settings among them)."""
    from hydrogen.simulation.scenarios import scenario
    return scenario(_rig(model), model).with_overrides(**fields)


def test_the_rigs_friction_switches_each_actuators_own_table_on_in_its_own_unit():
    """The rig's friction switches friction on; each actuator's numbers are its description's table,
    in its own unit (the slew vane's N m, N m s/rad); a scenario's own per-actuator friction overrides
    them key by key; a scenario with friction off (the ideal crane-sim) runs every actuator without."""
    from hydrogen.plant import friction
    from hydrogen.simulation.scenarios import actuator_settings, scenario
    model = hydrogen.load_model(MODEL)
    names = [q.name for q in friction.parameters_of(model.seal_friction)]
    slew = [c.kind for c in model.cylinders].index("rotary")
    sc = _crane_load_with(model, friction=(300.0, 900.0, 1e-3))
    fr = actuator_settings(sc, model)["friction"]
    for i, c in enumerate(model.cylinders):
        assert {k: v for k, v in zip(names, fr[i]) if k in c.friction} == c.friction, c.name
    assert model.cylinders[slew].friction["coulomb"] == fr[slew, 0] == 500.0  # N m, its own
    sc = sc.with_overrides(actuators={"slew_motor": {**sc.actuators["slew_motor"], "friction": {"viscous": 80.0}}})
    row = dict(zip(names, actuator_settings(sc, model)["friction"][slew]))
    assert row["viscous"] == 80.0 and row["coulomb"] == 500.0
    ideal = actuator_settings(scenario("crane-sim", model), model)["friction"]
    assert np.all(ideal[:, [names.index("coulomb"), names.index("viscous"), names.index("pressure_coefficient")]] == 0)


@pytest.mark.parametrize("key", ["quantization_l", "noise_l"])
def test_a_cylinders_sensor_setting_is_never_applied_to_the_slews_angle(key):
    """A sensor setting in m the rig switches on is refused for the slew unless it gives its own in rad."""
    from hydrogen.simulation.scenarios import actuator_settings
    model = hydrogen.load_model(MODEL)
    sc = _crane_load_with(model)
    own = {k: v for k, v in sc.actuators["slew_motor"].items() if k != key}
    with pytest.raises(hydrogen.ScenarioError, match=rf"{key} .* actuator 'slew_motor' \(kind rotary\) moves an "
                                                     rf"angle: give its own as actuators.slew_motor.{key} in rad"):
        actuator_settings(sc.with_overrides(actuators={"slew_motor": own}), model)


@pytest.mark.parametrize("actuators,words", [
    ({"swing": {"friction": [1.0, 1.0, 1e-3]}}, "actuators.swing: the model has no actuator of that name"),
    ({"slew_motor": {"stiction": 1.0}}, "actuators.slew_motor: unknown setting(s) ['stiction']"),
    ({"slew_motor": {"friction": [-1.0, 1.0, 1e-3]}}, "actuators.slew_motor.friction must be (Coulomb"),
    ({"slew_motor": {"noise_l": -1.0}}, "actuators.slew_motor.noise_l must be finite and >= 0"),
])
def test_per_actuator_settings_are_checked(actuators, words):
    from hydrogen.simulation.scenarios import actuator_settings
    model = hydrogen.load_model(MODEL)
    with pytest.raises(hydrogen.ScenarioError) as exc:
        actuator_settings(_crane_load_with(model, actuators=actuators), model)
    assert words in str(exc.value)


def test_the_slews_friction_reaches_the_plant_in_both_loops(crane):
    """The slew's own friction slows it in the C loop and the Python stages alike (same numbers), and
    the cylinders' friction does not act on it."""
    sc = _crane_load_with(crane.model, duration=0.3, noise_l=0.0, noise_p=0.0, noise_q=0.0, quantization_l=0.0,
                          kalman=False, actuators={})
    slew = [c.kind for c in crane.model.cylinders].index("rotary")
    base = simulate(crane, sc, "backstepping")
    own = sc.with_overrides(actuators={"slew_motor": {"friction": {"coulomb": 5000.0, "breakaway": 6000.0,
                                                                   "viscous": 20000.0}}})
    slowed = simulate(crane, own, "backstepping")
    py = simulate(crane, own, "backstepping", engine="python")
    err = lambda r: np.abs(r.q - r.q_d)[:, slew].max()  # noqa: E731
    assert err(slowed) > 1.5 * err(base)
    np.testing.assert_allclose(py.q, slowed.q, rtol=0, atol=1e-9)


def test_a_vanes_start_pose_is_named_in_its_own_angle(crane):
    """A start pose past the slew vane's angle range names the vane's angle in rad, not a length."""
    from hydrogen.simulation.checks import check_against_model
    slew = [c.kind for c in crane.model.cylinders].index("rotary")
    offset = [0.0] * crane.model.n
    offset[slew] = 3.0  # the slew is the first coordinate, its vane the first actuator
    sc = _crane_load_with(crane.model, q0_offset=tuple(offset))
    with pytest.raises(hydrogen.ScenarioError, match=r"actuator 'slew_motor''s angle range \(angle 3\.0000 rad, "
                                                     r"angle range \[-1\.8, 1\.8\] rad\)"):
        check_against_model(sc, crane.model, "p", crane)


def test_a_reference_past_the_vanes_angle_range_is_named_in_its_angle(crane):
    """A reference that turns the slew past its vane's angle range names the angle in rad, never a
    length in m or a stroke."""
    from hydrogen.simulation.reference import MultiSine
    from hydrogen.simulation.scenarios import scenario
    m = crane.model
    slew = [c.kind for c in m.cylinders].index("rotary")
    far = MultiSine(m.neutral_pose, ((slew, 2.5, 0.5),))
    sc = scenario(_ideal(m), m).with_overrides(reference=far)
    with pytest.raises(hydrogen.KinematicsError) as err:
        simulate(crane, sc, "p", duration=1.0)
    msg = str(err.value)
    assert "actuator 'slew_motor' would be at angle 1.8" in msg and "rad, outside its angle range [-1.8, 1.8] rad" in msg
    assert "stroke" not in msg and not re.search(r"\d m\b", msg)


def test_a_runs_actuator_override_replaces_the_scenarios_table():
    """A run's actuators= is the whole table (``{}`` clears the rig's slew settings, which a run
    that turns every sensor off relies on); changing one setting is the table with it changed."""
    from hydrogen.simulation.scenarios import scenario

    sc = scenario("crane-load", hydrogen.load_model("loader_crane"))
    own = dict(sc.actuators["slew_motor"])
    assert "quantization_l" in own
    assert sc.with_overrides(noise_l=0.0, quantization_l=0.0, actuators={}).actuators == {}
    one = sc.with_overrides(actuators={**sc.actuators, "slew_motor": {**own, "noise_l": 1e-6}})
    assert one.actuators["slew_motor"] == {**own, "noise_l": 1e-6}
