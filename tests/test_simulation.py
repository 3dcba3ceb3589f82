"""Closed loop: plant integration, τ̇_d, the paper's qualitative claims, and failure reporting."""
import json

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import hydrogen
from hydrogen.cli import main as cli
from hydrogen.codegen.sympy_to_casadi import SympyToCasadi
from hydrogen.simulation.control import make_controller
from hydrogen.simulation.reference import MultiSine
from hydrogen.simulation.scenarios import scenario
from hydrogen.plant.integrator import rk4 as _rk4
from hydrogen.simulation.simulator import equilibrium_pressures, simulate
from hydrogen.controllers import controller as controller_module

from conftest import plant_inputs
from reference import controller_rate_map, singular_pose
from controller_inputs import PAPER_LAWS

#: friction [Coulomb N, viscous N s/m, tanh speed m/s] of each leg
FRICTION = (100.0, 300.0, 1e-3)


def test_rk4_matches_a_stiff_adaptive_reference(dyn, model, rng):
    q0 = model.neutral_pose + np.array([0.01, -0.01, 0.02, 0.03, -0.02, 0.01])
    x0 = np.concatenate([q0, rng.normal(size=6) * 0.05, equilibrium_pressures(dyn, q0, model.theta),
                         np.zeros(12)])
    u = rng.uniform(-1, 1, 6) * 2e-4
    fric, ideal = plant_inputs(model, FRICTION)
    rhs = lambda x: dyn.functions["plant_rhs"](x, u, model.theta, *model.gamma, fric, ideal)  # noqa: E731
    T, h = 0.05, 1.0 / 4000
    x = x0.copy()
    for _ in range(int(round(T / h))):
        x = _rk4(rhs, x, h)
    ref = solve_ivp(lambda t, y: rhs(y), (0, T), x0, method="Radau", rtol=1e-10, atol=1e-12)
    assert ref.success
    scale = np.r_[np.full(6, 1e-3), np.full(6, 1e-2), np.full(6, 1e5), np.full(6, 1e-5), np.full(6, 1e-3)]
    assert np.max(np.abs(x - ref.y[:, -1]) / scale) < 1e-3


def test_plant_at_equilibrium_stays_still(dyn, model):
    q0 = model.neutral_pose
    x0 = np.concatenate([q0, np.zeros(6), equilibrium_pressures(dyn, q0, model.theta), np.zeros(12)])
    pc0 = x0[12:18]
    # spool at each leg's null position for its pressure: no net flow
    d, ps = model.underlap, model.supply_pressure
    r = np.sqrt(pc0 / (ps - pc0))
    u = d * (r - 1) / (r + 1)
    xdot = dyn.functions["plant_rhs"](x0, u, model.theta, *model.gamma, *plant_inputs(model))
    np.testing.assert_allclose(xdot[6:12], 0, atol=1e-9)
    np.testing.assert_allclose(xdot[12:18], 0, atol=1e-3)


def test_backstepping_errors_decay_exponentially(dyn, model):
    const = MultiSine(model.neutral_pose, ())
    sc = scenario("paper-sim", model).with_overrides(
        reference=const, duration=1.2, q0_offset=(0.01, -0.01, 0.01, 0.02, -0.02, 0.02), metric_start=0.0)
    res = simulate(dyn, sc, "backstepping")
    err = np.linalg.norm(res.error, axis=1)
    at = lambda t: err[np.searchsorted(res.t, t)]  # noqa: E731
    samples = [at(t) for t in (0.2, 0.4, 0.6)]
    assert samples[0] < 0.1 * err[0]
    assert samples[1] < 0.1 * samples[0] and samples[2] < 0.1 * samples[1]  # geometric decay
    assert err[-1] < 1e-8  # down to the integrator's floor


def _parts_with_rates(kind, model):
    parts = controller_module(kind).derive(model)
    stage = {str(s[0]): (s, v) for s, v in parts.intermediates}
    taud_sym, taud = stage["taud_0"]
    _, taud_dot = stage["taud_dot_0"]
    return parts, taud, taud_dot


def _tau_d_dot_and_ad(kind, model):
    """(X, idx, SymPy's τ̇_d, CasADi's forward AD of τ_d) over every symbol τ_d and τ̇_d hold."""
    parts, taud, taud_dot = _parts_with_rates(kind, model)
    syms = sorted(taud.free_symbols | taud_dot.free_symbols, key=str)
    X = ca.SX.sym("X", len(syms))
    conv = SympyToCasadi({s: X[i] for i, s in enumerate(syms)})
    tau_sx, tau_dot_sx = conv(taud), conv(taud_dot)
    idx = {str(s): i for i, s in enumerate(syms)}
    rate = controller_rate_map(model, syms, X, idx)
    return X, idx, tau_dot_sx, ca.jtimes(tau_sx, X, rate)


@pytest.mark.parametrize("kind", ["backstepping", "adaptive-robust", "adaptive-observer"])
def test_tau_d_dot_matches_casadi_ad(kind, model, rng):
    """SymPy's τ̇_d equals CasADi's forward AD of τ_d along the rates the controller assumes."""
    X, idx, tau_dot_sx, ad = _tau_d_dot_and_ad(kind, model)
    f = ca.Function("f", [X], [ad, tau_dot_sx])
    for _ in range(5):
        x = rng.normal(size=X.numel())
        for s, i in idx.items():
            if s.startswith("q_") and not s.startswith("q_hat"):
                x[i] = model.neutral_pose[model.coordinate_names.index(s[2:])] + 0.05 * x[i]
            if s.startswith("theta_hat"):
                x[i] = 40 + abs(x[i])
        a, b = (np.array(v).ravel() for v in f(x))
        np.testing.assert_allclose(b, a, rtol=1e-9, atol=1e-9 * max(1, np.abs(a).max()))


@pytest.mark.parametrize("kind", ["backstepping", "adaptive-robust", "adaptive-observer"])
def test_tau_d_dot_is_no_larger_than_casadi_ad(kind, model):
    """The size target, per controller: τ̇_d as SymPy derives it takes no more CasADi
    instructions (with CSE) than CasADi's own forward AD of the same τ_d."""
    X, _, tau_dot_sx, ad = _tau_d_dot_and_ad(kind, model)
    n_sympy = ca.Function("sympy", [X], [tau_dot_sx], {"cse": True}).n_instructions()
    n_ad = ca.Function("ad", [X], [ad], {"cse": True}).n_instructions()
    assert n_sympy <= n_ad, (n_sympy, n_ad)


@pytest.mark.parametrize("kind", ["backstepping", "adaptive-robust"])
def test_tau_d_dot_matches_finite_differences_along_a_trajectory(kind, dyn, model):
    """Propagate plant and controller state ±δ around a simulated state; (τ_d⁺ − τ_d⁻)/2δ ≈ τ̇_d."""
    sc = scenario("paper-sim", model)
    res = simulate(dyn, sc, kind, duration=0.6, t_adapt=0.2)
    ctrl = make_controller(dyn, kind, None, res.theta_hat[-1], model.gamma)
    q, pc = res.q[-1], res.pressures[-1]
    # rebuild a consistent state: velocity from the last two logged poses is not exact, so integrate
    # the plant from the logged state with the logged command instead.
    x = np.concatenate([q, (res.q[-1] - res.q[-2]) * sc.control_rate, pc, np.zeros(12)])
    ctrl.reset(q, x[6:12])
    t = res.t[-1]
    u = ctrl.command(q, x[6:12], pc, dyn.leg_lengths(q), sc.reference(t), True)
    tau_dot, xc, xc_dot = ctrl.tau_d_dot.copy(), ctrl.xc.copy(), ctrl.xc_dot.copy()
    fric, ideal = plant_inputs(model)
    rhs = lambda xx: dyn.functions["plant_rhs"](xx, u, model.theta, *model.gamma, fric, ideal)  # noqa: E731
    delta = 1e-6
    taus = []
    for sgn in (+1, -1):
        xs = _rk4(rhs, x, sgn * delta)
        ctrl.xc = xc + sgn * delta * xc_dot
        ctrl.command(xs[:6], xs[6:12], xs[12:18], dyn.leg_lengths(xs[:6]), sc.reference(t + sgn * delta), True)
        taus.append(ctrl.tau_d.copy())
    fd = (taus[0] - taus[1]) / (2 * delta)
    np.testing.assert_allclose(tau_dot, fd, rtol=1e-4, atol=1e-4 * np.abs(fd).max())


