"""Composite adaptation of γ (hydrogen/controllers/composite.py): the prediction error, the
least-squares gain, weight 0 = the paper's gradient law, and convergence on paper-sim."""
import numpy as np
import pytest
import sympy as sp

import hydrogen
from hydrogen.controllers.common import initial_gain_matrix
from hydrogen.pressures import n_pressures
from hydrogen.simulation.control import make_controller
from hydrogen.controllers.composite import normalised_least_squares, pack_symmetric, unpack_symmetric

from controller_inputs import PAPER_LAWS, kind_laws, random_controller_inputs

KINDS = ["adaptive-robust", "adaptive-observer"]


def _spd(k, rng):
    a = rng.standard_normal((k, k))
    return a @ a.T + 0.1 * np.eye(k)


def _ls_numeric(k_rows, p):
    """The symbolic law as a numeric function (W, eps, P, k, δ, ν) -> (ẋ, Ṗ as a matrix)."""
    W = sp.Matrix(k_rows, p, lambda i, j: sp.Symbol(f"w{i}_{j}"))
    eps = sp.Matrix(sp.symbols(f"e0:{k_rows}"))
    Pp = sp.symbols(f"P0:{p * (p + 1) // 2}")
    k, d, nu = sp.symbols("k d nu")
    xd, Pd = normalised_least_squares(W, eps, Pp, k, d, nu)
    f = sp.lambdify([list(W), list(eps), list(Pp), k, d, nu], [xd, Pd])

    def call(Wn, en, Pn, kk, dd, nn):
        packed = pack_symmetric(sp.Matrix(Pn))
        x, P = f(list(np.ravel(Wn)), list(en), [float(v) for v in packed], kk, dd, nn)
        return np.ravel(np.array(x, float)), np.array(unpack_symmetric(P, p), float)
    return call


def test_normalised_least_squares_matches_its_formula_and_keeps_the_gain_spd(rng):
    """ẋ = −k P Wᵀ ε / m², Ṗ = −k P Wᵀ W P / m² with m² = tr(W P Wᵀ) + δ‖W‖² + ν², against numpy;
    an explicit step with k h < 1 keeps P symmetric positive definite, P only shrinks."""
    for rows, p in [(1, 2), (3, 4)]:
        law = _ls_numeric(rows, p)
        for _ in range(20):
            W, e, P = rng.standard_normal((rows, p)) * 10 ** rng.uniform(-3, 3), rng.standard_normal(rows), _spd(p, rng)
            k, d, nu = 50.0, 1e-4, 1e-3
            x, Pd = law(W, e, P, k, d, nu)
            m2 = np.trace(W @ P @ W.T) + d * np.sum(W ** 2) + nu ** 2
            np.testing.assert_allclose(x, -k * P @ W.T @ e / m2, rtol=1e-10, atol=1e-14)
            np.testing.assert_allclose(Pd, -k * P @ W.T @ W @ P / m2, rtol=1e-10, atol=1e-12 * np.abs(P).max())
            np.testing.assert_array_equal(Pd, Pd.T)
            for h in (1e-3, 0.999 / k):
                P1 = P + h * Pd
                assert np.linalg.eigvalsh(P1).min() > 0
                assert np.linalg.eigvalsh(P - P1).min() > -1e-12 * np.abs(P).max()
        # k h > 1 can lose positive definiteness: the bound is not vacuous
        W = np.ones((1, 2)) * 1e3
        P = np.eye(2)
        _, Pd = _ls_numeric(1, 2)(W, [0.0], P, 50.0, 0.0, 0.0)
        assert np.linalg.eigvalsh(P + 0.05 * Pd).min() < 0


def test_initial_gain_matrix_is_p0_identity():
    np.testing.assert_array_equal(initial_gain_matrix(2, 2, 3.0), [3, 0, 3, 3, 0, 3])
    np.testing.assert_array_equal(np.array(unpack_symmetric(initial_gain_matrix(3, 1, 2.0), 3), float),
                                  2 * np.eye(3))


