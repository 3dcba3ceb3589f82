"""The list of functions derived for a model: names, symbolic inputs, expressions.

This is the single place where the derivation is assembled (acados style:
register everything, then code generation turns the whole list into C in one
pass). Each :class:`SymbolicFunction` holds SymPy symbols and expressions only.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import sympy as sp

from . import hydraulics as hyd
from . import controllers as ctl
from .constants import PRESSURE_EPS, baked, joints
from .kinematics import leg_stages, pose_symbols, rate_symbols
from .plant import plant_rhs
from .rigid_body import coriolis, gravity, mass_matrix, mass_matrix_inverse, regressor, theta_symbols

__all__ = ["SymbolicFunction", "derive_functions", "PRESSURE_EPS"]

@dataclass
class SymbolicFunction:
    """A function to generate: ``name``; inputs and outputs as (name, sympy Matrix) pairs."""

    name: str
    inputs: list
    outputs: list
    doc: str
    intermediates: list = field(default_factory=list)


def _vec(prefix, n=6):
    return rate_symbols(prefix, n)


def kinematics_functions(model) -> list:
    q = pose_symbols()
    _, l, JL, stages = leg_stages(q, *joints(model))
    return [
        SymbolicFunction("leg_lengths", [("q", q)], [("l", l)],
                         "Leg lengths l(q), m.", stages[:2]),
        SymbolicFunction("leg_jacobian", [("q", q)], [("JL", JL)],
                         "JL = dl/dq (6x6).", stages),
        SymbolicFunction("leg_kinematics", [("q", q)], [("l", l), ("JL", JL)],
                         "Leg lengths l(q) (m) and JL = dl/dq together (one Newton step of forward "
                         "kinematics).", stages),
    ]


def rigid_body_functions(model) -> list:
    q, qd = pose_symbols(), _vec("qdot")
    v, w, a, tau = _vec("v"), _vec("w"), _vec("a"), _vec("tau")
    th = theta_symbols()
    g = baked(model.gravity)
    D = mass_matrix(q, th)
    return [
        SymbolicFunction("mass_matrix", [("q", q), ("theta", th)], [("D", D)],
                         "D(q), eq. (63)."),
        SymbolicFunction("coriolis", [("q", q), ("qdot", qd), ("theta", th)],
                         [("C", coriolis(D, q, qd))], "Christoffel-form C(q, qdot)."),
        SymbolicFunction("gravity", [("q", q), ("theta", th)], [("G", gravity(th, g))],
                         "G, eq. (65), N."),
        SymbolicFunction("regressor", [("q", q), ("v", v), ("w", w), ("a", a)],
                         [("Y", regressor(q, v, w, a, th, g))],
                         "Y(q, v, w, a) (6x4): Y theta = D a + C(q, v) w + G."),
        SymbolicFunction("forward_dynamics", [("q", q), ("qdot", qd), ("tau", tau), ("theta", th)],
                         [("qddot", mass_matrix_inverse(q, th) * (tau - coriolis(D, q, qd) * qd - gravity(th, g)))],
                         "Forward dynamics qddot = D^-1 (tau - C(q, qdot) qdot - G)."),
    ]


def hydraulic_functions(model) -> list:
    u, pc, l, ld, wq = _vec("u"), _vec("pc"), _vec("l"), _vec("ldot"), _vec("w")
    gam = sp.Matrix(sp.symbols("gamma_1 gamma_2", real=True))
    ps, d = baked(model.supply_pressure), baked(model.underlap)
    A, a, L = (baked(x) for x in (model.piston_area, model.rod_area, model.chamber_length))
    flow = sp.Matrix([hyd.valve_flow_unit(u[i], pc[i], ps, d) for i in range(6)])
    inv = sp.Matrix([hyd.valve_inverse_unit(wq[i], pc[i], ps, d, PRESSURE_EPS) for i in range(6)])
    # Plant: ṗ_c with q_l = c · (unit flow), c = γ2/γ1, β = γ1, orifice linearised near Δp = 0.
    p_lin = baked(model.orifice_linear_below)
    plant_flow = [hyd.valve_flow_unit_smooth(u[i], pc[i], ps, d, p_lin) for i in range(6)]
    rate = sp.Matrix([hyd.chamber_pressure_rate(l[i], ld[i], gam[1] / gam[0] * plant_flow[i], A, L, gam[0])
                      for i in range(6)])
    force = sp.Matrix([hyd.leg_force(pc[i], ps, A, a) for i in range(6)])
    return [
        SymbolicFunction("valve_flow", [("u", u), ("pc", pc)], [("ql_per_c", flow)],
                         "q_l / c of eq. (57) per leg, m sqrt(Pa)."),
        SymbolicFunction("valve_inverse", [("ql_per_c", wq), ("pc", pc)], [("u", inv)],
                         "Spool position u (m) with q_l / c = ql_per_c: inverse of (57)."),
        SymbolicFunction("pressure_rate", [("l", l), ("ldot", ld), ("pc", pc), ("u", u), ("gamma", gam)],
                         [("pc_dot", rate)],
                         "Control-chamber pressure rate (56)-(57) of the simulated plant, Pa/s "
                         "(orifice law linear below orifice_linear_below)."),
        SymbolicFunction("leg_force", [("pc", pc)], [("f", force)], "f = pc A - ps a, N."),
    ]


_joints = joints  # kept for the benchmarks and tests that import it from here


def plant_functions(model) -> list:
    inputs, xdot, intermediates = plant_rhs(model, *_joints(model))
    return [SymbolicFunction("plant_rhs", inputs, [("xdot", xdot)],
                             "Plant state rate: x = [q, qdot, pc, spool] (24), SI units.", intermediates)]


CONTROLLERS = {
    "backstepping": (ctl.backstepping, "Theorem 1 (known parameters): spool command u, m."),
    "adaptive_robust": (ctl.adaptive_robust, "Theorem 3: adaptive controller, robust sliding observer."),
    "adaptive_observer": (ctl.adaptive_observer, "Theorem 2: adaptive controller, adaptive observer."),
    "p": (ctl.p_controller, "P controller on leg lengths (the paper's baseline)."),
}


def controller_functions(model) -> list:
    B, P = _joints(model)
    out = []
    for name, (make, doc) in CONTROLLERS.items():
        parts = make(model, B, P)
        out.append(SymbolicFunction(f"ctrl_{name}", parts.inputs, parts.outputs, doc, parts.intermediates))
    return out


def derive_functions(model, controllers: bool = True) -> list:
    """Every function generated for ``model``, in a fixed order."""
    funcs = kinematics_functions(model) + rigid_body_functions(model) + hydraulic_functions(model) \
        + plant_functions(model)
    return funcs + controller_functions(model) if controllers else funcs
