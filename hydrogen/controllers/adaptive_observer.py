"""Theorem 2: adaptive controller with the adaptive passivity-based observer (19)-(25)."""
from __future__ import annotations

import numpy as np

from .common import (ADAPTATION_SEARCH, FRICTION_BLOCKS, adaptation_gains, check_friction_start, composite_layout,
                     composite_static_inputs, estimate_layout, friction_gains, friction_layout, model_gains,
                     velocity_units)
from .spec import POSITION_BOUND, VELOCITY_BOUND, ControllerSpec, StateBlock

SPEC = ControllerSpec(name="adaptive-observer", doc="Theorem 2: adaptive controller, adaptive observer.",
                      main_gain="Lambda", main_gain_symbol="Λ", grid_low=5.0, adaptation_search=ADAPTATION_SEARCH, rank=2)
NAME, DOC = SPEC.name, SPEC.doc


def state_layout(model) -> list:
    n = model.n
    lower = ("its gains (Lambda2, Lp, Kd_obs) and the loop's (Lambda, Kd), or the adaptation rates "
             "(rate_theta, rate_gamma1, rate_gamma2)")
    return [StateBlock("q_hat", n, "the adaptive observer's position estimate (q_hat)", lower, POSITION_BOUND,
                       initial=lambda s: s.q0, unit=lambda m: list(m.coordinate_units), entries="coordinates"),
            StateBlock("z", n, "the adaptive observer's velocity estimate (z / q_hat_dot)", lower, VELOCITY_BOUND,
                       initial=lambda s: s.qdot0, unit=velocity_units, entries="coordinates"),
            *estimate_layout(model), *composite_layout(model), *friction_layout(model)]


def default_gains(model, scale) -> dict:
    scale = np.asarray(scale, float)
    return {**model_gains(model, scale), **adaptation_gains(model), **friction_gains(model, adaptive=True),
            "Lambda2": 60.0 * np.ones(model.n), "Lp": 3000.0 * scale, "Kd_obs": 60.0 * scale}


def complete_gains(gains: dict, scale) -> dict:
    """``gains`` with the friction estimates' start checked against their bounds."""
    return check_friction_start(dict(gains))


def static_inputs(dyn, theta0, gamma0) -> dict:
    return composite_static_inputs(dyn, theta0, gamma0)


def derive(model):
    import sympy as sp

    from .composite import HydraulicComposite, RigidBodyComposite
    from ..symbolic.calculus import matmul, time_derivative
    from ..symbolic.control_laws import Common, ControllerParts, diag, solve_or_inverse, state_and_rates, vector

    c = Common(model)
    n = c.n
    q_hat, z, th_hat = vector("q_hat", n), vector("z", n), c.theta()
    g1, g2 = vector("gamma1_hat", c.m), vector("gamma2_hat", c.m)
    Lam2, Lp, Kd2 = vector("Lambda2", n), vector("Lp", n), vector("Kd_obs", n)
    vecs, scal, ad_inputs = c.adaptive_inputs()
    z_dot, th_dot = vector("zdot", n), vector("thetadot", c.p)
    Lam1, Kd = diag(c.Lam), diag(c.Kd)
    qtil = c.q - q_hat
    q_hat_dot = z + diag(Lam2) * qtil
    qr_dot = c.qd[1] - Lam1 * (q_hat - c.qd[0])
    qr_ddot = c.qd[2] - Lam1 * (q_hat_dot - c.qd[1])
    s1 = c.qdot - qr_dot
    s2 = c.qdot - z  # q̇_o = q̂̇ − Λ2 q̃ = z
    # (22): holds q, q̂, z and the reference; τ̇_d needs ż, never q̈.
    tau_d = c.dynamics(th_hat, qr_dot, qr_dot, qr_ddot) - Kd * (z - qr_dot) - diag(c.Kp) * c.e
    tau_d_dot = time_derivative(tau_d, [(c.q, c.qdot), (q_hat, q_hat_dot), (z, z_dot), (th_hat, th_dot),
                                        *c.desired_rates(), *c.pose_rates])
    tau = c.JL.T * c.f
    rhs = tau - c.dynamics(th_hat, c.qdot, z) + diag(Lp) * qtil + Kd * s1 + diag(Kd2) * s2
    z_dot_value, solve_stages = solve_or_inverse(model, c.q, th_hat, rhs, "zdot_solve")
    Y1 = c.Y(qr_dot, qr_dot, qr_ddot, th_hat)
    Y2 = c.Y(c.qdot, z, z_dot, th_hat)
    rho = matmul(-diag(vecs["Gtheta_inv"]), matmul(Y1.T, s1) + matmul(Y2.T, s2))
    rc = RigidBodyComposite(c, th_hat)  # composite θ law; rate_ls_theta = 0 gives the paper's law
    th_dot_value = c.theta_rate(rc.combine(rho), th_hat, vecs, scal["adapt"])
    # friction compensation (off by default): the estimates F̂_c, b̂ at the reference velocity
    fr_hat = vector("coulomb_hat", c.m), vector("viscous_hat", c.m)
    friction, fr_rates, fr_inputs = c.friction_compensation(qr_dot, qr_ddot, s1, fr_hat, scal["adapt"])
    fd, ftil, f0, v, u, taud, stages = c.force_loop(tau_d, tau_d_dot, s1, g1, g2, friction)
    hc = HydraulicComposite(c, g1, g2)  # composite γ law; rate_ls_gamma = 0 gives the paper's law
    hc_rates = hc.rates(scal["adapt"])
    g1_dot, g2_dot = c.hydraulic_adaptation(
        ftil, f0, u, g1, g2, scal["adapt"], vecs["Ggamma1_inv"], vecs["Ggamma2_inv"],
        scal["gamma1_min"], scal["gamma1_max"], scal["gamma2_min"], scal["gamma2_max"], combine=hc.combine)
    parts = [
        ("q_hat", q_hat, q_hat_dot), ("z", z, z_dot), ("theta_hat", th_hat, th_dot), ("gamma1_hat", g1, g1_dot),
        ("gamma2_hat", g2, g2_dot), (hc.BLOCKS, hc.states(), hc_rates), (rc.BLOCKS, rc.states(), rc.rates(scal["adapt"]))]
    if fr_rates is not None:  # generated with friction compensation: its estimates last
        parts.append((FRICTION_BLOCKS, [*fr_hat[0], *fr_hat[1]], fr_rates))
    xc, xc_dot = state_and_rates(state_layout(model), parts)
    return ControllerParts(
        inputs=[*c.base_inputs(), ("xc", xc), *c.gain_inputs(), ("Lambda2", Lam2), ("Lp", Lp),
                ("Kd_obs", Kd2), *ad_inputs, *hc.inputs(), *rc.inputs(), *fr_inputs],
        intermediates=[*c.kin, c.jit_intermediate(), *solve_stages, (z_dot, sp.Matrix(z_dot_value)),
                       *rc.stages, (th_dot, th_dot_value), *stages, *hc.stages],
        outputs=[("u", u), ("xc_dot", xc_dot), ("tau_d", taud), ("tau_d_dot", c.taud_dot), ("f_d", fd)],
    )