@pytest.mark.parametrize("kind", KINDS)
def test_composite_weight_zero_is_the_papers_gradient_law(robot_dyn, kind, rng):
    """rate_ls_gamma = rate_ls_theta = 0: γ̂'s rates equal the paper's law computed here in numpy from
    the controller's own f_d and the spool the valves held (γ̂̇1 = Γ_γ1⁻¹ Γ_τ f0 f̃,
    γ̂̇2 = Γ_γ2⁻¹ Γ_τ g0(u_applied) f̃), and the command
    and every rate but the composite filters' (θ̂'s too) are unchanged by the composite states."""
    dyn, model = robot_dyn, robot_dyn.model
    # the weights at 0 whatever the description stores (the Stewart rig's use the composite γ law)
    ctrl = make_controller(dyn, kind, PAPER_LAWS)
    assert float(ctrl.values["rate_ls_gamma"][0]) == 0.0 and float(ctrl.values["rate_ls_theta"][0]) == 0.0
    m = model.n_cylinders
    comp = ["force_filter", "log_chamber_filter", "g0_filter", "pc_prev", "legl_prev", "gamma_gain",
            "momentum_filter", "momentum_offset_filter", "bias_filter", "bias_offset_filter", "torque_filter",
            "theta_gain"]
    for _ in range(5):
        q, qdot, pc, ref, xc = random_controller_inputs(ctrl, model, rng)
        ctrl.xc[:] = xc
        held = rng.uniform(-1, 1, m) * float(ctrl.values["u_max"][0])
        ctrl.applied(held)
        l = np.asarray(dyn.leg_lengths(q)).ravel()
        u = ctrl.command(q, qdot, pc, l, ref, True).copy()
        rate = ctrl.xc_dot.copy()
        ldot = np.asarray(dyn.leg_jacobian(q)).reshape(m, model.n) @ qdot
        f, f0, g0 = kind_laws(model, l, ldot, pc, held)  # each cylinder's kind (numpy)
        ftil = f - ctrl.f_d
        v = ctrl.values
        np.testing.assert_allclose(rate[ctrl.slices["gamma1_hat"]], v["Ggamma1_inv"] / v["Gtau_inv"] * f0 * ftil,
                                   rtol=1e-9)
        np.testing.assert_allclose(rate[ctrl.slices["gamma2_hat"]], v["Ggamma2_inv"] / v["Gtau_inv"] * g0 * ftil,
                                   rtol=1e-9)
        # other composite states: the command and every rate outside the composite filters unchanged
        ctrl.xc[:] = xc
        for name in comp:
            if not name.endswith("_gain"):
                ctrl.xc[ctrl.slices[name]] = xc[ctrl.slices[name]] * rng.uniform(0.5, 1.5) + 1.0
        u2 = ctrl.command(q, qdot, pc, l, ref, True)
        np.testing.assert_array_equal(u2, u)
        keep = np.ones(rate.size, bool)
        for name in comp:
            keep[ctrl.slices[name]] = False
        np.testing.assert_array_equal(ctrl.xc_dot[keep], rate[keep])


def _prediction_error(dyn, model, update, lam=100.0, periods=2500):
    """ε (N/s) and the filtered ḟ λ_f (f − φ_f) per period, from the controller's filter states along a
    paper-sim run with the true parameters, recomputed here from the plant's forces and lengths."""
    st = hydrogen.stepper("paper-sim", "adaptive-robust", dyn=dyn, gains={"lambda_f_gamma": lam}, duration=3.0,
                          theta0_factor=[1.0] * model.n_theta, gamma0_factor=[1.0, 1.0], estimator_update=update)
    sl, n, m, h = st.controller.slices, model.n, model.n_cylinders, st.h
    A, L = model.piston_area, model.chamber_length
    g1, g2 = model.gamma
    E, Y = [], []
    for _ in range(periods):
        x = st.x.copy()  # the plant at this period's measurement
        st.step()
        xc = st.xc
        f = np.asarray(dyn.leg_force(x[2 * n:2 * n + m])).ravel()
        l = np.asarray(dyn.leg_lengths(x[:n])).ravel()
        # the states after the update: the force-side filters have moved by (1 − h λ_f) once more
        y = lam * (f - xc[sl["force_filter"]]) / (1 - h * lam)
        w1 = -A * lam * (np.log(l - L) - xc[sl["log_chamber_filter"]]) / (1 - h * lam)
        E.append(g1 * w1 + g2 * xc[sl["g0_filter"]] - y)
        Y.append(y)
    E, Y = np.array(E)[500:], np.array(Y)[500:]
    return np.sqrt((E ** 2).mean(axis=0) / (Y ** 2).mean(axis=0))


@pytest.mark.parametrize("update", ["semi-implicit", "euler"])
def test_prediction_error_vanishes_with_the_true_parameters(dyn, model, update):
    """With the spool the valves held (the loop's u_applied input, under either state update) the
    filtered equation holds to < 1 % of the filtered ḟ per leg (the trapezoid's residual)."""
    rel = _prediction_error(dyn, model, update)
    assert np.all(rel < 0.01), rel


