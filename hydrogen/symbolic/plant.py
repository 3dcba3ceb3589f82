"""The simulated plant: rigid bodies driven by the cylinders, chamber pressures (56)-(57).

State x = [q (n), q̇ (n), pressures (one block per actuator, its kind's states: p_c of a three-way
cylinder, p_A, p_B of a four-way one; :mod:`hydrogen.pressures`), spool (m), spool rate (m)];
input u = spool command (m, metres).
Friction of each actuator, input ``friction`` = [F_c, b, v_s] per actuator in its own unit:
f_fric = F_c tanh(l̇ / v_s) + b l̇ opposing its motion (N on a cylinder, N m on a rotary actuator).
Valve, input ``valve`` = [τ_v, ω_v, ζ_v]:
- ω_v > 0: second-order servo-valve, spool̈ = ω_v² (u − spool) − 2 ζ_v ω_v spool̇ (ω_v rad/s, the
  natural frequency, where the spool lags the command by 90°);
- else τ_v > 0: first-order lag spool̇ = (u − spool)/τ_v (the spool rate state stays 0);
- else the ideal valve, spool = u (both spool states stay 0).
"""
from __future__ import annotations

import sympy as sp

from ..actuators import actuator
from ..pressures import blocks, n_pressures
from .constants import baked_table
from .kinematics import leg_intermediates, pose_symbols, rate_symbols
from .rigid_body import forward_dynamics, theta_symbols

__all__ = ["plant_rhs"]


def plant_rhs(model):
    """Symbols and right-hand side of the plant: returns (inputs, xdot, intermediates)."""
    n, m = model.n, model.n_cylinders
    q, qd = pose_symbols(model), rate_symbols("qdot", n)
    pc, spool, u = rate_symbols("pc", n_pressures(model)), rate_symbols("spool", m), rate_symbols("u", m)
    th = theta_symbols(model)
    g1, g2 = rate_symbols("gamma1", m), rate_symbols("gamma2", m)
    fric = sp.Matrix([s for i in range(m) for s in sp.symbols(f"F_coulomb_{i} b_viscous_{i} v_smooth_{i}",
                                                                      real=True)])
    spool_rate = rate_symbols("spool_rate", m)
    tau_v, w_v, z_v = valve = sp.symbols("tau_valve omega_valve zeta_valve", real=True)
    x = sp.Matrix([*q, *qd, *pc, *spool, *spool_rate])
    cyl = model.cylinders
    laws = [actuator(c.kind).Symbolic for c in cyl]
    P = [baked_table(actuator(c.kind).parameters(c.table), c.name) for c in cyl]
    p = [tuple(pc[a:b]) for a, b in blocks(model)]  # each actuator's pressure block

    l, JL, _, kin = leg_intermediates(model, q, qd, rates=False)  # the plant needs no J̇L
    ldot = rate_symbols("plant_ldot", m)
    ldot_value = JL * qd
    second = sp.Gt(w_v, 0, evaluate=False)
    lagged = sp.Gt(tau_v, 0, evaluate=False)
    # The effective spool position is an intermediate symbol: nesting its Piecewise
    # inside the valve law's would make SymPy merge conditions (slow, and ITE nodes).
    spool_eff = rate_symbols("spool_eff", m)
    # One selection per cylinder: the spool state with either valve model, else the command. Each
    # branch of a Piecewise costs CasADi two masked terms and a sum, so branches with the same value
    # share one condition, and the spool rate is a sum of masked terms (exactly one non-zero).
    spool_eff_value = sp.Matrix([sp.Piecewise((spool[i], sp.Or(second, lagged, evaluate=False)), (u[i], True),
                                              evaluate=False) for i in range(m)])
    lag_only = sp.And(sp.Not(second, evaluate=False), lagged, evaluate=False)
    spool_dot = sp.Matrix([sp.Piecewise((spool_rate[i], second), (0, True), evaluate=False)
                           + sp.Piecewise(((u[i] - spool[i]) / tau_v, lag_only), (0, True), evaluate=False)
                           for i in range(m)])
    spool_ddot = sp.Matrix([sp.Piecewise((w_v ** 2 * (u[i] - spool[i]) - 2 * z_v * w_v * spool_rate[i], second),
                                         (0, True), evaluate=False) for i in range(m)])
    f_leg = rate_symbols("plant_fleg", m)
    f_leg_value = sp.Matrix([laws[i].force(p[i], P[i])
                             - fric[3 * i] * sp.tanh(ldot[i] / fric[3 * i + 2]) - fric[3 * i + 1] * ldot[i]
                             for i in range(m)])
    qdd, solve = forward_dynamics(model, q, qd, JL.T * f_leg, th, prefix="plant_aba", solve="plant_qdd")  # poses: in kin
    # c = γ2/γ1, β = γ1; the orifice law linearised near Δp = 0 (smooth)
    pc_dot = sp.Matrix([rate for i in range(m) for rate in
                        laws[i].pressure_rates(l[i], ldot[i], p[i], spool_eff[i], g1[i], g2[i] / g1[i], P[i], smooth=True)])
    xdot = sp.Matrix([*qd, *qdd, *pc_dot, *spool_dot, *spool_ddot])
    inputs = [("x", x), ("u", u), ("theta", th), ("gamma1", g1), ("gamma2", g2), ("friction", fric),
              ("valve", sp.Matrix(valve))]
    return inputs, xdot, [*kin, (ldot, ldot_value), (f_leg, f_leg_value), (spool_eff, spool_eff_value), *solve]