def _window_ratio(res):
    first = np.abs(res.error[res.t < 2.0]).max(axis=0)
    last = np.abs(res.error[res.t >= res.t[-1] - 2.0]).max(axis=0)
    return last / first


@pytest.fixture(scope="module")
def paper_runs(dyn):
    return {k: simulate(dyn, "paper-sim", k) for k in ("adaptive-robust", "adaptive-observer")}


@pytest.mark.parametrize("kind", ["adaptive-robust", "adaptive-observer"])
def test_paper_sim_errors_shrink_twentyfold(paper_runs, kind):
    ratio = _window_ratio(paper_runs[kind])
    assert np.all(ratio <= 1 / 20), ratio


def test_paper_sim_observer_controller_estimates_rigid_body_within_6_percent(paper_runs):
    """Within 6 %: I_x ends +5.3 % off since γ̂2's law takes g0 at the spool the valves held over the
    period the update integrates (the previous period's applied command); +4.9 % with g0 at this
    period's provisional command."""
    res = paper_runs["adaptive-observer"]
    err = np.abs(res.theta_hat[-1] - res.theta_true) / res.theta_true
    assert np.all(err < 0.06), err


def test_paper_sim_robust_controller_estimates_end_within_5_percent(paper_runs):
    res = paper_runs["adaptive-robust"]
    err = np.abs(res.theta_hat[-1] - res.theta_true) / res.theta_true
    assert np.all(err < 0.05), err


def test_paper_sim_robust_controller_estimates_stay_within_5_percent_over_the_last_2_s(paper_runs):
    """With the observer's D̄, Ḡ from the current estimate (Theorem 3) the rigid-body estimates settle."""
    res = paper_runs["adaptive-robust"]
    err = np.abs(res.theta_hat[res.t >= 8.0] - res.theta_true) / res.theta_true
    assert np.all(err < 0.05), err.max(axis=0)


def test_paper_sim_observer_controller_estimates_stay_within_5_percent_over_the_last_2_s(paper_runs):
    res = paper_runs["adaptive-observer"]
    err = np.abs(res.theta_hat[res.t >= 8.0] - res.theta_true) / res.theta_true
    assert np.all(err < 0.05), err.max(axis=0)


@pytest.mark.parametrize("kind", ["adaptive-robust", "adaptive-observer"])
def test_paper_sim_hydraulic_estimates_end_and_stay_within_5_percent(paper_runs, kind):
    """With the composite law (the scenario's rate_ls_gamma) β̂ and (βc)^ of every leg end within 5 %
    and stay there over the last 2 s, although the β direction is excited 1e-3 to 1e-5 times less
    than the valve-gain direction (the excitation metric): the least-squares gain balances the rates
    the gradient law could not (README "What does not match the paper")."""
    res = paper_runs[kind]
    last = res.t >= res.t[-1] - 2.0
    for est, true in ((res.gamma1_hat, res.gamma_true[0]), (res.gamma2_hat, res.gamma_true[1])):
        err = np.abs(est[last] / true - 1)
        assert err.max() < 0.05, err.max(axis=0)
    exc = res.metrics["excitation"]
    assert exc["theta"] > 1e-3
    assert max(exc["gamma"]) < 1e-2 and min(exc["gamma"]) < 1e-3, exc["gamma"]


def test_paper_sim_gradient_law_keeps_the_valve_gain_but_not_beta(dyn):
    """The paper's law (composite weights 0) on the same run: the excited direction, the valve gain
    c = γ2/γ1, ends within 6 %, β̂ stays more than 5 % off (where the initial error and the gains leave
    it): what the composite law is for."""
    res = simulate(dyn, "paper-sim", "adaptive-robust", gains=PAPER_LAWS,
                   estimator_update="semi-implicit")
    c_hat = res.gamma2_hat[-1] / res.gamma1_hat[-1]
    c = res.gamma_true[1] / res.gamma_true[0]
    assert np.all(np.abs(c_hat / c - 1) < 0.06), c_hat / c
    assert np.all(np.abs(res.gamma1_hat[-1] / res.gamma_true[0] - 1) > 0.05)


def test_semi_implicit_estimator_update_is_stable_where_forward_euler_is_not(dyn):
    """Balanced hydraulic adaptation rates (3e-3 /J for both γ families): with the forward-Euler update
    of the controller state at 1 kHz the estimates oscillate to their bounds and the spool saturates;
    the semi-implicit update (state from this period's measurement, then the command) stays calm."""
    gains = {"rate_gamma1": 3e-3, "rate_gamma2": 3e-3, **PAPER_LAWS}  # the paper's law
    res = {upd: simulate(dyn, "paper-sim", "adaptive-observer", gains=gains, estimator_update=upd)
           for upd in ("euler", "semi-implicit")}
    th_err = {k: np.abs(r.theta_hat[-1] / r.theta_true - 1).max() for k, r in res.items()}
    sat = {k: (np.abs(r.u) >= 0.999 * r.u_max).mean() for k, r in res.items()}
    assert th_err["euler"] > 0.3 and sat["euler"] > 0.005, (th_err, sat)
    assert th_err["semi-implicit"] < 0.05 and sat["semi-implicit"] < 0.001, (th_err, sat)
    assert np.all(_window_ratio(res["semi-implicit"]) <= 1 / 20)


def test_normalised_adaptation_gains_and_raw_names(dyn, model):
    """Γ⁻¹ = rate · x_ref² per family (θ_ref: bound midpoints, γ_ref: initial estimates); the raw
    names still override."""
    g0 = model.gamma * np.array([0.7, 1.3])[:, None]
    ctrl = make_controller(dyn, "adaptive-robust", {"rate_theta": 2.0, "rate_gamma2": 1e-4}, model.theta, g0)
    mid = 0.5 * (model.theta_min + model.theta_max)
    np.testing.assert_allclose(ctrl.values["Gtheta_inv"], 2.0 * mid ** 2)
    np.testing.assert_allclose(ctrl.values["Ggamma2_inv"], 1e-4 * g0[1] ** 2)
    raw = make_controller(dyn, "adaptive-robust", {"Gtheta_inv": 5.0}, model.theta, g0)
    np.testing.assert_allclose(raw.values["Gtheta_inv"], 5.0)


@pytest.fixture(scope="module")
def arm_runs():
    return {k: hydrogen.simulate("arm-sim", k, model="excavator_arm") for k in ("adaptive-robust", "adaptive-observer")}


@pytest.mark.slow
def test_arm_sim_robust_controller_errors_shrink_twentyfold(arm_runs):
    ratio = _window_ratio(arm_runs["adaptive-robust"])
    assert np.all(ratio <= 1 / 20), ratio


@pytest.mark.slow
def test_arm_sim_observer_controller_errors_shrink_twentyfold(arm_runs):
    ratio = _window_ratio(arm_runs["adaptive-observer"])
    assert np.all(ratio <= 1 / 20), ratio


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["adaptive-robust", "adaptive-observer"])
def test_arm_sim_estimates_end_within_5_percent(arm_runs, kind):
    """arm-sim excites θ weakly (λmin/λmax 1.2e-3); the composite law (the scenario's rate_ls_theta)
    brings every estimate within 5 % and keeps it there over the last 2 s."""
    res = arm_runs[kind]
    err = np.abs(res.theta_hat[res.t >= res.t[-1] - 2.0] - res.theta_true) / np.abs(res.theta_true)
    assert np.all(err < 0.05), err.max(axis=0)


