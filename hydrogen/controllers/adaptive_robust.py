"""Theorem 3: adaptive controller with the robust sliding observer (40)-(46), as reconstructed in
READING-NOTES; sgn replaced by a saturation of width ``sat_width`` (m/s, rad/s).

Observer (40)-(42), (55): ż = K_o z̃ + Λ_o sat(z̃/ε) − Γ_z⁻¹ Wᵀ s + D̄⁻¹ (τ − Ḡ), C̄ = 0, with the
rough model taken from the current estimate: D̄ = D(q, θ̂), Ḡ = G(q, θ̂) (the paper's constant D̄, Ḡ
built from the wrong θ₀ at the neutral pose left a model error larger than Λ_o, so (55) failed).
Γ_z weights the observer term ½ z̃ᵀ Γ_z z̃ of V1 (the paper has Γ_z = I). Wᵀ s is a force and ż an
acceleration, so Γ_z ≈ D makes the units agree and keeps τ̇_d calm.

K_o follows the loop it observes (:func:`complete_gains`): the injection −Γ_z⁻¹ Wᵀ s drives z̃ at the
rate Λ + K_d/scale, so with K_o below that z strays from q̇ whenever s is not small (a start with the
valves saturated) and, through −W z̃ in τ_d, the observer adds the damping (Λ + K_d/scale)² / K_o × scale
to K_d's: at K_o = 30 /s and the default Λ = 60 /s that is 8 × K_d, and the loop is lost.
"""
from __future__ import annotations

import numpy as np

from .common import (ADAPTATION_SEARCH, FRICTION_BLOCKS, adaptation_gains, check_friction_start, composite_layout,
                     composite_static_inputs, estimate_layout, friction_gains, friction_layout, model_gains,
                     velocity_units)
from .spec import VELOCITY_BOUND, ControllerSpec, StateBlock

SPEC = ControllerSpec(name="adaptive-robust", doc="Theorem 3: adaptive controller, robust sliding observer.",
                      main_gain="Lambda", main_gain_symbol="Λ", grid_low=5.0,
                      # K_o first: it caps Λ (NaN: from Λ and K_d, complete_gains)
                      adaptation_search=(("Ko", "=", (float("nan"), 30.0, 100.0, 300.0, 1000.0)),
                                         *ADAPTATION_SEARCH), rank=1)
NAME, DOC = SPEC.name, SPEC.doc


def state_layout(model) -> list:
    return [StateBlock("z", model.n, "the robust sliding observer's velocity estimate (z)",
                       "its gains (Ko, Gz_inv, lambda_o) and the loop's (Lambda, Kd), or the adaptation rates "
                       "(rate_theta, rate_gamma1, rate_gamma2)", VELOCITY_BOUND, initial=lambda s: s.qdot0,
                       unit=velocity_units, entries="coordinates"),
            *estimate_layout(model), *composite_layout(model), *friction_layout(model)]


def default_gains(model, scale) -> dict:
    n = model.n
    return {**model_gains(model, scale), **adaptation_gains(model), **friction_gains(model, adaptive=True),
            "Ko": np.full(n, np.nan),                   # 1/s; NaN: from Λ and K_d (complete_gains)
            "Gz_inv": 1.0 / np.asarray(scale, float),   # Γ_z⁻¹ ≈ D⁻¹
            "lambda_o": np.zeros(4),                    # λ0..λ3 of (55): the sliding term off
            "sat_width": 1.0e-3 * np.ones(n)}           # per coordinate, its own unit (m/s or rad/s): sat(z̃/ε)


def observer_gain(Lam, Kd, scale) -> np.ndarray:
    """Default K_o (1/s, per coordinate) for Λ (1/s), K_d (N s/m or N m s/rad) and the inertia scale
    (kg or kg m²): (Λ + k_d)² / k_d with k_d = K_d / scale. The observer's error settles at
    z̃ ≈ K_o⁻¹ Γ_z⁻¹ Wᵀ s and, through −W z̃ in τ_d, adds the damping ≈ (Λ + k_d)² / K_o per unit
    inertia to k_d; this K_o makes it equal to k_d, whatever the robot's mass and the tuned Λ, K_d."""
    Lam, kd = np.broadcast_arrays(np.asarray(Lam, float), np.asarray(Kd, float) / np.asarray(scale, float))
    if not np.all(kd > 0):
        raise ValueError("the default K_o needs K_d > 0; give Ko explicitly")
    return (Lam + kd) ** 2 / kd


def complete_gains(gains: dict, scale) -> dict:
    """``gains`` with K_o filled from Λ and K_d (:func:`observer_gain`) where it is NaN (the default);
    the friction estimates' start checked against their bounds (:func:`check_friction_start`)."""
    out = check_friction_start(dict(gains))
    ko = np.array(out["Ko"], float)
    nan = np.isnan(ko)
    if nan.any():
        ko[nan] = np.broadcast_to(observer_gain(out["Lambda"], out["Kd"], scale), ko.shape)[nan]
        out["Ko"] = ko
    return out


def static_inputs(dyn, theta0, gamma0) -> dict:
    return composite_static_inputs(dyn, theta0, gamma0)


