"""Sliding-mode control with a bounded disturbance estimate, in the paper's cascade: a rigid-body outer
loop on the sliding surface s = q̇ − q̇_d + Λ (q − q_d) giving the desired generalised force

    τ_d = Y(q, q̇, q̇_r, q̈_r) θ − K_p e − K_d s − k_s sat(s / φ) − d̂,

then the hydraulic force loop of Theorem 1 (τ̇_d, the force error feedback and the valve inverse)
with the known θ and γ. d̂ estimates a disturbance d (N or N m per coordinate) entering
D q̈ + C q̇ + G = τ + d: with τ = τ_d, D ṡ + C s = −K_d s − … − (d̂ − d), and V = ½ sᵀ D s
+ ½ (d̂ − d)ᵀ Γ_d⁻¹ (d̂ − d) gives d̂̇ = Γ_d s (per coordinate), which cancels a constant d.
The estimate is projected onto |d̂| ≤ d_max (the rate stops at the bound, the loop clips to it).
sat(s/φ) is the boundary-layer saturation of the switching term (φ = ``sat_width``).
"""
from __future__ import annotations

import numpy as np

from .backstepping import static_inputs  # the known θ and γ, as Theorem 1 takes them
from .common import model_gains
from .spec import ControllerSpec, StateBlock

SPEC = ControllerSpec(name="sliding-mode", doc="Sliding mode with a bounded disturbance estimate (known parameters).",
                      main_gain="Lambda", main_gain_symbol="Λ", grid_low=5.0, knows_true_parameters=True)
NAME, DOC = SPEC.name, SPEC.doc

__all__ = ["SPEC", "NAME", "DOC", "state_layout", "default_gains", "static_inputs", "derive"]


def _force_units(model) -> list:
    """N for a translational coordinate (m), N.m for a rotational one (rad)."""
    return ["N" if u == "m" else "N.m" for u in model.coordinate_units]


def state_layout(model) -> list:
    return [StateBlock("d_hat", model.n, "the sliding-mode disturbance estimate (d_hat)",
                       "its rate Gamma_d, or its bound d_max", initial=0.0,
                       limits=(lambda m, g: -np.asarray(g["d_max"], float), "d_max"),
                       unit=_force_units, entries="coordinates")]


def default_gains(model, scale) -> dict:
    """Theorem 1's gains, and per coordinate (scaled by the inertia ``scale`` like K_d): Γ_d (N/s per
    m/s, or N m/s per rad/s) the estimate's rate, k_s (N or N m) the switching gain, φ = ``sat_width``
    (m/s or rad/s) its boundary layer, d_max (N or N m) the estimate's bound."""
    scale = np.asarray(scale, float)
    return {**model_gains(model, scale), "Gamma_d": 100.0 * scale, "k_s": 1.0 * scale,
            "sat_width": 0.05 * np.ones(model.n), "d_max": 5.0 * scale}


def derive(model):
    import sympy as sp

    from ..symbolic.calculus import clip, projection, time_derivative
    from ..symbolic.control_laws import Common, ControllerParts, diag, solve_or_inverse, state_and_rates, vector

    c = Common(model)
    n = c.n
    th = c.theta("theta")
    g1, g2 = vector("gamma1", c.m), vector("gamma2", c.m)
    d_hat, d_dot, acc = vector("d_hat", n), vector("d_hat_dot", n), vector("acc", n)
    Gd, ks, phi, d_max = vector("Gamma_d", n), vector("k_s", n), vector("sat_width", n), vector("d_max", n)
    Lam = diag(c.Lam)
    qr_dot = c.qd[1] - Lam * c.e
    qr_ddot = c.qd[2] - Lam * (c.qdot - c.qd[1])
    s = c.qdot - qr_dot
    # the smooth part of τ_d, differentiated exactly; the saturation's rate below, 0 outside its layer
    smooth = c.dynamics(th, c.qdot, qr_dot, qr_ddot) - diag(c.Kp) * c.e - diag(c.Kd) * s - d_hat
    tau_d = smooth - sp.Matrix([ks[i] * clip(s[i] / phi[i], -1, 1) for i in range(n)])
    s_dot = acc - (c.qd[2] - Lam * (c.qdot - c.qd[1]))
    inside = [sp.And(sp.StrictLessThan(-phi[i], s[i]), sp.StrictLessThan(s[i], phi[i]), evaluate=False)
              for i in range(n)]
    sat_dot = sp.Matrix([sp.Piecewise((ks[i] * s_dot[i] / phi[i], inside[i]), (sp.S.Zero, True), evaluate=False)
                         for i in range(n)])
    tau_d_dot = time_derivative(smooth, [(c.q, c.qdot), (c.qdot, acc), (d_hat, d_dot), *c.desired_rates(),
                                         *c.pose_rates]) - sat_dot
    # q̈ of the model with the estimated disturbance: D⁻¹ (τ + d̂ − C q̇ − G)
    acc_value, acc_stages = solve_or_inverse(model, c.q, th, c.JL.T * c.f + d_hat - c.dynamics(th, c.qdot, c.qdot),
                                             "acc_solve")
    d_dot_value = sp.Matrix([projection(d_hat[i], Gd[i] * s[i], -d_max[i], d_max[i]) for i in range(n)])
    fd, _, _, _, u, taud, stages = c.force_loop(tau_d, tau_d_dot, s, g1, g2)
    xc, xc_dot = state_and_rates(state_layout(model), [("d_hat", d_hat, d_dot)])
    return ControllerParts(
        inputs=[*c.base_inputs(), ("xc", xc), ("theta", th), ("gamma1", g1), ("gamma2", g2), *c.gain_inputs(),
                ("Gamma_d", Gd), ("k_s", ks), ("sat_width", phi), ("d_max", d_max)],
        intermediates=[*c.kin, c.jit_intermediate(), (d_dot, d_dot_value), *acc_stages, (acc, sp.Matrix(acc_value)),
                       *stages],
        outputs=[("u", u), ("xc_dot", xc_dot), ("tau_d", taud), ("tau_d_dot", c.taud_dot), ("f_d", fd)],
    )
