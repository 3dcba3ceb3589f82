"""The simulated plant: rigid body (60) driven by the legs, chamber pressures (56)-(57).

State x = [q (6), q̇ (6), p_c (6), spool (6)]; input u = spool command (6, m).
Leg friction: f_fric = F_c tanh(l̇ / v_s) + b l̇ opposing leg motion (N).
Valve: first-order lag spool̇ = (u − spool)/τ_v when τ_v > 0, else spool = u.
"""
from __future__ import annotations

import sympy as sp

from . import hydraulics as hyd
from .constants import baked
from .kinematics import leg_intermediates, pose_symbols, rate_symbols
from .rigid_body import coriolis, gravity, mass_matrix, mass_matrix_inverse, theta_symbols

__all__ = ["plant_rhs"]


def plant_rhs(model, B, P):
    """Symbols and right-hand side of the plant: returns (inputs, xdot, intermediates)."""
    q, qd = pose_symbols(), rate_symbols("qdot")
    pc, spool, u = rate_symbols("pc"), rate_symbols("spool"), rate_symbols("u")
    th = theta_symbols()
    gam = sp.Matrix(sp.symbols("gamma_1 gamma_2", real=True))
    fric = sp.Matrix(sp.symbols("F_coulomb b_viscous v_smooth", real=True))
    tau_v = sp.Symbol("tau_valve", real=True)
    x = sp.Matrix([*q, *qd, *pc, *spool])
    ps, d, A, a, L = (baked(v) for v in (model.supply_pressure, model.underlap, model.piston_area,
                                     model.rod_area, model.chamber_length))
    p_lin, g = baked(model.orifice_linear_below), baked(model.gravity)

    l, JL, _, kin = leg_intermediates(q, qd, B, P, rates=False)  # the plant needs no J̇L
    ldot = rate_symbols("plant_ldot")
    ldot_value = JL * qd
    lagged = sp.Gt(tau_v, 0, evaluate=False)
    # The effective spool position is an intermediate symbol: nesting its Piecewise
    # inside the valve law's would make SymPy merge conditions (slow, and ITE nodes).
    spool_eff = rate_symbols("spool_eff")
    spool_eff_value = sp.Matrix([sp.Piecewise((spool[i], lagged), (u[i], True), evaluate=False)
                                 for i in range(6)])
    spool_dot = sp.Matrix([sp.Piecewise(((u[i] - spool[i]) / tau_v, lagged), (0, True), evaluate=False)
                           for i in range(6)])
    f_leg = rate_symbols("plant_fleg")
    f_leg_value = sp.Matrix([hyd.leg_force(pc[i], ps, A, a)
                             - fric[0] * sp.tanh(ldot[i] / fric[2]) - fric[1] * ldot[i] for i in range(6)])
    D = mass_matrix(q, th)
    qdd = mass_matrix_inverse(q, th) * (JL.T * f_leg - coriolis(D, q, qd) * qd - gravity(th, g))
    c = gam[1] / gam[0]
    pc_dot = sp.Matrix([hyd.chamber_pressure_rate(
        l[i], ldot[i], c * hyd.valve_flow_unit_smooth(spool_eff[i], pc[i], ps, d, p_lin), A, L, gam[0])
        for i in range(6)])
    xdot = sp.Matrix([*qd, *qdd, *pc_dot, *spool_dot])
    inputs = [("x", x), ("u", u), ("theta", th), ("gamma", gam), ("friction", fric),
              ("tau_valve", sp.Matrix([tau_v]))]
    return inputs, xdot, [*kin, (ldot, ldot_value), (f_leg, f_leg_value), (spool_eff, spool_eff_value)]
