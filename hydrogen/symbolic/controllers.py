"""The paper's controllers for the Stewart platform (SymPy), in leg-force form.

Task-space design, leg-space actuation (READING-NOTES "Leg forces and task
space"): τ_d (task space) maps to leg forces f_d = (JL)⁻ᵀ τ_d, with
ḟ_d = (JL)⁻ᵀ (τ̇_d − d/dt[(JL)ᵀ] f_d), and the backstepping term reads
Γ_τ⁻¹ (JL) s. The spool position u solves g0(u) γ̂2 = v per leg, with

    v = ḟ_d − f0 γ̂1 − Γ_τ⁻¹ JL s − K_τ f̃,   f̃ = f − f_d,

so the leg-force error obeys ḟ̃ = −Γ_τ⁻¹ JL s − K_τ f̃ (+ parameter-error terms).
(JL)⁻ᵀ is an intermediate computed numerically (CasADi linear solve); every
other quantity, including τ̇_d, is derived here in closed form.

Controller state xc:
* ``adaptive-robust`` (Theorem 3): [z (6), θ̂ (4), γ̂1 (6), γ̂2 (6)]
* ``adaptive-observer`` (Theorem 2): [q̂ (6), z (6), θ̂ (4), γ̂1 (6), γ̂2 (6)]
* ``backstepping`` (Theorem 1): none (parameters known, q̈ from (14)).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp

from . import hydraulics as hyd
from .calculus import clip, projection, time_derivative
from .constants import PRESSURE_EPS, baked
from .layout import STATE_LAYOUT
from .kinematics import leg_intermediates, leg_stages, matrix_symbols, pose_symbols, rate_symbols
from .rigid_body import coriolis, gravity, mass_matrix, mass_matrix_inverse, regressor, theta_symbols

__all__ = ["ControllerParts", "backstepping", "adaptive_robust", "adaptive_observer", "p_controller",
           "STATE_LAYOUT"]



@dataclass
class ControllerParts:
    """Inputs, intermediates (symbols defined numerically, in order) and outputs of a controller."""

    inputs: list
    outputs: list
    intermediates: list = field(default_factory=list)


def _diag(v):
    return sp.diag(*list(v))


def _sym(name, n=6):
    return rate_symbols(name, n)


def _scalar(name):
    return sp.Symbol(name, real=True)


class _Common:
    """Symbols and expressions shared by the model-based controllers."""

    def __init__(self, model, B, P):
        self.ps, self.d, self.A, self.a, self.L = (baked(v) for v in (
            model.supply_pressure, model.underlap, model.piston_area, model.rod_area, model.chamber_length))
        self.g = baked(model.gravity)
        self.q, self.qdot, self.pc = pose_symbols(), _sym("qdot"), _sym("pc")
        self.qd = [_sym(f"qd{k}") for k in range(4)]  # q_d and its first three derivatives
        self.Lam, self.Kp, self.Kd = _sym("Lambda"), _sym("Kp"), _sym("Kd")
        self.Ktau, self.Gtau_inv = _sym("Ktau"), _sym("Gtau_inv")
        self.u_max = _scalar("u_max")
        self.l, self.JL, self.JLdot, self.kin = leg_intermediates(self.q, self.qdot, B, P)
        self.ldot = self.JL * self.qdot
        self.f = sp.Matrix([hyd.leg_force(self.pc[i], self.ps, self.A, self.a) for i in range(6)])
        self.Jit = matrix_symbols("JLinvT", 6, 6)
        self.e = self.q - self.qd[0]

    def desired_rates(self):
        return [(self.qd[k], self.qd[k + 1]) for k in range(3)]

    def force_loop(self, tau_d, tau_d_dot, s, g1, g2):
        """Stages of the leg-force loop as intermediates; returns (f_d, f̃, f0, v, u, stages).

        Each stage is bound to symbols so later stages (and τ̇_d's users) refer to
        a symbol, not to a copy of a large expression.
        """
        S = {n: _sym(n) for n in ("taud", "taud_dot", "fd", "fd_dot", "v", "u_raw")}
        stages = [
            (S["taud"], tau_d),
            (S["taud_dot"], tau_d_dot),
            (S["fd"], self.Jit * S["taud"]),
            (S["fd_dot"], self.Jit * (S["taud_dot"] - self.JLdot.T * S["fd"])),
        ]
        ftil = self.f - S["fd"]
        f0 = sp.Matrix([hyd.f0(self.l[i], self.ldot[i], self.A, self.L) for i in range(6)])
        Js = self.JL * s
        stages.append((S["v"], sp.Matrix([S["fd_dot"][i] - f0[i] * g1[i] - self.Gtau_inv[i] * Js[i]
                                          - self.Ktau[i] * ftil[i] for i in range(6)])))
        # g0 γ̂2 = v  ⇔  q_l / c = v (l − L) / γ̂2, then invert (57) for u.
        w = [S["v"][i] * (self.l[i] - self.L) / g2[i] for i in range(6)]
        stages.append((S["u_raw"], sp.Matrix([hyd.valve_inverse_unit(w[i], self.pc[i], self.ps, self.d,
                                                                     PRESSURE_EPS) for i in range(6)])))
        u = sp.Matrix([clip(S["u_raw"][i], -self.u_max, self.u_max) for i in range(6)])
        self.taud_dot = S["taud_dot"]
        return S["fd"], ftil, f0, S["v"], u, S["taud"], stages

    def jit_intermediate(self):
        return (self.Jit, ("inverse", self.JL.T))

    def hydraulic_adaptation(self, ftil, f0, v, g1, g2, adapt, Gg1_inv, Gg2_inv, g1_lo, g1_hi, g2_lo, g2_hi):
        """γ̂̇1 = κ Γ_γ1⁻¹ Γ_τ f0 f̃,  γ̂̇2 = κ Γ_γ2⁻¹ Γ_τ Π(f̃/γ̂2) v (per leg, with projection)."""
        g1_dot = sp.Matrix([adapt * projection(g1[i], Gg1_inv[i] / self.Gtau_inv[i] * f0[i] * ftil[i],
                                               g1_lo, g1_hi) for i in range(6)])
        g2_dot = sp.Matrix([adapt * projection(g2[i], Gg2_inv[i] / self.Gtau_inv[i] * ftil[i] / g2[i] * v[i],
                                               g2_lo, g2_hi) for i in range(6)])
        return g1_dot, g2_dot

    def base_inputs(self):
        return [("q", self.q), ("qdot", self.qdot), ("pc", self.pc),
                *[(f"qd{k}", self.qd[k]) for k in range(4)]]

    def gain_inputs(self):
        return [("Lambda", self.Lam), ("Kp", self.Kp), ("Kd", self.Kd), ("Ktau", self.Ktau),
                ("Gtau_inv", self.Gtau_inv), ("u_max", sp.Matrix([self.u_max]))]


def backstepping(model, B, P) -> ControllerParts:
    """Theorem 1: known θ and γ, q̈ from (14) with the measured leg forces."""
    c = _Common(model, B, P)
    th, gam = theta_symbols(), sp.Matrix(sp.symbols("gamma_1 gamma_2", real=True))
    acc = _sym("acc")
    Lam = _diag(c.Lam)
    D = mass_matrix(c.q, th)
    qr_dot = c.qd[1] - Lam * c.e
    qr_ddot = c.qd[2] - Lam * (c.qdot - c.qd[1])
    s = c.qdot - qr_dot
    tau_d = D * qr_ddot + coriolis(D, c.q, c.qdot) * qr_dot + gravity(th, c.g) \
        - _diag(c.Kp) * c.e - _diag(c.Kd) * s
    tau_d_dot = time_derivative(tau_d, [(c.q, c.qdot), (c.qdot, acc), *c.desired_rates()])
    acc_value = mass_matrix_inverse(c.q, th) * (
        c.JL.T * c.f - coriolis(D, c.q, c.qdot) * c.qdot - gravity(th, c.g))
    g1 = sp.Matrix([gam[0]] * 6)
    g2 = sp.Matrix([gam[1]] * 6)
    fd, _, _, _, u, taud, stages = c.force_loop(tau_d, tau_d_dot, s, g1, g2)
    return ControllerParts(
        inputs=[*c.base_inputs(), ("theta", th), ("gamma", gam), *c.gain_inputs()],
        intermediates=[*c.kin, c.jit_intermediate(), (acc, acc_value), *stages],
        outputs=[("u", u), ("tau_d", taud), ("tau_d_dot", c.taud_dot), ("f_d", fd)],
    )


def _adaptive_inputs(c):
    names = ("Gtheta_inv", 4), ("Ggamma1_inv", 6), ("Ggamma2_inv", 6), ("theta_min", 4), ("theta_max", 4)
    vecs = {n: _sym(n, k) for n, k in names}
    scal = {n: _scalar(n) for n in ("gamma1_min", "gamma1_max", "gamma2_min", "gamma2_max", "adapt")}
    inputs = [(n, vecs[n]) for n, _ in names] + [(n, sp.Matrix([scal[n]])) for n in scal]
    return vecs, scal, inputs


def adaptive_robust(model, B, P) -> ControllerParts:
    """Theorem 3: adaptive controller with the robust sliding observer (40)-(46), as reconstructed
    in READING-NOTES; sgn replaced by a saturation of width ``sat_width`` (m/s, rad/s)."""
    c = _Common(model, B, P)
    z, th_hat = _sym("z"), _sym("theta_hat", 4)
    g1, g2 = _sym("gamma1_hat"), _sym("gamma2_hat")
    Ko, lam_o, eps, Gz_inv = _sym("Ko"), _sym("lambda_o", 4), _scalar("sat_width"), _sym("Gz_inv")
    Dbar_inv = matrix_symbols("Dbar_inv", 6, 6)
    Gbar = _sym("Gbar")
    vecs, scal, ad_inputs = _adaptive_inputs(c)
    z_dot, th_dot = _sym("zdot"), _sym("thetadot", 4)
    Lam, Kd = _diag(c.Lam), _diag(c.Kd)
    D_hat = mass_matrix(c.q, th_hat)
    qr_dot = c.qd[1] - Lam * c.e
    qr_ddot = c.qd[2] - Lam * (c.qdot - c.qd[1])
    s = c.qdot - qr_dot
    ztil = c.qdot - z
    # (44) as read in the notes: holds q and z, never the measured q̇.
    tau_d = D_hat * (c.qd[2] - Lam * (z - c.qd[1])) + coriolis(D_hat, c.q, z) * qr_dot \
        + gravity(th_hat, c.g) - Kd * (z - qr_dot) - _diag(c.Kp) * c.e
    tau_d_dot = time_derivative(tau_d, [(c.q, c.qdot), (z, z_dot), (th_hat, th_dot), *c.desired_rates()])
    # Observer (40)-(42), (55): ż = K_o z̃ + Λ_o sat(z̃/ε) − Γ_z⁻¹ Wᵀ s + D̄⁻¹ (τ − Ḡ), C̄ = 0.
    # Γ_z weights the observer term ½ z̃ᵀ Γ_z z̃ of V1 (the paper has Γ_z = I). Wᵀ s is a
    # force and ż an acceleration, so Γ_z ≈ D makes the units agree and keeps τ̇_d calm.
    tau = c.JL.T * c.f
    qn2 = sum((x ** 2 for x in c.qdot), sp.S.Zero)
    Lam_o = lam_o[0] + lam_o[1] * qn2 + lam_o[2] * sp.sqrt(sum((x ** 2 for x in tau), sp.S.Zero)) \
        + lam_o[3] * sp.sqrt(qn2)
    W = -D_hat * Lam + coriolis(D_hat, c.q, qr_dot) - Kd
    qdd_bar = Dbar_inv * (tau - Gbar)
    WTs = W.T * s
    z_dot_value = sp.Matrix([Ko[i] * ztil[i] + Lam_o * clip(ztil[i] / eps, -1, 1) - Gz_inv[i] * WTs[i]
                             + qdd_bar[i] for i in range(6)])
    # (45): θ̂̇ = −κ Γ_θ⁻¹ Yᵀ(q, q̇, q̇_r, q̈_r) s
    Y = regressor(c.q, c.qdot, qr_dot, qr_ddot, th_hat, c.g)
    rho = -_diag(vecs["Gtheta_inv"]) * Y.T * s
    th_dot_value = sp.Matrix([scal["adapt"] * projection(th_hat[k], rho[k], vecs["theta_min"][k],
                                                         vecs["theta_max"][k]) for k in range(4)])
    fd, ftil, f0, v, u, taud, stages = c.force_loop(tau_d, tau_d_dot, s, g1, g2)
    g1_dot, g2_dot = c.hydraulic_adaptation(
        ftil, f0, v, g1, g2, scal["adapt"], vecs["Ggamma1_inv"], vecs["Ggamma2_inv"],
        scal["gamma1_min"], scal["gamma1_max"], scal["gamma2_min"], scal["gamma2_max"])
    xc = sp.Matrix([*z, *th_hat, *g1, *g2])
    xc_dot = sp.Matrix([*z_dot, *th_dot, *g1_dot, *g2_dot])
    return ControllerParts(
        inputs=[*c.base_inputs(), ("xc", xc), *c.gain_inputs(), ("Ko", Ko), ("lambda_o", lam_o), ("Gz_inv", Gz_inv),
                ("sat_width", sp.Matrix([eps])), ("Dbar_inv", Dbar_inv), ("Gbar", Gbar), *ad_inputs],
        intermediates=[*c.kin, c.jit_intermediate(), (z_dot, z_dot_value), (th_dot, th_dot_value), *stages],
        outputs=[("u", u), ("xc_dot", xc_dot), ("tau_d", taud), ("tau_d_dot", c.taud_dot), ("f_d", fd)],
    )


def adaptive_observer(model, B, P) -> ControllerParts:
    """Theorem 2: adaptive controller with the adaptive passivity-based observer (19)-(25)."""
    c = _Common(model, B, P)
    q_hat, z, th_hat = _sym("q_hat"), _sym("z"), _sym("theta_hat", 4)
    g1, g2 = _sym("gamma1_hat"), _sym("gamma2_hat")
    Lam2, Lp, Kd2 = _sym("Lambda2"), _sym("Lp"), _sym("Kd_obs")
    vecs, scal, ad_inputs = _adaptive_inputs(c)
    z_dot, th_dot = _sym("zdot"), _sym("thetadot", 4)
    Lam1, Kd = _diag(c.Lam), _diag(c.Kd)
    D_hat = mass_matrix(c.q, th_hat)
    qtil = c.q - q_hat
    q_hat_dot = z + _diag(Lam2) * qtil
    qr_dot = c.qd[1] - Lam1 * (q_hat - c.qd[0])
    qr_ddot = c.qd[2] - Lam1 * (q_hat_dot - c.qd[1])
    s1 = c.qdot - qr_dot
    s2 = c.qdot - z  # q̇_o = q̂̇ − Λ2 q̃ = z
    # (22): holds q, q̂, z and the reference; τ̇_d needs ż, never q̈.
    tau_d = D_hat * qr_ddot + coriolis(D_hat, c.q, qr_dot) * qr_dot + gravity(th_hat, c.g) \
        - Kd * (z - qr_dot) - _diag(c.Kp) * c.e
    tau_d_dot = time_derivative(tau_d, [(c.q, c.qdot), (q_hat, q_hat_dot), (z, z_dot), (th_hat, th_dot),
                                        *c.desired_rates()])
    tau = c.JL.T * c.f
    z_dot_value = mass_matrix_inverse(c.q, th_hat) * (
        tau - coriolis(D_hat, c.q, c.qdot) * z - gravity(th_hat, c.g) + _diag(Lp) * qtil
        + Kd * s1 + _diag(Kd2) * s2)
    Y1 = regressor(c.q, qr_dot, qr_dot, qr_ddot, th_hat, c.g)
    Y2 = regressor(c.q, c.qdot, z, z_dot, th_hat, c.g)
    rho = -_diag(vecs["Gtheta_inv"]) * (Y1.T * s1 + Y2.T * s2)
    th_dot_value = sp.Matrix([scal["adapt"] * projection(th_hat[k], rho[k], vecs["theta_min"][k],
                                                         vecs["theta_max"][k]) for k in range(4)])
    fd, ftil, f0, v, u, taud, stages = c.force_loop(tau_d, tau_d_dot, s1, g1, g2)
    g1_dot, g2_dot = c.hydraulic_adaptation(
        ftil, f0, v, g1, g2, scal["adapt"], vecs["Ggamma1_inv"], vecs["Ggamma2_inv"],
        scal["gamma1_min"], scal["gamma1_max"], scal["gamma2_min"], scal["gamma2_max"])
    xc = sp.Matrix([*q_hat, *z, *th_hat, *g1, *g2])
    xc_dot = sp.Matrix([*q_hat_dot, *z_dot, *th_dot, *g1_dot, *g2_dot])
    return ControllerParts(
        inputs=[*c.base_inputs(), ("xc", xc), *c.gain_inputs(), ("Lambda2", Lam2), ("Lp", Lp),
                ("Kd_obs", Kd2), *ad_inputs],
        intermediates=[*c.kin, c.jit_intermediate(), (z_dot, z_dot_value), (th_dot, th_dot_value), *stages],
        outputs=[("u", u), ("xc_dot", xc_dot), ("tau_d", taud), ("tau_d_dot", c.taud_dot), ("f_d", fd)],
    )


def p_controller(model, B, P) -> ControllerParts:
    """The paper's baseline: u = K (l_d − l) per leg, l_d = l(q_d), saturated at ±u_max."""
    l_meas, qd0, k, u_max = _sym("l"), _sym("qd0"), _sym("Kleg"), _scalar("u_max")
    _, ld, _, stages = leg_stages(qd0, B, P)
    u = sp.Matrix([clip(k[i] * (ld[i] - l_meas[i]), -u_max, u_max) for i in range(6)])
    return ControllerParts(inputs=[("l", l_meas), ("qd0", qd0), ("Kleg", k), ("u_max", sp.Matrix([u_max]))],
                           outputs=[("u", u)], intermediates=stages[:2])