@pytest.mark.slow
def test_arm_sim_gradient_law_leaves_theta_off(arm_runs):
    """The paper's law (rate_ls_theta = 0) on the same run leaves some estimate more than 5 % off."""
    res = hydrogen.simulate("arm-sim", "adaptive-robust", model="excavator_arm", gains={"rate_ls_theta": 0.0})
    err = np.abs(res.theta_hat[-1] - res.theta_true) / np.abs(res.theta_true)
    assert err.max() > 0.05, err


@pytest.mark.slow
def test_arm_sim_excitation_is_reported_and_weaker_than_paper_sims(arm_runs, paper_runs):
    arm = arm_runs["adaptive-robust"].metrics["excitation"]["theta"]
    stewart = paper_runs["adaptive-robust"].metrics["excitation"]["theta"]
    assert 0 < arm < stewart / 3, (arm, stewart)


def test_excitation_is_reported_for_what_a_controller_estimates_only(dyn, paper_runs):
    """A controller that adapts nothing (P, backstepping) has no estimate to excite: no metric, and no
    cost per run (a sweep runs thousands); an adaptive one gets it."""
    assert "excitation" in paper_runs["adaptive-robust"].metrics
    for kind in ("p", "backstepping"):
        res = simulate(dyn, "paper-sim", kind, duration=0.5)
        assert not res.estimated and "excitation" not in res.metrics and "max_error_pct" in res.metrics


def test_divergence_stops_with_time_state_and_partial_result(plain_stewart_dyn):
    """A command of 1 m of spool (the Stewart platform without its datasheet valve, which saturates
    at 5 mm) diverges, with the pressures clipped after each RK4 step only (held within their bounds at
    every stage too, the default, they bound the forces and this run stays finite)."""
    with pytest.raises(hydrogen.SimulationError) as err:
        simulate(plain_stewart_dyn, "paper-sim", "backstepping", duration=2.0,
                 gains={"Ktau": 5e4, "u_max": 1.0}, control_rate=200.0, substeps=2, pressure_bounds="step")
    msg = str(err.value)
    assert "t = " in msg and "paper-sim" in msg
    res = err.value.result
    assert res is not None and 0 < len(res.t) < 401


#: The message of an observer driven past its bound: its role, the time, the entry, what to lower.
_OBSERVER_DIVERGED = (r"with 'adaptive-observer': the adaptive observer's velocity estimate \(z / q_hat_dot\) "
                      r"diverged at t = \d\.\d{4} s \(z\[\d\] = [-0-9.e+]+, past its bound 1000\): lower its gains "
                      r"\(Lambda2, Lp, Kd_obs\) and the loop's \(Lambda, Kd\), or the adaptation rates \(rate_theta, "
                      r"rate_gamma1, rate_gamma2\); then it diverged at t = ")


def test_a_diverged_observer_is_named_by_its_role_with_what_to_lower(dyn, model):
    """An absurd observer gain Lp drives z past any velocity a robot has long before a block goes
    non-finite (the estimates theta_hat go NaN last): the message names the observer's velocity
    estimate and its gains first, in simulate and in the stepper."""
    gains = {"Lp": [1e9] * model.n}
    with pytest.raises(hydrogen.SimulationError, match=_OBSERVER_DIVERGED):
        simulate(dyn, "paper-sim", "adaptive-observer", duration=0.5, gains=gains)
    st = hydrogen.stepper("paper-sim", "adaptive-observer", dyn=dyn, duration=0.5, gains=gains)
    with pytest.raises(hydrogen.SimulationError, match=_OBSERVER_DIVERGED):
        for _ in range(st.n_max):
            st.step()


def test_the_first_block_past_its_bound_or_non_finite_is_named():
    """The earliest period decides, whichever block goes non-finite later; a block without a bound
    (inf) is named when it goes non-finite; a state within its bounds names none."""
    from types import SimpleNamespace

    from hydrogen.controllers.spec import StateBlock
    from hydrogen.simulation.simulator import diverged_block
    layout = [StateBlock("theta_hat", 2, "the estimates", "rate_theta"), StateBlock("z", 1, "the observer", "K_o", 10.0)]
    ctrl = SimpleNamespace(layout=layout, slices={"theta_hat": slice(0, 2), "z": slice(2, 3)})
    t = np.array([0.0, 0.1, 0.2, 0.3])
    xc = np.array([[1.0, 2.0, 0.0], [1.0, 2.0, 20.0], [1.0, np.nan, 1e9], [np.nan, np.nan, np.nan]])
    assert diverged_block(ctrl, xc, t) == ("the observer diverged at t = 0.1000 s (z[0] = 20, past its bound 10): "
                                           "lower K_o")
    xc[1, 2] = 5.0
    xc[2, 2] = 5.0
    assert diverged_block(ctrl, xc, t) == "the estimates diverged at t = 0.2000 s (theta_hat[1] = nan): lower rate_theta"
    assert diverged_block(ctrl, xc[:2], t[:2]) is None


def test_reference_outside_workspace_is_rejected(dyn, model):
    """Every control period is checked, and the message names the first one and its first leg
    (found here with the numpy geometry of tests/reference.py)."""
    from reference import leg_lengths as numpy_leg_lengths

    far = MultiSine(model.neutral_pose, ((2, 0.5, 1.0),))
    sc = scenario("z-1hz", model).with_overrides(reference=far)
    h = 1.0 / sc.control_rate
    for k in range(int(sc.duration * sc.control_rate) + 1):
        legs = numpy_leg_lengths(model, far(k * h)[0])
        bad = np.nonzero((legs < model.leg_min) | (legs > model.leg_max))[0]
        if bad.size:
            break
    with pytest.raises(hydrogen.KinematicsError,
                       match=rf"leaves the workspace at t = {k * h:.3f} s: actuator '{model.cylinders[bad[0]].name}' "
                             r"would be at length \d\.\d{4} m, outside its stroke \[.*\] m \(.*ubc_stewart\.toml\)$"):
        simulate(dyn, sc, "p")


