"""A robot on four-way cylinders (tests/data/four_way_arm.toml): its rigid-body physics, the plant's
two pressure states per cylinder, and the controllers on its ideal scenario (C loop and Python loop)."""
from pathlib import Path

import numpy as np
import pytest

import hydrogen
from hydrogen import pressures
from hydrogen.actuators import actuator
from hydrogen.plant import plant_inputs
from hydrogen.tree import link_poses

from conftest import random_theta, workspace_poses

ARM = Path(__file__).parent / "data" / "four_way_arm.toml"


@pytest.fixture(scope="module")
def arm():
    return hydrogen.load_model(ARM)


@pytest.fixture(scope="module")
def arm_dyn(arm, cache):
    return hydrogen.build(arm, cache=cache)


# --- rigid body ---------------------------------------------------------------------------------

def test_D_symmetric_positive_definite_and_Ddot_minus_2C_skew(arm, arm_dyn, rng):
    h = 1e-6
    for q in workspace_poses(arm, 20, rng, scale=3.0):
        th, qd = random_theta(arm, rng, spread=0.1), rng.normal(size=arm.n)
        D = arm_dyn.mass_matrix(q, th)
        np.testing.assert_allclose(D, D.T, atol=1e-12 * np.abs(D).max())
        assert np.linalg.eigvalsh(D).min() > 0
        Ddot = (arm_dyn.mass_matrix(q + h * qd, th) - arm_dyn.mass_matrix(q - h * qd, th)) / (2 * h)
        N = Ddot - 2 * arm_dyn.coriolis(q, qd, th)
        np.testing.assert_allclose(N + N.T, 0, atol=1e-6 * np.abs(N).max())
        assert np.abs(N).max() > 1e-3


def _potential(model, q):
    """Σ m g z of the links' centres of mass (J), from the numeric tree (independent of the SymPy)."""
    poses = link_poses(model, q)
    return sum(lk.mass * model.gravity * (poses[lk.name][1] + poses[lk.name][0] @ lk.com)[2] for lk in model.links)


def test_G_is_the_gradient_of_the_potential_energy(arm, arm_dyn, rng):
    h = 1e-6
    for q in workspace_poses(arm, 10, rng, scale=3.0):
        grad = [(_potential(arm, q + h * e) - _potential(arm, q - h * e)) / (2 * h) for e in np.eye(arm.n)]
        np.testing.assert_allclose(arm_dyn.gravity(q, arm.theta), grad, rtol=1e-6, atol=1e-6)


