"""Theorem 1: backstepping with known parameters θ and γ; q̈ from (14) with the measured forces.

Optionally (a deviation, off by default) with a known friction compensation in f_d
(:meth:`hydrogen.symbolic.control_laws.Common.friction_compensation`, gains ``friction_*``)."""
from __future__ import annotations

import numpy as np

from .common import friction_gains, model_gains
from .spec import ControllerSpec

SPEC = ControllerSpec(name="backstepping", doc="Theorem 1 (known parameters): spool command u, m.",
                      main_gain="Lambda", main_gain_symbol="Λ", grid_low=5.0, knows_true_parameters=True, rank=0)
NAME, DOC = SPEC.name, SPEC.doc


def state_layout(model) -> list:
    return []


def default_gains(model, scale) -> dict:
    return {**model_gains(model, scale), **friction_gains(model, adaptive=False)}


def static_inputs(dyn, theta0, gamma0) -> dict:
    """The known parameters: θ (p) and γ (2, m) as γ1, γ2."""
    gamma0 = np.asarray(gamma0, float)
    return {"theta": np.asarray(theta0, float), "gamma1": gamma0[0], "gamma2": gamma0[1]}


def derive(model):
    import sympy as sp

    from ..symbolic.calculus import time_derivative
    from ..symbolic.control_laws import Common, ControllerParts, diag, solve_or_inverse, vector

    c = Common(model)
    th = c.theta("theta")
    g1, g2 = vector("gamma1", c.m), vector("gamma2", c.m)
    acc = vector("acc", c.n)
    Lam = diag(c.Lam)
    qr_dot = c.qd[1] - Lam * c.e
    qr_ddot = c.qd[2] - Lam * (c.qdot - c.qd[1])
    s = c.qdot - qr_dot
    tau_d = c.dynamics(th, c.qdot, qr_dot, qr_ddot) - diag(c.Kp) * c.e - diag(c.Kd) * s
    tau_d_dot = time_derivative(tau_d, [(c.q, c.qdot), (c.qdot, acc), *c.desired_rates(), *c.pose_rates])
    acc_value, acc_stages = solve_or_inverse(model, c.q, th, c.JL.T * c.f - c.dynamics(th, c.qdot, c.qdot),
                                             "acc_solve")
    friction, _, fr_inputs = c.friction_compensation(qr_dot, qr_ddot, s)
    fd, _, _, _, u, taud, stages = c.force_loop(tau_d, tau_d_dot, s, g1, g2, friction)
    return ControllerParts(
        inputs=[*c.base_inputs(), ("theta", th), ("gamma1", g1), ("gamma2", g2), *c.gain_inputs(), *fr_inputs],
        intermediates=[*c.kin, c.jit_intermediate(), *acc_stages, (acc, sp.Matrix(acc_value)), *stages],
        outputs=[("u", u), ("tau_d", taud), ("tau_d_dot", c.taud_dot), ("f_d", fd)],
    )