def test_ls_gain_stays_symmetric_positive_definite_along_a_run(dyn):
    st = hydrogen.stepper("paper-sim", "adaptive-robust", dyn=dyn, gains={"rate_ls_gamma": 100.0}, duration=2.0,
                          estimator_update="euler")
    sl = st.controller.slices["gamma_gain"]
    for k in range(1500):
        st.step()
        if k % 50 == 0:
            for tri in st.xc[sl].reshape(-1, 3):
                P = np.array([[tri[0], tri[1]], [tri[1], tri[2]]])
                ev = np.linalg.eigvalsh(P)
                assert ev.min() > 0 and ev.max() <= 1.0 + 1e-12, (k, ev)
    assert st.xc[sl].reshape(-1, 3)[:, 0].max() < 0.1  # it has learnt: P shrank



def _ideal_scenario(model) -> str:
    """The robot's first scenario on the ideal plant (not ``rig = true``): its counterpart of paper-sim."""
    from hydrogen.simulation.scenarios import scenario_names
    return next(name for name in scenario_names(model) if not model.scenarios[name].get("rig"))


def _supply_state(model, x):
    """The supply pressure (Pa) in plant state ``x``, None where the supply is constant."""
    from hydrogen.plant import plant_layout
    part = {s.name: s for s in plant_layout(model)}.get("ps")
    return None if part is None else x[part.start:part.start + part.size]


def test_theta_prediction_error_vanishes_with_the_true_parameters(robot_dyn):
    """The momentum form: τ_f = λ_f (Y_p − ξ) θ + ζ θ + offsets, from the controller's filter states
    along each robot's ideal-plant run with the true parameters, against D(q, θ) q̇ (the compiled mass
    matrix) and (JL)ᵀ f filtered here: the error is < 1 % of the filtered force's variation."""
    dyn, model = robot_dyn, robot_dyn.model
    scen = _ideal_scenario(model)
    lam = 20.0
    # the composite θ law on (the filters run only then), as the shipped ideal scenarios but crane-sim set it
    st = hydrogen.stepper(scen, "adaptive-robust", dyn=dyn, gains={"lambda_f_theta": lam, "rate_ls_theta": 20.0},
                          duration=3.0, theta0_factor=[1.0] * model.n_theta, gamma0_factor=[1.0, 1.0])
    sl, n, m, p, h = st.controller.slices, model.n, model.n_cylinders, model.n_theta, st.h
    th = model.theta
    E, T = [], []
    tf = np.zeros(n)  # (JL)ᵀ f filtered here, as the controller's update does (from 0)
    for k in range(2500):
        x = st.x.copy()
        st.step()
        xc = st.xc
        q, qdot = x[:n], x[n:2 * n]
        f = np.asarray(dyn.leg_force(x[2 * n:2 * n + n_pressures(model)], ps=_supply_state(model, x))).ravel()
        xi = xc[sl["momentum_filter"]].reshape(n, p) @ th + xc[sl["momentum_offset_filter"]]
        ze = xc[sl["bias_filter"]].reshape(n, p) @ th + xc[sl["bias_offset_filter"]]
        mom = np.asarray(dyn.mass_matrix(q, th)).reshape(n, n) @ qdot
        # the momentum filter after the update has moved by (1 − h λ_f) once more
        E.append(lam * (mom - xi) / (1 - h * lam) + ze - xc[sl["torque_filter"]])
        tau = np.asarray(dyn.leg_jacobian(q)).reshape(m, n).T @ f
        if k or st.scenario.estimator_update == "euler":  # the semi-implicit loop's first period has no update
            tf = tf + h * lam * (tau - tf)
        np.testing.assert_allclose(xc[sl["torque_filter"]], tf, rtol=1e-9, atol=1e-9 * np.abs(tau).max())
        T.append(tf)
    E, T = np.array(E)[500:], np.array(T)[500:]
    # rows in units of acceleration (÷ the inertia scale), against the largest row's variation
    scale = st.controller.values["theta_row_scale"]
    rms = lambda a: np.sqrt((a ** 2).mean(axis=0)) / scale  # noqa: E731
    rel = rms(E) / rms(T - T.mean(axis=0)).max()
    assert rel.max() < 0.01, rel


def test_composite_rates_are_checked_against_the_control_period(dyn):
    with pytest.raises(hydrogen.ScenarioError, match="rate_ls_gamma"):
        hydrogen.simulate("paper-sim", "adaptive-robust", dyn=dyn, gains={"rate_ls_gamma": 2000.0}, duration=0.01)


def _tilted_arm():
    """The arm with its stick joint's origin turned by 0.2 rad about x: an oblique joint."""
    import dataclasses

    arm = hydrogen.load_model("excavator_arm")
    j = dataclasses.replace(arm.joints[1], origin_rpy=np.array([0.2, 0.0, 0.0]))
    return dataclasses.replace(arm, joints=(arm.joints[0], j, *arm.joints[2:]))