def test_cli_simulate_writes_json(tmp_path, capsys):
    out = tmp_path / "m.json"
    assert cli(["simulate", "--scenario", "z-1hz", "--controller", "p", "--duration", "0.5",
                "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    for key in ("max_error_pct", "rms_error", "theta_hat_final", "theta_true", "gamma_hat_final",
                "gamma_true", "sim_time_s", "wall_time_s"):
        assert key in data
    assert set(data["max_error_pct"]) == {"x", "y", "z", "psi", "theta", "phi"}
    assert data["max_error_pct"]["z"] > 0


@pytest.mark.parametrize("model_name,scenario_name,kind", [
    ("ubc_stewart", "paper-sim", "adaptive-robust"), ("ubc_stewart", "z-2hz", "p"),
    ("ubc_stewart", "z-step", "backstepping"), ("excavator_arm", "arm-dig", "adaptive-observer"),
    ("excavator_arm", "arm-sim", "p")])
def test_c_loop_matches_python_loop(cache, model_name, scenario_name, kind):
    """The whole loop in C and the same loop stepped from Python agree over the whole run (same noise
    samples), with forward kinematics (the platform) and with joint encoders (the arm). The rig's
    chaotic adaptive runs agree only up to a time: tests/test_rig.py (AGREE_S)."""
    dyn = hydrogen.build(hydrogen.load_model(model_name), cache=cache)
    c = simulate(dyn, scenario_name, kind)
    py = simulate(dyn, scenario_name, kind, engine="python")
    assert c.t.shape == py.t.shape and c.t[-1] >= c.scenario.duration - 2 / c.scenario.control_rate
    np.testing.assert_allclose(c.q, py.q, atol=1e-10)
    np.testing.assert_allclose(c.u, py.u, atol=1e-10)
    np.testing.assert_allclose(c.pressures, py.pressures, rtol=1e-8, atol=1e-3)
    np.testing.assert_allclose(c.theta_hat, py.theta_hat, rtol=1e-8)


@pytest.mark.parametrize("update", ["euler", "semi-implicit"])
def test_c_loop_matches_python_loop_for_both_estimator_updates(dyn, update):
    c = simulate(dyn, "paper-sim", "adaptive-observer", duration=0.8, t_adapt=0.1, estimator_update=update)
    py = simulate(dyn, "paper-sim", "adaptive-observer", duration=0.8, t_adapt=0.1, estimator_update=update,
                  engine="python")
    np.testing.assert_allclose(c.u, py.u, atol=1e-10)
    np.testing.assert_allclose(c.theta_hat, py.theta_hat, rtol=1e-8)
    np.testing.assert_allclose(c.gamma2_hat, py.gamma2_hat, rtol=1e-8)


def _xfail(why):
    return pytest.mark.xfail(strict=True, reason=why + " (docs/paper.md, The timing)")


_FULL = _xfail("full-period delay: adaptive-robust over 10 seeds 5.9 [5.6-6.4] / 16.7 [15.6-17.5] / 13.4 "
               "[12.8-13.7] % against the paper's 4 / 14 / 4 (unmodelled friction, delay and valve; with friction "
               "compensation it meets them)")
_LL_PSI = _xfail("near-zero computation latency (low-latency, 5 us): psi-1hz adaptive-robust 5.7 [5.3-5.9] % "
                 "(gains searched with headroom), adaptive-observer 4.6 [4.2-4.8] %, above the paper's 4 %")
_PRED_PSI = _xfail("full-period delay with the predictor: adaptive-robust psi-1hz 5.9 [4.9-6.6] %; the predictor "
                   "cannot see the valve's lag, the friction or the noise")
_P_PSI = _xfail("full-period delay: the better P 39.2 % on psi-1hz against adaptive-robust's worst seed 13.7 %: "
                "2.9 x (3 x and more with friction compensation)")


@pytest.fixture(scope="module")
def rig_over_seeds(dyn):
    """(scenario, controller) -> the metrics of its runs over the documented seeds, run on first use."""
    from hydrogen.simulation.tuning import SEEDS
    runs = {}

    def get(name, kind):
        if (name, kind) not in runs:
            metrics = simulate(dyn, name, kind, seeds=SEEDS, max_workers=2).metrics
            assert "error" not in metrics, f"{name}, {kind}: {metrics['error']}"  # no seed ran: say why
            runs[name, kind] = metrics
        return runs[name, kind]
    return get


#: (scenario, coordinate, the paper's nonlinear error %, the controller compared): the table (the
#: full-period rig), near-zero computation latency (the paper states none) and the full period with the predictor.
_TARGETS = [
    pytest.param("z-1hz", "z", 4.0, "adaptive-robust", marks=_FULL),
    pytest.param("z-2hz", "z", 14.0, "adaptive-robust", marks=_FULL),
    pytest.param("psi-1hz", "psi", 4.0, "adaptive-robust", marks=_FULL),
    pytest.param("z-1hz.low-latency", "z", 4.0, "adaptive-robust"),
    pytest.param("z-2hz.low-latency", "z", 14.0, "adaptive-robust"),
    pytest.param("psi-1hz.low-latency", "psi", 4.0, "adaptive-robust", marks=_LL_PSI),
    pytest.param("z-1hz.low-latency", "z", 4.0, "adaptive-observer"),
    pytest.param("z-2hz.low-latency", "z", 14.0, "adaptive-observer"),
    pytest.param("psi-1hz.low-latency", "psi", 4.0, "adaptive-observer", marks=_LL_PSI),
    pytest.param("z-1hz.predictor", "z", 4.0, "adaptive-robust"),
    pytest.param("z-2hz.predictor", "z", 14.0, "adaptive-robust"),
    pytest.param("psi-1hz.predictor", "psi", 4.0, "adaptive-robust", marks=_PRED_PSI),
]


@pytest.mark.parametrize("name,coord,paper_nonlinear,kind", _TARGETS)
def test_experiments_nonlinear_below_the_papers_error(rig_over_seeds, name, coord, paper_nonlinear, kind):
    """The median over the seeds at or below the paper's error."""
    assert rig_over_seeds(name, kind)["median"]["max_error_pct"][coord] <= paper_nonlinear


#: The seeds every claimed number is checked on: none of the tuning seeds 0..9.
CHECKING_SEEDS = list(range(100, 120))
#: The paper's nonlinear errors (%) on the table's experiments, and the compensation's gains for the
#: Stewart platform (benchmarks/friction_compensation.py, chosen on seeds 0-9).
PAPER = {"z-1hz": ("z", 4.0), "z-2hz": ("z", 14.0), "psi-1hz": ("psi", 4.0)}
COMPENSATION = {"rate_friction": 1.0, "friction_speed": 0.01}


@pytest.mark.slow
@pytest.mark.parametrize("name", list(PAPER))
def test_with_friction_compensation_adaptive_robust_meets_the_paper_on_unseen_seeds(model, dyn, cache, name):
    """The table's timing (full-period delay), seeds 100-119: adaptive-robust generated with friction
    compensation (a declared deviation) at or below the paper's error as the median, its worst seed
    below 1.5 x that, and the better P's best seed at least 3 x its worst."""
    import dataclasses
    coord, paper = PAPER[name]
    fdyn = hydrogen.build(dataclasses.replace(model, friction_compensation=True), cache=cache,
                          controllers=["adaptive-robust"])
    res = simulate(fdyn, name, "adaptive-robust", gains=COMPENSATION, seeds=CHECKING_SEEDS, max_workers=2)
    assert not res.failures
    errors = [r.metrics["max_error_pct"][coord] for r in res.results]
    assert np.median(errors) <= paper and max(errors) < 1.5 * paper
    p = min(simulate(dyn, name, k, seeds=CHECKING_SEEDS, max_workers=2).metrics["min"]["max_error_pct"][coord]
            for k in ("p", "p-task"))
    assert p >= 3 * max(errors)


@pytest.mark.parametrize("name,coord", [pytest.param(f"{s}{v}", c, marks=_P_PSI if (s, v) == ("psi-1hz", "") else ())
                                        for s, c in (("z-1hz", "z"), ("z-2hz", "z"), ("psi-1hz", "psi"))
                                        for v in ("", ".low-latency", ".predictor")])
def test_experiments_p_is_at_least_3x_worse_than_nonlinear(rig_over_seeds, name, coord):
    """On every seed: the better P's (task space) best run is 3 times worse than the nonlinear
    controller's worst."""
    nl = rig_over_seeds(name, "adaptive-robust")["max"]["max_error_pct"][coord]
    p = min(rig_over_seeds(name, k)["min"]["max_error_pct"][coord] for k in ("p", "p-task"))
    assert p > 3 * nl


@pytest.mark.parametrize("kind", ["backstepping", "adaptive-observer", "adaptive-robust"])
def test_arm_dig_nonlinear_is_at_least_3x_better_than_p(kind):
    dyn = hydrogen.build(hydrogen.load_model("excavator_arm"))
    nl = max(v for v in simulate(dyn, "arm-dig", kind).metrics["max_error_pct"].values() if v is not None)
    p = max(v for v in simulate(dyn, "arm-dig", "p").metrics["max_error_pct"].values() if v is not None)
    assert p > 3 * nl


def test_robust_observer_gain_follows_lambda_and_kd():
    """K_o defaults to (Λ + K_d/scale)² / (K_d/scale): with the former fixed 30 /s, the controller's
    default gains (Λ = 60 /s, K_d = 60 × scale) lost the arm on arm-dig's reference with the ideal
    plant, the true parameters and no adaptation (87 / 148 / 107 %, the valves saturated throughout)."""
    from hydrogen.controllers import controller as controller_module
    from hydrogen.simulation.control import gain_scale

    import dataclasses

    # the description pins K_o (its rig search chose 30 /s); this test is about the default rule
    model = hydrogen.load_model("excavator_arm")
    tables = {k: dict(v) for k, v in model.gains.items()}
    tables["adaptive-robust"].pop("Ko", None)
    dyn = hydrogen.build(dataclasses.replace(model, gains=tables))
    scale = gain_scale(dyn)
    defaults = controller_module("adaptive-robust").default_gains(dyn.model, scale)
    gains = {k: defaults[k] for k in ("Lambda", "Kd", "Kp", "Ktau")}
    ideal = dict(delay=0.0, valve_bandwidth_hz=0.0, friction=(0.0, 0.0, 1e-3), quantization_l=0.0,
                 noise_l=0.0, noise_q=0.0, noise_p=0.0, kalman=False, t_adapt=1e9,
                 theta0_factor=(1.0,) * dyn.model.n_theta, gamma0_factor=(1.0, 1.0))
    res = simulate(dyn, "arm-dig", "adaptive-robust", gains=gains, **ideal)
    assert max(res.metrics["max_error_pct"].values()) < 0.1
    saturated = (np.abs(res.u) >= 0.999 * res.u_max).any(axis=1)
    assert not saturated[res.t >= 1.0].any()  # only the start, where the reference moves and the arm is at rest
    ko = make_controller(dyn, "adaptive-robust", {**gains, "Lambda": 20.0}).values["Ko"]
    kd = np.asarray(gains["Kd"]) / scale
    np.testing.assert_allclose(ko, (20.0 + kd) ** 2 / kd)
    assert make_controller(dyn, "adaptive-robust", {"Ko": 30.0}).values["Ko"].tolist() == [30.0] * dyn.model.n
    with pytest.raises(hydrogen.ScenarioError, match="Ko"):
        make_controller(dyn, "adaptive-robust", {"Kd": 0.0})


def test_stepper_reproduces_simulate(dyn):
    res = simulate(dyn, "z-1hz", "adaptive-robust", duration=0.5)
    st = hydrogen.stepper("z-1hz", "adaptive-robust", dyn=dyn, duration=0.5)
    for _ in range(100):
        st.step()
    np.testing.assert_allclose(st.q, res.q[100], atol=1e-12)
    assert st.t == pytest.approx(100 / 512)
    np.testing.assert_allclose(st.xc[6:10], res.theta_hat[100], rtol=1e-12)


def test_a_stepper_past_its_run_says_so_as_a_hydrogen_error(dyn):
    from hydrogen.errors import HydrogenError, RunEndedError
    st = hydrogen.stepper("z-1hz", "p", dyn=dyn, duration=0.02)
    for _ in range(st.n_max):
        st.step()
    with pytest.raises(RunEndedError, match=r"scenario 'z-1hz' has 11 periods; pass a longer duration") as err:
        st.step()
    assert isinstance(err.value, HydrogenError) and isinstance(err.value, IndexError)


def test_sweep_any_executor_and_errors_in_place(plain_stewart):
    from concurrent.futures import ThreadPoolExecutor
    runs = [dict(scenario="z-1hz", controller="p", gains={"Kleg": k}, duration=1.0) for k in (0.02, 0.04)]
    runs.append(dict(scenario="paper-sim", controller="backstepping", duration=1.0,
                     gains={"Ktau": 5e4, "u_max": 1.0}, control_rate=200.0, substeps=2,
                     pressure_bounds="step"))
    with ThreadPoolExecutor(2) as ex:
        out = hydrogen.sweep(runs, executor=ex, model=plain_stewart)  # the unsaturated spool: run 2 diverges
    assert out[0]["max_error_pct"]["z"] > out[1]["max_error_pct"]["z"]  # more gain, less error
    assert "error" in out[2] and "t = " in out[2]["error"]
    again = hydrogen.sweep(runs[:2], max_workers=2, model=plain_stewart)  # default: a local process pool
    assert again[0]["max_error_pct"] == out[0]["max_error_pct"]


def test_two_steppers_on_one_library_keep_their_own_gains(dyn):
    solo = hydrogen.stepper("z-1hz", "adaptive-robust", dyn=dyn, gains={"Lambda": 30.0})
    a = hydrogen.stepper("z-1hz", "adaptive-robust", dyn=dyn, gains={"Lambda": 30.0})
    b = hydrogen.stepper("z-1hz", "adaptive-robust", dyn=dyn, gains={"Lambda": 90.0})
    for _ in range(300):
        solo.step()
        a.step()
        b.step()
        simulate(dyn, "z-1hz", "p", duration=0.01)  # another user of the same library in between
    np.testing.assert_array_equal(a.q, solo.q)
    assert np.abs(b.q - solo.q).max() > 1e-6


def test_c_loop_divergence_keeps_only_finite_rows(plain_stewart_dyn):
    with pytest.raises(hydrogen.SimulationError) as err:
        simulate(plain_stewart_dyn, "paper-sim", "backstepping", duration=2.0,
                 gains={"Ktau": 5e4, "u_max": 1.0}, control_rate=200.0, substeps=2, pressure_bounds="step")
    res = err.value.result
    assert np.all(np.isfinite(res.q)) and np.all(np.isfinite(res.u))
    assert f"t = {res.t[-1] + 1 / 200.0:.4f} s" in str(err.value)


def test_loop_runner_checks_its_arrays(dyn):
    from hydrogen.simulation import simulator as S
    p = S.prepare_run(dyn, "z-1hz", "p", None, 0.1, False, {})
    runner = S.make_runner(dyn, p.sc, p.ctrl, p.x0, p.q0, p.estimate, p.h)
    small = {"q": np.zeros((10, 6))}
    assert runner.run(10, p.noise, small) == 0
    with pytest.raises(ValueError, match="log 'q'"):
        runner.run(5, None, small)  # rows 10..14 do not exist
    with pytest.raises(ValueError, match="noise"):
        runner.run(100, p.noise[:3], None)


@pytest.mark.parametrize("override,field", [({"duration": -1.0}, "duration"), ({"duration": float("nan")}, "duration"),
                                            ({"friction": (0.0, float("nan"), 1e-3)}, "friction"),
                                            ({"substeps": 0}, "substeps"), ({"bogus": 1}, "bogus")])
def test_bad_scenario_settings_are_named(dyn, override, field):
    with pytest.raises(hydrogen.ScenarioError, match=field):
        simulate(dyn, "z-1hz", "p", **override)


def test_a_run_shorter_than_one_control_period_is_refused_and_one_period_runs(dyn):
    """Nothing is sampled after the start of a run shorter than a period: no error to report (it would
    read 0 %), so it is refused, naming the period; a run of one period gives its two samples."""
    from hydrogen.simulation.scenarios import scenario

    rate = scenario("z-1hz", dyn.model).control_rate
    for short in (1e-9, 0.5 / rate):
        with pytest.raises(hydrogen.ScenarioError, match=r"duration must be at least one control period "
                                                         rf"\(1/control_rate = {1.0 / rate!r} s\)"):
            simulate(dyn, "z-1hz", "p", duration=short)
    assert len(simulate(dyn, "z-1hz", "p", duration=1.0 / rate).t) == 2


def test_a_run_too_short_for_its_information_matrix_says_so(dyn):
    """An adaptive run of one period estimates nothing yet: the note says the run is too short, not
    that it excites θ (there is no information matrix to judge by)."""
    from hydrogen.simulation.scenarios import scenario
    from hydrogen.summary import excitation_lines

    period = 1.0 / scenario("paper-sim", dyn.model).control_rate
    res = hydrogen.simulate("paper-sim", "adaptive-robust", dyn=dyn, duration=period)
    assert "theta" not in res.metrics.get("excitation", {})
    (line,) = [x for x in excitation_lines(res) if x.startswith("note: theta")]
    assert "too short to tell how well it excites theta" in line and "lambda" not in line


def test_forward_kinematics_bad_arguments(dyn, model):
    l = dyn.leg_lengths(model.neutral_pose)
    with pytest.raises(hydrogen.KinematicsError, match="not finite"):
        dyn.forward_kinematics(l, q0=np.full(6, np.nan))
    with pytest.raises(hydrogen.KinematicsError, match=r"did not converge in 0 iterations for leg lengths \[1\.\d+ .*\]: "
                       r"residual \S+ m at q = \["):
        dyn.forward_kinematics(l, q0=model.neutral_pose + 0.01, max_iter=0)
    for bad in ({"max_iter": -1}, {"max_iter": 2.5}, {"tol": "x"}, {"tol": 0.0}, {"max_cond": float("nan")}):
        with pytest.raises(hydrogen.KinematicsError, match=f"max_iter >= 0.*got .*{list(bad)[0]} = "):
            dyn.forward_kinematics(l, **bad)


def _stewart_runner(dyn, scenario_name="z-1hz", n=20):
    from hydrogen.simulation import simulator as S
    p = S.prepare_run(dyn, scenario_name, "adaptive-robust", None, n / 512, False, {"seed": 1})
    return S.make_runner(dyn, p.sc, p.ctrl, p.x0, p.q0, p.estimate, p.h), p


def test_the_c_loop_estimates_the_pose_with_dynamics_forward_kinematics(dyn):
    """The loop's estimate and Dynamics.forward_kinematics are one solver: the same pose, bit for bit,
    from the same measured lengths and warm start, period after period of a run on the rig (noise)."""
    runner, p = _stewart_runner(dyn)
    st = runner.stages()
    for k in range(20):
        q_before = np.array(runner.state.q_meas[:])
        assert st.measure(p.noise[k]) == 0 and st.estimate() == 0
        expected = dyn.forward_kinematics(np.array(st.signals.l_meas[:]), q0=q_before)
        np.testing.assert_array_equal(np.array(runner.state.q_meas[:]), expected)
        st.reference()
        assert st.control() == 0 and st.plant_step() == 0 and st.control_advance() == 0
        runner.state.k += 1
    assert np.abs(p.noise[:20, :6]).max() > 0  # the lengths were noisy: Newton had work to do


def test_a_c_loop_forward_kinematics_failure_is_worded_as_dynamics_forward_kinematics(dyn, model):
    """A failed forward kinematics stops the C loop with the words Dynamics.forward_kinematics raises for
    the same lengths and start (JL's condition number, the pose), not a generic message."""
    from hydrogen.runtime.loop import LOOP_FK_FAILED
    from hydrogen.simulation.simulator import _loop_failure
    runner, p = _stewart_runner(dyn)
    q_lock = model.neutral_pose.copy()
    q_lock[4] = np.pi / 2  # gimbal lock: JL loses rank at the warm start
    runner.state.q_meas[:] = list(q_lock)
    st = runner.stages()
    assert st.measure(None) == 0
    l_meas = np.array(st.signals.l_meas[:])
    assert st.estimate() == LOOP_FK_FAILED
    with pytest.raises(hydrogen.KinematicsError, match="JL is singular") as err:
        dyn.forward_kinematics(l_meas, q0=q_lock)
    assert _loop_failure(LOOP_FK_FAILED, runner, p.h) == f"stopped at t = 0.0000 s: {err.value}"


def test_a_singular_jl_at_the_encoders_pose_is_worded_as_the_velocity_estimate(cache):
    """With joint encoders no forward kinematics runs: JL singular at the measured pose stops the
    velocity solve, and the C loop and the Python stages say so in the same words."""
    from hydrogen.runtime.loop import LOOP_FK_FAILED
    from hydrogen.simulation import simulator as S
    arm = hydrogen.build(hydrogen.load_model("excavator_arm"), cache=cache)
    assert arm.model.joint_encoders
    q = singular_pose(arm)
    p = S.prepare_run(arm, "arm-sim", "p", None, 20 / 512, False, {"seed": 1})
    x0 = p.x0.copy()
    x0[S.slot(S.plant_layout(arm.model), "q").slice] = q
    runner = S.make_runner(arm, p.sc, p.ctrl, x0, q, p.estimate, p.h)
    st = runner.stages()
    assert st.measure(None) == 0 and st.estimate() == LOOP_FK_FAILED
    said = S._loop_failure(LOOP_FK_FAILED, runner, p.h)
    assert said.startswith("stopped at t = 0.0000 s: velocity estimate: JL is singular at the measured pose q = [")
    assert "forward kinematics" not in said
    loop = S.PythonStages(arm, p.sc, p.ctrl, x0, q, p.estimate, p.h)
    s = loop.signals(np.zeros_like(p.noise[0]))
    loop.sensors(s)
    with pytest.raises(hydrogen.KinematicsError) as err:
        loop.estimator(s)
    assert said == f"stopped at t = 0.0000 s: {err.value}"


def test_thread_sweep_equals_serial_sweep(dyn):
    from concurrent.futures import ThreadPoolExecutor
    runs = [dict(scenario="z-1hz", controller="adaptive-robust", gains={"Lambda": lam}, duration=0.5)
            for lam in (30.0, 50.0, 70.0, 90.0)]
    serial = hydrogen.sweep(runs, max_workers=1)
    with ThreadPoolExecutor(4) as ex:
        threaded = hydrogen.sweep(runs, executor=ex)
    assert [r["max_error"] for r in serial] == [r["max_error"] for r in threaded]


def test_a_batched_chunk_equals_its_runs_one_at_a_time(plain_stewart_dyn, monkeypatch):
    """The sweep's worker runs a chunk of entries through one Batch per scenario (the scenario resolved
    and checked once, a controller and loop runner per gain set): every run's metrics and series are the
    ones its run alone gives, to the bit, failures with the same message (the Stewart platform without
    its datasheet valve: its unsaturated spool lets the last run diverge)."""
    from hydrogen.simulation import simulator as S
    from hydrogen.simulation import sweep as W
    model = plain_stewart_dyn.model
    runs = [dict(scenario="z-1hz", controller=c, gains=g, seed=s, duration=0.5)
            for c, g in (("p", {"Kleg": 0.02}), ("p", {"Kleg": 0.05}), ("adaptive-robust", {"Lambda": 30.0}),
                         ("adaptive-robust", {"Lambda": 60.0})) for s in (0, 1, 2)]
    runs.insert(4, dict(scenario="z-1hz", controller="p", gains={"Kleg": 0.02}, seed=2, duration=0.5))  # gains again
    runs += [dict(scenario="z-1hz", controller="p", duration=0.5, seed=2**64),  # a bad seed
             dict(scenario="z-1hz", controller="p", duration=0.5, gains={"Kleg": -1.0}, seed=1),  # a bad gain
             dict(scenario="z-1hz", controller="p", duration=-1.0, seed=1),  # a bad scenario field: no Batch
             dict(scenario="z-1hz", controller="p", duration=0.5),  # the scenario's own seed
             dict(scenario="paper-sim", controller="backstepping", duration=1.0, seed=0,  # diverges
                  gains={"Ktau": 5e4, "u_max": 1.0}, control_rate=200.0, substeps=2, pressure_bounds="step")]
    plans = []
    real_plan = S.plan_run
    monkeypatch.setattr(S, "plan_run", lambda *a, **k: plans.append(a[1]) or real_plan(*a, **k))
    W._run_chunk((model, runs[:13] + runs[-2:], False, None, {}))  # the runs that start: a plan per scenario
    assert plans == ["z-1hz", "z-1hz", "paper-sim"]  # z-1hz for P (its own seed too), for adaptive-robust
    batched = W._run_chunk((model, runs, True, None, {}))
    alone = [W._run_one((model, r, True, None)) for r in runs]
    timings = {"wall_time_s", "loop_wall_s"}
    for r, b, a in zip(runs, batched, alone):
        assert type(b) is type(a), r
        if isinstance(a, dict):
            assert b == a and "error" in a, r
            continue
        assert {k: v for k, v in b.metrics.items() if k not in timings} == \
            {k: v for k, v in a.metrics.items() if k not in timings}, r
        for series in ("q", "u", "pressures", "leg_lengths_measured", "theta_hat", "gamma1_hat"):
            np.testing.assert_array_equal(getattr(b, series), getattr(a, series), err_msg=f"{r} {series}")
    errors = [a["error"] for a in alone if isinstance(a, dict)]
    assert "seed must be an integer" in errors[0] and "'Kleg' must be >= 0" in errors[1]
    assert "duration" in errors[2] and "t = " in errors[3] and "failed_at_s" in alone[-1]
    # seeds 0 and 1 differ (their noise), the same seed and gains twice do not
    assert batched[0].metrics["max_error"] != batched[1].metrics["max_error"]
    np.testing.assert_array_equal(batched[2].q, batched[4].q)


@pytest.mark.parametrize("duration,rows", [(3.0, 513), (3.0 - 1 / 512, 512)])  # even and odd: the last bin
def test_high_frequency_error_is_the_rms_of_the_high_passed_error(dyn, duration, rows):
    res = simulate(dyn, "z-1hz", "p", duration=duration, check_workspace=False)
    sel = res.t >= res.metric_start - 1e-12
    e = res.error[sel]
    spec = np.fft.rfft(e - e.mean(axis=0), axis=0)
    spec[np.fft.rfftfreq(len(e), res.t[1] - res.t[0]) <= res.HF_FACTOR * 1.0] = 0  # z-1hz: 1 Hz
    want = np.sqrt((np.fft.irfft(spec, n=len(e), axis=0) ** 2).mean(axis=0))
    assert len(e) == rows and want.max() > 0
    np.testing.assert_allclose(res.high_frequency_error(), want, rtol=1e-12, atol=1e-300)


def test_high_frequency_burst_is_the_worst_short_window_of_the_high_passed_error(dyn):
    """A 0.4 s burst of 30 Hz ripple: the worst window of 2 cut-off periods (0.4 s at 1 Hz) holds it
    whole, at its own RMS, where the 4 s average dilutes it ten times; a slow drift of the error
    (a step where the transform's window wraps) does not ring into the worst window."""
    res = simulate(dyn, "z-1hz", "p", duration=6.0, check_workspace=False)
    t, z, a = res.t, res.coordinates.index("z"), 1e-4
    burst = (t >= 3.3) & (t < 3.7)
    e = np.zeros_like(res.q)
    e[:, 0] = 1e-3 * (t - 2.0)  # x drifts: 4 mm from start to end of the window, no ripple
    e[burst, z] = a * np.sin(2 * np.pi * 30 * t[burst])
    res.q = res.q_d + e
    rms, at = res.high_frequency_burst()
    assert res.BURST_PERIODS / (res.HF_FACTOR * 1.0) == pytest.approx(0.4)
    assert rms[z] == pytest.approx(a / np.sqrt(2), rel=0.05) and at[z] == pytest.approx(3.3, abs=0.02)
    assert res.high_frequency_error()[z] == pytest.approx(a / np.sqrt(2) * np.sqrt(0.4 / 4.0), rel=0.05)
    assert rms[0] < 0.01 * a  # the drift's wrap: no ringing at the ends
    m = res.compute_metrics()
    assert m["hf_error_burst"]["z"] == rms[z] and m["hf_error_burst_t"]["z"] == at[z]


@pytest.mark.parametrize("projection", [True, False])
def test_the_high_pass_is_zeroing_the_low_bins_of_the_transform(dyn, monkeypatch, projection):
    """Both routes of the high-pass (the projection on the low bins, the FFT where the basis would be
    large) give what zeroing the bins at or below the cut-off of the rfft gives, with and without the
    line through the window's ends taken out first."""
    from hydrogen.simulation import simulator as S
    if not projection:
        monkeypatch.setattr(S, "_LOW_BINS_MAX", 0)
        S._low_bins.cache_clear()
    res = simulate(dyn, "z-1hz", "p", duration=6.0, check_workspace=False)
    S._low_bins.cache_clear()
    rng = np.random.default_rng(3)
    res.q = res.q_d + np.cumsum(rng.standard_normal(res.q.shape), axis=0) * 1e-5  # every frequency, a drift
    e = res.error[res.t >= res.metric_start - 1e-12]
    k, h = len(e), res.t[1] - res.t[0]
    assert k == 2049  # an odd window: the FFT's slow size
    for ends in (False, True):
        x = e - e[0] - np.outer(np.arange(k) / (k - 1), e[-1] - e[0]) if ends else e
        spec = np.fft.rfft(x - x.mean(axis=0), axis=0)
        spec[np.fft.rfftfreq(k, h) <= res.HF_FACTOR * 1.0] = 0
        want = np.fft.irfft(spec, n=k, axis=0)
        got, h_got, f_cut = res._high_passed(ends=ends)
        assert (h_got, f_cut) == (h, res.HF_FACTOR * 1.0)
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12 * np.abs(want).max())
    kept = int(np.count_nonzero(np.fft.rfftfreq(k, h) <= res.HF_FACTOR * 1.0))
    assert (S._low_bins(k, kept) is not None) == projection  # the route this case meant to take
    S._low_bins.cache_clear()  # no basis refused under the patched limit is left for later tests


