"""Kinematics (SymPy): rotations of a floating joint, coordinate symbols (both defined in
:mod:`hydrogen.symbolic.coordinates`), the cylinders' stages.

A floating joint's coordinates are [x, y, z, ψ, θ, φ]: position in the parent frame (m) and
angles (rad) with R = Rz(φ) Ry(θ) Rx(ψ) mapping child-frame vectors to the parent frame.
"""
from __future__ import annotations

import sympy as sp

from .constants import mode_key
# the symbols and rotations sit below the tree (which builds on them); this is their public path too
from .coordinates import (angular_velocity_map, body_angular_velocity_map, matrix_symbols, pose_symbols,  # noqa: F401
                          rate_symbols, rotation, task_map)

__all__ = [
    "pose_symbols", "rate_symbols", "rotation", "angular_velocity_map",
    "body_angular_velocity_map", "task_map", "leg_stages", "leg_intermediates", "matrix_symbols", "pose_rates",
]


def leg_stages(model, q, prefix: str = ""):
    """Cylinder lengths and JL as intermediate symbols: ``(l, JL, stages)``.

    See :meth:`hydrogen.symbolic.tree.SymbolicTree.cylinder_stages`: each link's rotation once,
    then per cylinder l_i = ‖v_i‖ and its row of JL from the unit vector n_i and the pins' lever
    arms. For the floating platform the row is [n_iᵀ, ((R p_i) × n_i)ᵀ T]: the leg force along n_i
    acts on the platform's centre as a force n_i and a moment (R p_i) × n_i, and T maps Euler rates
    to ω. Each leg refers to the nine symbols of R instead of SymPy's expanded products of sines
    and cosines, so the legs share R: JL takes 392 CasADi instructions this way against 744 for
    the symbolic Jacobian of l(q) on the Stewart platform.
    """
    l, JL, stages, _ = _cylinder_stages(model, q, None, prefix)
    return l, JL, stages


_STAGES = {}


def _cylinder_stages(model, q, qdot, prefix=""):
    """The tree's cylinder stages for these symbols, derived once per process (SymPy expressions are
    immutable, so every function that needs them shares one copy)."""
    from .rigid_body import theta_symbols
    from .tree import SymbolicTree

    key = (model.baked_hash(), mode_key(), tuple(sp.Matrix(q)), None if qdot is None else tuple(sp.Matrix(qdot)),
           prefix)
    if key not in _STAGES:
        tree = SymbolicTree(model, q, theta_symbols(model))
        _STAGES[key] = tree.cylinder_stages(prefix, qdot=qdot)
    return _STAGES[key]


def _pose_rates(model, q, qdot):
    """(pairs, stages): each staged link's (R, Ṙ) and (p, ṗ) symbol pairs and the stages defining
    Ṙ = S(ω) R and ṗ (forward mode), derived once per process."""
    from .calculus import time_derivative
    from .tree import skew

    key = (model.baked_hash(), mode_key(), tuple(sp.Matrix(q)), tuple(sp.Matrix(qdot)), "rates")
    if key in _STAGES:
        return _STAGES[key]
    _, _, stages, links = _cylinder_stages(model, q, qdot)
    rate_pairs, pairs, rate_stages = [(sp.Matrix(q), sp.Matrix(qdot))], [], []
    staged_p = {id(sym) for sym, _ in stages}
    values = {id(sym): val for sym, val in stages}
    for k, (link, (R, p, w, _)) in enumerate(links.items()):
        tag = f"{k}" if len(links) > 1 else ""
        R_dot = matrix_symbols(f"Rdot{tag}", 3, 3)
        rate_stages.append((R_dot, skew(w) * R))
        rate_pairs.append((R, R_dot))
        pairs.append((R, R_dot))
        if id(p) in staged_p:
            p_dot = matrix_symbols(f"pdot{tag}", 3, 1)
            rate_stages.append((p_dot, time_derivative(values[id(p)], list(rate_pairs))))
            rate_pairs.append((p, p_dot))
            pairs.append((p, p_dot))
    _STAGES[key] = (pairs, rate_stages)
    return _STAGES[key]


def pose_rates(model, q, qdot) -> list:
    """(symbols, rate symbols) pairs of the staged link poses, (R, Ṙ) and (p, ṗ), for
    :func:`~hydrogen.symbolic.calculus.time_derivative` of expressions that hold them (the cylinder
    kinematics, and the rigid body of a staged tree); their stages are part of
    :func:`leg_intermediates`' list (with rates)."""
    return list(_pose_rates(model, q, qdot)[0])


def leg_intermediates(model, q, qdot, rates: bool = True):
    """Cylinder lengths, JL and d/dt JL as intermediate symbols (keeps SymPy expressions small).

    Returns ``(l, JL, JL_dot, stages)``: ``l`` (m×1), ``JL`` and ``JL_dot`` (m×n) are Matrices
    of symbols and ``stages`` lists ``(symbols, expression)`` pairs to evaluate in order (see
    :func:`leg_stages`). J̇L is the forward-mode time derivative of JL's stage, with q̇ for q,
    Ṙ = S(ω) R for each link's R (ω its angular velocity, base frame), ṗ by forward mode for each
    staged link origin, and l̇ = JL q̇ for l. With ``rates=False`` (the plant) there is no J̇L:
    ``JL_dot`` is None and its stages are left out.
    """
    from .calculus import time_derivative

    l, JL, stages, _ = _cylinder_stages(model, q, qdot)
    if not rates:
        return l, JL, None, stages
    qm, qdm = sp.Matrix(q), sp.Matrix(qdot)
    pairs, rate_stages = _pose_rates(model, q, qdot)
    rate_pairs = [(qm, qdm), *pairs]
    JL_dot = matrix_symbols("JLdot", *JL.shape)
    JL_dot_value = time_derivative(stages[-1][1], [*rate_pairs, (l, JL * qdm)])
    return l, JL, JL_dot, [*stages, *rate_stages, (JL_dot, JL_dot_value.reshape(*JL.shape))]