def test_D_equals_pinocchios_crba(arm, arm_dyn, rng):
    pin = pytest.importorskip("pinocchio")
    pm = pin.Model()
    parent = 0
    for j in arm.joints:
        lk = arm.link(j.child)
        jid = pm.addJoint(parent, pin.JointModelRevoluteUnaligned(*j.axis),
                          pin.SE3(np.eye(3), np.asarray(j.origin_xyz, float)), j.name)
        pm.appendBodyToJoint(jid, pin.Inertia(lk.mass, np.asarray(lk.com, float), np.asarray(lk.inertia, float)),
                             pin.SE3.Identity())
        parent = jid
    pm.gravity.linear = np.array([0.0, 0.0, -arm.gravity])
    data = pm.createData()
    for q in workspace_poses(arm, 10, rng, scale=2.0):
        v = rng.normal(size=arm.n)
        M = pin.crba(pm, data, q)
        M = np.triu(M) + np.triu(M, 1).T
        np.testing.assert_allclose(arm_dyn.mass_matrix(q, arm.theta), M, rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(arm_dyn.gravity(q, arm.theta), pin.computeGeneralizedGravity(pm, data, q),
                                   rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(arm_dyn.coriolis(q, v, arm.theta), pin.computeCoriolisMatrix(pm, data, q, v),
                                   rtol=1e-9, atol=1e-9)


# --- pressures ----------------------------------------------------------------------------------

def test_the_pressure_vector_has_two_states_per_cylinder(arm):
    assert pressures.n_pressures(arm) == 4 and pressures.blocks(arm) == [(0, 2), (2, 4)]
    assert pressures.state_names(arm) == ["shoulder_cylinder.pA", "shoulder_cylinder.pB",
                                          "elbow_cylinder.pA", "elbow_cylinder.pB"]
    lo, hi = pressures.bounds(arm)
    assert lo.tolist() == [0.0] * 4 and hi.tolist() == [10e6] * 4
    ubc = hydrogen.load_model()
    assert pressures.n_pressures(ubc) == 6 and pressures.uniform_three_way(ubc)


def test_force_is_pA_AA_minus_pB_AB(arm, arm_dyn, rng):
    p = rng.uniform(0, 10e6, 4)
    AA, AB = (np.array([c.params[k] for c in arm.cylinders]) for k in ("cap_area", "annulus_area"))
    np.testing.assert_allclose(arm_dyn.leg_force(p), p[0::2] * AA - p[1::2] * AB, rtol=1e-12)
    np.testing.assert_allclose(pressures.forces(arm, p), p[0::2] * AA - p[1::2] * AB, rtol=1e-12)


def test_a_blocked_cylinder_settles_at_the_valves_null_pressures(arm, arm_dyn):
    """l fixed, l̇ = 0, spool centred: the underlapped valve's matched orifices bring both chambers to
    (P_s + P_t)/2, from any start, within [P_t, P_s] all the way."""
    l = np.array([0.45, 0.6])
    p = np.array([1e6, 9e6, 8e6, 0.5e6])
    h = 1e-3  # the underlap's flows are small: a time constant of about 0.5 s
    for _ in range(10000):  # 10 s, explicit Euler well inside its stability bound (rates below 20/s)
        p = p + h * arm_dyn.pressure_rate(l, np.zeros(2), p, np.zeros(2), arm.gamma)
        assert np.all((p >= 0) & (p <= 10e6))
    np.testing.assert_allclose(p, 5e6, rtol=1e-3)


def test_the_plant_state_and_its_pressure_rates(arm, arm_dyn, rng):
    """plant_rhs's pressure rows are the pressure_rate function's at the same state (ideal valve)."""
    n, m = arm.n, arm.n_cylinders
    q, qd = arm.neutral_pose, rng.normal(size=n) * 0.1
    p, u = rng.uniform(2e6, 8e6, 4), rng.uniform(-1e-3, 1e-3, m)
    x = np.concatenate([q, qd, p, np.zeros(2 * m)])
    # every plant input by name, each block's numbers 0 (no friction; the spool rows are not read here)
    f = arm_dyn.functions["plant_rhs"]
    given = {"x": x, "u": u, "theta": arm.theta, "gamma1": arm.gamma[0], "gamma2": arm.gamma[1],
             **{i.name: np.zeros(i.width * m) for i in plant_inputs(arm)}}
    xdot = f(*[given[k] for k in f.in_names if k != "numbers"])
    assert xdot.size == 2 * n + 4 + 2 * m
    ldot = arm_dyn.leg_jacobian(q) @ qd
    np.testing.assert_allclose(xdot[2 * n:2 * n + 4],
                               arm_dyn.pressure_rate(arm_dyn.leg_lengths(q), ldot, p, u, arm.gamma), rtol=1e-12)
    # and the kind's own numpy law gives them too
    law, P = actuator("four_way_cylinder").Numeric, arm.cylinders[0].table
    rates = law.pressure_rates(arm_dyn.leg_lengths(q)[0], ldot[0], (p[0], p[1]), u[0], arm.gamma[0][0],
                               arm.gamma[1][0] / arm.gamma[0][0], P)
    np.testing.assert_allclose(xdot[2 * n:2 * n + 2], rates, rtol=1e-9)


def test_the_valve_inverse_gives_the_g0_it_was_asked_for(arm, arm_dyn, rng):
    l, p = arm_dyn.leg_lengths(arm.neutral_pose), rng.uniform(2e6, 8e6, 4)
    y = rng.normal(size=2) * 1e3
    u = arm_dyn.valve_inverse(y, p, l=l)
    law = actuator("four_way_cylinder").Numeric
    got = [law.g0(l[i], (p[2 * i], p[2 * i + 1]), u[i], arm.cylinders[i].table) for i in range(2)]
    np.testing.assert_allclose(got, y, rtol=1e-9)
    with pytest.raises(ValueError, match="needs the actuator coordinates l"):
        arm_dyn.valve_inverse(y, p)


def test_the_initial_pressures_hold_the_arm(arm, arm_dyn):
    from hydrogen.simulation.simulator import equilibrium_pressures
    q = arm.neutral_pose
    p = equilibrium_pressures(arm_dyn, q, arm.theta)
    np.testing.assert_allclose(arm_dyn.leg_jacobian(q).T @ arm_dyn.leg_force(p), arm_dyn.gravity(q, arm.theta),
                               rtol=1e-9)
    np.testing.assert_allclose(p[0::2] + p[1::2], 10e6)  # P_s + P_t: the valve's null at rest


# --- closed loop --------------------------------------------------------------------------------

def _errors(res):
    e, t = np.abs(res.q - res.q_d), res.t
    return e[t < 2.0].max(axis=0), e[t >= t[-1] - 2.0].max(axis=0)


def test_backstepping_tracks_and_the_pressures_stay_in_range(arm_dyn):
    res = hydrogen.simulate("arm-sim", "backstepping", dyn=arm_dyn)
    first, last = _errors(res)
    assert np.all(last < 2e-4), last  # rad, of 0.25 and 0.35 rad amplitudes
    assert res.pressures.shape[1] == 4
    assert res.pressures.min() > 0 and res.pressures.max() < 10e6


@pytest.mark.parametrize("controller", ["adaptive-robust", "adaptive-observer"])
def test_adaptive_controllers_shrink_every_error_20_fold(arm_dyn, controller):
    first, last = _errors(hydrogen.simulate("arm-sim", controller, dyn=arm_dyn))
    assert np.all(first > 20 * last), (first, last)


def test_the_python_loop_reproduces_the_c_loop(arm_dyn):
    kw = dict(dyn=arm_dyn, duration=0.3, noise_p=1e4, noise_l=1e-6, noise_q=1e-5)
    c = hydrogen.simulate("arm-sim", "adaptive-robust", **kw)
    py = hydrogen.simulate("arm-sim", "adaptive-robust", engine="python", **kw)
    for a, b in ((c.q, py.q), (c.pressures, py.pressures), (c.leg_forces, py.leg_forces), (c.u, py.u)):
        np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-12 * max(1.0, np.abs(b).max()))


@pytest.mark.skipif(__import__("shutil").which("make") is None or __import__("shutil").which("cc") is None,
                    reason="needs make and cc")
def test_the_exported_program_reproduces_the_simulation(tmp_path, arm_dyn):
    from hydrogen.export import export
    from test_export import reproduces_the_simulation
    folder = export(tmp_path / "export", "arm-sim", "adaptive-robust", duration=1.0, dyn=arm_dyn, metric_start=0.5)
    assert reproduces_the_simulation(folder, arm_dyn, "arm-sim", "adaptive-robust", 1.0, 0.5)[0].max() > 1e-5


def test_the_fmus_reproduce_the_simulation_with_two_pressures_per_cylinder(arm_dyn, tmp_path):
    """The FMUs of test_fmu.py on this robot: pA, pB per cylinder as variables, the closed-loop FMU and
    the plant + controller pair reproducing simulate."""
    fm = pytest.importorskip("test_fmu")
    from hydrogen.fmu import PARTS, export_fmu
    paths = {part: export_fmu(tmp_path / f"{part}.fmu", part, "arm-sim", "adaptive-robust", dyn=arm_dyn,
                              duration=fm.DURATION) for part in PARTS}
    fmus = (arm_dyn, "arm-sim", "adaptive-robust", paths)
    names = {v.name for v in fm.read_model_description(str(paths["plant"])).modelVariables}
    assert {"pA.shoulder_cylinder", "pB.elbow_cylinder", "pA_start.elbow_cylinder"} <= names
    assert not any(n.startswith("pc.") for n in names)
    fm.test_each_part_validates(fmus)
    fm.test_closed_loop_fmu_reproduces_simulate(fmus)
    fm.test_plant_and_controller_fmus_reproduce_the_closed_loop(fmus)


def test_identification_reads_the_pressure_vector(arm_dyn):
    """θ from a noise-free arm-sim log (pc0..pc3: pA, pB per cylinder), through the kinds' forces; γ's
    per-cylinder estimates through their f0 and g0."""
    res = hydrogen.simulate("arm-sim", "backstepping", dyn=arm_dyn)
    assert res.pressures.shape[1] == 4
    fit = hydrogen.identify(res, dyn=arm_dyn)
    np.testing.assert_allclose(fit.theta.estimate, arm_dyn.model.theta, rtol=0.02)
    np.testing.assert_allclose(fit.gamma_per_leg, arm_dyn.model.gamma.T, rtol=0.02)


def test_a_rotary_elbow_tracks_under_backstepping(tmp_path, cache):
    """The arm with a rotary vane actuator on its elbow (its coordinate the joint angle, its JL row a
    unit vector): built, and backstepping tracks on arm-sim with the pressures inside their bounds."""
    from test_model import rotary_arm_text
    path = tmp_path / "rotary_arm.toml"
    path.write_text(rotary_arm_text())
    dyn = hydrogen.build(hydrogen.load_model(path), cache=cache)
    np.testing.assert_allclose(dyn.leg_jacobian(dyn.model.neutral_pose)[1], [0.0, 1.0])
    res = hydrogen.simulate("arm-sim", "backstepping", dyn=dyn)
    first, last = _errors(res)
    assert np.all(last < 5e-5) and np.all(first > 50 * last), (first, last)
    assert res.pressures.min() > 0 and res.pressures.max() < 10e6


def test_a_three_way_parameter_of_a_four_way_robot_is_a_clear_error():
    m = hydrogen.load_model(ARM)
    with pytest.raises(AttributeError, match=r"'piston_area' is not a parameter of cylinder '\w+' \(kind four_way_cylinder\)"):
        m.piston_area
    assert m.supply_pressure.shape == (m.n_cylinders,)  # shared by every kind


# --- kinds mixed in one robot --------------------------------------------------------------------

@pytest.fixture(scope="module", params=["four_way", "rotary"])
def mixed_dyn(request, cache, tmp_path_factory):
    """The arm with a three-way shoulder cylinder and a four-way (or rotary) elbow."""
    from test_model import mixed_arm_text
    path = tmp_path_factory.mktemp("mixed") / f"mixed_{request.param}_arm.toml"
    path.write_text(mixed_arm_text(request.param))
    return hydrogen.build(hydrogen.load_model(path), cache=cache)


def test_each_actuator_of_a_mixed_robot_keeps_its_own_laws(mixed_dyn, rng):
    """One pressure for the three-way cylinder, two for the other kind; the compiled force, plant rate
    and valve inverse agree block by block with each kind's own numpy law."""
    m = mixed_dyn.model
    kinds = [c.kind for c in m.cylinders]
    assert kinds[0] == "three_way_cylinder" and kinds[1] in ("four_way_cylinder", "rotary")
    assert pressures.blocks(m) == [(0, 1), (1, 3)]
    assert pressures.state_names(m)[0] == "shoulder_cylinder.pc"
    q, qd = m.neutral_pose, rng.normal(size=m.n) * 0.1
    p, u = rng.uniform(2e6, 8e6, 3), rng.uniform(-1e-3, 1e-3, 2)
    l, ldot = mixed_dyn.leg_lengths(q), mixed_dyn.leg_jacobian(q) @ qd
    rates = mixed_dyn.pressure_rate(l, ldot, p, u, m.gamma)
    forces = mixed_dyn.leg_force(p)
    y = rng.normal(size=2) * 1e3
    spool = mixed_dyn.valve_inverse(y, p, l=l)
    for i, ((a, b), c) in enumerate(zip(pressures.blocks(m), m.cylinders)):
        law, P, block = actuator(c.kind).Numeric, c.table, tuple(p[a:b])
        np.testing.assert_allclose(forces[i], law.force(block, P), rtol=1e-12)
        np.testing.assert_allclose(rates[a:b], law.pressure_rates(l[i], ldot[i], block, u[i], m.gamma[0][i],
                                                                  m.gamma[1][i] / m.gamma[0][i], P), rtol=1e-9)
        np.testing.assert_allclose(law.g0(l[i], block, spool[i], P), y[i], rtol=1e-9)


def test_the_initial_pressures_hold_a_mixed_robot(mixed_dyn):
    from hydrogen.simulation.simulator import equilibrium_pressures
    m = mixed_dyn.model
    p = equilibrium_pressures(mixed_dyn, m.neutral_pose, m.theta)
    np.testing.assert_allclose(mixed_dyn.leg_jacobian(m.neutral_pose).T @ mixed_dyn.leg_force(p),
                               mixed_dyn.gravity(m.neutral_pose, m.theta), rtol=1e-9)


def test_a_mixed_robot_tracks_and_the_python_loop_reproduces_the_c_loop(mixed_dyn):
    """Backstepping tracks every coordinate on arm-sim with the pressures inside [0, P_s]; the Python
    loop (the oracle) gives the C loop's run with sensor noise on."""
    res = hydrogen.simulate("arm-sim", "backstepping", dyn=mixed_dyn)
    first, last = _errors(res)
    assert np.all(first > 20 * last) and np.all(last < 2e-4), (first, last)
    assert res.pressures.min() > 0 and res.pressures.max() < 10e6
    # a rotary actuator's reading is an angle: its noise is its own, in rad
    own = {c.name: {"noise_l": 1e-6} for c in mixed_dyn.model.cylinders if c.kind == "rotary"}
    kw = dict(dyn=mixed_dyn, duration=0.3, noise_p=1e4, noise_l=1e-6, noise_q=1e-5, actuators=own)
    c = hydrogen.simulate("arm-sim", "adaptive-robust", **kw)
    py = hydrogen.simulate("arm-sim", "adaptive-robust", engine="python", **kw)
    for a, b in ((c.q, py.q), (c.pressures, py.pressures), (c.u, py.u)):
        np.testing.assert_allclose(a, b, rtol=1e-8, atol=1e-12 * max(1.0, np.abs(b).max()))


@pytest.mark.parametrize("controller", ["adaptive-robust", "adaptive-observer"])
def test_adaptive_control_shrinks_a_mixed_robots_errors_20_fold(mixed_dyn, controller):
    first, last = _errors(hydrogen.simulate("arm-sim", controller, dyn=mixed_dyn))
    assert np.all(first > 20 * last), (first, last)


def test_a_rotary_actuator_needs_its_force_loop_gain(mixed_dyn, cache):
    """A rotary actuator's Γ_τ⁻¹ (N m/rad) has no default: the cylinders' 1e4 N/m, taken as is, weighs
    the vane's torque error as a cylinder's on a 1 m lever (the elbow error then shrinks only 8-15 fold
    under adaptive control); a run without it names the gain and the actuator."""
    m = mixed_dyn.model
    if m.cylinders[1].kind != "rotary":
        pytest.skip("cylinders have a default")
    import dataclasses
    bare = dataclasses.replace(m, gains={k: {g: v for g, v in t.items() if g != "Gtau_inv"}
                                         for k, t in m.gains.items()})
    dyn = hydrogen.build(bare, cache=cache)
    with pytest.raises(hydrogen.ScenarioError, match=r"gain 'Gtau_inv' .* must be given for 'elbow_motor' \(rotary\)"):
        hydrogen.simulate("arm-sim", "backstepping", dyn=dyn, duration=0.01)
    assert hydrogen.simulate("arm-sim", "p", dyn=dyn, duration=0.01).q.size  # a controller without the force loop