def test_a_batch_grid_gives_arrays_over_gain_sets_and_seeds(dyn):
    from hydrogen.simulation.simulator import Batch
    batch = Batch(dyn, "z-1hz", "p", duration=0.5)
    out = batch.grid([{"Kleg": 0.02}, {"Kleg": -1.0}, {"Kleg": 0.05}], [0, 3])
    assert out["max_error_pct"].shape == (3, 2, dyn.model.n) and out["failed"].tolist() == [[False] * 2, [True] * 2,
                                                                                            [False] * 2]
    z = dyn.model.coordinate_names.index("z")
    assert out["max_error_pct"][2, 1, z] == simulate(dyn, "z-1hz", "p", duration=0.5, gains={"Kleg": 0.05},
                                                     seed=3).metrics["max_error_pct"]["z"]
    assert np.isnan(out["max_error_pct"][1]).all() and "'Kleg' must be >= 0" in out["metrics"][1][0]["error"]
    with pytest.raises(hydrogen.ScenarioError, match="seed is each run's"):
        Batch(dyn, "z-1hz", "p", seed=1)


def test_a_sweeps_workers_take_the_kalman_gains_its_parent_solved(dyn, monkeypatch):
    """The parent solves each scenario's filter gain once and hands it over with every chunk: a
    worker neither imports SciPy for it nor solves the Riccati equation again."""
    import scipy.linalg

    from hydrogen.estimators import kalman as S
    from hydrogen.simulation import sweep as W
    runs = [dict(scenario="z-1hz", controller="p", duration=0.2, seed=s, gains={"Kleg": 0.05}) for s in (0, 1)]
    runs.append({"bogus": 1})
    runs.append(dict(scenario="z-1hz", controller="p", duration=0.2, noise_l=1e-5))  # another filter
    filters = W._estimator_designs(dyn.model, runs)
    assert list(filters) == ["kalman"] and len(filters["kalman"]) == 2
    alone = W._run_one((dyn.model, runs[3], False, None))
    S._kalman_gain.cache_clear()
    monkeypatch.setattr(S, "_KNOWN_GAINS", {})
    monkeypatch.setattr(scipy.linalg, "solve_discrete_are", lambda *a: pytest.fail("solved again in the worker"))
    out = W._run_chunk((dyn.model, runs, False, None, filters))
    assert [("error" in m) for m in out] == [False, False, True, False]
    assert out[3]["max_error"] == alone["max_error"]
    S._kalman_gain.cache_clear()  # no gain of the handed-over table stays in the cache