def derive(model):
    import sympy as sp

    from .composite import HydraulicComposite, RigidBodyComposite
    from ..symbolic.calculus import clip, matmul, time_derivative
    from ..symbolic.control_laws import Common, ControllerParts, diag, solve_or_inverse, state_and_rates, vector

    c = Common(model)
    n = c.n
    z, th_hat = vector("z", n), c.theta()
    g1, g2 = vector("gamma1_hat", c.m), vector("gamma2_hat", c.m)
    Ko, lam_o, eps, Gz_inv = vector("Ko", n), vector("lambda_o", 4), vector("sat_width", n), vector("Gz_inv", n)
    vecs, scal, ad_inputs = c.adaptive_inputs()
    z_dot, th_dot = vector("zdot", n), vector("thetadot", c.p)
    Lam, Kd = diag(c.Lam), diag(c.Kd)
    D_hat = c.D(th_hat)
    qr_dot = c.qd[1] - Lam * c.e
    qr_ddot = c.qd[2] - Lam * (c.qdot - c.qd[1])
    s = c.qdot - qr_dot
    ztil = c.qdot - z
    # (44) as read in the notes: holds q and z, never the measured q̇.
    tau_d = c.dynamics(th_hat, z, qr_dot, c.qd[2] - Lam * (z - c.qd[1])) - Kd * (z - qr_dot) - diag(c.Kp) * c.e
    tau_d_dot = time_derivative(tau_d, [(c.q, c.qdot), (z, z_dot), (th_hat, th_dot), *c.desired_rates(),
                                        *c.pose_rates])
    tau = c.JL.T * c.f
    qn2 = sum((x ** 2 for x in c.qdot), sp.S.Zero)
    Lam_o = lam_o[0] + lam_o[1] * qn2 + lam_o[2] * sp.sqrt(sum((x ** 2 for x in tau), sp.S.Zero)) \
        + lam_o[3] * sp.sqrt(qn2)
    W = matmul(-D_hat, Lam) + c.C(th_hat, qr_dot) - Kd
    # q̈̄ = D̄⁻¹ (τ − C̄ q̇ − Ḡ) with D̄ = D(q, θ̂), Ḡ = G(q, θ̂), C̄ = 0
    qdd_value, solve_stages = solve_or_inverse(model, c.q, th_hat, tau - c.G(th_hat), "qdd_bar")
    qdd_bar = vector("qddbar", n)
    WTs = matmul(W.T, s)
    z_dot_value = sp.Matrix([Ko[i] * ztil[i] + Lam_o * clip(ztil[i] / eps[i], -1, 1) - Gz_inv[i] * WTs[i]
                             + qdd_bar[i] for i in range(n)])
    # (45): θ̂̇ = −κ Γ_θ⁻¹ Yᵀ(q, q̇, q̇_r, q̈_r) s
    rho = matmul(-diag(vecs["Gtheta_inv"]), c.Y(c.qdot, qr_dot, qr_ddot, th_hat).T, s)
    rc = RigidBodyComposite(c, th_hat)  # composite θ law; rate_ls_theta = 0 gives the paper's law
    th_dot_value = c.theta_rate(rc.combine(rho), th_hat, vecs, scal["adapt"])
    # friction compensation (off by default): the estimates F̂_c, b̂ at the reference velocity
    fr_hat = vector("coulomb_hat", c.m), vector("viscous_hat", c.m)
    friction, fr_rates, fr_inputs = c.friction_compensation(qr_dot, qr_ddot, s, fr_hat, scal["adapt"])
    fd, ftil, f0, v, u, taud, stages = c.force_loop(tau_d, tau_d_dot, s, g1, g2, friction)
    hc = HydraulicComposite(c, g1, g2)  # composite γ law; rate_ls_gamma = 0 gives the paper's law
    hc_rates = hc.rates(scal["adapt"])
    g1_dot, g2_dot = c.hydraulic_adaptation(
        ftil, f0, u, g1, g2, scal["adapt"], vecs["Ggamma1_inv"], vecs["Ggamma2_inv"],
        scal["gamma1_min"], scal["gamma1_max"], scal["gamma2_min"], scal["gamma2_max"], combine=hc.combine)
    parts = [
        ("z", z, z_dot), ("theta_hat", th_hat, th_dot), ("gamma1_hat", g1, g1_dot), ("gamma2_hat", g2, g2_dot),
        (hc.BLOCKS, hc.states(), hc_rates), (rc.BLOCKS, rc.states(), rc.rates(scal["adapt"]))]
    if fr_rates is not None:  # generated with friction compensation: its estimates last
        parts.append((FRICTION_BLOCKS, [*fr_hat[0], *fr_hat[1]], fr_rates))
    xc, xc_dot = state_and_rates(state_layout(model), parts)
    return ControllerParts(
        inputs=[*c.base_inputs(), ("xc", xc), *c.gain_inputs(), ("Ko", Ko), ("lambda_o", lam_o),
                ("Gz_inv", Gz_inv), ("sat_width", eps), *ad_inputs, *hc.inputs(), *rc.inputs(), *fr_inputs],
        intermediates=[*c.kin, c.jit_intermediate(), *solve_stages, (qdd_bar, sp.Matrix(qdd_value)),
                       (z_dot, z_dot_value), *rc.stages, (th_dot, th_dot_value), *stages, *hc.stages],
        outputs=[("u", u), ("xc_dot", xc_dot), ("tau_d", taud), ("tau_d_dot", c.taud_dot), ("f_d", fd)],
    )