@pytest.mark.parametrize("tilted", [False, True], ids=["arm", "tilted arm"])
def test_theta_signals_of_a_staged_tree_equal_the_closed_forms(rng, tilted):
    """Y_p, p0, Y_b, b0 of the momentum form on a staged tree (D holds link-pose symbols, so Cᵀ q̇
    comes from the tree's Christoffel C, not from ∂D/∂q) equal the closed form's (∂/∂q of the
    kinetic energy) for the same robot, at random states: the arm, staged by its rigid_body_form;
    and the arm with an oblique joint, whose closed form takes Y_p and Y_b as Jacobians in θ
    instead of expanding D once per parameter."""
    from hydrogen.symbolic import rigid_body
    from hydrogen.controllers.composite import RigidBodyComposite
    from hydrogen.symbolic.control_laws import Common
    from hydrogen.symbolic.forms import oblique_joints, with_form
    from hydrogen.codegen.sympy_to_casadi import to_casadi
    import casadi as ca

    arm = _tilted_arm() if tilted else hydrogen.load_model("excavator_arm")
    assert bool(oblique_joints(arm)) == tilted

    def signals(form):
        model = with_form(arm, form)
        c = Common(model)
        out = RigidBodyComposite(c, c.theta()).signals()
        staged = len(rigid_body.rigid_body_stages(model, c.q))
        # the kinematics' stages (poses and their rates) composed in order, each from q, q̇ and the
        # stages before it, then the signals from all of them, as a CasADi graph: the composition the
        # generated code computes, without expanding the stages into SymPy expressions or printing
        # them for lambdify (what made this test slow)
        q, qd = ca.SX.sym("q", arm.n), ca.SX.sym("qd", arm.n)
        table = {**dict(zip(c.q, ca.vertsplit(q))), **dict(zip(c.qdot, ca.vertsplit(qd)))}
        for syms, expr in c.kin:
            if isinstance(expr, sp.MatrixBase):
                value = to_casadi(sp.Matrix(list(expr)), table)
                table.update(zip(list(syms), ca.vertsplit(value)))
        assert all(sp.Matrix(o).free_symbols <= set(table) for o in out)
        f = ca.Function("signals", [q, qd], [to_casadi(sp.Matrix(o), table) for o in out])
        return staged, lambda qv, qdv: [np.array(v) for v in f(qv, qdv)]

    n_closed, closed = signals("closed")
    n_staged, staged = signals("staged")
    assert n_closed == 0 and n_staged > 0  # the two forms were really built
    for _ in range(3):
        q, qd = rng.uniform(-1, 1, arm.n), rng.uniform(-1, 1, arm.n)
        for a, b in zip(closed(q, qd), staged(q, qd)):
            np.testing.assert_allclose(np.array(b, float), np.array(a, float), rtol=1e-9, atol=1e-9)


def test_copies_of_the_last_period_start_at_the_initial_measurement(robot_dyn):
    """The composite γ law's trapezoid divides by l − L: its copies of the last length and control
    pressure start at l(q0) and the run's initial pressures, never at 0 (a chamber of zero dead
    length would give 0/0 in the first period)."""
    from hydrogen.simulation.simulator import prepare_run

    dyn, model = robot_dyn, robot_dyn.model
    sc = _ideal_scenario(model)
    p = prepare_run(dyn, sc, "adaptive-robust", None, 0.01, False, {})
    sl, x0, n = p.ctrl.slices, p.x0, model.n
    np.testing.assert_allclose(p.ctrl.xc[sl["legl_prev"]], np.asarray(dyn.leg_lengths(x0[:n])).ravel())
    np.testing.assert_allclose(p.ctrl.xc[sl["pc_prev"]], x0[2 * n:2 * n + n_pressures(model)])