def test_an_entry_that_cannot_be_pickled_fails_alone_not_its_chunk(dyn):
    """A process pool pickles a chunk after submit: the entry that cannot be pickled spoils its chunk,
    whose runs then go one by one, so it alone fails."""
    good = dict(scenario="z-step", controller="p", duration=0.05)
    runs = [dict(good, gains={"Kleg": 0.03 + 0.01 * i}) for i in range(12)]
    runs[5] = dict(good, gains={"Kleg": lambda: 0.05})  # a local function: no pickle
    out = hydrogen.sweep(runs, max_workers=2)
    assert [i for i, m in enumerate(out) if "error" in m] == [5] and "pickle" in out[5]["error"].lower()
    assert out[4]["max_error"] == hydrogen.sweep(runs[4:5], max_workers=1)[0]["max_error"]


def test_sweep_cuts_its_runs_into_chunks_per_worker():
    from hydrogen.simulation.sweep import CHUNKS_PER_WORKER, MAX_CHUNK, chunks
    parts = chunks(100, 2)
    assert [i for p in parts for i in p] == list(range(100))
    assert len(parts) >= CHUNKS_PER_WORKER * 2 and max(map(len, parts)) <= MAX_CHUNK
    assert chunks(3, 8) == [range(0, 1), range(1, 2), range(2, 3)] and chunks(0, 2) == []
    assert max(map(len, chunks(10_000, 1))) == MAX_CHUNK
    # runs in groups of 10 (a sweep's seeds): chunks of whole groups where a group fits, never larger
    assert [len(p) for p in chunks(100, 2, 10)] == [10] * 10
    assert [len(p) for p in chunks(100, 2, 7)] == [7] * 14 + [2]
    assert chunks(10, 2, 10) == chunks(10, 2) and chunks(30, 2, 10) == chunks(30, 2)  # smaller: kept as they were
    assert max(map(len, chunks(1000, 3, 10))) <= max(map(len, chunks(1000, 3)))
    assert [i for p in chunks(1000, 3, 10) for i in p] == list(range(1000))


