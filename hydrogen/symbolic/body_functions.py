"""The derived function (:class:`SymbolicFunction`) and the rigid body's functions, which use no
block: what :func:`~hydrogen.symbolic.forms.form_costs` counts to choose the rigid body's form, below
the actuator and controller blocks; :mod:`hydrogen.symbolic.functions` lists them with the others."""
from __future__ import annotations

from dataclasses import dataclass, field

from .calculus import matmul
from .kinematics import pose_symbols, rate_symbols
from .rigid_body import (bias_forces, coriolis_matrix, forward_dynamics, gravity, mass_matrix,
                         recursive_inverse_dynamics, recursive_mass_matrix, regressor, regressor_offset,
                         rigid_body_stages, theta_symbols)

__all__ = ["SymbolicFunction", "rigid_body_functions"]


@dataclass
class SymbolicFunction:
    """A function to generate: ``name``; inputs and outputs as (name, sympy Matrix) pairs."""

    name: str
    inputs: list
    outputs: list
    doc: str
    intermediates: list = field(default_factory=list)
    #: The function of the same inputs and intermediates whose outputs hold these (a controller's rates
    #: function: its ``xc_dot``), or None: code generation may select them from that one's graph.
    selects: str | None = None


def rigid_body_functions(model, form_dynamics: bool = False, names=None) -> list:
    """D, C, G, Y (and y0), q̈ and τ of ``model``'s rigid body. ``form_dynamics``: D and τ as the
    form's own D and D a + C q̇ + G rather than by composite bodies and Newton-Euler in link frames
    (what :func:`~hydrogen.symbolic.forms.form_costs` counts: the form's share of the controllers'
    dynamics). ``names``: only the functions of these names are derived (None: all)."""
    n = model.n
    q, qd = pose_symbols(model), rate_symbols("qdot", n)
    v, w, a, tau = (rate_symbols(k, n) for k in ("v", "w", "a", "tau"))
    th = theta_symbols(model)
    wanted = (lambda name: True) if names is None else (lambda name: name in names)
    D = mass_matrix(model, q, th)
    poses = rigid_body_stages(model, q)  # the link poses a staged tree's expressions refer to
    funcs = []
    if wanted("mass_matrix"):
        # D by composite rigid bodies where the tree allows it; "auto" weighs the forms' own D
        crba = None if form_dynamics else recursive_mass_matrix(model, q, th)
        D_out, D_stages = (D, poses) if crba is None else crba
        funcs.append(SymbolicFunction("mass_matrix", [("q", q), ("theta", th)], [("D", D_out)], "D(q) (n x n).",
                                      D_stages))
    if wanted("coriolis"):
        funcs.append(SymbolicFunction("coriolis", [("q", q), ("qdot", qd), ("theta", th)],
                                      [("C", coriolis_matrix(model, q, qd, th))], "Christoffel-form C(q, qdot).",
                                      poses))
    if wanted("gravity"):
        funcs.append(SymbolicFunction("gravity", [("q", q), ("theta", th)], [("G", gravity(model, q, th))],
                                      "G(q), N or N m.", poses))
    if wanted("regressor"):
        funcs.append(SymbolicFunction("regressor", [("q", q), ("v", v), ("w", w), ("a", a)],
                                      [("Y", regressor(model, q, v, w, a, th))],
                                      "Y(q, v, w, a) (n x p): Y theta + y0 = D a + C(q, v) w + G.", poses))
    if wanted("regressor_offset"):
        y0 = regressor_offset(model, q, v, w, a, th)
        if any(e != 0 for e in y0):  # only when some parameter that moves the robot is not adapted
            funcs.append(SymbolicFunction("regressor_offset", [("q", q), ("v", v), ("w", w), ("a", a)],
                                          [("y0", y0)], "y0 = D a + C(q, v) w + G - Y theta (non-adapted share).",
                                          poses))
    if wanted("forward_dynamics"):
        qdd, fd_stages = forward_dynamics(model, q, qd, tau, th, poses)
        funcs.append(SymbolicFunction("forward_dynamics", [("q", q), ("qdot", qd), ("tau", tau), ("theta", th)],
                                      [("qddot", qdd)], "Forward dynamics qddot = D^-1 (tau - C(q, qdot) qdot - G).",
                                      fd_stages))
    if wanted("inverse_dynamics"):
        # τ by recursive Newton-Euler where the tree allows it; "auto" weighs the forms by their own
        # D a + C q̇ + G instead (form_dynamics), the kind of expression the controllers evaluate
        recursive = None if form_dynamics else recursive_inverse_dynamics(model, q, qd, a, th)
        tau_out, id_stages = (matmul(D, a) + bias_forces(model, q, qd, th), poses) if recursive is None \
            else recursive
        funcs.append(SymbolicFunction("inverse_dynamics", [("q", q), ("qdot", qd), ("qddot", a), ("theta", th)],
                                      [("tau", tau_out)],
                                      "Inverse dynamics tau = D(q) qddot + C(q, qdot) qdot + G, N or N m.", id_stages))
    return funcs