def test_staged_least_squares_equals_the_plain_law(rng):
    """The controllers' staged form (W, ε, P Wᵀ and k/m² bound to symbols) gives the same ẋ and Ṗ as
    the plain law, the stages substituted in order, at random values."""
    from hydrogen.controllers.composite import staged_least_squares

    rows, p = 3, 4
    W = sp.Matrix(rows, p, lambda i, j: sp.Symbol(f"w{i}_{j}"))
    eps = sp.Matrix(sp.symbols(f"e0:{rows}"))
    Pp = sp.symbols(f"P0:{p * (p + 1) // 2}")
    k, d, nu = sp.symbols("k d nu")
    x_plain, P_plain = normalised_least_squares(W, eps, Pp, k, d, nu)
    x_st, P_st, stages = staged_least_squares(W, eps, Pp, k, d, nu, "t")
    out = [sp.Matrix(x_st), sp.Matrix(P_st)]
    for syms, expr in reversed(stages):
        rep = dict(zip(list(syms), list(expr)))
        out = [o.xreplace(rep) for o in out]
    args = [*W, *eps, *Pp, k, d, nu]
    f_plain = sp.lambdify(args, [sp.Matrix(x_plain), sp.Matrix(P_plain)])
    f_st = sp.lambdify(args, out)
    for _ in range(3):
        P = _spd(p, rng)
        vals = [*rng.standard_normal(rows * p), *rng.standard_normal(rows),
                *[float(v) for v in pack_symmetric(sp.Matrix(P))], 20.0, 1e-3, 0.1]
        for a, b in zip(f_plain(*vals), f_st(*vals)):
            np.testing.assert_allclose(np.array(b, float), np.array(a, float), rtol=1e-12, atol=1e-14)


def test_a_bad_gain_from_the_description_names_its_file_and_table(tmp_path, dyn, cache):
    """A gain the description sets, checked only once the run's period is known, names the file and
    the table it came from (the caller's gains say ``gains``)."""
    from pathlib import Path

    text = Path(dyn.model.source).read_text()
    path = tmp_path / "stewart.toml"

    def run(edited, controller):
        path.write_text(edited)
        with pytest.raises(hydrogen.ScenarioError) as err:
            hydrogen.simulate("z-1hz", controller, dyn=hydrogen.build(hydrogen.load_model(path), cache=cache),
                              duration=0.01)
        return str(err.value)

    table = "[gains.adaptive-observer]\n"
    msg = run(text.replace(table, table + "rate_ls_theta = 5000.0\n"), "adaptive-observer")
    assert msg.startswith(f"{path}: [gains.adaptive-observer]: ") and "'rate_ls_theta'" in msg and "1/h" in msg
    msg = run(text.replace(table, table + "lambda_f_gamma = -1.0\n"), "adaptive-observer")
    assert msg.startswith(f"{path}: [gains.adaptive-observer]: ") and "'lambda_f_gamma' must be > 0" in msg
    with pytest.raises(hydrogen.ScenarioError, match=r"^gains: controller 'p': gain 'Kleg'"):
        hydrogen.simulate("z-1hz", "p", dyn=dyn, gains={"Kleg": -1.0}, duration=0.01)
    # a gain the scenario's table pins names that table; the caller's own wins and is named so
    pinned = "Ktau = 150.0, Ko = 300.0, rate_ls_gamma = 100.0"
    path.write_text(text.replace(pinned, "Ktau = 150.0, Ko = 300.0, rate_ls_gamma = 5000.0"))
    pinned_dyn = hydrogen.build(hydrogen.load_model(path), cache=cache)
    with pytest.raises(hydrogen.ScenarioError) as err:
        hydrogen.simulate("paper-sim", "adaptive-robust", dyn=pinned_dyn, duration=0.01)
    assert str(err.value).startswith(f"{path}: [scenarios.paper-sim] gains.adaptive-robust: controller "
                                     "'adaptive-robust': gain 'rate_ls_gamma' = 5000")
    with pytest.raises(hydrogen.ScenarioError, match=r"^gains: controller 'adaptive-robust': gain 'rate_ls_gamma'"):
        hydrogen.simulate("paper-sim", "adaptive-robust", dyn=pinned_dyn, duration=0.01,
                          gains={"rate_ls_gamma": 3000.0})


@pytest.mark.parametrize("kind", KINDS)
def test_a_measured_pressure_outside_the_supply_range_gives_finite_rates(robot_dyn, kind, rng):
    """Noise can put a measured p_c above p_s or below 0: the γ̂2 law's g0 then takes the clipped
    roots (no root of a negative drop); its command and rates stay finite."""
    dyn, model = robot_dyn, robot_dyn.model
    ctrl = make_controller(dyn, kind)
    q, qdot, pc, ref, xc = random_controller_inputs(ctrl, model, rng)
    ctrl.xc[:] = xc
    ctrl.applied(np.full(model.n_cylinders, 0.5 * float(ctrl.values["u_max"][0])))
    pc = pc.copy()
    pc[0] = model.supply_pressure[0] + 2.0e5
    pc[-1] = -2.0e5
    u = ctrl.command(q, qdot, pc, np.asarray(dyn.leg_lengths(q)).ravel(), ref, True)
    assert np.all(np.isfinite(u)) and np.all(np.isfinite(ctrl.xc_dot))