def test_a_parameter_whose_true_value_is_zero_has_an_absolute_error_not_nan(dyn):
    from hydrogen.summary import estimate_lines

    res = hydrogen.simulate("paper-sim", "adaptive-robust", dyn=dyn, duration=0.05)
    res.theta_true = np.array(res.theta_true, float)
    res.theta_true[1] = 0.0  # as for a sideways first moment
    m = res.compute_metrics()
    assert m["theta_error_pct_final"][1] is None
    assert m["theta_error_final"][1] == pytest.approx(m["theta_hat_final"][1])
    assert all(np.isfinite(v) for i, v in enumerate(m["theta_error_pct_final"]) if i != 1)
    text = " ".join(estimate_lines(res))
    assert "nan" not in text and "inf" not in text and "true 0: error" in text


@pytest.mark.parametrize("kind", ["rig", "ideal"])
def test_the_loop_is_its_stages_composed(robot_dyn, kind):
    """One period of the C loop is its public stages called in the header's order: a program (the
    FMUs, a real-time target) that composes them gets the loop's numbers bit for bit, on the rig (noise,
    quantisation, Kalman filter, delay) and on the ideal plant (ideal rate sensor)."""
    from hydrogen.simulation import simulator as S
    from hydrogen.simulation.scenarios import scenario_names
    model = robot_dyn.model
    names = [n for n in scenario_names(model) if scenario(n, model).kalman == (kind == "rig")]
    if not names:
        pytest.skip(f"{model.name} has no {kind} scenario")
    name, n = names[0], 200
    duration = n / scenario(name, model).control_rate
    runs = [S.prepare_run(robot_dyn, name, "adaptive-robust", None, duration, False, {"seed": 3}) for _ in range(2)]
    whole, staged = (S.make_runner(robot_dyn, p.sc, p.ctrl, p.x0, p.q0, p.estimate, p.h) for p in runs)
    noise = runs[0].noise
    assert noise.shape[0] >= n
    log = {"u": np.zeros((n, model.n_cylinders))}
    assert whole.run(n, noise, log) == 0
    st, u = staged.stages(), []
    for k in range(n):
        assert st.measure(noise[k]) == 0 and st.estimate() == 0
        st.reference()
        assert st.control() == 0 and st.plant_step() == 0 and st.control_advance() == 0
        u.append(list(st.signals.u))
        staged.state.k += 1
    np.testing.assert_array_equal(np.array(u), log["u"])
    np.testing.assert_array_equal(staged.plant_state, whole.plant_state)
    np.testing.assert_array_equal(staged.xc, whole.xc)
    for field in ("q_meas", "kf", "u_hist", "u_app"):
        assert list(getattr(staged.state, field)) == list(getattr(whole.state, field)), field
    assert np.abs(noise[:n]).max() > 0 if kind == "rig" else True


def test_a_run_logs_every_declared_block_of_the_controller_state(dyn):
    from hydrogen.controllers import controller as controller_module

    res = simulate(dyn, "z-1hz", "adaptive-robust", duration=0.05)
    layout = controller_module("adaptive-robust").state_layout(dyn.model)
    assert list(res.states) == [b.name for b in layout]
    assert all(res.states[b.name].shape == (len(res.t), b.size) for b in layout)
    np.testing.assert_array_equal(res.states["theta_hat"], res.theta_hat)
    np.testing.assert_array_equal(res.states["z"][0], np.zeros(dyn.model.n))  # at rest: its declared start
    assert simulate(dyn, "z-1hz", "p", duration=0.05).states == {}


def test_a_diverged_plant_state_names_each_bad_entry_by_its_part(model):
    """The divergence message names each non-finite entry of x by its part of the plant's layout and
    what it belongs to (hydrogen.plant.plant_layout), not by a bare index."""
    import types

    from hydrogen.plant import plant_layout, slot, state_size
    from hydrogen.simulation.simulator import _describe

    layout = plant_layout(model)
    x = np.zeros(state_size(layout))
    bad = [slot(layout, "pc").start + 1, slot(layout, "spool").start]
    x[bad] = np.nan
    msg = _describe(x, 0.5, types.SimpleNamespace(model=model, slices={}))
    assert (f"the plant state is non-finite at entries {bad} (pc[{model.cylinders[1].name}.pc], "
            f"spool[{model.cylinders[0].name}])") in msg


def test_a_model_and_dynamics_of_two_robots_are_refused_not_one_ignored(dyn, model):
    """``model=`` with ``dyn=`` of another description ran on ``dyn`` silently; now a ModelError names
    the call (as export's did); the same description given both ways runs; a dyn that is not compiled
    dynamics is named."""
    for call in (lambda **kw: hydrogen.simulate("z-1hz", "p", duration=0.01, **kw),
                 lambda **kw: hydrogen.stepper("z-1hz", "p", **kw),
                 lambda **kw: hydrogen.identify({"t": [0.0, 1.0]}, **kw)):
        with pytest.raises(hydrogen.ModelError, match=r"'model' and 'dyn' describe different models "
                                                      r"\(excavator_arm and ubc_stewart"):
            call(model="excavator_arm", dyn=dyn)
        with pytest.raises(hydrogen.ModelError, match=r"dyn must be the compiled dynamics hydrogen.build\(\) "
                                                      r"returns, got str 'x'"):
            call(dyn="x")
    assert len(hydrogen.simulate("z-1hz", "p", model=model, dyn=dyn, duration=0.01).t) > 1
